//! Conservative culling is exact (SPEC §6.2): the scenes with contacts and cuts end in
//! the same state bit for bit with culling on and off (`--no-culling`), on one thread and
//! on two; a world of one piece without self-contact, which skips contacts
//! altogether, ends as it does with self-contact on; and detect's blocks stay one
//! aligned cube each in a body that split blades have added particles to.

mod common;
use bevy_ecs::prelude::*;
use cleave::prelude::*;
use common::run_with;
use glam::{UVec3, Vec3};

const H: f32 = 0.1;

#[test]
fn culling_changes_no_result_for_any_thread_count() {
    for scene in ["pile", "stack", "press", "random", "slice", "cuts"] {
        let (_, reference) = run_with(scene, None, &["--threads", "1", "--no-culling"]);
        for extra in [
            &["--threads", "1"][..],
            &["--threads", "2"],
            &["--threads", "2", "--no-culling"],
        ] {
            let (_, dump) = run_with(scene, None, extra);
            assert!(
                dump == reference,
                "{scene} with {extra:?} differs from --threads 1 --no-culling"
            );
        }
    }
}

/// The contact kind's particles in `sim`'s solver.
fn contact_particles(sim: &Simulation) -> usize {
    let cache = sim.world().resource::<cleave::ecs::layout::SolverCache>();
    cache
        .solver
        .terms
        .extent("contacts")
        .map_or(0, |e| e.particles)
}

#[test]
fn a_lone_piece_without_self_contact_skips_contacts_and_ends_the_same() -> cleave::error::Result<()>
{
    // a rigid box dropped onto the ground, alone; then the same with self-contact on,
    // which keeps its surface in the contact kind but can find no pair in it
    let run = |self_contact: bool| -> cleave::error::Result<(Simulation, Entity)> {
        let mut sim = Simulation::new(SimConfig::default())?;
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(6)), H);
        desc.material = Material::rigid();
        desc.material.self_contact = self_contact;
        desc.position = Vec3::new(0.0, 0.6, 0.0);
        desc.angular_velocity = Vec3::new(0.0, 0.0, 2.0);
        let body = sim.spawn_body(&desc)?;
        for _ in 0..30 {
            sim.step();
        }
        Ok((sim, body))
    };
    let (mut sim, body) = run(false)?;
    let (searching, other_body) = run(true)?;
    let (none, some) = (contact_particles(&sim), contact_particles(&searching));
    let (skipped, searched) = (sim.positions(body)?, searching.positions(other_body)?);
    assert_eq!(none, 0, "a lone rigid piece takes no part");
    assert!(some > 0, "with self-contact on, its surface takes part");
    assert_eq!(skipped, searched, "and the runs end bit for bit the same");
    // a second body gives it something to meet
    let mut other = BodyDesc::new(Shape::cuboid(UVec3::splat(3)), H);
    other.position = Vec3::new(2.0, 0.3, 0.0);
    sim.spawn_body(&other)?;
    sim.step();
    assert!(contact_particles(&sim) > 6 * 6 * 6 - 4 * 4 * 4);
    Ok(())
}

#[test]
fn detect_tests_a_body_with_split_particles_in_blocks_of_one_cube_each() {
    // split blades add halves to the body: laid out again, the particles no longer come
    // in runs of 64 per aligned cube of 4³ cells, and detect's blocks must follow the
    // cubes (a run of 64 that straddled a jump of the Morton curve would span the body)
    let mut scene = cleave::io::scene::builtin("cuts", 0).expect("a built-in scene");
    for tool in &mut scene.tools {
        tool.cut_mode = CutMode::Split;
    }
    let mut sim = Simulation::from_scene(&scene).expect("the scene loads");
    let body = sim.bodies()[0];
    let mut checked = 0;
    for _ in 0..120 {
        sim.step();
        let world = sim.world();
        let cache = world.resource::<cleave::ecs::layout::SolverCache>();
        let blocks = &world
            .resource::<cleave::ecs::resources::DetectCulling>()
            .blocks;
        let lattice = &world.get::<BodyLattice>(body).expect("a body").lattice;
        if lattice.len() == 32 * 16 * 16 {
            continue; // nothing split yet
        }
        assert_eq!(blocks.particles(), cache.particles.len());
        for b in 0..blocks.len() {
            let cubes: Vec<_> = blocks
                .range(b)
                .map(|d| cache.layout.owner(d).map(|(_, p)| lattice.morton_cube(p)))
                .collect();
            assert!(cubes.len() <= cleave::cut::blocks::BLOCK);
            assert!(
                cubes.windows(2).all(|w| w[0] == w[1]),
                "block {b} spans cubes {:?}",
                cubes.first()
            );
        }
        checked += 1;
    }
    assert!(checked > 50, "{checked} frames after a split");
}
