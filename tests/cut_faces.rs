//! Cut faces where the blade passed: oblique planar blades through blocks at rest, in
//! `sever` and `split`, measured against the blade's own plane (not the engine's
//! crossings) in the rest frame and, 40 frames later, in the world; a sphere's carve
//! against the sphere. The meshes are checked by a checker written here: closed,
//! consistently oriented, and the pieces' enclosed volumes adding up to the block's.

mod common;

use cleave::config::SimConfig;
use cleave::cut::tool::{CutMode, Path, Pose, ToolShape};
use cleave::ecs::components::BodyLattice;
use cleave::ecs::desc::{BodyDesc, ToolDesc};
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::prelude::*;
use common::closed_volumes;
use glam::{Mat3, Quat};

const H: f32 = 0.1;

/// Space without gravity or ground.
fn still() -> SimConfig {
    SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    }
}

/// A block of `n³` cells of spacing [`H`] centred on the origin, and the offset from
/// its rest frame to the world (world = rest + offset: it is spawned unturned).
fn block(sim: &mut Simulation, n: u32) -> (Entity, Vec3) {
    let body = sim
        .spawn_body(&BodyDesc::new(Shape::cuboid(UVec3::splat(n)), H))
        .unwrap();
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    let p = lattice.live_particles().next().unwrap();
    let rest = lattice.rest_position(p);
    let world = sim.positions(body).unwrap()[0];
    assert_eq!(world.0, p);
    (body, world.1 - rest)
}

/// A blade in the plane through `through` with unit `normal`, knifing along the plane
/// through everything within `reach` of it between frames 1 and 2.
fn knife(normal: Vec3, through: Vec3, reach: f32, mode: CutMode) -> ToolDesc {
    knife_at(0, normal, through, reach, mode)
}

/// [`knife`], between frames `frame + 1` and `frame + 2`.
fn knife_at(frame: u32, normal: Vec3, through: Vec3, reach: f32, mode: CutMode) -> ToolDesc {
    let along = normal.any_orthonormal_vector();
    let rotation = Quat::from_mat3(&Mat3::from_cols(along.cross(normal), along, normal));
    let dt = SimConfig::default().dt;
    let at = |s: f32| Pose {
        position: through + along * s,
        rotation,
    };
    ToolDesc {
        shape: ToolShape::Blade {
            half_width: 2.0 * reach,
            half_height: reach,
        },
        cut_width: 0.5 * H,
        cut_mode: mode,
        path: Path {
            keys: vec![
                ((frame + 1) as f32 * dt, at(2.0 * reach)),
                ((frame + 2) as f32 * dt, at(-2.0 * reach)),
            ],
        },
        pose: at(2.0 * reach),
    }
}

/// The box of the cells of `lattice`'s live particles, rest frame.
fn bounds(lattice: &cleave::body::lattice::Lattice) -> (Vec3, Vec3) {
    let cells: Vec<Vec3> = (lattice.live_particles())
        .map(|p| lattice.coord(p).as_vec3() * H)
        .collect();
    let lo = cells.iter().copied().fold(Vec3::MAX, Vec3::min);
    let hi = cells.iter().copied().fold(Vec3::MIN, Vec3::max) + Vec3::splat(H);
    (lo, hi)
}

/// The vertices of triangles that do not lie in one face of the box `[lo, hi]` (rest
/// frame): the cut faces', rims included.
fn cut_face_vertices(rest: &[Vec3], triangles: &[[u32; 3]], lo: Vec3, hi: Vec3) -> Vec<u32> {
    let on = |x: Vec3, axis: usize, value: f32| (x[axis] - value).abs() < 1e-4;
    let mut found: Vec<u32> = triangles
        .iter()
        .filter(|t| {
            !(0..3).any(|axis| {
                [lo[axis], hi[axis]]
                    .iter()
                    .any(|&v| t.iter().all(|&i| on(rest[i as usize], axis, v)))
            })
        })
        .flatten()
        .copied()
        .collect();
    found.sort_unstable();
    found.dedup();
    found
}

/// RMS and largest distance of `points` from the plane through `through` with unit
/// `normal`, in units of h.
fn off_plane(points: impl Iterator<Item = Vec3>, normal: Vec3, through: Vec3) -> (f32, f32) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f32, 0);
    for x in points {
        let d = (x - through).dot(normal).abs() / H;
        sum += (d as f64).powi(2);
        max = max.max(d);
        n += 1;
    }
    assert!(n > 0, "no cut face");
    (((sum / n as f64).sqrt()) as f32, max)
}

/// Cuts an `n³` block by a blade through a point 0.137 h off its centre with `normal`
/// in `mode`; checks the cut faces against the blade's plane at once (rest frame) and
/// 40 frames later (world), and the surface closed with the block's volume.
fn oblique(n: u32, normal: Vec3, mode: CutMode) -> ((f32, f32), (f32, f32)) {
    let mut sim = Simulation::new(still()).unwrap();
    let (body, offset) = block(&mut sim, n);
    let normal = normal.normalize();
    let through = normal * 0.137 * H;
    sim.spawn_tool(&knife(normal, through, n as f32 * H, mode))
        .unwrap();
    sim.run(3);
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    assert_eq!(lattice.piece_count(), 2, "{mode} {normal}: cut in two");
    let (lo, hi) = bounds(lattice);
    let mesh = sim.world().get::<SurfaceMesh>(body).unwrap().clone();
    let topology = mesh.topology();
    let on_cut = cut_face_vertices(&topology.rest, &topology.triangles, lo, hi);
    assert!(
        on_cut.len() >= (n * n) as usize,
        "{} cut face vertices",
        on_cut.len()
    );
    let rest = off_plane(
        on_cut.iter().map(|&v| topology.rest[v as usize]),
        normal,
        through - offset,
    );
    let volumes = closed_volumes(
        &topology.rest,
        &topology.triangles,
        &topology.triangle_piece,
    );
    assert_eq!(volumes.len(), 2);
    let total: f64 = volumes.values().sum();
    let block = (n as f64 * H as f64).powi(3);
    assert!(
        (total / block - 1.0).abs() < 1e-3,
        "{mode} {normal}: pieces enclose {total} of {block}"
    );
    sim.run(40);
    let mesh = sim.world().get::<SurfaceMesh>(body).unwrap();
    closed_volumes(&mesh.positions, mesh.triangles(), mesh.triangle_pieces());
    let world = off_plane(
        on_cut.iter().map(|&v| mesh.positions[v as usize]),
        normal,
        through,
    );
    (rest, world)
}

fn assert_on_plane(n: u32, mode: CutMode) {
    let normals = [
        Vec3::new(30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(1.0, 0.6, 0.35),
    ];
    for normal in normals {
        let (rest, world) = oblique(n, normal, mode);
        eprintln!(
            "{n}³ {mode} {normal}: rest {:.4} h rms, {:.4} h max; world {:.4} h rms, {:.4} h max",
            rest.0, rest.1, world.0, world.1
        );
        for (frame, (rms, max)) in [("rest", rest), ("world", world)] {
            assert!(
                rms <= 0.05 && max <= 0.15,
                "{n}³ {mode} {normal} ({frame}): {rms:.3} h rms, {max:.3} h at most"
            );
        }
    }
}

#[test]
fn oblique_severs_lie_on_the_blades_plane() {
    assert_on_plane(16, CutMode::Sever);
    assert_on_plane(32, CutMode::Sever);
}

#[test]
fn oblique_splits_lie_on_the_blades_plane() {
    assert_on_plane(16, CutMode::Split);
    assert_on_plane(32, CutMode::Split);
}

#[test]
fn crossings_lie_where_the_blade_passed_in_the_bodys_rest_frame() {
    // a turned block: the crossings are kept in its rest frame
    let mut sim = Simulation::new(still()).unwrap();
    let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.4, 1.1, -0.3);
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(12)), H);
    desc.rotation = turn;
    let body = sim.spawn_body(&desc).unwrap();
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    let p = lattice.live_particles().next().unwrap();
    let to_rest = |x: Vec3| {
        turn.inverse() * (x - sim.positions(body).unwrap()[0].1) + lattice.rest_position(p)
    };
    let normal = Vec3::new(1.0, 0.6, 0.35).normalize();
    let through = Vec3::new(0.02, -0.01, 0.03);
    let (rest_normal, rest_through) = (turn.inverse() * normal, to_rest(through));
    sim.spawn_tool(&knife(normal, through, 1.2, CutMode::Sever))
        .unwrap();
    sim.run(3);
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    assert_eq!(lattice.piece_count(), 2);
    let mut checked = 0;
    for a in lattice.live_particles() {
        for d in [1, 3, 5] {
            let Some(b) =
                lattice.at(lattice.coord(a) + cleave::body::lattice::NEIGHBOUR_OFFSETS[d])
            else {
                continue;
            };
            let crossing = lattice.crossing_between(a, b);
            // every severed edge has its crossing, and no linked one
            assert_eq!(
                crossing.is_some(),
                lattice.link(a, d) == u32::MAX,
                "{a}–{b}"
            );
            let Some(c) = crossing else { continue };
            let (ra, rb) = (lattice.rest_position(a), lattice.rest_position(b));
            let at = ra + c.fraction * (rb - ra);
            assert!(
                (at - rest_through).dot(rest_normal).abs() < 1e-3 * H,
                "{a}–{b} off the plane"
            );
            assert!(c.normal.cross(rest_normal).length() < 1e-3, "{}", c.normal);
            checked += 1;
        }
    }
    assert!(checked > 144, "{checked} crossings");
}

/// The cut face of a sphere of `radius` carving (sever) down from above a 16³ block
/// to `depth` below its top: its vertices' RMS distance from the swept surface
/// (the capsule of the sphere's path), in h.
fn carved_face(radius: f32, depth: f32) -> f32 {
    let mut sim = Simulation::new(still()).unwrap();
    let (body, offset) = block(&mut sim, 16);
    let top = 0.8;
    let (from, to) = (
        Vec3::new(0.03, top + radius + 0.2, -0.02),
        Vec3::new(0.03, top - depth, -0.02),
    );
    let dt = SimConfig::default().dt;
    sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Sphere { radius },
        cut_width: 0.5 * H,
        cut_mode: CutMode::Sever,
        path: Path {
            keys: vec![(dt, Pose::at(from)), (4.0 * dt, Pose::at(to))],
        },
        pose: Pose::at(from),
    })
    .unwrap();
    sim.run(6);
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    assert_eq!(lattice.piece_count(), 2, "a plug carved out");
    let (lo, hi) = bounds(lattice);
    let mesh = sim.world().get::<SurfaceMesh>(body).unwrap();
    let topology = mesh.topology();
    let on_cut = cut_face_vertices(&topology.rest, &topology.triangles, lo, hi);
    assert!(on_cut.len() > 50);
    let (a, b) = (from - offset, to - offset);
    let swept = |x: Vec3| {
        let s = ((x - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        (x.distance(a + s * (b - a)) - radius).abs() / H
    };
    let sum: f32 = on_cut
        .iter()
        .map(|&v| swept(topology.rest[v as usize]).powi(2))
        .sum();
    (sum / on_cut.len() as f32).sqrt()
}

#[test]
fn a_spheres_carve_faces_lie_on_what_it_swept() {
    for (radius, depth) in [(0.35, 0.3), (0.5, 0.45)] {
        let rms = carved_face(radius, depth);
        eprintln!("sphere r = {radius}: carve face {rms:.4} h rms from the swept surface");
        assert!(rms <= 0.1, "r = {radius}: {rms} h rms");
    }
}

#[test]
fn a_stroke_cuts_along_its_fan() {
    let mut sim = Simulation::new(still()).unwrap();
    let (body, offset) = block(&mut sim, 16);
    let eye = Vec3::new(0.3, 0.5, 6.0);
    let cut = cleave::cut::stroke::stroke_cut(
        eye,
        Vec3::new(-1.2, 1.0, 0.013) - eye,
        Vec3::new(1.1, -0.9, -0.021) - eye,
        1.0,
        12.0,
    )
    .unwrap();
    let dt = SimConfig::default().dt;
    let keys = (cut.poses.iter().enumerate())
        .map(|(i, p)| ((i + 1) as f32 * dt, *p))
        .collect();
    sim.spawn_tool(&ToolDesc {
        shape: cut.shape,
        cut_width: 0.5 * H,
        cut_mode: CutMode::Sever,
        path: Path { keys },
        pose: cut.poses[0],
    })
    .unwrap();
    sim.run(cut.poses.len() as u32 + 2);
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    assert_eq!(lattice.piece_count(), 2);
    let (lo, hi) = bounds(lattice);
    let topology = sim
        .world()
        .get::<SurfaceMesh>(body)
        .unwrap()
        .topology()
        .clone();
    let on_cut = cut_face_vertices(&topology.rest, &topology.triangles, lo, hi);
    let normal = cut.poses[0].rotation * Vec3::Z;
    let (rms, max) = off_plane(
        on_cut.iter().map(|&v| topology.rest[v as usize]),
        normal,
        eye - offset,
    );
    eprintln!("stroke: {rms:.4} h rms, {max:.4} h at most from its fan");
    assert!(rms <= 0.1, "{rms} h rms");
}

/// A body split by an oblique blade, gravity off: how far its pieces' centroids move
/// in the 60 frames after the cut, in h.
#[test]
fn split_pieces_stay_where_they_were() {
    let mut sim = Simulation::new(still()).unwrap();
    let (body, _) = block(&mut sim, 16);
    let normal = Vec3::new(1.0, 0.6, 0.35).normalize();
    sim.spawn_tool(&knife(normal, normal * 0.137 * H, 1.6, CutMode::Split))
        .unwrap();
    sim.run(3);
    assert_eq!(sim.pieces(body).unwrap().len(), 2);
    let before = sim.piece_centroids(body).unwrap();
    sim.run(60);
    let after = sim.piece_centroids(body).unwrap();
    let moved = before
        .iter()
        .zip(&after)
        .map(|(a, b)| a.distance(*b) / H)
        .fold(0.0f32, f32::max);
    eprintln!("split pieces' centroids moved {moved:.5} h in 60 frames");
    assert!(moved < 0.02, "{moved} h");
}

#[test]
fn a_split_block_on_the_ground_keeps_resting_on_its_balls() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 12)), H);
    desc.position = Vec3::new(0.0, 0.3, 0.0);
    let body = sim.spawn_body(&desc).unwrap();
    sim.run(60);
    // a blade through the bottom layer's particles, parallel to the ground: every
    // particle of it split, its lower half resting a quarter cell lower
    let bottom = sim
        .positions(body)
        .unwrap()
        .iter()
        .map(|p| p.1.y)
        .fold(f32::MAX, f32::min);
    let through = Vec3::new(0.0, bottom + 0.05 * H, 0.0);
    sim.spawn_tool(&knife_at(60, Vec3::Y, through, 1.2, CutMode::Split))
        .unwrap();
    sim.run(60);
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    let halves = lattice
        .live_particles()
        .filter(|&p| lattice.is_split_half(p))
        .count();
    assert!(halves >= 2 * 144, "{halves} halves");
    let radius = |p: u32| 0.5 * H - lattice.split_shift(p).length() * H;
    let lowest = sim
        .positions(body)
        .unwrap()
        .into_iter()
        .map(|(p, x)| (x.y, radius(p)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap();
    eprintln!(
        "lowest particle centre {:.4} h above the ground, its radius {:.4} h",
        lowest.0 / H,
        lowest.1 / H
    );
    assert!((lowest.0 - lowest.1).abs() < 0.02 * H, "{lowest:?}");
}

/// Every edge's crossing of `body`, by particle pair, in order.
fn crossings_of(sim: &Simulation, body: Entity) -> Vec<(u32, u32, u32, [u32; 3])> {
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    let mut out = Vec::new();
    for a in lattice.live_particles() {
        for d in [1, 3, 5] {
            let next = lattice.coord(a) + cleave::body::lattice::NEIGHBOUR_OFFSETS[d];
            if let Some(c) = lattice
                .at(next)
                .and_then(|b| lattice.crossing_between(a, b))
            {
                out.push((
                    a,
                    d as u32,
                    c.fraction.to_bits(),
                    c.normal.to_array().map(f32::to_bits),
                ));
            }
        }
    }
    out
}

#[test]
fn crossings_survive_a_save_and_a_bad_one_is_refused() {
    let mut sim = Simulation::new(still()).unwrap();
    let (body, _) = block(&mut sim, 12);
    sim.spawn_tool(&knife(
        Vec3::new(1.0, 0.6, 0.35).normalize(),
        Vec3::ZERO,
        1.2,
        CutMode::Split,
    ))
    .unwrap();
    sim.run(3);
    let before = crossings_of(&sim, body);
    assert!(before.len() > 100);
    let mut bytes = Vec::new();
    sim.save(&mut bytes).unwrap();
    let mut loaded = Simulation::load(&bytes[..]).unwrap();
    let copy = loaded.loaded_entity(body).unwrap();
    assert_eq!(crossings_of(&loaded, copy), before);
    // the two go on alike: the same dump, the same surfaces vertex for vertex (what an
    // export writes)
    sim.run(2);
    loaded.run(2);
    let dump = |s: &mut Simulation| {
        serde_json::to_string(&cleave::io::dump::dump_world(s.world_mut())).unwrap()
    };
    assert!(dump(&mut sim) == dump(&mut loaded), "the dumps differ");
    let surface = |s: &Simulation, b| {
        let m = s.world().get::<SurfaceMesh>(b).unwrap();
        let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
            v.iter().map(|x| x.to_array().map(f32::to_bits)).collect()
        };
        (
            bits(&m.topology().rest),
            bits(&m.positions),
            bits(&m.normals),
            m.triangles().to_vec(),
        )
    };
    assert!(
        surface(&sim, body) == surface(&loaded, copy),
        "the surfaces differ"
    );
    // a crossing out of range in the file: refused, naming the part
    let fraction = f32::from_bits(before[0].2);
    let pattern = fraction.to_le_bytes();
    let mut bad = bytes.clone();
    // sections: u64 length, u32 CRC, bytes; the fifth is the bodies
    let mut at = 12;
    for _ in 0..4 {
        at += 12 + u64::from_le_bytes(bad[at..at + 8].try_into().unwrap()) as usize;
    }
    let len = u64::from_le_bytes(bad[at..at + 8].try_into().unwrap()) as usize;
    let section = at + 12..at + 12 + len;
    let k = bad[section.clone()]
        .windows(4)
        .position(|w| w == pattern)
        .expect("the crossing's fraction in the bodies section");
    let k = section.start + k;
    bad[k..k + 4].copy_from_slice(&1.5f32.to_le_bytes());
    let crc = crc32fast::hash(&bad[section.clone()]);
    bad[at + 8..at + 12].copy_from_slice(&crc.to_le_bytes());
    let error = Simulation::load(&bad[..])
        .err()
        .expect("refused")
        .to_string();
    assert!(
        error.contains("bodies: body 0: the crossing of edge"),
        "{error}"
    );
}
