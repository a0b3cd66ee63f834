//! `cleave deform`, the `bend` and `grab` scenes and `cleave bench --deform` through the
//! binary: the outputs a person looks at, the figures the report promises, and bad
//! handles in a scene file refused with exit code 2 and their place in the file.

mod common;

use common::{assert_mentions, run_file};
use serde_json::Value;
use std::process::Command;

fn cleave(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(args)
        .output()
        .expect("run cleave")
}

#[test]
fn deform_bend_poses_the_bar_and_writes_pictures_and_a_summary() {
    let dir = std::env::temp_dir().join(format!("cleave-deform-{}", std::process::id()));
    for method in ["linear", "arap", "reduced"] {
        let out = dir.join(method);
        let run = cleave(&[
            "deform",
            "bend",
            "--method",
            method,
            "--frames",
            "60",
            "--quiet",
            "--png-every",
            "60",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let summary: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(summary["finite"], true);
        assert_eq!(summary["invariant_violations"], 0);
        // bent a quarter turn: far from its rest shape (a body left still would be at it)
        let error = summary["final_shape_error_h"].as_f64().unwrap();
        assert!(error > 1.0, "{method}: shape error {error} h");
        assert!(out.join("frame_00060.png").exists());
    }
}

#[test]
fn bench_deform_reports_every_figure() {
    let run = cleave(&["bench", "--deform", "--json", "--steps", "1"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let row: Value = serde_json::from_str(String::from_utf8(run.stdout).unwrap().trim()).unwrap();
    for key in [
        "weights_16_ms",
        "weights_32_ms",
        "pose_64_ms",
        "arap_32_iteration_ms",
        "reduced_arap_frame_ms",
        "reduced_dynamics_frame_ms",
    ] {
        let ms = row[key].as_f64().unwrap_or(f64::NAN);
        assert!(ms.is_finite() && ms > 0.0, "{key}: {ms}");
    }
    assert!(row["weights_32_ms"].as_f64() > row["weights_16_ms"].as_f64());
}

#[test]
fn a_handle_that_selects_nothing_is_refused_with_its_place_in_the_file() {
    let scene = r#"(
    frames: 2,
    bodies: [(
        shape: Cells(cells: (4, 4, 4)),
        spacing: 0.1,
        position: (0.0, 0.5, 0.0),
        handles: [(region: (min: (5.0, 5.0, 5.0), max: (6.0, 6.0, 6.0)), point: true)],
    )],
)"#;
    let (code, stderr) = run_file("empty_handle.ron", scene);
    assert_eq!(code, Some(2), "{stderr}");
    assert_mentions(&stderr, &["empty_handle.ron:3:", "handles[0].region"]);
    let scene = scene.replace(
        "point: true)",
        "path: [(0.0, (position: (0.0, 0.5, 0.0), scale: (0.0, 1.0, 1.0)))])",
    );
    let (code, stderr) = run_file("zero_scale.ron", &scene);
    assert_eq!(code, Some(2), "{stderr}");
    assert_mentions(&stderr, &["zero_scale.ron:", "scale"]);
}
