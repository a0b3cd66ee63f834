//! The `bevy_app` feature: a cutting scene inside a Bevy `App`, stepped by `Update`
//! (the game's clock is `tests/bevy_game.rs`),
//! splits into pieces, and the messages reach an ordinary app system; a system ordered
//! after [`CleaveFrame`] reads the frame's positions; systems drag a body by an
//! attachment and let go.
#![cfg(feature = "bevy_app")]

use bevy_app::{App, Update};
use bevy_ecs::prelude::*;
use cleave::ecs::spawn::{spawn_body, spawn_tool};
use cleave::io::scene::builtin;
use cleave::prelude::*;

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
    app.add_plugins(
        CleavePlugin::new(scene.config.clone())
            .unwrap()
            .in_schedule(Update),
    );
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

/// A body of the app's world and the heights of its particle 0 that a system saw.
#[derive(Resource)]
struct Watched {
    body: Entity,
    heights: Vec<f32>,
}

/// A component of the test's own on the body.
#[derive(Component)]
struct Mine;

fn record(
    mut watched: ResMut<Watched>,
    bodies: Query<&BodyLattice, With<Mine>>,
    x: Query<&Position>,
) {
    let Ok(lattice) = bodies.get(watched.body) else {
        return;
    };
    if let Ok(p) = x.get(lattice.particles[0]) {
        watched.heights.push(p.0.y);
    }
}

fn height(app: &App, body: Entity) -> f32 {
    let particle = app.world().get::<BodyLattice>(body).unwrap().particles[0];
    app.world().get::<Position>(particle).unwrap().0.y
}

#[test]
fn a_system_ordered_after_the_frame_reads_its_positions() {
    let mut app = App::new();
    app.add_plugins(
        CleavePlugin::new(SimConfig::default())
            .unwrap()
            .in_schedule(Update),
    );
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(3)), 0.1);
    desc.position = Vec3::new(0.0, 2.0, 0.0);
    let body = spawn_body(app.world_mut(), &desc).unwrap();
    app.world_mut().entity_mut(body).insert(Mine);
    app.insert_resource(Watched {
        body,
        heights: Vec::new(),
    });
    app.add_systems(Update, record.after(CleaveFrame));
    for _ in 0..5 {
        app.update();
        // falling: what the system saw is this frame's height, not the last one's
        let seen = *app.world().resource::<Watched>().heights.last().unwrap();
        assert_eq!(seen, height(&app, body));
    }
    let heights = &app.world().resource::<Watched>().heights;
    assert!(heights.windows(2).all(|w| w[1] < w[0]), "{heights:?}");
}

/// The attachment a drag made, and the frame.
#[derive(Resource, Default)]
struct Drag {
    attachment: Option<Entity>,
    frame: u32,
}

/// Grabs the body's top particles at the first frame (an exclusive system: attaching
/// reads where they are), releases them at the 31st.
fn grab_and_release(world: &mut World) {
    let body = world.resource::<Watched>().body;
    let frame = world.resource::<Drag>().frame;
    if frame == 0 {
        let lattice = &world.get::<BodyLattice>(body).unwrap().lattice;
        let top: Vec<u32> = lattice
            .live_particles()
            .filter(|&p| lattice.coord(p).y == 1)
            .collect();
        let a = cleave::ecs::attach::attach(world, body, &top, 1e-5, Hold::Each).unwrap();
        world.resource_mut::<Drag>().attachment = Some(a);
    } else if frame == 30 {
        let a = world.resource_mut::<Drag>().attachment.take().unwrap();
        world.despawn(a);
    }
    world.resource_mut::<Drag>().frame += 1;
}

/// Pulls the attachment up 2 m/s, before the frame.
fn pull(mut targets: Query<&mut AttachmentTarget>) {
    for mut t in &mut targets {
        t.pose.position.y += 2.0 / 60.0;
    }
}

#[test]
fn systems_drag_a_body_with_an_attachment_and_let_go() {
    let mut app = App::new();
    let config = SimConfig {
        ground: None,
        ..SimConfig::default()
    };
    app.add_plugins(CleavePlugin::new(config).unwrap().in_schedule(Update));
    let body = spawn_body(
        app.world_mut(),
        &BodyDesc::new(Shape::cuboid(UVec3::splat(3)), 0.1),
    )
    .unwrap();
    app.insert_resource(Watched {
        body,
        heights: Vec::new(),
    });
    app.init_resource::<Drag>();
    app.add_systems(Update, (grab_and_release, pull).chain().before(CleaveFrame));
    let start = height(&app, body);
    for _ in 0..30 {
        app.update();
    }
    // held against gravity and pulled up 1 m
    let lifted = height(&app, body);
    assert!(lifted - start > 0.8, "{start} → {lifted}");
    for _ in 0..60 {
        app.update();
    }
    // let go at 2 m/s upward, 1 s of gravity later it is falling, far below the target
    let fallen = height(&app, body);
    assert!(fallen < lifted - 2.0, "{lifted} → {fallen}");
}
