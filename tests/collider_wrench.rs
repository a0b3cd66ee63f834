//! Rigid bodies of the game's own engine, both ways: the wrench the particles put on a
//! collider (`Simulation::collider_wrench`), checked against physics outside the code —
//! a table under a resting block takes its weight and the torque of its offset, and a
//! box the test's own integrator moves by the wrench gains the momentum the soft block
//! sliding on it loses.

use cleave::ecs::components::{ColliderWrench, InvMass};
use cleave::ecs::resources::ColliderPushed;
use cleave::prelude::*;

const DT: f32 = 1.0 / 60.0;

/// A box the test integrates (not cleave): mass, position, velocity.
struct RigidBox {
    entity: Entity,
    mass: f32,
    position: Vec3,
    velocity: Vec3,
}

impl RigidBox {
    /// One semi-implicit Euler step under `gravity` and the particles' force of the last
    /// frame, moving only along `free` axes (1) — then tells cleave where it goes.
    fn step(&mut self, sim: &mut Simulation, gravity: Vec3, free: Vec3) {
        let (force, _) = sim.collider_wrench(self.entity).unwrap();
        self.velocity += (gravity + force / self.mass) * DT * free;
        self.position += self.velocity * DT;
        sim.set_collider_pose(self.entity, Pose::at(self.position))
            .unwrap();
    }
}

fn spawn_box(sim: &mut Simulation, half: Vec3, at: Vec3, friction: f32, mass: f32) -> RigidBox {
    let entity = sim
        .spawn_collider(&ColliderDesc {
            shape: ColliderShape::Box { half_extents: half },
            friction,
            pose: Pose::at(at),
            path: Path { keys: vec![] },
        })
        .unwrap();
    RigidBox {
        entity,
        mass,
        position: at,
        velocity: Vec3::ZERO,
    }
}

/// Σ m v over the live particles of `body`.
fn momentum(sim: &mut Simulation, body: Entity) -> Vec3 {
    let lattice = sim.world().get::<BodyLattice>(body).unwrap();
    let particles: Vec<Entity> = (lattice.lattice.live_particles())
        .map(|i| lattice.particles[i as usize])
        .collect();
    particles
        .iter()
        .map(|&e| {
            let w = sim.world();
            w.get::<Velocity>(e).unwrap().0 / w.get::<InvMass>(e).unwrap().0
        })
        .sum()
}

#[test]
fn a_table_under_a_resting_block_takes_its_weight_and_the_torque_of_its_offset() {
    let config = SimConfig {
        ground: None,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).unwrap();
    let gravity = sim.config().gravity;
    // a table top (a box collider, the game's rigid body held still) and a block
    // resting on it 0.3 m right of its centre
    let table = spawn_box(&mut sim, Vec3::new(1.0, 0.2, 1.0), Vec3::ZERO, 0.5, 1.0);
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(6, 4, 6)), 0.1);
    desc.position = Vec3::new(0.3, 0.45, 0.0);
    let body = sim.spawn_body(&desc).unwrap();
    sim.run(240);
    let (mut force, mut torque) = (Vec3::ZERO, Vec3::ZERO);
    for _ in 0..60 {
        sim.step();
        let (f, t) = sim.collider_wrench(table.entity).unwrap();
        force += f / 60.0;
        torque += t / 60.0;
    }
    let mass: f32 = (sim.positions(body).unwrap().iter())
        .map(|&(i, _)| {
            let e = sim.world().get::<BodyLattice>(body).unwrap().particles[i as usize];
            1.0 / sim.world().get::<InvMass>(e).unwrap().0
        })
        .sum();
    let weight = gravity * mass;
    let centre = sim.centroid(body).unwrap();
    let lever = Vec3::new(centre.x, 0.0, centre.z).cross(weight);
    assert!(
        (force - weight).length() < 0.02 * weight.length(),
        "the table holds {force} N of a {weight} N weight"
    );
    assert!(
        (torque - lever).length() < 0.02 * lever.length(),
        "torque {torque} N·m, the weight's about the table's centre {lever}"
    );
    let w = sim.world().get::<ColliderWrench>(table.entity).unwrap();
    assert_eq!(
        (w.force, w.torque),
        sim.collider_wrench(table.entity).unwrap()
    );
    assert!(!sim.messages::<ColliderPushed>().is_empty());
}

#[test]
fn a_soft_block_sliding_on_a_free_box_gives_it_the_momentum_it_loses() {
    let config = SimConfig {
        ground: None,
        damping: 0.0,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).unwrap();
    let gravity = sim.config().gravity;
    // a 300 kg box on a frictionless floor (it moves along x only), and a 144 kg block
    // sliding onto it at 2 m/s (undamped, so that only the box takes momentum from it)
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(6, 4, 6)), 0.1);
    desc.position = Vec3::new(-0.8, 1.0, 0.0);
    desc.velocity = Vec3::new(2.0, 0.0, 0.0);
    let body = sim.spawn_body(&desc).unwrap();
    let bottom = sim
        .positions(body)
        .unwrap()
        .iter()
        .map(|(_, x)| x.y)
        .fold(f32::MAX, f32::min);
    let at = Vec3::new(0.0, bottom - 0.05 - 0.21, 0.0);
    let mut rigid = spawn_box(&mut sim, Vec3::new(1.5, 0.2, 1.0), at, 0.8, 300.0);
    let before = momentum(&mut sim, body);
    for _ in 0..45 {
        rigid.step(&mut sim, gravity, Vec3::X);
        sim.step();
    }
    let lost = before.x - momentum(&mut sim, body).x;
    let gained = rigid.mass * rigid.velocity.x;
    assert!(
        lost > 0.2 * before.x,
        "the block hardly slowed: {lost} of {}",
        before.x
    );
    assert!(
        (gained - lost).abs() < 0.05 * lost,
        "the box gained {gained} N·s, the block lost {lost}"
    );
}

#[test]
fn a_wrench_of_what_is_not_a_collider_is_an_error() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let body = sim
        .spawn_body(&BodyDesc::new(Shape::cuboid(UVec3::splat(2)), 0.1))
        .unwrap();
    let e = sim.collider_wrench(body).unwrap_err().to_string();
    assert!(e.contains("not a collider"), "{e}");
}
