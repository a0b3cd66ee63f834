//! Where a frame runs: `Simulation::step` from a thread outside the rayon pool (a game's
//! main thread, this test's) runs the frame's stages on a thread of the pool, under the
//! caller's tracing dispatcher.

use cleave::bevy_ecs::prelude::*;
use cleave::prelude::*;
use cleave::systems::{CleaveSchedule, SimStage};
use glam::{UVec3, Vec3};
use tracing_subscriber::Registry;

/// What each run of the probe system saw: its rayon thread index (`None`: not in the
/// pool), and whether the default tracing dispatcher was the caller's.
#[derive(Resource, Default)]
struct Seen(Vec<(Option<usize>, bool)>);

fn probe(mut seen: ResMut<Seen>) {
    let callers = tracing::dispatcher::get_default(|current| current.is::<Registry>());
    seen.0.push((rayon::current_thread_index(), callers));
}

#[test]
fn a_frame_stepped_from_outside_the_pool_runs_in_the_pool_under_the_callers_dispatcher() {
    assert_eq!(
        rayon::current_thread_index(),
        None,
        "the test thread is no worker"
    );
    let mut sim = Simulation::new(SimConfig::default()).expect("default config");
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(4)), 0.1);
    desc.position = Vec3::new(0.0, 0.5, 0.0);
    sim.spawn_body(&desc).expect("a small block spawns");
    let world = sim.world_mut();
    world.init_resource::<Seen>();
    world.schedule_scope(CleaveSchedule, |_, schedule| {
        schedule.add_systems(probe.after(SimStage::Verify));
    });
    // (this thread's dispatcher alone, as a game's profiler or a tool sets one)
    tracing::subscriber::with_default(tracing_subscriber::registry(), || sim.run(3));
    let seen = &sim.world().resource::<Seen>().0;
    assert_eq!(seen.len(), 3);
    for (thread, callers) in seen {
        assert!(thread.is_some(), "{seen:?}");
        assert!(callers, "{seen:?}");
    }
}
