//! Scene files: every built-in round-trips through RON, and bad files give one clear
//! error line (file, line, column, field, allowed range) and exit code 2.

use cleave::ecs::desc::Scene;
use cleave::io::scene::{BUILTIN_SCENES, builtin};
use cleave::io::scene_file::SceneFile;
use cleave::prelude::*;
use std::path::Path;
use std::process::Command;

mod common;
use common::{GOOD, run_file};

/// Runs the scene file `text` as `name`, which must be refused (exit code 2) with an
/// error naming the file and `expected`; the error.
fn refused_naming(name: &str, text: &str, expected: &str) -> String {
    let (code, err) = run_file(name, text);
    assert_eq!(code, Some(2), "{name}: {err}");
    assert!(
        err.contains(expected) && err.contains(name),
        "{name}: {err}"
    );
    err
}

fn positions_after(scene: &Scene, frames: u32) -> Vec<u32> {
    let mut sim = Simulation::from_scene(scene).unwrap();
    sim.run(frames);
    let mut q = sim.world_mut().query::<(&Particle, &Position)>();
    let mut v: Vec<(u32, [f32; 3])> = q
        .iter(sim.world())
        .map(|(p, x)| (p.index, x.0.to_array()))
        .collect();
    v.sort_by_key(|(i, _)| *i);
    v.into_iter()
        .flat_map(|(_, x)| x.map(f32::to_bits))
        .collect()
}

#[test]
fn every_builtin_round_trips_through_ron() {
    for name in BUILTIN_SCENES.map(|b| b.name) {
        let scene = builtin(name, 3).unwrap();
        let text = SceneFile::from_scene(&scene).unwrap().to_ron();
        let parsed = SceneFile::parse(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let again = parsed.to_scene(Path::new(".")).unwrap();
        assert_eq!(
            SceneFile::from_scene(&again).unwrap().to_ron(),
            text,
            "{name}: text changed"
        );
        assert_eq!(again.frames, scene.frames);
        assert_eq!(again.tools.len(), scene.tools.len());
        assert_eq!(again.colliders.len(), scene.colliders.len());
        // and it is the same simulation
        assert!(
            positions_after(&again, 40) == positions_after(&scene, 40),
            "{name}: the file runs differently"
        );
    }
}

#[test]
fn a_minimal_file_runs() {
    let (code, err) = run_file("good.ron", GOOD);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_file_with_many_bodies_and_colliders_runs() {
    let text = GOOD.replace(
        "bodies: [(shape: Cells(cells: (4, 4, 4)), spacing: 0.1, position: (0.0, 0.5, 0.0))],",
        "bodies: [(shape: Cells(cells: (4, 4, 4)), spacing: 0.1, position: (0.0, 0.5, 0.0)), \
         (shape: Sphere(radius: 0.2), spacing: 0.1, position: (0.0, 1.2, 0.0))], \
         colliders: [(shape: Capsule(radius: 0.1, half_length: 0.5), \
         pose: Some((position: (0.0, 0.1, 1.0), rotation: (0.0, 0.38268343, 0.0, 0.9238795)))), \
         (shape: Box(half_extents: (0.5, 0.05, 0.5)), friction: 0.2, \
         path: [(0.0, (position: (2.0, 0.5, 0.0))), (1.0, (position: (2.0, 0.1, 0.0)))])],",
    );
    let (code, err) = run_file("many.ron", &text);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_smoothed_surface_is_read_from_files_and_a_misspelt_option_is_named() {
    let text = GOOD.replace("spacing: 0.1,", "spacing: 0.1, surface: (smooth: true),");
    let scene = SceneFile::parse(&text)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    assert!(scene.bodies[0].surface.smooth);
    let plain = SceneFile::parse(GOOD)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    assert!(!plain.bodies[0].surface.smooth);
    let (code, err) = run_file("smooth.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run_file("smoth.ron", &text.replace("smooth: true", "smoth: true"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("smoth.ron") && err.contains("smoth"), "{err}");
}

#[test]
fn cut_modes_tearing_and_moving_pins_are_read_from_files_and_checked() {
    let text = GOOD
        .replace("cut_width: 0.05,", r#"cut_width: 0.05, cut_mode: "sever","#)
        .replace(
            "spacing: 0.1,",
            "spacing: 0.1, material: (tear_stretch: 1.3, tear_budget: 5, tear_min_piece: 2), \
             pins: [(min: (-1.0, 0.0, -1.0), max: (-0.1, 2.0, 1.0), velocity: (-0.5, 0.0, 0.0))],",
        );
    let scene = SceneFile::parse(&text)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    assert_eq!(scene.tools[0].cut_mode, CutMode::Sever);
    let body = &scene.bodies[0];
    assert_eq!(body.material.tear_stretch, Some(1.3));
    assert_eq!(
        (body.material.tear_budget, body.material.tear_min_piece),
        (5, 2)
    );
    assert_eq!(body.pins[0].velocity, Vec3::new(-0.5, 0.0, 0.0));
    let (code, err) = run_file("modes.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    for (name, good, bad, expected) in [
        (
            "stretch.ron",
            "tear_stretch: 1.3",
            "tear_stretch: 1.0",
            "material.tear_stretch",
        ),
        (
            "stretchnan.ron",
            "tear_stretch: 1.3",
            "tear_stretch: NaN",
            "material.tear_stretch",
        ),
        (
            "budget.ron",
            "tear_budget: 5",
            "tear_budget: 0",
            "material.tear_budget",
        ),
        (
            "mode.ron",
            r#""sever""#,
            r#""slice""#,
            "unknown cut mode `slice`",
        ),
        ("pin.ron", "velocity: (-0.5", "velocity: (1e9", "velocity"),
    ] {
        let text = text.replace(good, bad);
        refused_naming(name, &text, expected);
    }
}

#[test]
fn bad_files_give_one_line_naming_file_position_and_field() {
    let collider = |shape: &str| {
        GOOD.replace(
            "    tools: [(",
            &format!("    colliders: [(shape: {shape})],\n    tools: [("),
        )
    };
    let cases: [(&str, String, &[&str]); 25] = [
        (
            "zero.ron",
            GOOD.replace("Cells(cells: (4, 4, 4))", r#"Mesh(path: "/dev/zero")"#),
            &["zero.ron", "bodies[0].shape.path", "/dev/zero", "not a regular file"],
        ),
        (
            "nothing.ron",
            GOOD.replace("Cells(cells: (4, 4, 4))", "Sphere(radius: 0.001)"),
            &["nothing.ron:3:14: bodies[0]", "`shape` produced no particles"],
        ),
        (
            "capsule.ron",
            GOOD.replace(
                "Cells(cells: (4, 4, 4))",
                "Capsule(radius: 0.2, half_length: -0.5)",
            ),
            &["capsule.ron:3:60: bodies[0].shape.Capsule.half_length", "-0.5", "0 ≤ size ≤ 1e6"],
        ),
        (
            "union.ron",
            GOOD.replace(
                "Cells(cells: (4, 4, 4))",
                "Union(parts: [(shape: Sphere(radius: 0.3), at: (0, 0, 0)), (shape: Cells(cells: (2, 2, 2)), at: (1, 0, 0))])",
            ),
            &["union.ron:3:14: bodies[0]", "shape.parts[1].shape", "Cells"],
        ),
        (
            "empty_union.ron",
            GOOD.replace("Cells(cells: (4, 4, 4))", "Union(parts: [])"),
            &["empty_union.ron:3:14: bodies[0]", "shape.parts", "at least one part"],
        ),
        (
            "raw.ron",
            GOOD.replace("Cells(cells: (4, 4, 4))", "Sphere(0.6)"),
            &[
                "raw.ron:3:",
                "bodies[0].shape.Sphere",
                "expected a field name, found `0.6`",
                "Sphere(radius: 0.6)",
            ],
        ),
        (
            "memory.ron",
            GOOD.replace("frames: 2,", "frames: 2, settings: (memory_budget_gb: 0),"),
            &["memory.ron:2:", "settings.memory_budget_gb", "1e-3 ≤ memory_budget_gb"],
        ),
        (
            "ball.ron",
            collider("Sphere(radius: -1.0)"),
            &["ball.ron:4:", "colliders[0].shape.radius:", "allowed: 0 < size ≤ 1e6 (metres)"],
        ),
        (
            "friction.ron",
            GOOD.replace("spacing: 0.1,", "spacing: 0.1, material: (static_friction: NaN),"),
            &["friction.ron:3:", "bodies[0].material.static_friction", "allowed: 0 ≤ static_friction ≤ 100"],
        ),
        (
            "meshcollider.ron",
            collider(r#"Mesh(path: "nowhere.obj")"#),
            &["meshcollider.ron", "colliders[0].shape.path", "nowhere.obj"],
        ),
        (
            "pinregion.ron",
            GOOD.replace(
                "position: (0.0, 0.5, 0.0))],",
                "position: (0.0, 0.5, 0.0), pins: [(min: (inf, 0.0, 0.0), max: (1.0, 1.0, 1.0))])],",
            ),
            &["pinregion.ron:3:", "bodies[0].pins", "allowed: finite"],
        ),
        (
            "syntax.ron",
            GOOD.replace("frames: 2,", "frames: 2,,"),
            &["syntax.ron:2:"],
        ),
        (
            "unknown.ron",
            GOOD.replace("spacing: 0.1,", "spacing: 0.1, colour: 3,"),
            &["unknown.ron:3:", "colour"],
        ),
        (
            "spacing.ron",
            GOOD.replace("spacing: 0.1", "spacing: -0.1"),
            &[
                "spacing.ron:3:",
                "bodies[0].spacing",
                "-0.1",
                "allowed: 1e-4 ≤ spacing ≤ 100",
            ],
        ),
        (
            "tiny.ron",
            GOOD.replace("spacing: 0.1", "spacing: 1e-44"),
            &["tiny.ron:3:", "bodies[0].spacing", "allowed: 1e-4 ≤ spacing"],
        ),
        (
            "far.ron",
            GOOD.replace("position: (0.0, 0.5, 0.0))],", "position: (1e30, 0.5, 0.0))],"),
            &["far.ron:3:", "bodies[0].position", "allowed: |x|, |y|, |z| ≤ 1e6"],
        ),
        (
            "fast.ron",
            GOOD.replace("spacing: 0.1,", "spacing: 0.1, velocity: (0.0, -1e30, 0.0),"),
            &["fast.ron:3:", "bodies[0].velocity", "≤ 1e4 (m/s)"],
        ),
        (
            "heavy.ron",
            GOOD.replace("frames: 2,", "frames: 2, settings: (gravity: (0.0, -1e38, 0.0)),"),
            &["heavy.ron:2:", "settings.gravity", "≤ 1e4 (m/s²)"],
        ),
        (
            "ground.ron",
            GOOD.replace("frames: 2,", "frames: 2, settings: (ground: Some((height: 1e30, friction: 0.5))),"),
            &["ground.ron:2:", "settings.ground", "-1e6 ≤ height ≤ 1e6"],
        ),
        (
            "mass.ron",
            GOOD.replace("spacing: 0.1,", "spacing: 0.1, material: (particle_mass: 1e-40),"),
            &["mass.ron:3:", "bodies[0].material.particle_mass", "1e-9 ≤ particle_mass"],
        ),
        (
            "nan.ron",
            GOOD.replace(
                "(1.0, (position: (0.0, 0.5, 0.0)))",
                "(1.0, (position: (NaN, 0.5, 0.0)))",
            ),
            &["nan.ron:7:", "tools[0].path", "allowed: |x|, |y|, |z| ≤ 1e6"],
        ),
        (
            "empty.ron",
            "(bodies: [])".to_string(),
            &["empty.ron:1:", "bodies", "empty", "at least one body"],
        ),
        (
            "mesh.ron",
            GOOD.replace("Cells(cells: (4, 4, 4))", r#"Mesh(path: "missing.obj")"#),
            &["mesh.ron", "bodies[0].shape", "missing.obj"],
        ),
        (
            "render.ron",
            GOOD.replace(
                "spacing: 0.1, position: (0.0, 0.5, 0.0))",
                r#"spacing: 0.1, position: (0.0, 0.5, 0.0), render_mesh: Some("gone.obj"))"#,
            ),
            &["render.ron", "bodies[0].render_mesh", "gone.obj", "cannot open"],
        ),
        (
            "render_zero.ron",
            GOOD.replace(
                "spacing: 0.1, position: (0.0, 0.5, 0.0))",
                r#"spacing: 0.1, position: (0.0, 0.5, 0.0), render_mesh: Some("/dev/zero"))"#,
            ),
            &["bodies[0].render_mesh", "/dev/zero", "not a regular file"],
        ),
    ];
    for (name, text, expected) in cases {
        let (code, err) = run_file(name, &text);
        assert_eq!(code, Some(2), "{name}: {err}");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{name}: not one line: {err}"
        );
        for e in expected {
            assert!(err.contains(e), "{name}: `{e}` missing from: {err}");
        }
    }
}

#[test]
fn a_byte_order_mark_and_a_long_rotation_are_read_as_meant() {
    let text = format!(
        "\u{feff}{}",
        GOOD.replace(
            "(1.0, (position: (0.0, 0.5, 0.0)))",
            "(1.0, (position: (0.0, 0.5, 0.0), rotation: (0.0, 0.0, 0.0, 1e30)))",
        )
    );
    let (code, err) = run_file("bom.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    let scene = SceneFile::parse(&text)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    assert_eq!(scene.tools[0].path.keys[1].1.rotation, glam::Quat::IDENTITY);
}

#[test]
fn the_readme_scene_file_parses() {
    let readme = include_str!("../README.md");
    let start = readme.find("```ron\n").expect("a RON block in the README") + 7;
    let end = start + readme[start..].find("```").unwrap();
    let scene = SceneFile::parse(&readme[start..end])
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    assert_eq!(
        (scene.frames, scene.bodies.len(), scene.tools.len()),
        (240, 1, 1)
    );
}

#[test]
fn attachments_and_edge_compliance_are_read_from_files_and_checked() {
    let text = GOOD.replace(
        "spacing: 0.1,",
        "spacing: 0.1, material: (compliance: 1e-5, edge_compliance: Some(1e-7)), \
         attachments: [(region: (min: (-1.0, 0.6, -1.0), max: (1.0, 2.0, 1.0)), \
         path: [(0.0, (position: (0.0, 1.0, 0.0))), (0.5, (position: (1.0, 1.0, 0.0)))], \
         compliance: 1e-4)],",
    );
    let scene = SceneFile::parse(&text)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    let body = &scene.bodies[0];
    assert_eq!(body.material.edge_compliance, Some(1e-7));
    assert_eq!(body.attachments.len(), 1);
    assert_eq!(body.attachments[0].compliance, 1e-4);
    assert_eq!(body.attachments[0].path.keys.len(), 2);
    let (code, err) = run_file("attached.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    for (name, good, bad, expected) in [
        (
            "edgeneg.ron",
            "Some(1e-7)",
            "Some(-1.0)",
            "bodies[0].material.edge_compliance",
        ),
        (
            "edgenan.ron",
            "Some(1e-7)",
            "Some(NaN)",
            "bodies[0].material.edge_compliance",
        ),
        (
            "edgeinf.ron",
            "Some(1e-7)",
            "Some(inf)",
            "bodies[0].material.edge_compliance",
        ),
        (
            "attneg.ron",
            "compliance: 1e-4)",
            "compliance: -1e-4)",
            "bodies[0].attachments[0].compliance",
        ),
        (
            "attnan.ron",
            "compliance: 1e-4)",
            "compliance: NaN)",
            "bodies[0].attachments[0].compliance",
        ),
        (
            "attinf.ron",
            "compliance: 1e-4)",
            "compliance: inf)",
            "bodies[0].attachments[0].compliance",
        ),
        (
            "attorder.ron",
            "(0.5, (position: (1.0",
            "(-0.5, (position: (1.0",
            "bodies[0].attachments[0].path",
        ),
        (
            "atttime.ron",
            "(0.5, (position: (1.0",
            "(NaN, (position: (1.0",
            "bodies[0].attachments[0].path",
        ),
        (
            "attregion.ron",
            "min: (-1.0, 0.6, -1.0)",
            "min: (5.0, 0.6, -1.0)",
            "attachments[0].region",
        ),
    ] {
        let text = text.replace(good, bad);
        assert_ne!(text, GOOD, "{name}: replaced");
        let err = refused_naming(name, &text, expected);
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{name}: not one line: {err}"
        );
    }
}

#[test]
fn numbers_that_are_not_whole_or_out_of_range_name_the_field_and_its_range() {
    let collider = |shape: &str| {
        GOOD.replace(
            "frames: 2,",
            &format!("frames: 2, colliders: [(shape: {shape})],"),
        )
    };
    for (name, text, expected) in [
        (
            "fraction.ron",
            GOOD.replace("frames: 2,", "frames: 2, settings: (substeps: 2.5),"),
            "fraction.ron:2:40: settings.substeps: 2.5 is out of range (allowed: a whole number, 1 ≤ substeps ≤ 1000)",
        ),
        (
            "seed.ron",
            GOOD.replace("frames: 2,", "frames: 2, seed: 18446744073709551616,"),
            "seed: 18446744073709552000 is out of range (allowed: a whole number, 0 ≤ seed ≤ 18446744073709551615)",
        ),
        (
            "resolution.ron",
            collider(r#"Mesh(path: "x.obj", resolution: -4)"#),
            "-4 is out of range (allowed: a whole number, 4 ≤ resolution ≤ 256)",
        ),
    ] {
        let (code, err) = run_file(name, &text);
        assert_eq!(code, Some(2), "{name}: {err}");
        assert!(err.contains(expected), "{name}: {err}");
    }
    // flags: a negative, a fraction, a size beyond the memory budget, a crowd out of range
    for (args, expected) in [
        (
            &["run", "drop", "--frames", "-1"][..],
            "'--frames <FRAMES>': -1 is out of range (allowed: a whole number, 0 ≤ frames ≤ 1e7)",
        ),
        (
            &["run", "drop", "--substeps", "2.5"][..],
            "'--substeps <SUBSTEPS>': 2.5 is out of range",
        ),
        (
            &["bench", "--sizes", "256"][..],
            "--sizes: 256 is out of range (allowed 2 ≤ size ≤ 149",
        ),
        (
            &["bench", "--crowd-bodies", "0"][..],
            "--crowd-bodies: 0 is out of range (allowed 1 ≤ bodies ≤ 64)",
        ),
        (
            &["bench", "--crowd-bodies", "65"][..],
            "--crowd-bodies: 65 is out of range (allowed 1 ≤ bodies ≤ 64)",
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}

#[test]
fn centroid_holds_are_read_from_files_drag_their_body_and_are_checked() {
    // the top layer of the 4×4×4 block (y = 0.65) held by its centroid, which a path
    // moves 1 m along x over half a second
    let text = GOOD.replace(
        "spacing: 0.1,",
        "spacing: 0.1, centroids: [(region: (min: (-1.0, 0.6, -1.0), max: (1.0, 2.0, 1.0)), \
         path: [(0.0, (position: (0.0, 0.65, 0.0))), (0.5, (position: (1.0, 0.65, 0.0)))], \
         compliance: 0.0)],",
    );
    let scene = SceneFile::parse(&text)
        .unwrap()
        .to_scene(Path::new("."))
        .unwrap();
    let holds = &scene.bodies[0].attachments;
    assert_eq!(holds.len(), 1);
    assert_eq!(holds[0].hold, Hold::Centroid);
    // written back as a centroid hold
    let ron = SceneFile::from_scene(&scene).unwrap().to_ron();
    assert!(
        ron.contains("centroids: [") && ron.contains("attachments: []"),
        "{ron}"
    );
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    let top: Vec<u32> = sim
        .positions(body)
        .unwrap()
        .into_iter()
        .filter(|(_, x)| x.y > 0.6)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(top.len(), 16);
    sim.run(60);
    let positions = sim.positions(body).unwrap();
    let held = top
        .iter()
        .map(|p| positions.iter().find(|(i, _)| i == p).unwrap().1)
        .sum::<glam::Vec3>()
        / 16.0;
    assert!(
        held.distance(glam::Vec3::new(1.0, 0.65, 0.0)) < 1e-4 * 0.1,
        "the held centroid is at {held}"
    );
    assert!(sim.centroid(body).unwrap().x > 0.8, "the block was dragged");
    for (name, good, bad, expected) in [
        (
            "centneg.ron",
            "compliance: 0.0)",
            "compliance: -1.0)",
            "bodies[0].centroids[0].compliance",
        ),
        (
            "centorder.ron",
            "(0.5, (position: (1.0",
            "(-0.5, (position: (1.0",
            "bodies[0].centroids[0].path",
        ),
        (
            "centregion.ron",
            "min: (-1.0, 0.6, -1.0)",
            "min: (5.0, 0.6, -1.0)",
            "centroids[0].region",
        ),
    ] {
        let text = text.replace(good, bad);
        refused_naming(name, &text, expected);
    }
}
