//! The command line against what an adversarial user tries: `cleave deform` resumed from
//! a save goes on bit for bit under every method (and is refused under another method or
//! as `cleave run`), a save names its scene file however the file is typed, and numbers
//! out of any sensible range, flags that would write nothing and shapes nested past the
//! reader's depth are refused with exit code 2 and a message that says what to do.

mod common;

use common::run_file;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn cleave_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cleave"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run cleave")
}

fn cleave(args: &[&str]) -> Output {
    cleave_in(Path::new("."), args)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cleave-hostile-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn ok(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn refused(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{needles:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
}

const QUIET: [&str; 5] = ["--quiet", "--png-every", "0", "--gif-every", "0"];

#[test]
fn deform_resumes_bit_for_bit_under_every_method() {
    let dir = scratch("deform");
    let path = |f: &str| dir.join(f).to_str().unwrap().to_string();
    for method in ["linear", "arap", "reduced"] {
        let (straight, save, resumed) = (path("straight.json"), path("s.bin"), path("r.json"));
        let run = |extra: &[&str]| {
            let args = [&["deform", "bend", "--method", method][..], &QUIET, extra].concat();
            cleave(&[&args[..], &["--out", &path("out")]].concat())
        };
        ok(&run(&["--frames", "12", "--dump-state", &straight]), method);
        ok(&run(&["--frames", "5", "--save-state", &save]), method);
        // resumed without --method: the saved run's method goes on
        let out = cleave(
            &[
                &["deform", "bend", "--frames", "7", "--load-state", &save][..],
                &QUIET,
                &["--dump-state", &resumed, "--out", &path("out")],
            ]
            .concat(),
        );
        ok(&out, method);
        let (a, b) = (
            std::fs::read(&straight).unwrap(),
            std::fs::read(&resumed).unwrap(),
        );
        assert!(a == b, "{method}: the resumed deform's dump differs");
        // the bar was posed (a resume that dropped the pose would let it fall)
        let dump: serde_json::Value = serde_json::from_slice(&b).unwrap();
        assert_eq!(dump["frame"], 12);
        let other = if method == "linear" { "arap" } else { "linear" };
        refused(
            &cleave(&["deform", "bend", "--load-state", &save, "--method", other]),
            &["--load-state", &format!("poses by `{method}`")],
        );
        refused(
            &cleave(&["run", "bend", "--load-state", &save]),
            &["resume it with `cleave deform`"],
        );
    }
}

#[test]
fn a_save_names_its_scene_file_however_it_is_typed() {
    let dir = scratch("label");
    let scene = "(frames: 3, bodies: [(shape: Cells(cells: (3, 3, 3)), spacing: 0.1, position: (0.0, 0.5, 0.0))])";
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::write(dir.join("scenes/x.ron"), scene).unwrap();
    std::fs::create_dir_all(dir.join("elsewhere")).unwrap();
    let save = dir.join("s.bin");
    let save = save.to_str().unwrap();
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    let run = |cwd: &Path, scene: &str, extra: &[&str]| {
        let args = [&["run", scene, "--out", out][..], &QUIET, extra].concat();
        cleave_in(cwd, &args)
    };
    ok(&run(&dir, "scenes/x.ron", &["--save-state", save]), "save");
    let absolute = dir.join("scenes/x.ron");
    for (cwd, typed) in [
        (dir.clone(), "./scenes/x.ron"),
        (dir.clone(), absolute.to_str().unwrap()),
        (dir.join("elsewhere"), "../scenes/x.ron"),
    ] {
        ok(&run(&cwd, typed, &["--load-state", save]), typed);
    }
    std::fs::write(dir.join("scenes/y.ron"), scene).unwrap();
    refused(
        &run(&dir, "scenes/y.ron", &["--load-state", save]),
        &["holds a run of scene", "x.ron"],
    );
}

#[test]
fn numbers_past_any_sensible_range_are_refused() {
    let handle = |scale: &str| {
        format!(
            r#"(
    frames: 2,
    bodies: [(
        shape: Cells(cells: (4, 4, 4)),
        spacing: 0.1,
        position: (0.0, 0.5, 0.0),
        handles: [(
            region: (min: (-1.0, -1.0, -1.0), max: (0.0, 1.0, 1.0)),
            path: [(0.0, (position: (0.0, 0.5, 0.0), scale: {scale}))],
        )],
    )],
)"#
        )
    };
    let (code, err) = run_file("huge_scale.ron", &handle("(1e30, 1e30, 1e30)"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("scale") && err.contains("1000"), "{err}");
    // (a simulated body's handles move it rigidly: scales are `cleave deform`'s)
    let dir = scratch("scale");
    for (scale, fine) in [("(1e3, 1e-3, 2.0)", true), ("(1001.0, 1.0, 1.0)", false)] {
        let file = dir.join("scale.ron");
        std::fs::write(&file, handle(scale)).unwrap();
        let out = dir.join("out");
        let args = [
            &[
                "deform",
                file.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ][..],
            &QUIET,
        ]
        .concat();
        let run = cleave(&args);
        match fine {
            true => ok(&run, scale),
            false => refused(&run, &["scale", "1e-3 ≤ scale ≤ 1000 on every axis"]),
        }
    }
    let tool = |width: &str| {
        format!(
            "(frames: 2, bodies: [(shape: Cells(cells: (4, 4, 4)), spacing: 0.1)], \
             tools: [(shape: Sphere(radius: 0.1), cut_width: {width}, path: [])])"
        )
    };
    let (code, err) = run_file("huge_width.ron", &tool("1e30"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cut_width") && err.contains("1e6"), "{err}");
    let (code, err) = run_file(
        "huge_radius.ron",
        &tool("0.05").replace("radius: 0.1", "radius: 1e9"),
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("radius") && err.contains("1e6"), "{err}");
    refused(
        &cleave(&["relax", "drop", "--frames", "4000000000"]),
        &["--frames", "0 ≤ frames ≤ 1e7"],
    );
    refused(
        &cleave(&["run", "drop", "--frames", "10000001"]),
        &["0 ≤ frames ≤ 1e7"],
    );
    refused(
        &cleave(&["bench", "--convergence", "--budget", "-1"]),
        &["-1 is out of range", "0 < budget ≤ 86400"],
    );
}

#[test]
fn flags_that_would_write_nothing_say_so() {
    let dir = scratch("export");
    let out = dir.join("out");
    let run = |extra: &[&str]| {
        let base = [
            "run",
            "drop",
            "--frames",
            "1",
            "--out",
            out.to_str().unwrap(),
        ];
        cleave(&[&base[..], extra].concat())
    };
    refused(
        &run(&["--export", "obj,gltf", "--png-every", "0"]),
        &["--export obj/gltf", "--png-every"],
    );
    refused(
        &run(&["--export", "ply", "--ply-every", "0"]),
        &["--ply-every"],
    );
    assert!(!dir.join("out/obj").exists(), "no empty folder is made");
}

#[test]
fn shapes_nested_past_the_readers_depth_are_refused_with_a_limit() {
    let mut shape = "Box(half_extents: (0.2, 0.2, 0.2))".to_string();
    for _ in 0..20 {
        shape = format!("Union(parts: [(shape: {shape}, at: (0.0, 0.0, 0.0))])");
    }
    let scene = format!("(frames: 1, bodies: [(shape: {shape}, spacing: 0.1)])");
    let (code, err) = run_file("deep_union.ron", &scene);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("nested too deep") && err.contains("128"),
        "{err}"
    );
    assert!(!err.contains("serde_stacker"), "{err}");
}
