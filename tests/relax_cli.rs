//! `cleave relax` and the scene fields of shape keeping: the relaxation's report in the
//! summary, the picture before it, and bad values refused with the file, line, column
//! and field, exit code 2.

use std::process::Command;

mod common;
use common::run_file;

fn cleave(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(args)
        .output()
        .expect("cleave runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn cleave_relax_reports_every_body_settled_into_its_rest_shape() {
    let dir = std::env::temp_dir().join(format!("cleave-relax-{}", std::process::id()));
    let out = dir.to_str().expect("a path");
    let (code, err) = cleave(&[
        "relax",
        "jittered",
        "--out",
        out,
        "--quiet",
        "--gif-every",
        "0",
    ]);
    assert_eq!(code, Some(0), "{err}");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("summary.json")).expect("a summary"),
    )
    .expect("JSON");
    assert_eq!(
        summary["frames"], 0,
        "cleave relax runs no frames unless asked"
    );
    let bodies = summary["bodies"].as_array().expect("bodies");
    assert_eq!(bodies.len(), 2);
    for body in bodies {
        let relax = &body["relax"];
        let number = |key: &str| {
            relax[key]
                .as_f64()
                .unwrap_or_else(|| panic!("{key}: {relax}"))
        };
        assert_eq!(relax["converged"], true, "{relax}");
        assert!(number("shape_error_before") > 0.2, "{relax}");
        assert!(number("shape_error") < 0.05, "{relax}");
        assert!(number("boundary_drift") < 1e-4, "{relax}");
        assert!(number("frames") >= 2.0, "{relax}");
        // the run starts from the relaxed shape
        let start = body["before"]["shape_error_h"]
            .as_f64()
            .expect("a shape error");
        assert!((start - number("shape_error")).abs() < 1e-3, "{body}");
    }
    assert!(dir.join("before_relax.png").is_file());
    assert!(dir.join("frame_00000.png").is_file());
    // `cleave run` of a scene without `settings.relax` relaxes nothing
    let (code, err) = cleave(&["run", "drop", "--frames", "1", "--out", out, "--quiet"]);
    assert_eq!(code, Some(0), "{err}");
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("a summary");
    assert!(summary.contains("\"relax\": null"), "{summary}");
}

#[test]
fn bad_shape_keeping_fields_are_refused_naming_file_line_column_and_field() {
    let scene = |settings: &str, material: &str, body: &str| {
        format!(
            "(\n    settings: ({settings}),\n    bodies: [(\n        shape: Cells(cells: (6, 6, 6)),\n        spacing: 0.1,\n        position: (0.0, 1.0, 0.0),\n        material: ({material}),{body}\n    )],\n)\n"
        )
    };
    let good = scene(
        "relax: Some((tolerance: 0.05, damping: 20.0))",
        "patch_rings: 3, patch_normal_compliance: Some(1e-6), patch_threshold: 0.2",
        " jitter: 0.2,",
    );
    let (code, err) = run_file("shapes.ron", &good);
    assert_eq!(code, Some(0), "{err}");
    for (name, text, field, line) in [
        (
            "rings0.ron",
            good.replace("patch_rings: 3", "patch_rings: 0"),
            "patch_rings",
            7,
        ),
        (
            "rings9.ron",
            good.replace("patch_rings: 3", "patch_rings: 9"),
            "patch_rings",
            7,
        ),
        (
            "threshold.ron",
            good.replace("patch_threshold: 0.2", "patch_threshold: 0.0"),
            "patch_threshold",
            7,
        ),
        (
            "normal.ron",
            good.replace("Some(1e-6)", "Some(-1e-6)"),
            "patch_normal_compliance",
            7,
        ),
        (
            "tangent.ron",
            good.replace(
                "patch_threshold",
                "patch_tangent_compliance: Some(NaN), patch_threshold",
            ),
            "patch_tangent_compliance",
            7,
        ),
        (
            "tolerance.ron",
            good.replace("tolerance: 0.05", "tolerance: 0.0"),
            "relax.tolerance",
            2,
        ),
        (
            "tolnan.ron",
            good.replace("tolerance: 0.05", "tolerance: NaN"),
            "relax.tolerance",
            2,
        ),
        (
            "jitter.ron",
            good.replace("jitter: 0.2", "jitter: 0.7"),
            "jitter",
            7,
        ),
    ] {
        let (code, err) = run_file(name, &text);
        assert_eq!(code, Some(2), "{name}: {err}");
        assert!(
            err.contains(&format!("{name}:{line}:")) && err.contains(field),
            "{name}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}
