//! Spin, checked against rigid motions: a rigid block spun in free space turns as a
//! rigid body does under every solver and both models — spawned spinning, and severed
//! in two while it spins (each half keeps the spin).

use cleave::analysis::stats::rigid_fit;
use cleave::ecs::desc::Scene;
use cleave::prelude::*;

/// A simulation of `body` and `tools` under `config` with no gravity, ground or damping.
fn in_free_space(config: SimConfig, body: BodyDesc, tools: Vec<ToolDesc>) -> Simulation {
    Simulation::from_scene(&Scene {
        config: SimConfig {
            gravity: Vec3::ZERO,
            ground: None,
            damping: 0.0,
            ..config
        },
        bodies: vec![body],
        tools,
        colliders: vec![],
        frames: 30,
    })
    .unwrap()
}

/// Half a second of an 8³ rigid block (h = 0.1) of `model` under `solver`, spun at
/// 1 rad/s about z with no gravity, ground or damping, its rest positions and a blade
/// severing it through its axis from 0.2 s to 0.25 s when `cut`: how far each piece
/// turned about z, in degrees.
fn turns(solver: SolverMode, model: Model, cut: bool) -> Vec<f32> {
    let mut body = BodyDesc::new(Shape::cuboid(UVec3::new(8, 8, 8)), 0.1);
    body.angular_velocity = Vec3::new(0.0, 0.0, 1.0);
    body.material = Material {
        model,
        ..Material::rigid()
    };
    // (the blade's normal is its local z: turned to x, so it cuts along the spin's axis)
    let at = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    let blade = ToolDesc {
        shape: ToolShape::Blade {
            half_width: 2.0,
            half_height: 0.5,
        },
        cut_width: 0.01,
        cut_mode: CutMode::Sever,
        path: Path {
            keys: vec![(0.2, at(2.0)), (0.25, at(-2.0)), (0.3, at(-9.0))],
        },
        pose: at(2.0),
    };
    let config = SimConfig {
        solver,
        ..SimConfig::default()
    };
    let mut sim = in_free_space(config, body, if cut { vec![blade] } else { vec![] });
    let b = sim.bodies()[0];
    let rest: Vec<Vec3> = sim.positions(b).unwrap().iter().map(|(_, x)| *x).collect();
    sim.run(30);
    let now = sim.positions(b).unwrap();
    sim.pieces(b)
        .unwrap()
        .iter()
        .map(|piece| {
            let from: Vec<Vec3> = piece.iter().map(|&i| rest[i as usize]).collect();
            let to: Vec<Vec3> = piece
                .iter()
                .map(|&i| now.iter().find(|(j, _)| *j == i).unwrap().1)
                .collect();
            rigid_fit(&from, &to).0.to_scaled_axis().z.to_degrees()
        })
        .collect()
}

#[test]
fn a_rigid_block_spinning_in_free_space_keeps_its_spin() {
    // in 0.5 s it turns 28.65°; the clusters' rotation fits start each substep turned
    // ahead by the last substep's turn, or fitted to the predictions when there is none
    // (`clusters::spin`), else every substep would lose a third of the spin
    let expected = 0.5f32.to_degrees();
    for (solver, model) in [
        (SolverMode::Jacobi, Model::Clusters),
        (SolverMode::GaussSeidel, Model::Clusters),
        (SolverMode::Projective, Model::Clusters),
        (SolverMode::Jacobi, Model::Oriented),
    ] {
        let whole = turns(solver, model, false);
        let halves = turns(solver, model, true);
        eprintln!(
            "{solver} {model}: turned {whole:.2?}; severed, {halves:.2?} (of {expected:.2}°)"
        );
        assert_eq!(whole.len(), 1);
        assert_eq!(halves.len(), 2, "{solver} {model}: severed in two");
        // (neither lost nor gained: a cut gives no piece a spin of its own)
        for turned in whole.into_iter().chain(halves) {
            let kept = turned / expected;
            assert!((0.99..=1.01).contains(&kept), "{solver} {model}: {turned}°");
        }
    }
}

#[test]
fn the_particles_of_a_spinning_cluster_body_turn_with_it_whatever_the_substeps() {
    // Spawned with the particles' velocities of a spin of 1 rad/s about z but their
    // angular velocities zeroed: the clusters turn the particles, and each particle's
    // angular velocity after a frame must be read off that turn (the last substep's),
    // however many substeps the frame has.
    for substeps in [1, 2, 3] {
        let mut body = BodyDesc::new(Shape::cuboid(UVec3::new(6, 6, 6)), 0.1);
        body.angular_velocity = Vec3::new(0.0, 0.0, 1.0);
        body.material = Material::rigid();
        let config = SimConfig {
            substeps,
            ..SimConfig::default()
        };
        let mut sim = in_free_space(config, body, vec![]);
        let world = sim.world_mut();
        let mut spins = world.query::<&mut AngularVelocity>();
        for mut w in spins.iter_mut(world) {
            w.0 = Vec3::ZERO;
        }
        sim.run(30);
        let world = sim.world_mut();
        let mut spins = world.query::<&AngularVelocity>();
        let spins: Vec<Vec3> = spins.iter(world).map(|w| w.0).collect();
        assert_eq!(spins.len(), 216);
        for w in spins {
            assert!((w - Vec3::Z).length() < 0.01, "{substeps} substeps: {w}");
        }
        // half a second at 1 rad/s: every particle turned by 0.5 rad about z
        let turned = Quat::from_rotation_z(0.5);
        let b = sim.bodies()[0];
        for (i, q) in sim.orientations(b).unwrap() {
            assert!(q.dot(turned).abs() > 1.0 - 1e-4, "{substeps}: {i} {q}");
        }
    }
}
