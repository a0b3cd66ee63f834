//! End-to-end acceptance of the built-in scenes through the `cleave` binary: bodies
//! falling, resting, bending and colliding; summaries and state dumps, the dumps
//! checked by the test-side checker in `common`.

mod common;

use common::*;
use std::process::Command;

#[test]
fn drop_rests_on_the_ground_on_its_contact_balls_undeformed() {
    let (s, dump) = run("drop", Some(300));
    assert!(s["finite"].as_bool().unwrap());
    // its particles' balls (radius h/2 by default) rest on the ground, not their centres:
    // the lowest centre half a spacing up, ±5 %, read from the dump itself
    let lowest = positions_of(&dump)
        .values()
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min);
    let h = 0.1;
    assert!(
        (lowest / h - 0.5).abs() <= 0.025,
        "lowest centre at {} h",
        lowest / h
    );
    assert!((f(&s["lowest_particle_y_h"]) - lowest / h).abs() < 1e-4);
    assert!(
        f(&s["final_shape_error_h"]) <= 0.2,
        "{}",
        s["final_shape_error_h"]
    );
    assert_eq!(check_dump(&dump), 1);
}

#[test]
fn soft_beam_hangs_like_a_chain_with_its_edges_barely_stretched() {
    let (s, dump) = run("soft_beam", None);
    let body = &s["bodies"][0];
    assert!(f(&body["tip_drop_h_end"]) >= 5.0, "{body}");
    assert!(f(&body["after"]["max_edge_strain"]) < 0.01, "{body}");
    // the pins held
    assert_eq!(f(&body["pinned_max_displacement_h"]), 0.0, "{body}");
    assert_eq!(check_dump(&dump), 1);
}

#[test]
fn cantilever_stiffness_belongs_to_the_material_not_the_solver_settings() {
    // the corners of substeps {2, 4, 8} × iterations {5, 10, 20} (the sag is monotone
    // in each between them)
    let mut sags = vec![];
    for substeps in ["2", "8"] {
        for iterations in ["5", "20"] {
            let sag = cantilever_sag(&["--substeps", substeps, "--iterations", iterations]);
            assert!(
                (2.0..=15.0).contains(&sag),
                "{substeps}×{iterations}: {sag} h"
            );
            sags.push(sag);
        }
    }
    let (lo, hi) = sags
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), s| (lo.min(*s), hi.max(*s)));
    assert!(hi / lo <= 1.22, "{sags:?}");
    // projective dynamics agrees with Jacobi at its highest setting
    let projective = cantilever_sag(&["--solver", "projective"]);
    assert!(
        (projective / sags[3] - 1.0).abs() <= 0.10,
        "{projective} vs {sags:?}"
    );
    // and Gauss–Seidel, solving the same energy, with the scene's own settings
    let gauss_seidel = cantilever_sag(&["--solver", "gauss-seidel"]);
    assert!(
        (gauss_seidel / sags[3] - 1.0).abs() <= 0.10,
        "{gauss_seidel} vs {sags:?}"
    );
}

#[test]
fn solver_flags_override_the_scene_and_bad_values_are_refused() {
    let (s, _) = run_with(
        "drop",
        Some(2),
        &[
            "--solver",
            "gauss-seidel",
            "--substeps",
            "3",
            "--iterations",
            "4",
            "--png-every",
            "0",
            "--gif-every",
            "0",
            "--quiet",
        ],
    );
    assert_eq!(s["frames"], 2);
    for (flag, value, says) in [
        ("--substeps", "0", "--substeps"),
        ("--iterations", "20000", "--iterations"),
        ("--solver", "gauss_seidel", "gauss-seidel"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(["run", "drop", "--frames", "1", "--quiet", flag, value])
            .output()
            .expect("run cleave");
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{flag} {value}: {err}");
    }
}

#[test]
fn cutting_scenes_under_projective_dynamics_keep_their_piece_counts() {
    for (scene, pieces) in [("slice", 2), ("dice", 4)] {
        let (s, dump) = run_with(
            scene,
            None,
            &[
                "--solver",
                "projective",
                "--png-every",
                "0",
                "--gif-every",
                "0",
                "--quiet",
            ],
        );
        assert_eq!(s["pieces"], pieces, "{scene}");
        assert_eq!(s["invariant_violations"], 0, "{scene}");
        assert_eq!(check_dump(&dump), pieces, "{scene}");
        let body = &s["bodies"][0];
        assert!(
            f(&body["piece_separation_end_h"]) > f(&body["piece_separation_start_h"]),
            "{scene}: pieces separate"
        );
        // one factorization at the start, and one after each cut that changed the body
        let factors = s["factor_ms"].as_array().expect("factor_ms");
        assert!(factors.len() >= 2, "{scene}: {factors:?}");
        assert!(factors.iter().all(|t| t.as_f64().is_some_and(|t| t > 0.0)));
    }
}

#[test]
fn cantilever_sag_is_steady_and_pin_holds() {
    let (s, _) = run("cantilever", Some(600));
    let s = &s["bodies"][0];
    let (half, end) = (f(&s["tip_drop_h_half"]), f(&s["tip_drop_h_end"]));
    assert!(end.is_finite() && end > 0.5, "beam must sag: {end}");
    assert!(
        (end - half).abs() <= 0.05 * end,
        "sag {half} at 300 vs {end} at 600"
    );
    assert!(f(&s["pinned_max_displacement_h"]) == 0.0);
}

#[test]
fn stack_comes_to_rest_on_top_without_overlap() {
    let (s, dump) = run("stack", Some(300));
    assert_eq!(check_dump(&dump), 2);
    let h = f(&dump["bodies"][0]["spacing"]);
    for body in s["bodies"].as_array().unwrap() {
        assert!(
            f(&body["after"]["max_speed"]) < 0.05,
            "at rest: {}",
            body["after"]
        );
    }
    let heights = |b: usize| -> Vec<f64> {
        dump["bodies"][b]["particles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| f(&p["position"][1]))
            .collect()
    };
    // the upper box is the larger one (the dump lists bodies by id, not spawn order)
    let (lower, upper) = if heights(0).len() < heights(1).len() {
        (0, 1)
    } else {
        (1, 0)
    };
    let lower_top = heights(lower).into_iter().fold(f64::MIN, f64::max);
    let upper_bottom = heights(upper).into_iter().fold(f64::MAX, f64::min);
    assert!(upper_bottom > lower_top, "{upper_bottom} ≤ {lower_top}");
    let (_, bodies) = dump_gaps(&dump);
    assert!(bodies / h >= 0.8, "bodies {} h apart", bodies / h);
}

#[test]
fn pile_settles_in_the_bin_without_overlap() {
    let (s, dump) = run("pile", Some(400));
    assert_eq!(s["invariant_violations"], 0);
    assert_eq!(check_dump(&dump), 7);
    let h = f(&dump["bodies"][0]["spacing"]);
    let (_, bodies) = dump_gaps(&dump);
    assert!(bodies / h >= 0.7, "bodies {} h apart", bodies / h);
    for body in s["bodies"].as_array().unwrap() {
        assert!(
            f(&body["after"]["max_speed"]) < 0.1,
            "at rest: {}",
            body["after"]
        );
    }
    // inside the bin: within its floor's square (the walls lean outwards from it)
    for p in positions_of(&dump).values() {
        assert!(
            p[0].abs() < 1.25 && p[2].abs() < 1.25 && p[1] >= -1e-6,
            "{p:?}"
        );
    }
}

#[test]
fn press_squeezes_then_cuts_in_two() {
    let (s, dump) = run("press", None);
    assert_eq!(s["pieces"], 2);
    assert_eq!(check_dump(&dump), 2);
    assert_eq!(s["invariant_violations"], 0);
    // squeezed to under 80 % of its height while the plate is down (at rest on its
    // contact balls, its centroid is 0.05 + 0.35 m up)
    let half = &s["bodies"][0]["half_time"]["piece_centroids"];
    assert!(f(&half[0][1]) < 0.8 * 0.4, "{half}");
    // the frames as a game feels them: every frame counted, the cut ones among them
    let (all, cut) = (&s["frame_ms"], &s["cut_frame_ms"]);
    assert_eq!(all["frames"], s["frames"]);
    assert!(cut["frames"].as_u64().unwrap() >= 1, "{cut}");
    assert!(cut["frames"].as_u64() < all["frames"].as_u64());
    for stats in [all, cut] {
        let (median, p95, max) = (
            f(&stats["median_ms"]),
            f(&stats["p95_ms"]),
            f(&stats["max_ms"]),
        );
        assert!(0.0 < median && median <= p95 && p95 <= max, "{stats}");
    }
}

#[test]
fn thread_counts_out_of_range_are_clear_errors() {
    for threads in ["0", "100000"] {
        let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(["run", "drop", "--frames", "1", "--threads", threads])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "--threads {threads}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--threads") && err.contains("allowed 1 ≤ threads ≤ 1024"),
            "{err}"
        );
    }
}

#[test]
fn unknown_scene_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["run", "nope"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown scene `nope`"));
}
