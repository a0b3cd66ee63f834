//! Rigid bodies, both ways. The game's own: the wrench the particles put on a collider
//! (`Simulation::collider_wrench`), checked against physics outside the code — a table
//! under a resting block takes its weight and the torque of its offset, and a box the
//! test's own integrator moves by the wrench gains the momentum the soft block sliding on
//! it loses. cleave's own (`DynamicCollider`): a box resting on a soft block is held by
//! its weight, a block landing on a crate on a frictionless floor gives it the momentum
//! it loses, a free body falls as a ballistic one does, a ball dents a soft block and
//! bounces off it (the rigid ground, an inelastic contact, stops it dead).

use cleave::ecs::components::{ColliderPose, ColliderWrench, DynamicCollider, InvMass};
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
    let shape = ColliderShape::Box { half_extents: half };
    spawn_collider(sim, shape, at, friction, mass)
}

fn spawn_collider(
    sim: &mut Simulation,
    shape: ColliderShape,
    at: Vec3,
    friction: f32,
    mass: f32,
) -> RigidBox {
    let entity = sim
        .spawn_collider(&ColliderDesc {
            shape,
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
    let after = momentum(&mut sim, body).x;
    passed_on(before.x, after, rigid.mass * rigid.velocity.x, 0.2);
}

/// The block's momentum along x went from `before` to `after`, at least `slowed` of it
/// lost, and the rigid body `gained` what it lost, within 5 %.
fn passed_on(before: f32, after: f32, gained: f32, slowed: f32) {
    let lost = before - after;
    assert!(
        lost > slowed * before,
        "the block hardly slowed: {lost} of {before}"
    );
    assert!(
        (gained - lost).abs() < 0.05 * lost,
        "the rigid body gained {gained} N·s, the block lost {lost}"
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

#[test]
fn a_dynamic_box_resting_on_a_soft_block_is_held_by_its_weight() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let gravity = sim.config().gravity;
    let mut block = BodyDesc::new(Shape::cuboid(UVec3::new(8, 4, 8)), 0.1);
    block.position = Vec3::new(0.0, 0.2, 0.0);
    sim.spawn_body(&block).unwrap();
    // a 20 kg box, 0.4 m wide, let go 7 cm above the block's top balls (at 0.4 m)
    let shape = ColliderShape::Box {
        half_extents: Vec3::splat(0.2),
    };
    let at = Vec3::new(0.0, 0.67, 0.0);
    let b = spawn_box(&mut sim, Vec3::splat(0.2), at, 0.5, 20.0).entity;
    sim.make_dynamic(b, DynamicCollider::solid(&shape, 20.0).unwrap())
        .unwrap();
    sim.run(300);
    let settled = sim.world().get::<ColliderPose>(b).unwrap().current.position;
    let (mut force, mut torque) = (Vec3::ZERO, Vec3::ZERO);
    for _ in 0..60 {
        sim.step();
        let (f, t) = sim.collider_wrench(b).unwrap();
        force += f / 60.0;
        torque += t / 60.0;
    }
    let holding = -gravity * 20.0;
    assert!(
        (force - holding).length() < 0.02 * holding.length(),
        "the block pushes {force} N on a box whose weight needs {holding} N"
    );
    assert!(torque.length() < 0.01 * holding.length() * 0.2, "{torque}");
    // it stays where it settled (it rocks a little: a thousandth of a radian, a few
    // cm/s, on the block's jiggling top), its bottom on the block's top balls
    let rest = sim.world().get::<ColliderPose>(b).unwrap().current;
    assert!(
        rest.position.distance(settled) < 0.01,
        "{settled} → {rest:?}"
    );
    assert!((rest.position.y - 0.6).abs() < 0.02, "{rest:?}");
    let v = sim.world().get::<DynamicCollider>(b).unwrap().velocity;
    assert!(v.length() < 0.1, "moving at {v}");
}

/// A 50 kg crate cleave moves, on the frictionless ground, and a 144 kg block about to
/// land on it sliding at 2 m/s: the simulation, the crate, the block.
fn crate_and_block(config: SimConfig) -> (Simulation, Entity, Entity) {
    let mut sim = Simulation::new(config).unwrap();
    let half = Vec3::new(1.5, 0.2, 1.0);
    let shape = ColliderShape::Box { half_extents: half };
    let c = spawn_box(&mut sim, half, Vec3::new(0.0, 0.2, 0.0), 0.8, 50.0).entity;
    sim.make_dynamic(c, DynamicCollider::solid(&shape, 50.0).unwrap())
        .unwrap();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(6, 4, 6)), 0.1);
    desc.position = Vec3::new(-0.8, 0.65, 0.0);
    desc.velocity = Vec3::new(2.0, 0.0, 0.0);
    let body = sim.spawn_body(&desc).unwrap();
    (sim, c, body)
}

#[test]
fn a_block_landing_on_a_dynamic_crate_gives_it_the_momentum_it_loses() {
    // undamped, so that only the crate takes momentum from the block
    let config = SimConfig {
        damping: 0.0,
        ..SimConfig::default()
    };
    let (mut sim, c, body) = crate_and_block(config);
    let before = momentum(&mut sim, body).x;
    sim.run(45);
    let gained = 50.0 * sim.world().get::<DynamicCollider>(c).unwrap().velocity.x;
    passed_on(before, momentum(&mut sim, body).x, gained, 0.1);
}

#[test]
fn a_free_dynamic_body_flies_as_a_ballistic_one() {
    let config = SimConfig {
        ground: None,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).unwrap();
    let shape = ColliderShape::Sphere { radius: 0.1 };
    let ball = sim
        .spawn_collider(&ColliderDesc {
            shape: shape.clone(),
            friction: 0.0,
            pose: Pose::at(Vec3::ZERO),
            path: Path { keys: vec![] },
        })
        .unwrap();
    let mut dynamic = DynamicCollider::solid(&shape, 1.0).unwrap();
    dynamic.velocity = Vec3::new(1.0, 5.0, 0.0);
    dynamic.angular_velocity = Vec3::new(0.0, 0.0, 2.0);
    sim.make_dynamic(ball, dynamic).unwrap();
    sim.run(60);
    // semi-implicit Euler over n substeps of h: y = v₀·t − g·h²·n(n+1)/2
    let n = 60.0 * sim.config().substeps as f32;
    let h = 1.0 / n;
    let expected = Vec3::new(1.0, 5.0 - 9.81 * h * h * n * (n + 1.0) / 2.0, 0.0);
    let pose = sim.world().get::<ColliderPose>(ball).unwrap().current;
    assert!(
        (pose.position - expected).length() < 1e-4,
        "{pose:?} against {expected}"
    );
    // and within g·h·t/2 of the parabola itself
    assert!((pose.position.y - (5.0 - 0.5 * 9.81)).abs() <= 9.81 * h / 2.0 + 1e-4);
    let (axis, angle) = pose.rotation.to_axis_angle();
    assert!(
        (axis.z.abs() - 1.0).abs() < 1e-3 && (angle - 2.0).abs() < 1e-2,
        "{axis} {angle}"
    );
}

#[test]
fn a_dynamic_state_out_of_bounds_is_refused() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let shape = ColliderShape::Sphere { radius: 0.1 };
    let ball = spawn_box(&mut sim, Vec3::splat(0.1), Vec3::Y, 0.0, 1.0).entity;
    for (mass, field) in [(0.0, "mass"), (-1.0, "mass"), (f32::NAN, "mass")] {
        let e = DynamicCollider::solid(&shape, mass)
            .unwrap_err()
            .to_string();
        assert!(e.contains(field), "{e}");
    }
    let mut fast = DynamicCollider::solid(&shape, 1.0).unwrap();
    fast.velocity.x = f32::INFINITY;
    let e = sim.make_dynamic(ball, fast).unwrap_err().to_string();
    assert!(e.contains("dynamic.velocity"), "{e}");
    // set from game code past the check: the collider stays kinematic, nothing is NaN
    sim.world_mut().entity_mut(ball).insert(fast);
    let body = sim
        .spawn_body(&BodyDesc::new(Shape::cuboid(UVec3::splat(3)), 0.1))
        .unwrap();
    sim.run(10);
    assert_eq!(
        sim.world()
            .get::<ColliderPose>(ball)
            .unwrap()
            .current
            .position,
        Vec3::Y
    );
    assert!(
        sim.positions(body)
            .unwrap()
            .iter()
            .all(|(_, x)| x.is_finite())
    );
    // a pose written as NaN by game code: the collider is left out
    let mut at = *sim.world().get::<ColliderPose>(ball).unwrap();
    at.current.position.y = f32::NAN;
    sim.world_mut().entity_mut(ball).insert(at);
    sim.run(10);
    assert!(
        sim.positions(body)
            .unwrap()
            .iter()
            .all(|(_, x)| x.is_finite())
    );
    let not_a_collider = sim.make_dynamic(body, DynamicCollider::solid(&shape, 1.0).unwrap());
    assert!(
        not_a_collider
            .unwrap_err()
            .to_string()
            .contains("not a collider")
    );
}

#[test]
fn a_dynamic_crate_resumes_bit_for_bit() {
    let run = |save_at: Option<u32>| {
        let (mut sim, c, _) = crate_and_block(SimConfig::default());
        let mut c = c;
        if let Some(frames) = save_at {
            sim.run(frames);
            let mut bytes = Vec::new();
            sim.save(&mut bytes).unwrap();
            let saved = c;
            sim = Simulation::load(bytes.as_slice()).unwrap();
            c = sim.loaded_entity(saved).unwrap();
            sim.run(40 - frames);
        } else {
            sim.run(40);
        }
        let crate_state = *sim.world().get::<DynamicCollider>(c).unwrap();
        let pose = sim.world().get::<ColliderPose>(c).unwrap().current;
        let body = sim.bodies()[0];
        (sim.positions(body).unwrap(), crate_state, pose)
    };
    let (straight, resumed) = (run(None), run(Some(12)));
    assert!(straight.1.velocity.x > 0.5, "the crate was pushed");
    assert!(straight == resumed, "the resumed run differs");
}

#[test]
fn a_dynamic_ball_dents_a_soft_block_and_bounces_where_the_rigid_ground_stops_it() {
    // (rebound speed, the deepest the block's top went under it)
    let drop = |on_block: bool| -> (f32, f32) {
        let mut sim = Simulation::new(SimConfig::default()).unwrap();
        let mut block = BodyDesc::new(Shape::cuboid(UVec3::new(8, 4, 8)), 0.1);
        block.position = Vec3::new(0.0, 0.2, 0.0);
        let body = on_block.then(|| sim.spawn_body(&block).unwrap());
        sim.run(120);
        let top = |sim: &Simulation| {
            body.map_or(0.0, |b| {
                let near = sim.positions(b).unwrap().into_iter();
                let under = near.filter(|(_, x)| x.x.abs() < 0.1 && x.z.abs() < 0.1);
                under.map(|(_, x)| x.y).fold(f32::MIN, f32::max)
            })
        };
        let rest_top = top(&sim);
        let shape = ColliderShape::Sphere { radius: 0.1 };
        let ball = spawn_collider(&mut sim, shape.clone(), Vec3::new(0.0, 1.5, 0.0), 0.5, 20.0);
        let ball = ball.entity;
        sim.make_dynamic(ball, DynamicCollider::solid(&shape, 20.0).unwrap())
            .unwrap();
        let (mut rebound, mut dent) = (0.0f32, 0.0f32);
        for _ in 0..90 {
            sim.step();
            let v = sim.world().get::<DynamicCollider>(ball).unwrap().velocity;
            rebound = rebound.max(v.y);
            dent = dent.max(rest_top - top(&sim));
        }
        (rebound, dent)
    };
    let (bounce, dent) = drop(true);
    assert!(bounce > 0.3, "off the block: {bounce} m/s up");
    assert!(
        dent > 0.01,
        "the block's top went down {dent} m under the ball"
    );
    let (bounce, _) = drop(false);
    assert!(bounce < 0.05, "off the rigid ground: {bounce} m/s up");
}
