//! One schema per type: a field's allowed values are declared once (`cleave::config::
//! ranges`, `cleave::error`'s bounds) or checked by the type's own `validate`, and the
//! scene file and the API refuse the same values with the same text.

mod common;

use cleave::config::ranges::*;
use cleave::error::allowed::Allowed;
use cleave::io::scene_file::SceneFile;
use cleave::prelude::*;
use common::GOOD;

/// Each material range is declared once: a value out of it is refused by the scene file
/// and by the API with the same allowed range, and a value inside it by neither.
#[test]
fn the_file_and_the_api_state_each_material_range_alike() {
    type Set = fn(&mut Material, f64);
    let cases: [(Allowed, f64, f64, Set); 8] = [
        (COMPLIANCE, 2.0, 0.5, |m, v| m.compliance = v as f32),
        (DENSITY, 0.0, 1.0, |m, v| m.density = v as f32),
        (TEAR_STRETCH, 1.0, 1.5, |m, v| {
            m.tear_stretch = Some(v as f32)
        }),
        (TEAR_BUDGET, 0.0, 3.0, |m, v| m.tear_budget = v as u32),
        (PATCH_THRESHOLD, 0.0, 0.5, |m, v| {
            m.patch_threshold = v as f32
        }),
        (CREEP, 1.5, 1.0, |m, v| m.creep = v as f32),
        (EXPAND_COUNT, 1001.0, 1000.0, |m, v| {
            m.expand_count = v as u32
        }),
        (PATCH_RINGS, 9.0, 8.0, |m, v| m.patch_rings = v as u32),
    ];
    for (allowed, bad, good, set) in cases {
        let field = allowed.field;
        let file = |v: f64| {
            let value = if allowed.field == "tear_stretch" {
                format!("Some({v:?})")
            } else if allowed.whole {
                format!("{v}")
            } else {
                format!("{v:?}")
            };
            let text = GOOD.replace(
                "spacing: 0.1,",
                &format!("spacing: 0.1, material: ({field}: {value}),"),
            );
            SceneFile::parse(&text).map(|_| ())
        };
        let api = |v: f64| {
            let mut m = Material::default();
            set(&mut m, v);
            m.validate().map_err(|e| e.to_string())
        };
        let (from_file, from_api) = (
            file(bad).expect_err("the file refuses it"),
            api(bad).expect_err("the API refuses it"),
        );
        let text = allowed.text();
        assert!(
            from_file.contains(&text),
            "{field}: {from_file} (declared: {text})"
        );
        assert!(
            from_api.contains(&format!("material.{field}")) && from_api.contains(&text),
            "{field}: {from_api} (declared: {text})"
        );
        file(good).unwrap_or_else(|e| panic!("{field} = {good}: {e}"));
        api(good).unwrap_or_else(|e| panic!("{field} = {good}: {e}"));
    }
}

/// A body's spacing, position and velocity: the file and the API state the same
/// declared bound.
#[test]
fn the_file_and_the_api_state_a_body_bound_alike() {
    use cleave::error::{POSITION, VELOCITY};
    let body = |field: &str| {
        GOOD.replace(
            "position: (0.0, 0.5, 0.0))",
            &format!("position: (0.0, 0.5, 0.0), {field})"),
        )
    };
    type Set = fn(&mut BodyDesc);
    let cases: [(String, String, Set); 3] = [
        (body("velocity: (2e4, 0.0, 0.0)"), VELOCITY.text(), |d| {
            d.velocity = Vec3::new(2e4, 0.0, 0.0)
        }),
        (
            GOOD.replace("position: (0.0, 0.5, 0.0)", "position: (0.0, 2e6, 0.0)"),
            POSITION.text(),
            |d| d.position = Vec3::new(0.0, 2e6, 0.0),
        ),
        (
            GOOD.replace("spacing: 0.1,", "spacing: 1000.0,"),
            SPACING.text(),
            |d| d.spacing = 1000.0,
        ),
    ];
    for (text, declared, set) in cases {
        let from_file = SceneFile::parse(&text).map(|_| ()).expect_err("refused");
        assert!(
            from_file.contains(&declared),
            "{from_file} (declared: {declared})"
        );
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(4, 4, 4)), 0.1);
        set(&mut desc);
        let mut sim = Simulation::new(SimConfig::default()).expect("a simulation");
        let from_api = sim.spawn_body(&desc).expect_err("refused").to_string();
        assert!(
            from_api.contains(&declared),
            "{from_api} (declared: {declared})"
        );
    }
}

/// What the API refuses, as its error reads.
type Api = Box<dyn Fn() -> Result<(), CleaveError>>;

/// A body with `set` applied, spawned by the API.
fn api_body(set: impl Fn(&mut BodyDesc) + 'static) -> Api {
    Box::new(move || {
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(4, 4, 4)), 0.1);
        desc.position = Vec3::new(0.0, 0.5, 0.0);
        set(&mut desc);
        let mut sim = Simulation::new(SimConfig::default())?;
        sim.spawn_body(&desc).map(|_| ())
    })
}

/// The same simulation with `set` applied to its settings.
fn api_config(set: impl Fn(&mut SimConfig) + 'static) -> Api {
    Box::new(move || {
        let mut config = SimConfig::default();
        set(&mut config);
        Simulation::new(config).map(|_| ())
    })
}

/// A tool, spawned by the API.
fn api_tool(desc: ToolDesc) -> Api {
    Box::new(move || {
        Simulation::new(SimConfig::default())?
            .spawn_tool(&desc)
            .map(|_| ())
    })
}

fn blade(half_width: f32, cut_width: f32, path: Path) -> ToolDesc {
    ToolDesc {
        shape: ToolShape::Blade {
            half_width,
            half_height: 0.5,
        },
        cut_width,
        cut_mode: CutMode::Remove,
        path,
        pose: Pose::at(Vec3::ZERO),
    }
}

fn region() -> Region {
    Region {
        min: Vec3::splat(-1.0),
        max: Vec3::splat(1.0),
    }
}

/// Shapes, colliders, tools, attachments, handles, pins, paths and settings: the scene
/// file and the API refuse each bad value naming the same field with the same allowed
/// text, written once (the type's own check, or a declared bound). Each case gives the
/// file's text, the API's call, the field as the API names it, as the file names it,
/// and the allowed text.
#[test]
fn the_file_and_the_api_refuse_each_type_alike() {
    let body = |from: &str, to: &str| GOOD.replace(from, to);
    let with = |field: &str| body("spacing: 0.1,", &format!("spacing: 0.1, {field},"));
    let cells = "shape: Cells(cells: (4, 4, 4))";
    let size = "0 < size ≤ 1e6 (metres)";
    let increasing = "times strictly increasing (no two keys at one time)";
    let cases: Vec<(String, Api, &str, &str, String)> = vec![
        (
            body(cells, "shape: Sphere(radius: -1.0)"),
            api_body(|d| d.shape = Shape::Sphere { radius: -1.0 }),
            "shape.radius",
            "bodies[0].shape.Sphere.radius",
            size.into(),
        ),
        (
            body(cells, "shape: Capsule(radius: 0.2, half_length: -0.5)"),
            api_body(|d| {
                d.shape = Shape::Capsule {
                    radius: 0.2,
                    half_length: -0.5,
                }
            }),
            "shape.half_length",
            "bodies[0].shape.Capsule.half_length",
            "0 ≤ size ≤ 1e6 (metres)".into(),
        ),
        (
            body(cells, "shape: Box(half_extents: (0.2, 0.0, 0.2))"),
            api_body(|d| {
                d.shape = Shape::Box {
                    half_extents: Vec3::new(0.2, 0.0, 0.2),
                }
            }),
            "shape.half_extents",
            "bodies[0].shape.Box.half_extents",
            format!("{size} on every axis"),
        ),
        (
            body(cells, "shape: Cells(cells: (4, 0, 4))"),
            api_body(|d| d.shape = Shape::cuboid(UVec3::new(4, 0, 4))),
            "shape.cells",
            "bodies[0].shape.Cells.cells",
            "a whole number, 1 ≤ cells ≤ 1e6 on every axis".into(),
        ),
        (
            with("rotation: (0.0, 0.0, 0.0, 0.0)"),
            api_body(|d| d.rotation = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)),
            "body.rotation",
            "bodies[0].rotation",
            "a finite, non-zero quaternion (x, y, z, w)".into(),
        ),
        (
            with(
                "pins: [(min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0), velocity: (2e4, 0.0, 0.0))]",
            ),
            api_body(|d| {
                d.pins = vec![PinRegion {
                    min: Vec3::splat(-1.0),
                    max: Vec3::splat(1.0),
                    velocity: Vec3::new(2e4, 0.0, 0.0),
                }]
            }),
            "body.pins[0].velocity",
            "bodies[0].pins[0].velocity",
            cleave::error::VELOCITY.text(),
        ),
        (
            with(
                "attachments: [(region: (min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0)), compliance: -1.0)]",
            ),
            api_body(|d| {
                d.attachments = vec![AttachmentDesc {
                    region: region(),
                    path: Path::default(),
                    compliance: -1.0,
                    hold: Hold::Each,
                }]
            }),
            "body.attachments[0].compliance",
            "bodies[0].attachments[0].compliance",
            ATTACHMENT_COMPLIANCE.text(),
        ),
        (
            with(
                "attachments: [(region: (min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, NaN)), compliance: 0.0)]",
            ),
            api_body(|d| {
                d.attachments = vec![AttachmentDesc {
                    region: Region {
                        max: Vec3::new(1.0, 1.0, f32::NAN),
                        ..region()
                    },
                    path: Path::default(),
                    compliance: 0.0,
                    hold: Hold::Each,
                }]
            }),
            "body.attachments[0].region.max",
            "bodies[0].attachments[0].region.max",
            "finite".into(),
        ),
        (
            with(
                "handles: [(region: (min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0)), path: [(0.0, (position: (0.0, 0.5, 0.0))), (0.0, (position: (0.0, 0.6, 0.0)))])]",
            ),
            api_body(|d| {
                let key = |y| HandleKey::at(Vec3::new(0.0, y, 0.0));
                d.handles = vec![HandleDesc {
                    region: region(),
                    point: false,
                    path: HandlePath {
                        keys: vec![(0.0, key(0.5)), (0.0, key(0.6))],
                    },
                    compliance: 0.0,
                }]
            }),
            "body.handles[0].path[1].time",
            "bodies[0].handles[0].path[1].time",
            "finite, after the previous key's".into(),
        ),
        (
            body(
                "Sphere(radius: 0.1)",
                "Blade(half_width: 0.0, half_height: 0.5)",
            ),
            api_tool(blade(0.0, 0.05, Path::default())),
            "tool.shape.half_width",
            "tools[0].shape.half_width",
            size.into(),
        ),
        (
            body("cut_width: 0.05", "cut_width: 0.0"),
            api_tool(ToolDesc {
                cut_width: 0.0,
                ..blade(0.1, 0.05, Path::default())
            }),
            "tool.cut_width",
            "tools[0].cut_width",
            size.into(),
        ),
        (
            body(
                "(1.0, (position: (0.0, 0.5, 0.0)))",
                "(0.0, (position: (0.0, 0.5, 0.0)))",
            ),
            api_tool(blade(
                0.1,
                0.05,
                Path {
                    keys: vec![
                        (0.0, Pose::at(Vec3::Y * 2.0)),
                        (0.0, Pose::at(Vec3::Y * 0.5)),
                    ],
                },
            )),
            "tool.path[1].time",
            "tools[0].path[1].time",
            increasing.into(),
        ),
        (
            body(
                "frames: 2,",
                "frames: 2, settings: (boxes: [(min: (1.0, 1.0, 1.0), max: (0.0, 0.0, 0.0), friction: 0.5)]),",
            ),
            api_config(|c| {
                c.boxes = vec![StaticBox {
                    min: Vec3::ONE,
                    max: Vec3::ZERO,
                    friction: 0.5,
                }]
            }),
            "config.boxes[0]",
            "settings.boxes[0]",
            "min ≤ max on every axis".into(),
        ),
        (
            body(
                "frames: 2,",
                "frames: 2, settings: (ground: Some((height: 0.0, friction: -1.0))),",
            ),
            api_config(|c| {
                c.ground = Some(GroundPlane {
                    height: 0.0,
                    friction: -1.0,
                })
            }),
            "config.ground.friction",
            "settings.ground.friction",
            FRICTION.text(),
        ),
    ];
    for (text, api, api_field, file_field, declared) in cases {
        let allowed = format!("(allowed: {declared})");
        let from_file = SceneFile::parse(&text).map(|_| ()).expect_err(api_field);
        assert!(
            from_file.contains(&format!(" {file_field}: ")) && from_file.contains(&allowed),
            "the file: {from_file} (expected {file_field} and {allowed})"
        );
        let from_api = api().expect_err(api_field).to_string();
        assert!(
            from_api.contains(&format!("`{api_field}`")) && from_api.contains(&allowed),
            "the API: {from_api} (expected {api_field} and {allowed})"
        );
    }
}
