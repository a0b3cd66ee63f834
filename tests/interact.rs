//! Cutting by a stroke and grabbing by a pointer (`cleave::sim::interact`), headless:
//! what a viewer's mouse does, checked against the geometry of the stroke's plane and
//! the body's motion.

use cleave::cut::tool::CutMode;
use cleave::ecs::components::Attachment;
use cleave::io::scene::builtin;
use cleave::sim::interact::Interaction;
use cleave::sim::simulation::Simulation;
use glam::Vec3;

/// The `slice` block on its pedestal, without the scene's own blade.
fn block() -> (Simulation, bevy_ecs::entity::Entity) {
    let mut scene = builtin("slice", 0).unwrap();
    scene.tools.clear();
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.run(5);
    let body = sim.bodies()[0];
    (sim, body)
}

fn step(sim: &mut Simulation, interaction: &mut Interaction, frames: usize) {
    for _ in 0..frames {
        interaction.before_step(sim).unwrap();
        sim.step();
    }
}

#[test]
fn a_stroke_across_the_block_parts_it_along_the_strokes_plane_in_every_mode() {
    for mode in [CutMode::Sever, CutMode::Remove, CutMode::Split] {
        let (mut sim, body) = block();
        let mut interaction = Interaction::new();
        let centre = sim.centroid(body).unwrap();
        // seen from above and aside (the stroke's plane is oblique to the lattice), a
        // stroke from over the block to under it, a little off its middle
        let eye = centre + Vec3::new(3.5 * 0.6f32.sin(), 1.5, 3.5 * 0.6f32.cos());
        let aside = (centre - eye).cross(Vec3::Y).normalize() * 0.2;
        let (top, bottom) = (
            centre + aside + Vec3::new(0.0, 1.5, 0.0),
            centre + aside - Vec3::new(0.0, 1.5, 0.0),
        );
        interaction
            .stroke(&mut sim, eye, top - eye, bottom - eye, mode)
            .unwrap();
        assert_eq!(sim.pieces(body).unwrap().len(), 1);
        // which side of the stroke's plane each particle is on, and how many lie
        // within the blade's cut width of it
        let normal = (top - eye).cross(bottom - eye).normalize();
        let before = sim.positions(body).unwrap();
        let ahead = before
            .iter()
            .filter(|(_, x)| normal.dot(*x - eye) > 0.0)
            .count();
        let near = before
            .iter()
            .filter(|(_, x)| normal.dot(*x - eye).abs() < 0.101)
            .count();
        step(&mut sim, &mut interaction, 40);
        assert_eq!(interaction.strokes_under_way(), 0, "the blade is let go");
        let pieces = sim.pieces(body).unwrap();
        assert_eq!(pieces.len(), 2, "{mode:?}");
        // each piece holds the particles of one side, give or take those the blade
        // passed near
        let sizes: Vec<usize> = pieces.iter().map(Vec::len).collect();
        let expected = [ahead, before.len() - ahead];
        let matched = sizes
            .iter()
            .zip(&expected)
            .all(|(s, e)| s.abs_diff(*e) <= near)
            || sizes
                .iter()
                .rev()
                .zip(&expected)
                .all(|(s, e)| s.abs_diff(*e) <= near);
        assert!(
            matched,
            "{mode:?}: pieces {sizes:?}, sides {expected:?}, near {near}"
        );
        if mode == CutMode::Sever {
            // no mass is lost (and, two pieces, no particle freed on its own)
            assert_eq!(sizes.iter().sum::<usize>(), before.len());
        }
    }
}

#[test]
fn a_grabbed_block_follows_the_pointer_and_falls_when_let_go() {
    let (mut sim, body) = block();
    let mut interaction = Interaction::new();
    let start = sim.centroid(body).unwrap();
    let eye = start + Vec3::new(0.0, 4.0, 4.0);
    let grab = interaction
        .press(&mut sim, eye, start - eye)
        .unwrap()
        .expect("the block is under the pointer");
    assert_eq!(grab.body, body);
    // drag the pointer up by 1.2 m at the grabbed depth, over half a second
    let grabbed = eye + grab.depth * (start - eye).normalize();
    for k in 1..=30 {
        let target = grabbed + Vec3::Y * 1.2 * k as f32 / 30.0;
        interaction.drag(&mut sim, eye, target - eye).unwrap();
        step(&mut sim, &mut interaction, 1);
    }
    step(&mut sim, &mut interaction, 60);
    // the held particles hang where the pointer put them (the spring stretches by
    // the block's weight over their stiffness: well under a millimetre), and the
    // block hangs from them
    let held = &sim
        .world()
        .get::<Attachment>(grab.attachment)
        .unwrap()
        .particles
        .clone();
    let positions = sim.positions(body).unwrap();
    let held_at = held
        .iter()
        .map(|p| positions.iter().find(|(i, _)| i == p).unwrap().1)
        .sum::<Vec3>()
        / held.len() as f32;
    // (the pointer's point stays at the grabbed depth along its ray)
    let pointer = grabbed + Vec3::Y * 1.2;
    let pulled_to = eye + grab.depth * (pointer - eye).normalize() + grab.offset;
    assert!(
        held_at.distance(pulled_to) < 0.02,
        "the held particles are {} m from the pointer",
        held_at.distance(pulled_to)
    );
    let lifted = sim.centroid(body).unwrap();
    assert!(
        lifted.y - start.y > 0.4,
        "the block rose {} m",
        lifted.y - start.y
    );
    interaction.release(&mut sim).unwrap();
    assert!(interaction.grab().is_none());
    step(&mut sim, &mut interaction, 60);
    let dropped = sim.centroid(body).unwrap();
    assert!(
        lifted.y - dropped.y > 0.25,
        "let go, it fell {} m",
        lifted.y - dropped.y
    );
}

#[test]
fn pointing_at_nothing_or_with_a_bad_ray_changes_nothing() {
    let (mut sim, body) = block();
    let mut interaction = Interaction::new();
    let centre = sim.centroid(body).unwrap();
    let eye = centre + Vec3::new(0.0, 0.0, 6.0);
    // away from the block
    assert!(
        interaction
            .press(&mut sim, eye, Vec3::new(0.0, 0.0, 1.0))
            .unwrap()
            .is_none()
    );
    for bad in [
        Vec3::ZERO,
        Vec3::splat(f32::NAN),
        Vec3::new(f32::INFINITY, 0.0, 0.0),
    ] {
        assert!(interaction.press(&mut sim, eye, bad).is_err());
        if !bad.is_finite() {
            assert!(interaction.press(&mut sim, bad, Vec3::NEG_Z).is_err());
        }
        assert!(interaction.drag(&mut sim, eye, bad).is_err());
        assert!(
            interaction
                .stroke(&mut sim, eye, bad, Vec3::NEG_Z, CutMode::Sever)
                .is_err()
        );
        if !bad.is_finite() {
            assert!(
                interaction
                    .stroke(&mut sim, bad, Vec3::X, Vec3::NEG_Z, CutMode::Sever)
                    .is_err()
            );
        }
    }
    assert_eq!(interaction.strokes_under_way(), 0);
    step(&mut sim, &mut interaction, 10);
    assert_eq!(sim.pieces(body).unwrap().len(), 1);
    assert!(sim.centroid(body).unwrap().is_finite());
}
