//! A body's render mesh: a sphere voxelised from a closed mesh is drawn from that mesh,
//! each vertex where the particles of the cell of particle centres around it carry it
//! (checked against trilinear interpolation of those particles' displacements, computed
//! here);
//! a slanted blade that severs it clips it where it passed and caps each piece, closed,
//! the cut's vertices on the blade's plane; a mesh outside its body is refused.

mod common;

use cleave::body::lattice::Lattice;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::geometry::mesh::TriangleMesh;
use cleave::prelude::*;
use common::closed_volumes;
use glam::IVec3;
use std::collections::HashMap;
use std::sync::Arc;

const H: f32 = 0.1;

/// A closed sphere of `radius` about the origin: an octahedron subdivided `levels`
/// times, pushed onto the sphere, wound counter-clockwise seen from outside.
fn sphere(radius: f32, levels: u32) -> TriangleMesh {
    let (corners, mut triangles) = common::octahedron(1.0);
    let mut vertices: Vec<Vec3> = corners.into_iter().map(Vec3::from).collect();
    for _ in 0..levels {
        let mut middle: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |a: u32, b: u32, vertices: &mut Vec<Vec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push((vertices[a as usize] + vertices[b as usize]).normalize());
                vertices.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    split(a, b, &mut vertices),
                    split(b, c, &mut vertices),
                    split(c, a, &mut vertices),
                );
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
    }
    let vertices = vertices.into_iter().map(|v| v * radius).collect();
    TriangleMesh::new(vertices, triangles, std::path::Path::new("sphere.obj")).unwrap()
}

/// Where `rest` goes when moved by the trilinear interpolation of the displacements of
/// the live particles at the corners of the cell of particle centres around it (weights
/// renormalised over those), or, with none there, by its nearest particle's.
fn displaced(lattice: &Lattice, at: &HashMap<u32, Vec3>, rest: Vec3) -> Vec3 {
    let g = rest / lattice.spacing() - Vec3::splat(0.5);
    let (base, f) = (g.floor().as_ivec3(), g - g.floor());
    let (mut sum, mut total) = (Vec3::ZERO, 0.0);
    for k in 0..8 {
        let o = IVec3::new(k & 1, k >> 1 & 1, k >> 2 & 1);
        let w = (0..3)
            .map(|a| if o[a] == 1 { f[a] } else { 1.0 - f[a] })
            .product::<f32>();
        if let Some(p) = lattice.at(base + o) {
            sum += w * (at[&p] - lattice.rest_position(p));
            total += w;
        }
    }
    if total > 0.0 {
        return rest + sum / total;
    }
    let p = lattice
        .live_particles()
        .min_by(|a, b| {
            let d = |p: u32| lattice.rest_position(p).distance(rest);
            d(*a).total_cmp(&d(*b))
        })
        .unwrap();
    rest + at[&p] - lattice.rest_position(p)
}

fn sphere_body(sim: &mut Simulation, mesh: &Arc<TriangleMesh>) -> (Entity, BodyDesc) {
    let mut desc = BodyDesc::new(Shape::Mesh(mesh.clone()), H);
    desc.position = Vec3::new(0.0, 0.6, 0.0);
    desc.material = Material::rubber();
    (sim.spawn_body(&desc).unwrap(), desc)
}

#[test]
fn a_sphere_is_drawn_from_its_mesh_and_follows_the_body_as_it_lands() {
    let mesh = Arc::new(sphere(0.45, 3));
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let (body, _) = sphere_body(&mut sim, &mesh);
    let mut worst: f32 = 0.0;
    // falling, landing on the ground, squashing and springing back
    for frame in 0..60 {
        sim.step();
        let surface = sim.world().get::<SurfaceMesh>(body).unwrap();
        assert_eq!(surface.positions.len(), mesh.vertices.len());
        assert_eq!(surface.triangles(), &mesh.triangles[..]);
        let lattice = &sim.world().get::<BodyLattice>(body).unwrap().lattice;
        let at: HashMap<u32, Vec3> = sim.positions(body).unwrap().into_iter().collect();
        for (v, rest) in mesh.vertices.iter().enumerate() {
            // (the body is spawned unturned: its lattice frame is the world's, shifted)
            let off = surface.positions[v].distance(displaced(lattice, &at, *rest));
            assert!(off < 0.5 * H, "frame {frame}: vertex {v} {off} m off");
            worst = worst.max(off);
        }
    }
    println!(
        "worst vertex off trilinear interpolation: {:.4} h",
        worst / H
    );
}

#[test]
fn a_sphere_sliced_at_a_slant_is_clipped_and_capped_closed() {
    sliced_at_a_slant(CutMode::Sever);
    sliced_at_a_slant(CutMode::Split);
}

/// A render-mesh sphere cut at a slant in `mode`: closed per piece, filling the sphere,
/// the cut's vertices on the blade's plane.
fn sliced_at_a_slant(mode: CutMode) {
    let mesh = Arc::new(sphere(0.45, 3));
    let mut sim = Simulation::new(SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    })
    .unwrap();
    let (body, desc) = sphere_body(&mut sim, &mesh);
    // a knife in a plane tilted out of every axis, through a point beside the centre,
    // moving along its plane through the sphere in one frame
    let normal = Vec3::new(1.0, 0.6, 0.35).normalize();
    let along = normal.any_orthonormal_vector();
    let through = desc.position + Vec3::new(0.031, -0.017, 0.022);
    let rotation = Quat::from_mat3(&glam::Mat3::from_cols(along.cross(normal), along, normal));
    let at = |s: f32| Pose {
        position: through + along * s,
        rotation,
    };
    let dt = SimConfig::default().dt;
    sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Blade {
            half_width: 2.0,
            half_height: 1.0,
        },
        cut_width: 0.1 * H,
        cut_mode: mode,
        path: Path {
            keys: vec![(dt, at(3.0)), (2.0 * dt, at(-3.0))],
        },
        pose: at(3.0),
    })
    .unwrap();
    sim.run(3);
    assert_eq!(sim.pieces(body).unwrap().len(), 2);
    let surface = sim.world().get::<SurfaceMesh>(body).unwrap().clone();
    let (rest, triangles, pieces) = (
        &surface.topology().rest,
        surface.triangles(),
        surface.triangle_pieces(),
    );
    // closed per piece, at rest and enclosing the sphere between them
    let volumes = closed_volumes(rest, triangles, pieces);
    assert_eq!(volumes.len(), 2);
    let whole: f64 = closed_volumes(
        &mesh.vertices,
        &mesh.triangles,
        &vec![0; mesh.triangles.len()],
    )[&0];
    let total: f64 = volumes.values().sum();
    assert!(volumes.values().all(|v| *v > 0.1 * whole), "{volumes:?}");
    assert!(
        (total / whole - 1.0).abs() < 1e-3,
        "{mode}: {total} of {whole}"
    );
    // the mesh's vertices keep their numbers; the ones the cut added lie on the blade's
    // plane (the body is spawned unturned: rest frame = world less its offset)
    assert_eq!(&rest[..mesh.vertices.len()], &mesh.vertices[..]);
    let offset = sim.positions(body).unwrap()[0].1
        - sim
            .world()
            .get::<BodyLattice>(body)
            .unwrap()
            .lattice
            .rest_position(0);
    let added = &rest[mesh.vertices.len()..];
    assert!(added.len() > 20, "{} vertices on the cut", added.len());
    for x in added {
        let d = (*x + offset - through).dot(normal).abs();
        assert!(
            d < 1e-3 * H,
            "a cut vertex {} h off the blade's plane",
            d / H
        );
    }
    // 40 frames on the pieces have parted nothing: still closed, no triangle between them
    sim.run(40);
    let surface = sim.world().get::<SurfaceMesh>(body).unwrap();
    closed_volumes(
        &surface.positions,
        surface.triangles(),
        surface.triangle_pieces(),
    );
    println!(
        "{mode}: mesh {} triangles; drawn {} (cut and capped), {} vertices on the cut",
        mesh.triangles.len(),
        triangles.len(),
        added.len()
    );
}

#[test]
fn a_render_mesh_outside_its_body_is_refused_naming_its_file() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let mut desc = BodyDesc::new(Shape::Sphere { radius: 0.3 }, H);
    let mut far = sphere(0.2, 1);
    for v in &mut far.vertices {
        *v += Vec3::new(2.0, 0.0, 0.0);
    }
    desc.render_mesh = Some(Arc::new(far));
    let error = sim.spawn_body(&desc).unwrap_err().to_string();
    assert!(
        error.contains("sphere.obj") && error.contains("outside its body"),
        "{error}"
    );
    assert!(sim.bodies().is_empty());
}
