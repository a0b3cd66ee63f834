//! Centroid holds (`Simulation::hold_centroid`, SPEC §6.1): a block hung by the centroid
//! of a patch of its top. The centroid stays on its target while the patch turns and
//! gives (unlike a patch pinned particle by particle), under all three solvers; a moving
//! target drags the block.

use cleave::body::shape::Shape;
use cleave::config::{Material, SimConfig, SolverMode};
use cleave::cut::tool::Pose;
use cleave::ecs::desc::BodyDesc;
use cleave::sim::simulation::Simulation;
use glam::{UVec3, Vec3};

const H: f32 = 0.1;

/// A rubbery 12×6×6 block in the air, held by the centroid of the left third of its
/// top layer (or, with `each`, by those particles each), hard: the block's centre of
/// mass is not under the held centroid, so it swings until it is.
fn hung(solver: SolverMode, each: bool) -> (Simulation, bevy_ecs::entity::Entity, Vec<u32>) {
    let mut sim = Simulation::new(SimConfig {
        solver,
        ground: None,
        iterations: 20,
        damping: 2.0,
        ..SimConfig::default()
    })
    .unwrap();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 6)), H);
    desc.position = Vec3::new(0.0, 2.0, 0.0);
    desc.material = Material {
        compliance: 1.2e-6,
        ..Material::rigid()
    };
    let body = sim.spawn_body(&desc).unwrap();
    let positions = sim.positions(body).unwrap();
    let top_y = positions.iter().map(|(_, x)| x.y).fold(f32::MIN, f32::max);
    let left = positions.iter().map(|(_, x)| x.x).fold(f32::MAX, f32::min);
    let top: Vec<u32> = positions
        .iter()
        .filter(|(_, x)| x.y > top_y - 0.5 * H && x.x < left + 3.5 * H)
        .map(|(i, _)| *i)
        .collect();
    if each {
        sim.attach(body, &top, 0.0).unwrap();
    } else {
        sim.hold_centroid(body, &top, 0.0).unwrap();
    }
    (sim, body, top)
}

fn mean_of(sim: &Simulation, body: bevy_ecs::entity::Entity, set: &[u32]) -> Vec3 {
    let positions = sim.positions(body).unwrap();
    set.iter()
        .map(|p| positions.iter().find(|(i, _)| i == p).unwrap().1)
        .sum::<Vec3>()
        / set.len() as f32
}

/// How far the set's particles moved from where they were, after taking out the
/// set's mean motion: how much the set deformed (or turned).
fn spread(before: &[(u32, Vec3)], after: &[(u32, Vec3)], set: &[u32]) -> f32 {
    let at = |list: &[(u32, Vec3)], p: u32| list.iter().find(|(i, _)| *i == p).unwrap().1;
    let shift = set
        .iter()
        .map(|&p| at(after, p) - at(before, p))
        .sum::<Vec3>()
        / set.len() as f32;
    set.iter()
        .map(|&p| (at(after, p) - at(before, p) - shift).length())
        .fold(0.0, f32::max)
}

#[test]
fn a_held_centroid_stays_on_its_target_while_the_patch_turns_under_every_solver() {
    for solver in [
        SolverMode::Jacobi,
        SolverMode::GaussSeidel,
        SolverMode::Projective,
    ] {
        let (mut sim, body, top) = hung(solver, false);
        let target = mean_of(&sim, body, &top);
        let start = sim.positions(body).unwrap();
        let centre = sim.centroid(body).unwrap();
        sim.run(240);
        let held = mean_of(&sim, body, &top);
        assert!(
            held.distance(target) < 1e-4 * H,
            "{solver:?}: the held centroid is {} h from its target",
            held.distance(target) / H
        );
        // the block hangs (it does not fall) and swings toward hanging its centre of
        // mass under the hold: the held particles turn about their centroid
        let now = sim.centroid(body).unwrap();
        assert!(
            now.distance(centre) < 6.0 * H,
            "{solver:?}: {now} from {centre}"
        );
        assert!(
            (now.x - target.x).abs() < 0.5 * (centre.x - target.x).abs(),
            "{solver:?}: the centre of mass went from {centre} to {now}, held at {target}"
        );
        let give = spread(&start, &sim.positions(body).unwrap(), &top);
        assert!(
            give > 0.5 * H,
            "{solver:?}: the held particles moved {} h about their centroid",
            give / H
        );
        // a layer pinned particle by particle does not give at all
        let (mut pinned, body, top) = hung(solver, true);
        let start = pinned.positions(body).unwrap();
        pinned.run(240);
        let rigid = spread(&start, &pinned.positions(body).unwrap(), &top);
        assert!(
            rigid < 1e-3 * H,
            "{solver:?}: a pinned layer moved {} h",
            rigid / H
        );
    }
}

#[test]
fn a_moving_centroid_target_drags_the_block_and_letting_go_drops_it() {
    let (mut sim, body, top) = hung(SolverMode::Jacobi, false);
    let hold = {
        let world = sim.world_mut();
        let mut q = world.query::<(
            bevy_ecs::entity::Entity,
            &cleave::ecs::components::Attachment,
        )>();
        q.iter(world).next().unwrap().0
    };
    let start = mean_of(&sim, body, &top);
    let centre = sim.centroid(body).unwrap();
    for k in 1..=60 {
        let to = start + Vec3::X * (k as f32 / 60.0);
        sim.move_attachment(hold, Pose::at(to)).unwrap();
        sim.step();
    }
    sim.run(120);
    let held = mean_of(&sim, body, &top);
    assert!(
        held.distance(start + Vec3::X) < 1e-4 * H,
        "{}",
        held.distance(start + Vec3::X)
    );
    let moved = sim.centroid(body).unwrap() - centre;
    // (the block swings under the hold as it goes)
    assert!(moved.x > 0.5, "the block moved {moved}");
    sim.detach(hold).unwrap();
    sim.run(30);
    assert!(
        sim.centroid(body).unwrap().y < centre.y - 0.5,
        "let go, it falls"
    );
}

#[test]
fn a_centroid_hold_of_nothing_or_of_a_bad_compliance_is_refused() {
    let (mut sim, body, top) = hung(SolverMode::Jacobi, false);
    assert!(sim.hold_centroid(body, &[], 0.0).is_err());
    assert!(sim.hold_centroid(body, &top, -1.0).is_err());
    assert!(sim.hold_centroid(body, &top, f32::NAN).is_err());
    assert!(sim.hold_centroid(body, &[1 << 30], 0.0).is_err());
}
