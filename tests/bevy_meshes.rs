//! The `bevy_mesh` feature: every body's `Mesh` asset holds exactly its `SurfaceMesh`
//! after each frame, in every cut mode, re-uploading triangles only when they changed;
//! between fixed steps the drawn positions are blended by the clock's overstep.
#![cfg(feature = "bevy_mesh")]

use bevy_app::{App, Update};
use bevy_asset::Assets;
use bevy_mesh::{Indices, Mesh, Mesh3d, VertexAttributeValues};
use bevy_time::{Fixed, Time, TimePlugin, TimeUpdateStrategy};
use cleave::ecs::spawn::{spawn_body, spawn_tool};
use cleave::io::scene::builtin;
use cleave::prelude::*;
use cleave::sim::meshes::MeshSync;
use std::time::Duration;

fn vec3s(mesh: &Mesh, id: bevy_mesh::MeshVertexAttribute) -> Vec<[f32; 3]> {
    match mesh.attribute(id) {
        Some(VertexAttributeValues::Float32x3(v)) => v.clone(),
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_meshes_hold_the_surfaces_in_every_cut_mode_and_upload_triangles_only_on_change() {
    for mode in [CutMode::Remove, CutMode::Sever, CutMode::Split] {
        let mut scene = builtin("slice", 0).unwrap();
        scene.tools[0].cut_mode = mode;
        let mut app = App::new();
        app.add_plugins(
            CleavePlugin::new(scene.config.clone())
                .unwrap()
                .in_schedule(Update),
        );
        app.init_resource::<Assets<Mesh>>();
        let body = spawn_body(app.world_mut(), &scene.bodies[0]).unwrap();
        spawn_tool(app.world_mut(), &scene.tools[0]).unwrap();
        for frame in 0..120 {
            app.update();
            let world = app.world();
            let surface = world.get::<SurfaceMesh>(body).unwrap();
            let Some(handle) = world.get::<Mesh3d>(body) else {
                assert_eq!(frame, 0, "no mesh after the first frame");
                continue;
            };
            let mesh = world.resource::<Assets<Mesh>>().get(&handle.0).unwrap();
            let positions: Vec<[f32; 3]> = surface.positions.iter().map(|p| p.to_array()).collect();
            let normals: Vec<[f32; 3]> = surface.normals.iter().map(|p| p.to_array()).collect();
            assert_eq!(
                vec3s(mesh, Mesh::ATTRIBUTE_POSITION),
                positions,
                "{mode:?} {frame}"
            );
            assert_eq!(
                vec3s(mesh, Mesh::ATTRIBUTE_NORMAL),
                normals,
                "{mode:?} {frame}"
            );
            let Some(Indices::U32(indices)) = mesh.indices() else {
                panic!("no u32 indices")
            };
            let triangles: Vec<u32> = surface.triangles().iter().flatten().copied().collect();
            assert_eq!(*indices, triangles, "{mode:?} {frame}");
        }
        let world = app.world();
        assert_eq!(
            world.get::<BodyLattice>(body).unwrap().pieces,
            2,
            "{mode:?}"
        );
        let uploads = world.get::<MeshSync>(body).unwrap().index_uploads;
        let versions = world.get::<SurfaceMesh>(body).unwrap().topology_version;
        // once per change of the triangles (the first mesh came with the second frame)
        assert!(
            uploads <= versions && uploads >= 2,
            "{mode:?}: {uploads} uploads, {versions} versions"
        );
        assert!(uploads < 60, "{mode:?}: {uploads} uploads in 120 frames");
    }
}

#[test]
fn between_fixed_steps_the_drawn_positions_are_blended_by_the_overstep() {
    let mut app = App::new();
    app.add_plugins(TimePlugin);
    app.insert_resource(Time::<Fixed>::from_hz(60.0));
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::ZERO));
    app.add_plugins(CleavePlugin::new(SimConfig::default()).unwrap());
    app.init_resource::<Assets<Mesh>>();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(4)), 0.1);
    desc.position = Vec3::new(0.0, 3.0, 0.0);
    let body = spawn_body(app.world_mut(), &desc).unwrap();
    app.update();
    // whole fixed steps, then a step and a half: the last draw is half way
    let step = app.world().resource::<Time<Fixed>>().timestep();
    app.insert_resource(TimeUpdateStrategy::ManualDuration(step));
    for _ in 0..5 {
        app.update();
    }
    app.insert_resource(TimeUpdateStrategy::ManualDuration(step + step / 2));
    app.update();
    let world = app.world();
    let fraction = world.resource::<Time<Fixed>>().overstep_fraction();
    assert!((fraction - 0.5).abs() < 1e-3, "{fraction}");
    let handle = world.get::<Mesh3d>(body).unwrap();
    let mesh = world.resource::<Assets<Mesh>>().get(&handle.0).unwrap();
    let drawn = vec3s(mesh, Mesh::ATTRIBUTE_POSITION);
    let now = world.get::<SurfaceMesh>(body).unwrap().positions.clone();
    // falling: the drawn body is above where the simulation's now is, by half a frame's
    // fall (≈ g·t·dt/2 at t ≈ 0.1 s)
    let (drawn_y, now_y) = (drawn[0][1], now[0].y);
    let fall = 9.81 * 0.1 / 60.0;
    assert!(drawn_y > now_y, "{drawn_y} vs {now_y}");
    assert!(
        ((drawn_y - now_y) - fall / 2.0).abs() < fall / 4.0,
        "{drawn_y} vs {now_y}"
    );
}

#[test]
fn a_body_at_rest_is_drawn_still_whatever_the_overstep() {
    let mut app = App::new();
    app.add_plugins(TimePlugin);
    app.insert_resource(Time::<Fixed>::from_hz(60.0));
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    app.add_plugins(CleavePlugin::new(SimConfig::default()).unwrap());
    app.init_resource::<Assets<Mesh>>();
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(6)), 0.1);
    desc.position = Vec3::new(0.0, 0.5, 0.0);
    let body = spawn_body(app.world_mut(), &desc).unwrap();
    for _ in 0..420 {
        app.update();
    }
    let step = app.world().resource::<Time<Fixed>>().timestep();
    let drawn = |app: &App| {
        let handle = app.world().get::<Mesh3d>(body).unwrap();
        vec3s(
            app.world()
                .resource::<Assets<Mesh>>()
                .get(&handle.0)
                .unwrap(),
            Mesh::ATTRIBUTE_POSITION,
        )
    };
    // a frame and a half, then half a frame: overstep 0.5, then 0
    app.insert_resource(TimeUpdateStrategy::ManualDuration(step + step / 2));
    app.update();
    let half = drawn(&app);
    app.insert_resource(TimeUpdateStrategy::ManualDuration(step / 2));
    app.update();
    assert_eq!(
        half,
        drawn(&app),
        "a resting body's drawing moves with the overstep"
    );
}
