//! `cleave bench --json` through the binary: one JSON object per size with every key the
//! report promises, and numbers that are consistent with each other.

use serde_json::Value;
use std::process::Command;

/// The JSON rows `cleave ARGS` prints, one per line; panics with its errors if it fails.
fn json_rows(args: &[&str]) -> Vec<Value> {
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(args)
        .output()
        .expect("run cleave");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect()
}

#[test]
fn bench_json_has_one_consistent_line_per_size() {
    let mut lines = json_rows(&[
        "bench",
        "--json",
        "--sizes",
        "8,6",
        "--steps",
        "3",
        "--threads",
        "1",
        "--pile-spacing",
        "0.1",
        "--pile-frames",
        "60",
    ]);
    // the last line is the crowd's contact row: more bodies at the pile's spacing
    let crowd = lines.pop().expect("a crowd row");
    assert_eq!(crowd["row"], "crowd");
    assert_eq!(crowd["bodies"], 18, "{crowd}");
    let ns = crowd["ms_per_step"].as_f64().expect("a step time") * 1e6
        / crowd["particles"].as_f64().expect("a particle count");
    let reported = crowd["ns_per_particle_step"].as_f64().expect("a cost");
    assert!(ns > 0.0 && (ns - reported).abs() < 1e-6 * ns, "{crowd}");
    assert!(crowd["contact_pairs"].as_f64() > Some(0.0), "{crowd}");
    // before it, the pile's
    let pile = lines.pop().expect("a pile row");
    assert_eq!(pile["row"], "pile");
    let number = |key: &str| {
        pile[key]
            .as_f64()
            .unwrap_or_else(|| panic!("`{key}` in {pile}"))
    };
    assert!(
        number("particles") > 500.0 && number("bodies") == 7.0,
        "{pile}"
    );
    assert!(crowd["particles"].as_f64() > Some(2.0 * number("particles")));
    assert!(number("contact_particles") < number("particles"), "{pile}");
    assert!(
        number("contact_pairs") > 0.0,
        "the bodies touch by the end: {pile}"
    );
    let ratio = number("ms_per_step") / number("ms_per_step_without_contacts");
    assert!((ratio - number("contacts_over_without")).abs() < 1e-9 * ratio);
    let (inside, step) = (number("contact_ms_per_step"), number("ms_per_step"));
    assert!(inside > 0.0 && inside < step, "{pile}");
    // the two phases of the contact kind, each timed on its own
    for phase in ["contact_find_ms_per_step", "contact_projection_ms_per_step"] {
        assert!(
            number(phase) > 0.0 && number(phase) <= step,
            "{phase}: {pile}"
        );
    }
    let share = inside / (step - inside);
    assert!((share - number("contact_share")).abs() < 1e-9 * share);
    // before it, the edge row: the largest size with edge constraints
    let edges = lines.pop().expect("an edge row");
    assert_eq!(edges["row"], "edges");
    let number = |key: &str| {
        edges[key]
            .as_f64()
            .unwrap_or_else(|| panic!("missing or non-numeric `{key}` in {edges}"))
    };
    assert_eq!(number("size"), 8.0);
    // the live edges of an 8³ box
    assert_eq!(number("edges"), 3.0 * 8.0 * 8.0 * 7.0);
    let ns = number("edge_ms_per_step") * 1e6 / (number("edges") * number("iterations"));
    assert!(
        ns > 0.0 && (ns - number("ns_per_edge_iteration")).abs() < 1e-6 * ns,
        "{edges}"
    );
    assert!(
        number("edge_ms_per_step") < number("ms_per_step"),
        "{edges}"
    );
    assert_eq!(lines.len(), 2);
    // ascending sizes
    assert_eq!(lines[0]["size"], 6);
    assert_eq!(lines[1]["size"], 8);
    for row in &lines {
        let n = row["size"].as_u64().unwrap();
        let number = |key: &str| {
            row[key]
                .as_f64()
                .unwrap_or_else(|| panic!("missing or non-numeric `{key}` in {row}"))
        };
        assert_eq!(number("particles") as u64, n * n * n);
        assert_eq!(number("threads"), 1.0);
        assert_eq!(number("iterations"), 20.0);
        let per_step = number("memberships") * number("iterations");
        let ns = number("ms_per_step") * 1e6 / per_step;
        assert!((ns - number("ns_per_membership_iteration")).abs() < 1e-6 * ns);
        let ratio = number("ms_per_step") / number("bare_ms_per_step");
        assert!((ratio - number("engine_over_bare")).abs() < 1e-9 * ratio);
        for key in [
            "clusters",
            "bare_ns_per_membership_iteration",
            "bytes_per_particle",
            "cut_event_ms",
            "cut_frame_ms",
            "sever_event_ms",
            "sever_frame_ms",
            "split_event_ms",
            "split_frame_ms",
            "recluster_ms",
            "relayout_ms",
            "rebuild_ms",
        ] {
            assert!(number(key) > 0.0, "{key} in {row}");
        }
        // the cut frame contains the cut event
        for mode in ["cut", "sever", "split"] {
            let (frame, event) = (
                number(&format!("{mode}_frame_ms")),
                number(&format!("{mode}_event_ms")),
            );
            assert!(frame >= event, "{mode}: {row}");
        }
        // every part of the solve, timed by name: the clusters and each registered term
        let kinds: Vec<(&str, f64)> = row["kinds"]
            .as_array()
            .unwrap_or_else(|| panic!("no kinds in {row}"))
            .iter()
            .map(|k| {
                (
                    k["name"].as_str().unwrap(),
                    k["ms_per_step"].as_f64().unwrap(),
                )
            })
            .collect();
        let names: Vec<&str> = kinds.iter().map(|k| k.0).collect();
        assert_eq!(
            names,
            [
                "clusters",
                "attachments",
                "oriented",
                "patches",
                "centroids",
                "edges",
                "contacts",
                "colliders"
            ]
        );
        assert!(
            kinds[0].1 > 0.0 && kinds[0].1 < number("ms_per_step"),
            "{row}"
        );
        assert!(kinds.iter().all(|k| k.1 >= 0.0), "{row}");
        // the cut is patched into the solver layout, not rebuilt
        assert_eq!(
            row["relayout_patched"],
            serde_json::Value::Bool(true),
            "{row}"
        );
    }
}

#[test]
fn bench_convergence_gives_one_row_per_solver_and_projective_needs_fewest_iterations() {
    let rows = json_rows(&[
        "bench",
        "--convergence",
        "--json",
        "--convergence-size",
        "6",
        "--budget",
        "3",
    ]);
    let solvers: Vec<&str> = rows.iter().map(|r| r["solver"].as_str().unwrap()).collect();
    assert_eq!(solvers, ["jacobi", "gauss-seidel", "projective"]);
    let (jacobi, projective) = (&rows[0], &rows[2]);
    let reference = projective["cantilever_static_sag_h"].as_f64().unwrap();
    // the static sag is the one the `cantilever` scene's beam theory predicts, roughly
    // (Euler–Bernoulli with E = 1/compliance: 11.5 h; the lattice is a little softer)
    assert!((9.0..16.0).contains(&reference), "{reference}");
    // the cantilever's target is 1e-3 unless its f32 floor is higher; it is not far off
    let target = projective["cantilever_target_residual"].as_f64().unwrap();
    assert!((1e-3..1e-2).contains(&target), "{target}");
    for row in [jacobi, projective] {
        // converged to the residual, each run sits where the static solution is
        let residual = |key: &str| row[key].as_f64().unwrap();
        assert!(residual("twisted_box_final_residual") < 1e-3, "{row}");
        assert!(residual("cantilever_final_residual") < target, "{row}");
        let sag = row["cantilever_final_sag_h"].as_f64().unwrap();
        assert!((sag - reference).abs() <= 0.01 * reference, "{row}");
        assert!(
            row["twisted_box_final_error_h"].as_f64().unwrap() < 0.1,
            "{row}"
        );
    }
    // counts, not times: the global step converges in far fewer iterations
    let iterations = |row: &Value| row["cantilever_iterations"].as_u64().unwrap();
    assert!(
        10 * iterations(projective) < iterations(jacobi),
        "{projective} vs {jacobi}"
    );
}

#[test]
fn bench_rejects_bad_sizes_with_exit_code_2() {
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["bench", "--sizes", "0", "--steps", "1"])
        .output()
        .expect("run cleave bench");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--sizes") && err.contains("allowed"), "{err}");
}

#[test]
fn the_cutting_bench_times_whole_frames_and_each_cut_by_stage() {
    use cleave::analysis::bench_cutting::{CuttingOptions, bench_cutting};
    let mut rows = Vec::new();
    let options = CuttingOptions {
        cuts: true,
        block: false,
        slice: false,
        dice: None,
    };
    // under a default subscriber of its own, as the command line runs it: the runs'
    // systems' spans must still close under the dispatchers they were made under
    tracing::subscriber::with_default(tracing_subscriber::registry(), || {
        bench_cutting(options, &mut |row| rows.push(row.clone()))
    })
    .unwrap();
    assert_eq!(rows.len(), 3, "cuts in each mode");
    for row in &rows {
        let v = serde_json::to_value(row).unwrap();
        assert_eq!(v["row"], "cutting");
        let frames = |s: &Value| s["frames"].as_u64().unwrap();
        // every frame of both runs timed; some of the cutting run's cut
        assert_eq!(frames(&v["plain"]), frames(&v["all"]));
        assert!(
            frames(&v["cut"]) > 10 && frames(&v["cut"]) < frames(&v["all"]),
            "{v}"
        );
        for s in ["plain", "all", "cut"] {
            let stats = &v[s];
            let at = |k: &str| stats[k].as_f64().unwrap();
            assert!(0.0 < at("median_ms") && at("median_ms") <= at("p95_ms"));
            assert!(at("p95_ms") <= at("max_ms") && at("max_after_first_ms") <= at("max_ms"));
        }
        // the stages of a cut frame fit inside it (the layout's is the next frame's)
        let stages = &v["cut_stages"];
        let within: f64 = ["detect_ms", "cut_ms", "rebuild_ms", "surface_ms"]
            .iter()
            .map(|k| stages[*k].as_f64().unwrap())
            .sum();
        assert!(
            within > 0.0 && within < v["cut"]["max_ms"].as_f64().unwrap(),
            "{v}"
        );
        let ratio = v["p95_over_plain"].as_f64().unwrap();
        let expected =
            v["all"]["p95_ms"].as_f64().unwrap() / v["plain"]["median_ms"].as_f64().unwrap();
        assert!((ratio - expected).abs() < 1e-9);
        assert!(v["cut_work_over_substeps"].as_f64().unwrap() > 0.0);
        // the frames less their cut work are no slower than the frames, and not empty
        for k in [
            "p95_over_plain",
            "slowest_over_plain",
            "cut_median_over_plain",
            "cut_slowest_over_plain",
        ] {
            let (floor, as_run) = (
                v["without_cut_work"][k].as_f64().unwrap(),
                v[k].as_f64().unwrap(),
            );
            assert!(0.0 < floor && floor <= as_run, "{k}: {v}");
        }
        // every cut frame pays some cut work (its detection at least), so the slowest
        // of them less it is faster
        assert!(
            v["without_cut_work"]["cut_slowest_over_plain"]
                .as_f64()
                .unwrap()
                < v["cut_slowest_over_plain"].as_f64().unwrap(),
            "{v}"
        );
    }
}

#[test]
fn the_surface_bench_gives_a_row_per_size_moving_and_at_rest() {
    let rows = json_rows(&[
        "bench",
        "--surface",
        "--json",
        "--sizes",
        "6,4",
        "--steps",
        "3",
        "--threads",
        "1",
    ]);
    assert_eq!(rows.len(), 2);
    for (row, n) in rows.iter().zip([6u64, 4]) {
        assert_eq!(row["row"], "surface");
        assert_eq!(row["size"], n);
        assert_eq!(row["particles"], n * n * n);
        for key in [
            "frame_ms",
            "resting_frame_ms",
            "extract_ms",
            "sliced_extract_ms",
            "local_update_ms",
        ] {
            let ms = row[key].as_f64().unwrap_or(f64::NAN);
            assert!(ms.is_finite() && ms > 0.0, "{key}: {}", row[key]);
        }
        // a box's surface: two triangles per face of each boundary cell; the slice
        // through the middle adds two faces of n² cells each
        let triangles = row["triangles"].as_u64().unwrap();
        assert_eq!(triangles, 12 * n * n);
        assert_eq!(
            row["sliced_triangles"].as_u64().unwrap(),
            triangles + 4 * n * n
        );
    }
}

#[test]
fn the_diced_box_is_cut_into_its_25_blocks_in_the_one_frame_the_blades_cross_it() {
    use cleave::analysis::bench_cutting::diced_box;
    use cleave::cut::tool::CutMode;
    use cleave::sim::simulation::Simulation;
    let n = 16;
    for mode in [CutMode::Sever, CutMode::Split] {
        let workload = diced_box(n, mode);
        let h = workload.scene.bodies[0].spacing;
        let mut sim = Simulation::from_scene(&workload.scene).unwrap();
        let body = sim.bodies()[0];
        let mut pieces = Vec::new();
        for _ in 0..3 {
            sim.step();
            pieces.push(sim.pieces(body).unwrap());
        }
        let counts: Vec<usize> = pieces.iter().map(|p| p.len()).collect();
        assert_eq!(counts, [1, 25, 25], "{mode:?}: pieces after frames 1, 2, 3");
        // the planes the blades follow, from the box's size: no piece holds particles
        // that rest clearly on both sides of one
        let world = sim.world_mut();
        let lattice = &world
            .query::<&cleave::ecs::components::BodyLattice>()
            .single(world)
            .unwrap()
            .lattice;
        let size = n as f32 * h;
        let planes: Vec<f32> = [1, 3, 5, 7]
            .map(|e| ((e * n / 8) as f32 + 0.5) * h - 0.5 * size)
            .to_vec();
        for piece in &pieces[1] {
            for axis in [0, 2] {
                for &plane in &planes {
                    let side = |p: &u32| {
                        let c = lattice.rest_position(*p)[axis] - plane;
                        if c.abs() < 0.3 * h {
                            0
                        } else {
                            c.signum() as i32
                        }
                    };
                    let sides: std::collections::BTreeSet<i32> = piece.iter().map(side).collect();
                    assert!(
                        !(sides.contains(&-1) && sides.contains(&1)),
                        "{mode:?}: a piece crosses the plane {plane} across axis {axis}"
                    );
                }
            }
        }
    }
}

#[test]
fn the_cutting_bench_dices_a_box_on_request_and_says_what_its_cut_frame_held() {
    let rows = json_rows(&[
        "bench",
        "--cutting",
        "--dice",
        "12",
        "--json",
        "--threads",
        "1",
    ]);
    assert_eq!(rows.len(), 2, "sever and split");
    for (row, mode) in rows.iter().zip(["sever", "split"]) {
        assert_eq!(row["workload"], "diced12");
        assert_eq!(row["mode"], mode);
        assert_eq!(row["particles"], 12 * 12 * 12);
        assert_eq!(row["cut"]["frames"], 1, "{row}");
        if cfg!(target_os = "linux") {
            let extra = row["cut_peak_extra_mb"]
                .as_f64()
                .expect("measured on Linux");
            assert!(extra >= 0.0, "{row}");
        }
    }
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["bench", "--cutting", "--dice", "1"])
        .output()
        .expect("run cleave bench");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("allowed"));
}
