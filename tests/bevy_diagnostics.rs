//! The `bevy_diagnostic` feature: the plugin's step time and counts reach Bevy's
//! `DiagnosticsStore`, the step time agreeing with the stage profile's time for the
//! frame system, the counts with the world.
#![cfg(feature = "bevy_diagnostic")]

use bevy_app::{App, Update};
use bevy_diagnostic::DiagnosticsStore;
use cleave::analysis::profile::StageProfile;
use cleave::ecs::spawn::{spawn_body, spawn_tool};
use cleave::io::scene::builtin;
use cleave::prelude::*;
use cleave::sim::diagnostics::{CLUSTERS, CUT_EVENTS, PARTICLES, PIECES, STEP_TIME};

#[test]
fn the_step_time_and_counts_reach_the_diagnostics_store() {
    let profile = StageProfile::default();
    let _guard = profile.install();
    let scene = builtin("slice", 0).unwrap();
    let mut app = App::new();
    app.add_plugins(
        CleavePlugin::new(scene.config.clone())
            .unwrap()
            .in_schedule(Update),
    );
    let body = spawn_body(app.world_mut(), &scene.bodies[0]).unwrap();
    spawn_tool(app.world_mut(), &scene.tools[0]).unwrap();
    let (mut sum_ms, mut cuts) = (0.0, 0.0);
    for _ in 0..120 {
        app.update();
        let store = app.world().resource::<DiagnosticsStore>();
        sum_ms += store.get(&STEP_TIME).unwrap().value().unwrap();
        cuts += store.get(&CUT_EVENTS).unwrap().value().unwrap();
    }
    let frame_ms = profile
        .totals_ms()
        .into_iter()
        .find(|(name, _)| name.ends_with("run_cleave_frame"))
        .map(|(_, ms)| ms)
        .expect("the profile saw the frame system");
    assert!(
        (sum_ms - frame_ms).abs() < 0.1 * frame_ms,
        "diagnostics {sum_ms} ms, profile {frame_ms} ms over 120 frames"
    );
    assert!(cuts >= 1.0, "no cut event counted");
    let store = app.world().resource::<DiagnosticsStore>();
    let [particles, pieces, clusters] =
        [PARTICLES, PIECES, CLUSTERS].map(|path| store.get(&path).unwrap().value().unwrap());
    let lattice = app.world().get::<BodyLattice>(body).unwrap();
    assert_eq!(particles, lattice.lattice.live_count() as f64);
    assert_eq!(pieces, 2.0);
    let world = app.world_mut();
    assert_eq!(
        clusters,
        world.query::<&ClusterMembers>().iter(world).count() as f64
    );
}
