//! End-to-end acceptance of the built-in cutting scenes through the `cleave` binary:
//! slices, dice, scoops, tearing, random cuts, saved runs and fidelity; the state dumps
//! checked by the test-side checker in `common`.

mod common;

use common::*;
use serde_json::Value;
use std::collections::HashMap;
use std::process::Command;

#[test]
fn slice_makes_two_pieces_that_move_apart() {
    let (s, dump) = run("slice", None);
    assert_eq!(s["pieces"], 2);
    assert_eq!(check_dump(&dump), 2);
    let body = &s["bodies"][0];
    assert!(f(&body["piece_separation_end_h"]) >= f(&body["piece_separation_start_h"]) + 1.0);
    for key in ["mean_cluster_size", "memberships_per_particle"] {
        let (b, a) = (f(&body["before"][key]), f(&body["after"][key]));
        assert!((a / b - 1.0).abs() <= 0.25, "{key}: {b} -> {a}");
    }
    assert_eq!(s["invariant_violations"], 0);
    // the halves never came closer than 0.8 h, by the summary and by the final dump
    let h = f(&dump["bodies"][0]["spacing"]);
    // (null: they never came within 2 h)
    assert!(
        s["min_gap_between_pieces_h"]
            .as_f64()
            .is_none_or(|gap| gap >= 0.8),
        "{}",
        s["min_gap_between_pieces_h"]
    );
    let (pieces, _) = dump_gaps(&dump);
    assert!(pieces / h >= 0.8, "final gap {} h", pieces / h);
}

#[test]
fn slice_in_sever_and_split_modes_makes_two_pieces_and_keeps_the_mass() {
    for mode in ["sever", "split"] {
        slice_keeps_the_mass(mode);
    }
}

#[test]
fn a_severing_scoop_leaves_one_plug_at_any_speed() {
    // the sphere carves over 60 frames; what it was ever inside is one piece
    let (s, dump) = run_with("scoop", None, &["--cut-mode", "sever"]);
    assert_eq!(s["pieces"], 2);
    assert_eq!(check_dump(&dump), 2);
    assert_eq!(s["cut_particles"], 0);
    assert_eq!(s["invariant_violations"], 0);
}

fn slice_keeps_the_mass(mode: &str) {
    let (s, dump) = run_with("slice", None, &["--cut-mode", mode]);
    assert_eq!(s["pieces"], 2);
    assert_eq!(check_dump(&dump), 2);
    assert_eq!(s["invariant_violations"], 0);
    assert_eq!(s["cut_particles"], 0);
    let start = &s["bodies"][0]["before"];
    let particles = dump["bodies"][0]["particles"].as_array().unwrap();
    // (split particles add their new halves)
    let kept = start["particles"].as_u64().unwrap();
    match mode {
        "sever" => assert_eq!(particles.len() as u64, kept),
        _ => assert!(particles.len() as u64 >= kept),
    }
    // the mass at the start: the same particles, each of the material's mass
    let mass: f64 = particles.iter().map(|p| f(&p["mass"])).sum();
    let h = f(&dump["bodies"][0]["spacing"]);
    let expected = start["particles"].as_f64().unwrap() * 1000.0 * h.powi(3);
    assert!(
        (mass / expected - 1.0).abs() <= 1e-6,
        "{mass} vs {expected}"
    );
}

#[test]
fn dice_makes_four_pieces_and_scoop_one() {
    let (s, dump) = run("dice", None);
    assert_eq!(s["pieces"], 4);
    assert_eq!(check_dump(&dump), 4);
    let (s, dump) = run("scoop", None);
    assert!(
        s["cut_particles"].as_u64().unwrap() > 100,
        "the scoop must carve"
    );
    assert_eq!(s["pieces"], 1);
    assert_eq!(check_dump(&dump), 1);
}

/// The pieces of the first body of a checked dump, each as its particles' lattice x.
fn piece_columns(dump: &Value) -> Vec<Vec<i64>> {
    let lattice_x: HashMap<u64, i64> = dump["bodies"][0]["particles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["id"].as_u64().unwrap(), p["lattice"][0].as_i64().unwrap()))
        .collect();
    pieces_of(dump)
        .into_iter()
        .map(|(_, ids)| ids.iter().map(|i| lattice_x[i]).collect())
        .collect()
}

#[test]
fn a_pulled_bar_tears_in_two_near_the_middle_or_at_its_notch() {
    let (s, dump) = run("tear", None);
    assert_eq!(s["invariant_violations"], 0);
    let pieces = piece_columns(&dump);
    assert_eq!(
        pieces.len(),
        2,
        "{:?}",
        pieces.iter().map(Vec::len).collect::<Vec<_>>()
    );
    let total: usize = pieces.iter().map(Vec::len).sum();
    assert_eq!(total, 32 * 6 * 6, "tearing keeps every particle");
    let smaller = pieces.iter().map(Vec::len).min().unwrap();
    assert!(smaller * 100 >= 35 * total, "{smaller} of {total}");
    // the notched bar: the crack plane between the two pieces' facing columns lies
    // within 2 h of the notch
    let (s, dump) = run("notch", None);
    assert_eq!(s["invariant_violations"], 0);
    let mut pieces = piece_columns(&dump);
    assert_eq!(pieces.len(), 2);
    pieces.sort_by_key(|p| p.iter().min().copied());
    let (left_end, right_start) = (
        *pieces[0].iter().max().unwrap(),
        *pieces[1].iter().min().unwrap(),
    );
    let h = f(&dump["bodies"][0]["spacing"]);
    // (cell c's rest centre is (c + ½) h: the crack lies between the two columns)
    let crack = (left_end + right_start + 1) as f64 * 0.5 * h;
    // the notch lies where the scene's blade stands
    let notch = cleave::io::scene::builtin("notch", 0).unwrap().tools[0]
        .pose
        .position
        .x as f64;
    assert!(
        (crack - notch).abs() <= 2.0 * h,
        "crack at {crack}, notch at {notch}"
    );
}

#[test]
fn random_cuts_keep_invariants() {
    let (s, dump) = run("random", None);
    assert!(s["cut_particles"].as_u64().unwrap() > 0);
    assert_eq!(s["invariant_violations"], 0);
    assert_eq!(check_dump(&dump), s["pieces"].as_u64().unwrap() as usize);
}

#[test]
fn fifty_cuts_keep_the_dump_legal_and_a_scooped_beam_sags_as_if_built_with_its_holes() {
    let (s, dump) = run("cuts", None);
    assert_eq!(s["invariant_violations"], 0);
    assert!(f(&s["particles"]) < 0.8 * 8192.0, "{}", s["particles"]);
    assert!(check_dump(&dump) > 1);
    // the scooped cantilever's steady sag, with its rebuilt clusters and with a fresh
    // clustering of the same holes after the scoops
    let quiet = ["--png-every", "0", "--gif-every", "0", "--quiet"];
    let (rebuilt, dump) = run_with("scooped", None, &quiet);
    check_dump(&dump);
    let fresh = run_with(
        "scooped",
        None,
        &[&quiet[..], &["--recluster-at", "8"]].concat(),
    )
    .0;
    assert_eq!(fresh["reclustered_at"], 8);
    assert_eq!(rebuilt["reclustered_at"], Value::Null);
    assert_eq!(fresh["particles"], rebuilt["particles"]);
    let sag = |s: &Value| f(&s["bodies"][0]["tip_drop_h_end"]);
    assert!(
        (sag(&rebuilt) / sag(&fresh) - 1.0).abs() <= 0.10,
        "{} vs {}",
        sag(&rebuilt),
        sag(&fresh)
    );
    // the holes soften the beam
    assert!(sag(&rebuilt) > cantilever_sag(&[]), "{}", sag(&rebuilt));
}

/// Every particle's lattice coordinate and position in a dump, sorted (entity ids
/// differ between a run and a loaded one).
fn particles_of(dump: &Value) -> Vec<String> {
    let mut out: Vec<String> = dump["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|b| b["particles"].as_array().unwrap().iter())
        .map(|p| format!("{} {}", p["lattice"], p["position"]))
        .collect();
    out.sort();
    out
}

#[test]
fn a_run_saved_and_loaded_from_the_command_line_goes_on_as_one_run() {
    let quiet = ["--png-every", "0", "--gif-every", "0", "--quiet"];
    let file = std::env::temp_dir().join(format!("cleave-save-{}.bin", std::process::id()));
    let file = file.to_str().unwrap();
    // the same state dumps to the same bytes, straight or saved and resumed (ids are
    // derived from the state, not from entities)
    for (scene, mode) in [
        ("slice", "remove"),
        ("random", "remove"),
        ("random", "sever"),
        ("random", "split"),
    ] {
        let moded = [&quiet[..], &["--cut-mode", mode]].concat();
        let (_, straight) = run_with(scene, Some(300), &moded);
        run_with(
            scene,
            Some(100),
            &[&moded[..], &["--save-state", file]].concat(),
        );
        let (summary, resumed) = run_with(
            scene,
            Some(200),
            &[&quiet[..], &["--load-state", file]].concat(),
        );
        assert_eq!(resumed["frame"], 300);
        assert_eq!(summary["invariant_violations"], 0);
        assert_eq!(particles_of(&resumed), particles_of(&straight));
        assert!(resumed == straight, "{scene} {mode}: the dumps differ");
    }
    let cleave = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(args)
            .output()
            .unwrap()
    };
    for (args, needle) in [
        (
            vec![
                "run",
                "random",
                "--load-state",
                file,
                "--solver",
                "projective",
            ],
            "--solver cannot be combined",
        ),
        (
            vec!["run", "random", "--load-state", "/nonexistent.bin"],
            "/nonexistent.bin: cannot be opened",
        ),
        (
            vec!["run", "random", "--load-state", "Cargo.toml"],
            "not a saved cleave simulation",
        ),
        (
            vec!["run", "random", "--load-state", "/dev/zero"],
            "/dev/zero: saved simulation: not a saved cleave simulation",
        ),
        (
            vec!["run", "slice", "--load-state", file],
            "holds a run of scene `random`, not `slice`",
        ),
    ] {
        let out = cleave(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn fidelity_reports_and_refuses_bad_counts() {
    let cleave = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_cleave"))
            .args(args)
            .output()
            .unwrap()
    };
    let out = cleave(&["fidelity", "--cuts", "6", "--seed", "3", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["seed"], 3);
    assert_eq!(report["cut_mode"], "remove");
    assert_eq!(report["block"]["cuts"], 6);
    assert_eq!(report["block"]["violations"], 0);
    let fresh = f(&report["block"]["fresh"]["mean_size"]);
    let ratio = f(&report["block"]["ratio"]["mean_size"]);
    assert!((f(&report["block"]["rebuilt"]["mean_size"]) - ratio * fresh).abs() < 1e-9);
    assert!(f(&report["cantilever"]["fresh_sag_h"]) > 0.0);
    for (args, needle) in [
        (
            &["fidelity", "--cuts", "0"][..],
            "--cuts: 0 is out of range",
        ),
        (
            &["fidelity", "--cuts", "1001"],
            "--cuts: 1001 is out of range",
        ),
        (&["fidelity", "--cut-mode", "chop"], "chop"),
        (
            &["run", "scooped", "--recluster-at", "601", "--quiet"],
            "--recluster-at: 601 is past the last frame",
        ),
    ] {
        let out = cleave(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}
