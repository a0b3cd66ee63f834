//! A body's render mesh: a sphere voxelised from a closed mesh is drawn from that mesh,
//! each vertex where the particles of the cell of particle centres around it carry it
//! (checked against trilinear interpolation of those particles' displacements, computed
//! here);
//! a blade that severs it drops exactly the triangles that would span the cut and draws
//! the lattice's cut faces on both pieces; a mesh outside its body is refused.

mod common;
use cleave::body::lattice::Lattice;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::geometry::mesh::TriangleMesh;
use cleave::prelude::*;
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
fn a_severed_sphere_drops_the_triangles_across_the_cut_and_shows_its_cut_faces() {
    let mesh = Arc::new(sphere(0.45, 3));
    let mut sim = Simulation::new(SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    })
    .unwrap();
    let (body, desc) = sphere_body(&mut sim, &mesh);
    // a blade in the plane x = 0.013 (between particle columns) sweeping down through it
    let at = |y: f32| Pose {
        position: desc.position + Vec3::new(0.013, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Blade {
            half_width: 1.0,
            half_height: 0.6,
        },
        cut_width: 0.1 * H,
        cut_mode: CutMode::Sever,
        path: Path {
            keys: vec![(0.0, at(1.5)), (0.4, at(-1.5))],
        },
        pose: at(1.5),
    })
    .unwrap();
    sim.run(40);
    let lattice = sim
        .world()
        .get::<BodyLattice>(body)
        .unwrap()
        .lattice
        .clone();
    assert_eq!(lattice.piece_count(), 2);
    let surface = sim.world().get::<SurfaceMesh>(body).unwrap();
    let render = surface.render_mesh().expect("a render mesh");
    // the mesh's triangles come first, then the cut faces; their rest places tell
    let rest = &surface.topology().rest;
    let is_mesh_vertex = |v: u32| {
        let r = rest[v as usize];
        (r.length() - 0.45).abs() < 1e-4
    };
    let (kept, faces): (Vec<usize>, Vec<usize>) = (0..surface.triangles().len())
        .partition(|&t| surface.triangles()[t].iter().all(|&v| is_mesh_vertex(v)));
    // the cut plane lies between particle columns at x = 0 (cells k·h … (k + 1)·h): a
    // mesh triangle with a vertex within half a cell of it is bound across it
    let plane = 0.0;
    let dropped = render.triangle_count() - kept.len();
    for &t in &kept {
        let xs = surface.triangles()[t].map(|v| rest[v as usize].x - plane);
        assert!(
            xs.iter().all(|x| *x > 0.0) || xs.iter().all(|x| *x < 0.0),
            "kept triangle {t} spans the cut: {xs:?}"
        );
        assert!(xs.iter().all(|x| x.abs() > 0.5 * H - 1e-4));
    }
    let near = mesh
        .triangles
        .iter()
        .filter(|t| {
            t.iter()
                .any(|&v| (mesh.vertices[v as usize].x - plane).abs() < 0.5 * H)
        })
        .count();
    assert_eq!(
        dropped, near,
        "exactly the triangles bound across the cut go"
    );
    // the cut faces: a quad on each side of every severed link across the plane
    let severed = lattice
        .live_particles()
        .filter(|&p| lattice.coord(p).x == -1)
        .filter(|&p| lattice.at(lattice.coord(p) + IVec3::X).is_some())
        .count();
    assert_eq!(faces.len(), 4 * severed);
    // both pieces show their cut faces, a quad per severed link each, and the mesh's
    // triangles on each side of the cut belong to the piece on that side
    let pieces = surface.triangle_pieces();
    let mut per_piece: HashMap<u32, usize> = HashMap::new();
    for &t in &faces {
        *per_piece.entry(pieces[t]).or_default() += 1;
    }
    assert_eq!(per_piece.len(), 2);
    assert!(
        per_piece.values().all(|&n| n == 2 * severed),
        "{per_piece:?}"
    );
    for side in [-1.0f32, 1.0] {
        let mut on_side: Vec<u32> = kept
            .iter()
            .filter(|&&t| rest[surface.triangles()[t][0] as usize].x * side > 0.0)
            .map(|&t| pieces[t])
            .collect();
        on_side.sort_unstable();
        on_side.dedup();
        assert_eq!(on_side.len(), 1, "one piece on side {side}");
        assert!(per_piece.contains_key(&on_side[0]));
    }
    println!(
        "mesh triangles {}, dropped {dropped}, cut-face triangles {} ({severed} severed links)",
        render.triangle_count(),
        faces.len()
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
