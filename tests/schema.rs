//! One schema per type: a number field's allowed values are declared once
//! (`cleave::config::ranges`), and the scene file and the API refuse the same values
//! with the same text.

mod common;

use cleave::config::allowed::Allowed;
use cleave::config::ranges::*;
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
