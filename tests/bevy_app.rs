//! The `bevy_app` feature: a cutting scene inside a Bevy `App`, stepped by `Update`,
//! splits into pieces, and the messages reach an ordinary app system.
#![cfg(feature = "bevy_app")]

use bevy_app::{App, Update};
use bevy_ecs::prelude::*;
use cleave::ecs::spawn::{spawn_body, spawn_tool};
use cleave::io::scene::builtin;
use cleave::prelude::*;
use cleave::sim::plugin::CleavePlugin;

#[derive(Resource, Default)]
struct Seen {
    splits: Vec<(usize, usize)>,
    cut_particles: usize,
}

fn watch(
    mut splits: MessageReader<BodySplit>,
    mut cuts: MessageReader<ParticlesCut>,
    mut seen: ResMut<Seen>,
) {
    for s in splits.read() {
        seen.splits.push((s.pieces_before, s.pieces_after));
    }
    seen.cut_particles += cuts.read().map(|c| c.particles.len()).sum::<usize>();
}

#[test]
fn slice_scene_splits_inside_an_app_and_messages_reach_app_systems() {
    let scene = builtin("slice", 0).unwrap();
    let mut app = App::new();
    app.add_plugins(CleavePlugin::new(scene.config.clone()).unwrap());
    app.init_resource::<Seen>();
    app.add_systems(Update, watch);
    let body = spawn_body(app.world_mut(), &scene.bodies[0]).unwrap();
    for t in &scene.tools {
        spawn_tool(app.world_mut(), t).unwrap();
    }
    for _ in 0..120 {
        app.update();
    }
    let pieces = app.world().get::<BodyLattice>(body).unwrap().pieces;
    assert_eq!(pieces, 2);
    let seen = app.world().resource::<Seen>();
    assert!(
        seen.cut_particles > 0,
        "no ParticlesCut message reached the app"
    );
    assert!(
        seen.splits.contains(&(1, 2)),
        "splits seen: {:?}",
        seen.splits
    );
    assert!(check_invariants(app.world()).is_empty());
}

#[test]
fn bad_config_is_an_error_not_a_panic() {
    let config = SimConfig {
        iterations: 0,
        ..SimConfig::default()
    };
    let e = CleavePlugin::new(config).unwrap_err().to_string();
    assert!(e.contains("iterations"), "{e}");
}
