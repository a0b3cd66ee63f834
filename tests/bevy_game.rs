//! cleave in a Bevy game (feature `bevy_app`): the game's fixed clock drives the
//! simulation step for step; bodies and tools spawn through `Commands` from plain
//! systems; a tool can be disabled or despawned; a body at rest stops marking its
//! `SurfaceMesh` changed.
#![cfg(feature = "bevy_app")]

use bevy_app::{App, FixedUpdate, Startup, Update};
use bevy_ecs::entity_disabling::Disabled;
use bevy_ecs::prelude::*;
use bevy_time::{Fixed, Time, TimePlugin, TimeUpdateStrategy};
use cleave::ecs::commands::{CleaveCommands, SpawnBody};
use cleave::ecs::resources::SimSettings;
use cleave::io::scene::builtin;
use cleave::prelude::*;
use std::time::Duration;

/// The positions of every live particle of every body, in body then index order.
fn all_positions(sim: &mut Simulation) -> Vec<Vec3> {
    let mut out = Vec::new();
    for body in sim.bodies() {
        out.extend(sim.positions(body).unwrap().into_iter().map(|(_, x)| x));
    }
    out
}

/// The same, read from an app's world.
fn app_positions(app: &mut App) -> Vec<Vec3> {
    let world = app.world_mut();
    let mut bodies: Vec<(Entity, Vec<Entity>, Vec<u32>)> = world
        .query::<(Entity, &BodyLattice)>()
        .iter(world)
        .map(|(e, l)| (e, l.particles.clone(), l.lattice.live_particles().collect()))
        .collect();
    bodies.sort_by_key(|b| b.0);
    let mut out = Vec::new();
    for (_, particles, live) in bodies {
        for i in live {
            out.push(world.get::<Position>(particles[i as usize]).unwrap().0);
        }
    }
    out
}

/// An app with bevy_time's clock (fixed step 1/60 s) and the plugin on its default
/// schedule, the `slice` scene spawned through `Commands` by a startup system.
fn game(time: TimeUpdateStrategy) -> App {
    let scene = builtin("slice", 0).unwrap();
    let mut app = App::new();
    app.add_plugins(TimePlugin);
    // 1/60 s to the nanosecond below: bevy's `from_hz(60.0)` rounds up to 16 666 667
    // ns, and 300 of those are 100 ns more than 5 s
    app.insert_resource(Time::<Fixed>::from_duration(Duration::from_nanos(
        16_666_666,
    )));
    app.insert_resource(time);
    app.add_plugins(CleavePlugin::new(scene.config.clone()).unwrap());
    app.add_systems(Startup, move |mut commands: Commands| {
        for b in &scene.bodies {
            commands.spawn_soft_body(b.clone());
        }
        for t in &scene.tools {
            commands.spawn_cutting_tool(t.clone());
        }
    });
    app
}

#[test]
fn the_fixed_clock_steps_exactly_as_the_headless_simulation_at_uneven_frame_times() {
    let mut app = game(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
    app.update(); // (bevy's clock starts at the first update)
    // display frames of 7, 11, 23 and 31 ms, repeated, to 5 s of game time
    let mut elapsed = Duration::ZERO;
    let pattern = [7u64, 11, 23, 31].map(Duration::from_millis);
    let mut updates = 0;
    while elapsed < Duration::from_secs(5) {
        let d = pattern[updates % 4].min(Duration::from_secs(5) - elapsed);
        app.insert_resource(TimeUpdateStrategy::ManualDuration(d));
        app.update();
        elapsed += d;
        updates += 1;
    }
    let virtual_time = app.world().resource::<Time<bevy_time::Virtual>>().elapsed();
    assert_eq!(virtual_time, Duration::from_secs(5));
    let clock = *app.world().resource::<SimClock>();
    assert_eq!(clock.frame, 300, "{updates} display frames");
    // the config's 1/60 s, not the Duration's 16 666 666 ns rounded back
    assert_eq!(app.world().resource::<SimSettings>().0.dt, 1.0 / 60.0);

    let mut sim = Simulation::from_scene(&builtin("slice", 0).unwrap()).unwrap();
    sim.run(300);
    let (ours, theirs) = (app_positions(&mut app), all_positions(&mut sim));
    assert_eq!(ours.len(), theirs.len());
    assert!(
        ours == theirs,
        "the game's run differs from the headless one"
    );
    let world = app.world_mut();
    let pieces: Vec<usize> = world
        .query::<&BodyLattice>()
        .iter(world)
        .map(|l| l.pieces)
        .collect();
    assert_eq!(pieces, [2], "the blade cut the loaf in two");
}

#[test]
fn a_new_fixed_timestep_is_followed_and_time_moves_on_by_it() {
    let mut app = game(TimeUpdateStrategy::FixedTimesteps(1));
    app.update(); // (bevy's clock starts at the first update)
    for _ in 0..30 {
        app.update();
    }
    app.insert_resource(Time::<Fixed>::from_hz(120.0));
    for _ in 0..30 {
        app.update();
    }
    let dt = app.world().resource::<SimSettings>().0.dt;
    assert_eq!(dt, Duration::from_secs_f64(1.0 / 120.0).as_secs_f32());
    let clock = *app.world().resource::<SimClock>();
    assert_eq!(clock.frame, 60);
    assert!((clock.time - 0.75).abs() < 1e-6, "{}", clock.time);
    assert!(app_positions(&mut app).iter().all(|x| x.is_finite()));
}

#[test]
fn a_refused_description_from_commands_is_logged_and_the_game_goes_on() {
    let mut app = App::new();
    app.add_plugins(
        CleavePlugin::new(SimConfig::default())
            .unwrap()
            .in_schedule(Update),
    );
    #[derive(Resource)]
    struct Reserved(Entity, Entity);
    app.add_systems(Startup, |mut commands: Commands| {
        let mut bad = BodyDesc::new(Shape::cuboid(UVec3::splat(3)), 0.1);
        bad.spacing = -1.0;
        let refused = commands.spawn_empty().queue(SpawnBody(bad)).id();
        let good = BodyDesc::new(Shape::cuboid(UVec3::splat(3)), 0.1);
        let kept = commands.spawn_soft_body(good);
        commands.insert_resource(Reserved(refused, kept));
    });
    for _ in 0..3 {
        app.update();
    }
    let Reserved(refused, kept) = *app.world().resource::<Reserved>();
    assert!(app.world().get_entity(refused).is_err(), "despawned");
    assert!(app.world().get::<BodyLattice>(kept).is_some());
    assert!(app_positions(&mut app).iter().all(|x| x.is_finite()));
}

/// A 12×6×6 block and a blade above it, moved by the test between frames.
fn block_and_blade() -> (Simulation, Entity, Entity) {
    let config = SimConfig {
        ground: None,
        gravity: Vec3::ZERO,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).unwrap();
    let body = sim
        .spawn_body(&BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 6)), 0.1))
        .unwrap();
    let tool = sim
        .spawn_tool(&ToolDesc {
            shape: ToolShape::Blade {
                half_width: 1.0,
                half_height: 0.2,
            },
            cut_width: 0.101,
            cut_mode: CutMode::Remove,
            path: Path { keys: vec![] },
            pose: blade_at(1.0),
        })
        .unwrap();
    (sim, body, tool)
}

fn blade_at(y: f32) -> Pose {
    Pose {
        position: Vec3::new(0.05, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    }
}

/// Moves the blade from `from` to `to` (heights) over 10 frames.
fn stroke(sim: &mut Simulation, tool: Entity, from: f32, to: f32) {
    for i in 1..=10 {
        let y = from + (to - from) * i as f32 / 10.0;
        sim.set_tool_pose(tool, blade_at(y)).unwrap();
        sim.step();
    }
}

#[test]
fn a_disabled_tool_cuts_nothing_and_enabled_again_cuts_only_from_where_it_is() {
    let (mut sim, body, tool) = block_and_blade();
    sim.world_mut().entity_mut(tool).insert(Disabled);
    stroke(&mut sim, tool, 1.0, -1.0);
    assert_eq!(sim.pieces(body).unwrap().len(), 1, "disabled, it cut");
    assert!(sim.messages::<ParticlesCut>().is_empty());
    // enabled below the block: no sweep from where it was disabled
    sim.world_mut().entity_mut(tool).remove::<Disabled>();
    sim.set_tool_pose(tool, blade_at(-1.0)).unwrap();
    sim.run(3);
    assert_eq!(sim.pieces(body).unwrap().len(), 1, "enabling it cut");
    // and it cuts again when it moves through
    stroke(&mut sim, tool, -1.0, 1.0);
    assert_eq!(sim.pieces(body).unwrap().len(), 2);
}

#[test]
fn a_tool_despawned_mid_stroke_stops_cutting() {
    let (mut sim, body, tool) = block_and_blade();
    stroke(&mut sim, tool, 1.0, 0.15);
    let live = sim.positions(body).unwrap().len();
    assert!(live < 12 * 6 * 6, "the blade has entered the block");
    sim.world_mut().despawn(tool);
    sim.run(20);
    assert_eq!(sim.positions(body).unwrap().len(), live);
    assert_eq!(sim.pieces(body).unwrap().len(), 1);
    assert!(check_invariants(sim.world()).is_empty());
}

/// Counts the frames whose `SurfaceMesh` was marked changed.
#[derive(Resource, Default)]
struct Uploads(u32);

fn count_uploads(changed: Query<(), Changed<SurfaceMesh>>, mut uploads: ResMut<Uploads>) {
    uploads.0 += changed.iter().count() as u32;
}

#[test]
fn a_body_at_rest_stops_marking_its_surface_changed() {
    let mut app = App::new();
    app.add_plugins(TimePlugin);
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    app.add_plugins(CleavePlugin::new(SimConfig::default()).unwrap());
    app.init_resource::<Uploads>();
    app.add_systems(FixedUpdate, count_uploads);
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(6)), 0.1);
    desc.position = Vec3::new(0.0, 0.5, 0.0);
    app.add_systems(Startup, move |mut commands: Commands| {
        commands.spawn_soft_body(desc.clone());
    });
    // falling: every frame is an upload
    for _ in 0..20 {
        app.update();
    }
    let falling = app.world().resource::<Uploads>().0;
    assert!(falling >= 18, "{falling} uploads in 20 falling frames");
    for _ in 0..400 {
        app.update();
    }
    app.world_mut().resource_mut::<Uploads>().0 = 0;
    for _ in 0..60 {
        app.update();
    }
    assert_eq!(app.world().resource::<Uploads>().0, 0, "re-uploads at rest");
}

#[test]
fn the_surface_tells_each_vertex_and_triangle_its_piece() {
    let mut sim = Simulation::from_scene(&builtin("slice", 0).unwrap()).unwrap();
    sim.run(120);
    let body = sim.bodies()[0];
    let surface = sim.surface(body).unwrap();
    let pieces = surface.vertex_pieces();
    assert_eq!(pieces.len(), surface.positions.len());
    for (t, &p) in surface.triangles().iter().zip(surface.triangle_pieces()) {
        assert!(t.iter().all(|&v| pieces[v as usize] == p));
    }
    let (sorted, ranges) = surface.triangles_by_piece();
    assert_eq!(ranges.iter().map(|r| r.0).collect::<Vec<_>>(), [0, 1]);
    assert_eq!(ranges[1].1.end, sorted.len());
    for (piece, range) in &ranges {
        assert!(
            sorted[range.clone()]
                .iter()
                .all(|t| pieces[t[0] as usize] == *piece)
        );
    }
    let not_a_body = sim
        .spawn_tool(&builtin("slice", 0).unwrap().tools[0])
        .unwrap();
    assert!(sim.surface(not_a_body).is_err());
}
