//! Solver behaviour under every solver, with rigid and compliant clusters: rest stays
//! rest, rotated bodies return to a rotated rest shape, a spinning body keeps spinning,
//! linear momentum is conserved,
//! runs are bit-identical across thread counts; and bad input gives errors that name
//! the field.

use bevy_ecs::prelude::*;
use cleave::analysis::stats::body_stats;
use cleave::io::scene::builtin;
use cleave::prelude::*;
use glam::{Quat, UVec3, Vec3};

fn free_config() -> SimConfig {
    SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        damping: 0.0,
        ..SimConfig::default()
    }
}

fn positions(sim: &mut Simulation) -> Vec<Vec3> {
    let mut q = sim.world_mut().query::<(&Particle, &Position)>();
    let mut v: Vec<(u32, Vec3)> = q.iter(sim.world()).map(|(p, x)| (p.index, x.0)).collect();
    v.sort_by_key(|(i, _)| *i);
    v.into_iter().map(|(_, x)| x).collect()
}

fn momentum(sim: &mut Simulation) -> Vec3 {
    let mut q = sim.world_mut().query::<(&Velocity, &InvMass)>();
    q.iter(sim.world()).map(|(v, m)| v.0 / m.0).sum()
}

/// Every solver, with rigid and with compliant clusters.
fn solvers_and_materials() -> impl Iterator<Item = (SolverMode, f32)> {
    SolverMode::ALL
        .into_iter()
        .flat_map(|solver| [0.0, 1e-6].map(|compliance| (solver, compliance)))
}

fn config_for(solver: SolverMode) -> SimConfig {
    SimConfig {
        solver,
        ..free_config()
    }
}

#[test]
fn body_without_forces_stays_at_rest() {
    for (solver, compliance) in solvers_and_materials() {
        let mut sim = Simulation::new(config_for(solver)).unwrap();
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(8, 6, 5)), 0.1);
        desc.position = Vec3::new(1.0, 2.0, 3.0);
        desc.material.compliance = compliance;
        let body = sim.spawn_body(&desc).unwrap();
        let before = positions(&mut sim);
        sim.run(200);
        let after = positions(&mut sim);
        // Exactly: the solver drops steps at the rounding level of the coordinates.
        assert!(
            before == after,
            "{solver} {compliance}: a body without forces moved"
        );
        let shape_error = body_stats(sim.world_mut(), body).unwrap().shape_error_h;
        assert!(
            shape_error < 1e-3,
            "{solver} {compliance}: shape error {shape_error} h"
        );
    }
}

#[test]
fn rotated_body_keeps_its_rotated_rest_shape() {
    for (solver, compliance) in solvers_and_materials() {
        let mut sim = Simulation::new(config_for(solver)).unwrap();
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(10, 4, 4)), 0.1);
        desc.rotation = Quat::from_euler(glam::EulerRot::XYZ, 0.7, -1.1, 2.3);
        desc.material.compliance = compliance;
        let body = sim.spawn_body(&desc).unwrap();
        // Perturb: squash every particle towards the centre along world Y.
        let mut q = sim.world_mut().query::<&mut Position>();
        for mut x in q.iter_mut(sim.world_mut()) {
            x.0.y *= 0.6;
        }
        let squashed = body_stats(sim.world_mut(), body).unwrap().shape_error_h;
        sim.run(120);
        let stats = body_stats(sim.world_mut(), body).unwrap();
        assert!(squashed > 0.3, "perturbation too small: {squashed}");
        assert!(
            stats.shape_error_h < 0.05,
            "{solver} {compliance}: shape error {}",
            stats.shape_error_h
        );
    }
}

#[test]
fn linear_momentum_is_conserved_without_gravity_and_ground() {
    for (solver, compliance) in solvers_and_materials() {
        let mut sim = Simulation::new(config_for(solver)).unwrap();
        let mut desc = BodyDesc::new(Shape::Sphere { radius: 0.45 }, 0.1);
        desc.velocity = Vec3::new(0.3, -0.2, 0.1);
        desc.material.compliance = compliance;
        sim.spawn_body(&desc).unwrap();
        // Give it a spin and a dent so the constraints really work.
        let mut q = sim.world_mut().query::<(&Position, &mut Velocity)>();
        for (x, mut v) in q.iter_mut(sim.world_mut()) {
            v.0 += Vec3::new(-x.0.z, 0.0, x.0.x) * 3.0 + Vec3::Y * x.0.x.signum() * 0.5;
        }
        let p0 = momentum(&mut sim);
        sim.run(60);
        let p1 = momentum(&mut sim);
        // Exact in exact arithmetic (each scheme's cluster steps carry no momentum, the
        // global solve's matrix rows sum to the masses); f32 rounding leaves ≈ 1e-3.
        // Gauss–Seidel drifts more, 0.5–1 % here, as it already did before compliance
        // (same figures at 9982760), and projective dynamics with rigid clusters 0.3 %;
        // neither is explained yet.
        let tolerance = match solver {
            SolverMode::GaussSeidel => 1.5e-2,
            SolverMode::Projective => 5e-3,
            SolverMode::Jacobi => 2e-3,
        };
        assert!(
            (p1 - p0).length() < tolerance * p0.length(),
            "{solver} {compliance}: {p0} -> {p1}"
        );
    }
}

/// A component games might add to some particles: those move to another ECS table.
#[derive(Component)]
struct GameTag;

fn run_scene_bits(name: &str, frames: u32, threads: usize, solver: SolverMode) -> Vec<u32> {
    run_scene_bits_tagged(name, frames, threads, solver, false)
}

/// The state of a scene after `frames` frames as bits; `tag_half` puts every other
/// particle in a second table.
fn run_scene_bits_tagged(
    name: &str,
    frames: u32,
    threads: usize,
    solver: SolverMode,
    tag_half: bool,
) -> Vec<u32> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut scene = builtin(name, 7).unwrap();
        scene.config.solver = solver;
        let mut sim = Simulation::from_scene(&scene).unwrap();
        if tag_half {
            let mut q = sim.world_mut().query::<(Entity, &Particle)>();
            let tagged: Vec<Entity> = q
                .iter(sim.world())
                .filter(|(_, p)| p.index % 2 == 0)
                .map(|(e, _)| e)
                .collect();
            for e in tagged {
                sim.world_mut().entity_mut(e).insert(GameTag);
            }
        }
        sim.run(frames);
        let mut q = sim.world_mut().query::<(Entity, &ClusterMembers)>();
        let clusters: Vec<u32> = q
            .iter(sim.world())
            .flat_map(|(e, m)| [e.index_u32()].into_iter().chain(m.0.iter().copied()))
            .collect();
        positions(&mut sim)
            .iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .chain(clusters)
            .collect()
    })
}

#[test]
fn bit_identical_across_thread_counts_and_runs() {
    for solver in SolverMode::ALL {
        let one = run_scene_bits("slice", 40, 1, solver);
        let two = run_scene_bits("slice", 40, 2, solver);
        let again = run_scene_bits("slice", 40, 2, solver);
        assert_eq!(one.len(), two.len());
        assert!(one == two, "{solver:?}: 1 vs 2 threads differ");
        assert!(two == again, "{solver:?}: two runs differ");
    }
    // with attachments and edge constraints (in projective dynamics' matrix, too)
    for solver in SolverMode::ALL {
        let one = run_scene_bits("soft_beam", 20, 1, solver);
        let two = run_scene_bits("soft_beam", 20, 2, solver);
        assert!(one == two, "soft_beam {solver:?}: 1 vs 2 threads differ");
    }
}

#[test]
fn particles_in_several_tables_move_exactly_as_in_one() {
    // One table: columns copied through the row map; two: entity by entity.
    let one_table = run_scene_bits_tagged("slice", 40, 2, SolverMode::Jacobi, false);
    let two_tables = run_scene_bits_tagged("slice", 40, 2, SolverMode::Jacobi, true);
    assert!(one_table == two_tables, "the two copy paths differ");
}

#[test]
fn gauss_seidel_mode_settles_a_dropped_box() {
    let mut config = builtin("drop", 0).unwrap().config;
    config.solver = SolverMode::GaussSeidel;
    let mut sim = Simulation::new(config).unwrap();
    let body = sim
        .spawn_body(&builtin("drop", 0).unwrap().bodies[0])
        .unwrap();
    sim.run(200);
    let stats = body_stats(sim.world_mut(), body).unwrap();
    assert!(stats.finite);
    assert!(stats.lowest_y > -0.005, "sank to {}", stats.lowest_y);
    assert!(
        stats.shape_error_h < 0.2,
        "shape error {} h",
        stats.shape_error_h
    );
}

#[test]
fn bad_input_is_an_error_naming_the_field() {
    let err = |r: cleave::error::Result<Entity>| r.unwrap_err().to_string();
    let bad_configs = [
        (
            SimConfig {
                gravity: Vec3::new(f32::NAN, 0.0, 0.0),
                ..SimConfig::default()
            },
            "gravity",
        ),
        (
            SimConfig {
                gravity: Vec3::new(0.0, f32::INFINITY, 0.0),
                ..SimConfig::default()
            },
            "gravity",
        ),
        (
            SimConfig {
                substeps: 0,
                ..SimConfig::default()
            },
            "substeps",
        ),
        (
            SimConfig {
                iterations: 0,
                ..SimConfig::default()
            },
            "iterations",
        ),
    ];
    for (config, field) in bad_configs {
        let e = Simulation::new(config).err().unwrap().to_string();
        assert!(e.contains(field), "{e}");
    }
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let shape = Shape::cuboid(UVec3::new(3, 3, 3));
    assert!(err(sim.spawn_body(&BodyDesc::new(shape.clone(), 0.0))).contains("spacing"));
    assert!(err(sim.spawn_body(&BodyDesc::new(shape.clone(), -1.0))).contains("spacing"));
    let e = err(sim.spawn_body(&BodyDesc::new(Shape::Sphere { radius: 0.01 }, 1.0)));
    assert!(e.contains("empty shape"), "{e}");
    let mut pinned = BodyDesc::new(shape.clone(), 0.1);
    pinned.pins = vec![PinRegion {
        min: Vec3::new(f32::NAN, 0.0, 0.0),
        max: Vec3::ONE,
        ..PinRegion::default()
    }];
    assert!(err(sim.spawn_body(&pinned)).contains("body.pins[0].min"));
    // density and spacing each in range, their particle mass (1e-15 kg) not
    let mut tiny = BodyDesc::new(Shape::Cells { cells: UVec3::ONE }, 1e-4);
    tiny.material.density = 1e-3;
    let e = err(sim.spawn_body(&tiny));
    assert!(
        e.contains("material.particle_mass") && e.contains("density"),
        "{e}"
    );
    for (material, field) in [
        (
            Material {
                compliance: -0.1,
                ..Material::default()
            },
            "compliance",
        ),
        (
            Material {
                compliance: f32::NAN,
                ..Material::default()
            },
            "compliance",
        ),
        (
            Material {
                density: 1e30,
                ..Material::default()
            },
            "density",
        ),
        (
            Material {
                max_cluster_size: 1,
                ..Material::default()
            },
            "max_cluster_size",
        ),
    ] {
        let desc = BodyDesc {
            material,
            ..BodyDesc::new(shape.clone(), 0.1)
        };
        let e = err(sim.spawn_body(&desc));
        assert!(e.contains(field) && e.contains("allowed"), "{e}");
    }
    let missing =
        cleave::geometry::mesh::TriangleMesh::load_obj(std::path::Path::new("no/such/file.obj"));
    assert!(
        missing
            .unwrap_err()
            .to_string()
            .contains("no/such/file.obj")
    );
    let dir = std::env::temp_dir().join(format!("cleave-open-{}.obj", std::process::id()));
    std::fs::write(&dir, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let e = cleave::geometry::mesh::TriangleMesh::load_obj(&dir)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not closed"), "{e}");
    let tool = |shape, width| ToolDesc {
        shape,
        cut_width: width,
        cut_mode: CutMode::Remove,
        path: Path::default(),
        pose: Pose::at(Vec3::ZERO),
    };
    assert!(
        sim.spawn_tool(&tool(ToolShape::Sphere { radius: 0.0 }, 0.1))
            .is_err()
    );
    assert!(
        sim.spawn_tool(&tool(ToolShape::Sphere { radius: 1.0 }, -0.1))
            .is_err()
    );
    let nan_path = ToolDesc {
        path: Path {
            keys: vec![
                (0.0, Pose::at(Vec3::ZERO)),
                (1.0, Pose::at(Vec3::new(0.0, f32::NAN, 0.0))),
            ],
        },
        ..tool(ToolShape::Sphere { radius: 1.0 }, 0.1)
    };
    assert!(err(sim.spawn_tool(&nan_path)).contains("tool.path[1].position"));
}

#[test]
fn closed_obj_mesh_voxelises() {
    let path = std::env::temp_dir().join(format!("cleave-cube-{}.obj", std::process::id()));
    let mut obj = String::new();
    for i in 0..8 {
        obj += &format!(
            "v {} {} {}\n",
            (i & 1) as f32 - 0.5,
            ((i >> 1) & 1) as f32 - 0.5,
            ((i >> 2) & 1) as f32 - 0.5
        );
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        obj += &format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]);
    }
    std::fs::write(&path, obj).unwrap();
    let mesh = cleave::geometry::mesh::TriangleMesh::load_obj(&path).unwrap();
    let lattice = Shape::Mesh(std::sync::Arc::new(mesh))
        .voxelise(0.25)
        .unwrap();
    assert_eq!(
        lattice.live_count(),
        64,
        "a unit cube at h = 0.25 holds 4³ lattice points"
    );
}

/// The `drop` scene with its invariants checked every frame, and its body.
fn checked_drop() -> (Simulation, Entity) {
    let mut scene = builtin("drop", 0).unwrap();
    scene.config.check_invariants_every_frame = true;
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    (sim, body)
}

#[test]
fn a_particle_despawned_from_outside_is_removed_as_if_cut() {
    let (mut sim, body) = checked_drop();
    sim.run(5);
    let before = sim.positions(body).unwrap().len();
    // a particle in the middle of the box, gone without a word to the engine
    let victim = {
        let lattice = sim.world().get::<BodyLattice>(body).unwrap();
        lattice.particles[lattice.lattice.len() / 2]
    };
    sim.world_mut().despawn(victim);
    // the frame after: the body has one particle fewer, every invariant holds (checked
    // every frame), every position is finite, and the body still rests
    sim.run(60);
    let positions = sim.positions(body).unwrap();
    assert_eq!(positions.len(), before - 1);
    assert!(positions.iter().all(|(_, p)| p.is_finite()));
    assert!(check_invariants(sim.world()).is_empty());
    let stats = body_stats(sim.world_mut(), body).unwrap();
    assert!(stats.shape_error_h < 0.2, "{}", stats.shape_error_h);
    let dump = serde_json::to_string(&cleave::io::dump::dump_world(sim.world_mut())).unwrap();
    assert!(!dump.contains("null"), "the dump lists no missing particle");
}

#[test]
fn clusters_despawned_from_outside_are_forgotten_and_their_particles_covered_again() {
    let (mut sim, body) = checked_drop();
    sim.run(5);
    let clusters = sim.clusters(body).unwrap();
    // one cluster, then every cluster of one corner particle, gone without a word
    sim.world_mut().despawn(clusters[3].0);
    assert!(
        check_invariants(sim.world()).iter().any(|(_, v)| matches!(
            v,
            cleave::clusters::invariants::Violation::MissingCluster { .. }
        )),
        "the checker sees the hole before the engine repairs it"
    );
    sim.run(1);
    assert!(check_invariants(sim.world()).is_empty());
    let corner = sim.clusters(body).unwrap()[0].1[0];
    let holding: Vec<Entity> = sim
        .clusters(body)
        .unwrap()
        .into_iter()
        .filter(|(_, m)| m.contains(&corner))
        .map(|(e, _)| e)
        .collect();
    for e in holding {
        sim.world_mut().despawn(e);
    }
    // every invariant holds every frame after (checked by the schedule), the particle is
    // in a cluster again, and the body still rests
    sim.run(60);
    assert!(
        sim.clusters(body)
            .unwrap()
            .iter()
            .any(|(_, m)| m.contains(&corner))
    );
    let stats = body_stats(sim.world_mut(), body).unwrap();
    assert!(stats.shape_error_h < 0.2, "{}", stats.shape_error_h);
}

#[test]
fn a_nan_written_into_one_particle_is_repaired_and_does_not_spread() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(8, 4, 4)), 0.1);
    desc.position = Vec3::new(0.0, 0.3, 0.0);
    let body = sim.spawn_body(&desc).unwrap();
    sim.run(10);
    let victim = sim.world().get::<BodyLattice>(body).unwrap().particles[13];
    sim.world_mut()
        .entity_mut(victim)
        .insert((Position(Vec3::NAN), Velocity(Vec3::splat(f32::NAN))));
    let mut cursor = sim
        .world()
        .resource::<Messages<ParticlesRepaired>>()
        .get_cursor();
    let mut reports: Vec<ParticlesRepaired> = Vec::new();
    for _ in 0..30 {
        sim.step();
        reports.extend(
            cursor
                .read(sim.world().resource::<Messages<ParticlesRepaired>>())
                .cloned(),
        );
    }
    assert_eq!(reports.len(), 1, "one report: {reports:?}");
    assert_eq!(
        (reports[0].body, reports[0].particles.clone()),
        (body, vec![13])
    );
    let positions = sim.positions(body).unwrap();
    assert!(
        positions.iter().all(|(_, p)| p.is_finite()),
        "the NaN spread"
    );
    assert!(check_invariants(sim.world()).is_empty());
    // back in its place among its neighbours: within a spacing of the body's shape
    let (_, p) = positions.iter().find(|(i, _)| *i == 13).copied().unwrap();
    assert!(p.y > 0.0 && p.y < 0.5, "{p}");
}
