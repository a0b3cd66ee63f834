//! The drawable surfaces, checked by a mesh checker written here (not the engine's):
//! each piece's surface closed and consistently oriented (every directed edge once,
//! its reverse once), enclosing the volume of the cells its live particles own (by the
//! divergence theorem), a box's surface exactly its voxel boundary, cuts opening the
//! surface along the cut, and a bent beam's triangles never flipped.

use cleave::config::SimConfig;
use cleave::cut::tool::CutMode;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::desc::BodyDesc;
use cleave::ecs::layout::SolverCache;
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::io::scene::builtin;
use cleave::prelude::*;
use glam::IVec3;
use std::collections::{HashMap, HashSet};

/// Per piece, the enclosed volume of a closed, consistently oriented mesh; an error
/// naming the first edge that is open, doubled or turned the wrong way.
fn closed_volumes(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    pieces: &[u32],
) -> Result<HashMap<u32, f64>, String> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    let mut volume: HashMap<u32, f64> = HashMap::new();
    for (t, piece) in triangles.iter().zip(pieces) {
        for k in 0..3 {
            let e = (t[k], t[(k + 1) % 3]);
            if e.0 == e.1 {
                return Err(format!("degenerate triangle {t:?}"));
            }
            *directed.entry(e).or_default() += 1;
        }
        let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
        *volume.entry(*piece).or_default() += a.dot(b.cross(c)) / 6.0;
    }
    for (&(a, b), &n) in &directed {
        if n != 1 {
            return Err(format!("edge {a}→{b} in {n} triangles the same way"));
        }
        if directed.get(&(b, a)) != Some(&1) {
            return Err(format!("edge {a}→{b} has no single twin"));
        }
    }
    Ok(volume)
}

/// The volume of the cells `lattice`'s live particles occupy (two halves of a split
/// particle share one cell), in units of h³.
fn occupied_cells(lattice: &cleave::body::lattice::Lattice) -> usize {
    let cells: HashSet<IVec3> = lattice.live_particles().map(|p| lattice.coord(p)).collect();
    cells.len()
}

fn surface(sim: &Simulation, body: Entity) -> SurfaceMesh {
    sim.world()
        .get::<SurfaceMesh>(body)
        .expect("a surface")
        .clone()
}

#[test]
fn a_box_at_rest_is_its_voxel_boundary() {
    let config = SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).unwrap();
    let h = 0.1;
    let (n, m, k) = (5u32, 3u32, 4u32);
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(n, m, k)), h);
    desc.position = Vec3::new(0.3, 1.7, -0.2);
    let body = sim.spawn_body(&desc).unwrap();
    sim.run(1);
    let mesh = surface(&sim, body);
    assert_eq!(mesh.topology_version, 1);
    let lowest = mesh.positions.iter().fold(Vec3::MAX, |a, b| a.min(*b));
    let mut corners = HashSet::new();
    for x in &mesh.positions {
        let w = (*x - lowest) / h;
        assert!(
            (w - w.round()).abs().max_element() < 1e-5,
            "{x} off the grid"
        );
        assert!(corners.insert(w.round().as_ivec3()), "two vertices at {w}");
    }
    let all = (n + 1) * (m + 1) * (k + 1);
    let inside = (n - 1) * (m - 1) * (k - 1);
    assert_eq!(corners.len() as u32, all - inside);
    assert_eq!(mesh.triangles().len() as u32, 4 * (n * m + m * k + n * k));
    let volumes =
        closed_volumes(&mesh.positions, mesh.triangles(), mesh.triangle_pieces()).unwrap();
    assert_eq!(volumes.len(), 1);
    let expected = (n * m * k) as f64 * (h as f64).powi(3);
    assert!((volumes[&0] / expected - 1.0).abs() < 1e-5, "{volumes:?}");
    // normals point out of the box
    let centre = mesh.positions.iter().sum::<Vec3>() / mesh.positions.len() as f32;
    for (x, normal) in mesh.positions.iter().zip(&mesh.normals) {
        assert!((*x - centre).dot(*normal) > 0.0);
    }
}

/// Runs built-in `scene` in `mode`, then checks every body's surface: closed per piece,
/// a piece per body piece, and at rest enclosing the occupied cells' volume. Returns
/// the first body's rest surface area in h².
fn cut_scene_surfaces_are_closed(name: &str, mode: CutMode) -> f64 {
    let mut scene = builtin(name, 0).unwrap();
    for tool in &mut scene.tools {
        tool.cut_mode = mode;
    }
    let frames = scene.frames;
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.run(frames);
    let mut area = None;
    for body in sim.bodies() {
        let mesh = surface(&sim, body);
        let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
        let pieces = sim.pieces(body).unwrap().len();
        let now = closed_volumes(&mesh.positions, mesh.triangles(), mesh.triangle_pieces())
            .unwrap_or_else(|e| panic!("{name} {mode:?}: {e}"));
        assert_eq!(now.len(), pieces, "{name} {mode:?}: a surface per piece");
        let rest = &mesh.topology().rest;
        let at_rest = closed_volumes(rest, mesh.triangles(), mesh.triangle_pieces()).unwrap();
        assert!(
            at_rest.values().all(|v| *v > 0.0),
            "{name} {mode:?}: inside out"
        );
        let h = lattice.spacing() as f64;
        let total: f64 = at_rest.values().sum::<f64>() / h.powi(3);
        let cells = occupied_cells(lattice) as f64;
        // (cut faces rest on the cuts, splitting cells: the two sides of a face that
        // is not flat take opposite diagonals, so the pieces' volumes add up to the
        // cells' to within what those folds hold)
        assert!(
            (total / cells - 1.0).abs() < 1e-3,
            "{name} {mode:?}: {total} h³ enclosed, {cells} cells"
        );
        area.get_or_insert_with(|| {
            mesh.triangles()
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| rest[i as usize].as_dvec3());
                    (b - a).cross(c - a).length() / 2.0
                })
                .sum::<f64>()
                / (h * h)
        });
    }
    area.unwrap()
}

#[test]
fn slice_opens_the_surface_along_the_cut_in_every_mode() {
    // the 24×12×12 block: 2·(24·12 + 12·12 + 24·12) h² before the cut
    let whole = 2.0 * (24.0 * 12.0 + 12.0 * 12.0 + 24.0 * 12.0);
    let severed = cut_scene_surfaces_are_closed("slice", CutMode::Sever);
    // the blade leaves a 12×12 face on each half
    assert!((severed - whole - 2.0 * 144.0).abs() < 1e-3, "{severed} h²");
    // removing a layer takes its rim off the sides; a split blade through particle
    // centres may leave steps
    for mode in [CutMode::Remove, CutMode::Split] {
        let area = cut_scene_surfaces_are_closed("slice", mode);
        assert!(area >= whole + 144.0, "{mode:?}: {area} h²");
    }
}

#[test]
fn dice_and_scoop_surfaces_are_closed_in_every_mode() {
    for scene in ["dice", "scoop"] {
        for mode in [CutMode::Remove, CutMode::Sever, CutMode::Split] {
            cut_scene_surfaces_are_closed(scene, mode);
        }
    }
}

#[test]
fn random_and_cuts_surfaces_are_closed_in_every_mode() {
    for scene in ["random", "cuts"] {
        for mode in [CutMode::Remove, CutMode::Sever, CutMode::Split] {
            cut_scene_surfaces_are_closed(scene, mode);
        }
    }
}

#[test]
fn a_bent_cantilever_flips_no_triangle_and_keeps_its_volume() {
    let scene = builtin("cantilever", 0).unwrap();
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.run(300);
    let body = sim.bodies()[0];
    let mesh = surface(&sim, body);
    let rest = &mesh.topology().rest;
    let normal = |x: &[Vec3], t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| x[i as usize]);
        (b - a).cross(c - a).normalize()
    };
    // the beam spawns unrotated and bends by less than a right angle: every triangle
    // still faces the way it faced at rest
    let worst = mesh
        .triangles()
        .iter()
        .map(|t| normal(&mesh.positions, t).dot(normal(rest, t)))
        .fold(1.0f32, f32::min);
    assert!(worst > 0.5, "a triangle turned to {worst}");
    let volume = |x: &[Vec3]| -> f64 {
        closed_volumes(x, mesh.triangles(), mesh.triangle_pieces())
            .unwrap()
            .values()
            .sum()
    };
    let ratio = volume(&mesh.positions) / volume(rest);
    assert!((ratio - 1.0).abs() < 0.02, "volume ratio {ratio}");
}

/// Each vertex of `body`'s surface lies within `reach` of every particle it is bound
/// to, those particles read from their entities: the vertices follow the particles the
/// topology names, not whatever sits where they used to be in the solver's arrays.
fn vertices_follow_their_particles(
    sim: &Simulation,
    body: Entity,
    reach: f32,
) -> Result<(), String> {
    let mesh = surface(sim, body);
    let lattice = sim.world().get::<BodyLattice>(body).unwrap();
    let topology = mesh.topology();
    for (v, x) in mesh.positions.iter().enumerate() {
        let range = topology.binding_start[v] as usize..topology.binding_start[v + 1] as usize;
        for b in &topology.bindings[range] {
            let entity = lattice.particles[b.particle as usize];
            let Some(p) = sim.world().get::<Position>(entity) else {
                continue;
            };
            if x.distance(p.0) > reach {
                return Err(format!(
                    "vertex {v} at {x} is {} from its particle {} at {}",
                    x.distance(p.0),
                    b.particle,
                    p.0
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn surfaces_follow_their_particles_through_every_layout_change() {
    // split cuts lay the solver out afresh (the dense indices of every body after the
    // cut one move, though their surfaces do not change), sever cuts patch it
    for mode in [CutMode::Split, CutMode::Sever] {
        let mut scene = builtin("cuts", 0).unwrap();
        for tool in &mut scene.tools {
            tool.cut_mode = mode;
        }
        // a body no tool reaches, spawned first: laid out after the cut one
        let h = scene.bodies[0].spacing;
        let mut aside = BodyDesc::new(Shape::cuboid(UVec3::new(4, 3, 5)), h);
        aside.position = Vec3::new(3.0, 0.5, 0.0);
        scene.bodies.insert(0, aside);
        let mut sim = Simulation::from_scene(&scene).unwrap();
        let mut bodies = sim.bodies();
        let world = sim.world();
        bodies.sort_by_key(|b| {
            std::cmp::Reverse(world.get::<BodyLattice>(*b).unwrap().lattice.len())
        });
        let (cut, aside) = (bodies[0], bodies[1]);
        let mut relaid = 0;
        let mut version = sim.world().resource::<SolverCache>().layout.version();
        for frame in 0..scene.frames {
            sim.step();
            let layout = &sim.world().resource::<SolverCache>().layout;
            let first = |b: Entity| layout.body(b).map(|d| d.first);
            assert!(
                first(aside) > first(cut),
                "the untouched body laid out last"
            );
            let now = layout.version();
            relaid += (now != version) as u32;
            version = now;
            // (a vertex rests within a cell of its corner, its particles within the
            // cells around that corner)
            for body in [cut, aside] {
                vertices_follow_their_particles(&sim, body, 3.0 * h)
                    .unwrap_or_else(|e| panic!("{mode:?} frame {frame}: {e}"));
            }
        }
        if mode == CutMode::Split {
            assert!(relaid > 5, "{relaid} layouts laid out afresh");
        }
    }
}

#[test]
fn the_triangles_change_with_the_cuts_and_say_so() {
    use cleave::ecs::resources::{EdgesSevered, ParticlesCut, SurfaceChanged};
    let mut scene = builtin("slice", 0).unwrap();
    scene.tools[0].cut_mode = CutMode::Remove;
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    let mut version = 0;
    let mut cut_frames = 0;
    for frame in 0..120 {
        sim.step();
        let cut = !sim.messages::<ParticlesCut>().is_empty()
            || !sim.messages::<EdgesSevered>().is_empty();
        cut_frames += cut as u32;
        let now = surface(&sim, body).topology_version;
        // the first frame makes the surface; a frame that cut makes it again
        let expected = version + (frame == 0 || cut) as u64;
        assert_eq!(now, expected, "frame {frame}");
        let changed = sim.messages::<SurfaceChanged>();
        assert_eq!(changed.len(), (now != version) as usize, "frame {frame}");
        assert!(
            changed
                .iter()
                .all(|m| m.body == body && m.topology_version == now)
        );
        version = now;
    }
    assert!(cut_frames > 0);
}

#[test]
fn a_smoothed_sphere_is_round_closed_and_keeps_its_volume() {
    let config = SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    };
    let h = 0.1;
    let radius = 0.8;
    // the spread of the vertices' distances from the centre, relative to their mean,
    // and the enclosed volume over the occupied cells' volume
    let roundness = |smooth: bool| {
        let mut sim = Simulation::new(config.clone()).unwrap();
        let mut desc = BodyDesc::new(Shape::Sphere { radius }, h);
        desc.position = Vec3::new(0.0, 2.0, 0.0);
        desc.surface.smooth = smooth;
        let body = sim.spawn_body(&desc).unwrap();
        sim.update_surfaces().unwrap();
        let mesh = surface(&sim, body);
        let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
        let volume = closed_volumes(&mesh.positions, mesh.triangles(), mesh.triangle_pieces())
            .unwrap()[&0]
            / (occupied_cells(lattice) as f64 * (h as f64).powi(3));
        let distances: Vec<f32> = mesh
            .positions
            .iter()
            .map(|x| x.distance(desc.position))
            .collect();
        let mean = distances.iter().sum::<f32>() / distances.len() as f32;
        let spread = (distances.iter().map(|d| (d - mean).powi(2)).sum::<f32>()
            / distances.len() as f32)
            .sqrt()
            / mean;
        (mesh.triangles().to_vec(), spread, volume)
    };
    let (staircase, rough, _) = roundness(false);
    let (rounded, smooth, volume) = roundness(true);
    assert_eq!(staircase, rounded, "smoothing moves vertices only");
    // (measured 0.055 → 0.018: what is left is the voxel sphere's own flats, which
    // smoothing of the steps alone keeps)
    assert!(smooth < rough / 2.5, "spread {rough} → {smooth}");
    assert!((volume - 1.0).abs() < 0.05, "volume {volume} of the cells'");
}

#[test]
fn a_surface_change_past_the_budget_is_put_in_place_when_due_and_says_so() {
    // the slice scene severed twice: by itself, and with a budget of 10 quads put in
    // place 3 frames later, so that every cut's rebuild runs beside the frames
    use cleave::ecs::resources::{SurfaceBudget, SurfaceChanged, SurfaceDeferred};
    use cleave::surface::extract::extract;
    let mut scene = builtin("slice", 0).unwrap();
    scene.tools[0].cut_mode = CutMode::Sever;
    let mut at_once = Simulation::from_scene(&scene).unwrap();
    let mut spread = Simulation::from_scene(&scene).unwrap();
    spread.world_mut().insert_resource(SurfaceBudget {
        quads: 10,
        frames: 3,
    });
    let (a, b) = (at_once.bodies()[0], spread.bodies()[0]);
    let (mut due, mut deferrals, mut installs) = (None, 0, 0);
    for frame in 1..=120u64 {
        let version = surface(&spread, b).topology_version;
        at_once.step();
        spread.step();
        let mesh = surface(&spread, b);
        let deferred = spread.messages::<SurfaceDeferred>();
        let changed = spread.messages::<SurfaceChanged>();
        for m in &deferred {
            assert!(
                m.body == b && m.quads > 10 && m.due == frame + 3,
                "frame {frame}"
            );
            due = Some(m.due);
            deferrals += 1;
        }
        if frame == 1 || due == Some(frame) {
            // the first surface at once; a deferred one at its frame, unless the body
            // was cut again meanwhile (then it waits for the newest)
            assert!(
                deferred.is_empty() && !mesh.is_rebuilding(),
                "frame {frame}"
            );
            assert_eq!(mesh.topology_version, version + 1, "frame {frame}");
            assert_eq!(changed.len(), 1, "frame {frame}");
            installs += (frame > 1) as u32;
            due = None;
        } else {
            // meanwhile the last surface, carried by the particles
            assert_eq!(mesh.topology_version, version, "frame {frame}");
            assert!(changed.is_empty(), "frame {frame}");
            assert_eq!(mesh.is_rebuilding(), due.is_some(), "frame {frame}");
            assert!(mesh.positions.iter().all(|x| x.is_finite()));
        }
    }
    assert!(
        installs > 0 && deferrals >= installs,
        "{deferrals} {installs}"
    );
    // the last rebuild: the local update the undeferred run made when the body was cut
    // in one frame; the surface of the lattice extracted afresh when it was cut again
    // while a rebuild ran
    let lattice = &spread.world().get::<BodyLattice>(b).unwrap().lattice;
    let last = surface(&spread, b);
    if deferrals == 1 {
        assert!(last.topology() == surface(&at_once, a).topology());
    } else {
        assert!(last.topology() == &extract(lattice));
    }
    // the physics never waits for a surface
    let positions = |sim: &Simulation, body| -> Vec<glam::Vec3> {
        let l = sim.world().get::<BodyLattice>(body).unwrap();
        l.particles
            .iter()
            .filter_map(|e| sim.world().get::<Position>(*e).map(|p| p.0))
            .collect()
    };
    assert_eq!(positions(&at_once, a), positions(&spread, b));
}

#[test]
fn bringing_surfaces_up_to_date_puts_a_deferred_rebuild_in_place() {
    use cleave::ecs::resources::SurfaceBudget;
    let mut scene = builtin("slice", 0).unwrap();
    scene.tools[0].cut_mode = CutMode::Sever;
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.world_mut().insert_resource(SurfaceBudget {
        quads: 10,
        frames: 1000,
    });
    let body = sim.bodies()[0];
    let mut frames = 0;
    while !surface(&sim, body).is_rebuilding() {
        sim.step();
        frames += 1;
        assert!(frames < 200, "the slice never cut");
    }
    let version = surface(&sim, body).topology_version;
    sim.update_surfaces().unwrap();
    let mesh = surface(&sim, body);
    assert!(!mesh.is_rebuilding());
    assert_eq!(mesh.topology_version, version + 1);
    // two triangles for every face of the cells, the cut's faces among them
    let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
    let faces = cleave::surface::extract::face_count(lattice) as usize;
    assert_eq!(mesh.triangles().len(), 2 * faces);
}

#[test]
fn a_surface_is_carried_again_only_once_a_particle_moved_past_still() {
    // a box drifting without gravity, a tenth of `STILL` spacings a frame
    let (h, frames_past_still) = (0.1, 10);
    let config = SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        damping: 0.0,
        ..SimConfig::default()
    };
    let drift = SurfaceMesh::STILL * h / frames_past_still as f32;
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(5)), h);
    desc.velocity = Vec3::X * drift / config.dt;
    let mut sim = Simulation::new(config).unwrap();
    let body = sim.spawn_body(&desc).unwrap();
    sim.step();
    let shown = sim.surface(body).unwrap().positions.clone();
    let lowest_x = |sim: &Simulation| {
        let particles = sim.positions(body).unwrap();
        particles.iter().map(|(_, x)| x.x).fold(f32::MAX, f32::min)
    };
    let start = lowest_x(&sim);
    let mut kept = 0;
    while sim.surface(body).unwrap().positions == shown {
        sim.step();
        kept += 1;
        assert!(kept <= 2 * frames_past_still, "never carried again");
    }
    // kept while every particle stayed within STILL of where the surface shows it
    assert!(
        kept >= frames_past_still / 2,
        "carried again after {kept} frames"
    );
    // then carried with the box: every vertex moved as its particles did
    let moved = lowest_x(&sim) - start;
    assert!(moved > SurfaceMesh::STILL * h, "moved {moved}");
    for (now, then) in sim.surface(body).unwrap().positions.iter().zip(&shown) {
        let d = *now - *then;
        assert!(
            (d - Vec3::X * moved).abs().max_element() < 1e-5 * h,
            "a vertex moved {d}, the box {moved}"
        );
    }
}
