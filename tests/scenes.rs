//! End-to-end acceptance of the built-in scenes through the `cleave` binary: summaries
//! and state dumps, the dumps checked by an invariant checker written here against the
//! JSON alone (it shares no code with the engine).

use serde_json::Value;
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::PathBuf;
use std::process::Command;

fn run(scene: &str, frames: Option<u32>) -> (Value, Value) {
    run_with(scene, frames, &[])
}

/// Runs `scene` with extra arguments; returns the summary and the dump.
fn run_with(scene: &str, frames: Option<u32>, extra: &[&str]) -> (Value, Value) {
    let tag = extra.join("_").replace('-', "");
    let dir = std::env::temp_dir().join(format!("cleave-test-{scene}{tag}-{}", std::process::id()));
    let dump = dir.join("state.json");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_cleave"));
    cmd.args(["run", scene, "--out"])
        .arg(&dir)
        .arg("--dump-state")
        .arg(&dump);
    if let Some(f) = frames {
        cmd.args(["--frames", &f.to_string()]);
    }
    cmd.args(extra);
    let out = cmd.output().expect("run cleave");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |p: PathBuf| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    (read(dir.join("summary.json")), read(dump))
}

/// Independent check of a `cleave-state/2` dump: returns the number of pieces over all
/// bodies, panics on a violation.
fn check_dump(dump: &Value) -> usize {
    pieces_of(dump).len()
}

/// Every piece of every body of a checked dump, as `(body index, particle ids)`.
fn pieces_of(dump: &Value) -> Vec<(usize, HashSet<u64>)> {
    assert_eq!(dump["format"], "cleave-state/2");
    assert!(dump["frame"].as_u64().is_some() && dump["time"].as_f64().is_some());
    let mut all_ids = HashSet::new();
    let mut out = Vec::new();
    for (b, body) in dump["bodies"].as_array().unwrap().iter().enumerate() {
        for p in body["particles"].as_array().unwrap() {
            assert!(
                all_ids.insert(p["id"].as_u64().unwrap()),
                "particle id repeated"
            );
            assert!(p["mass"].as_f64().unwrap() > 0.0);
        }
        out.extend(check_body(body).into_iter().map(|piece| (b, piece)));
    }
    out
}

/// Positions by particle id over every body of a dump.
fn positions_of(dump: &Value) -> HashMap<u64, [f64; 3]> {
    let mut out = HashMap::new();
    for body in dump["bodies"].as_array().unwrap() {
        for p in body["particles"].as_array().unwrap() {
            let x: Vec<f64> = (0..3).map(|k| p["position"][k].as_f64().unwrap()).collect();
            out.insert(p["id"].as_u64().unwrap(), [x[0], x[1], x[2]]);
        }
    }
    out
}

/// The smallest distance between particles of different groups (by brute force).
fn min_distance_between(groups: &[Vec<[f64; 3]>]) -> f64 {
    let mut best = f64::INFINITY;
    for (i, a) in groups.iter().enumerate() {
        for b in &groups[i + 1..] {
            for p in a {
                for q in b {
                    let d = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
                    best = best.min(d);
                }
            }
        }
    }
    best
}

/// The smallest distance between particles of different pieces, and of different
/// bodies, in a dump.
fn dump_gaps(dump: &Value) -> (f64, f64) {
    let pieces = pieces_of(dump);
    let at = positions_of(dump);
    let points = |ids: &HashSet<u64>| ids.iter().map(|i| at[i]).collect::<Vec<_>>();
    let by_piece: Vec<Vec<[f64; 3]>> = pieces.iter().map(|(_, p)| points(p)).collect();
    let bodies = pieces.iter().map(|(b, _)| b + 1).max().unwrap_or(0);
    let by_body: Vec<Vec<[f64; 3]>> = (0..bodies)
        .map(|b| {
            pieces
                .iter()
                .filter(|(body, _)| *body == b)
                .flat_map(|(_, p)| points(p))
                .collect()
        })
        .collect();
    (
        min_distance_between(&by_piece),
        min_distance_between(&by_body),
    )
}

/// Checks one body of a dump; returns its pieces.
fn check_body(dump: &Value) -> Vec<HashSet<u64>> {
    let max = dump["config"]["max_cluster_size"].as_u64().unwrap() as usize;
    let ids: HashSet<u64> = dump["particles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["id"].as_u64().unwrap())
        .collect();
    let mut adjacency: HashMap<u64, Vec<u64>> = ids.iter().map(|i| (*i, Vec::new())).collect();
    let coords: HashMap<u64, Vec<i64>> = dump["particles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["id"].as_u64().unwrap(),
                p["lattice"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|c| c.as_i64().unwrap())
                    .collect(),
            )
        })
        .collect();
    for e in dump["edges"].as_array().unwrap() {
        let (a, b) = (e[0].as_u64().unwrap(), e[1].as_u64().unwrap());
        assert!(
            ids.contains(&a) && ids.contains(&b),
            "edge to a dead particle"
        );
        let d: i64 = coords[&a]
            .iter()
            .zip(&coords[&b])
            .map(|(x, y)| (x - y).abs())
            .sum();
        assert_eq!(d, 1, "edge {a}-{b} is not a voxel edge");
        adjacency.get_mut(&a).unwrap().push(b);
        adjacency.get_mut(&b).unwrap().push(a);
    }
    let components = |set: &HashSet<u64>| -> Vec<HashSet<u64>> {
        let mut seen = HashSet::new();
        let mut out = Vec::new();
        for &s in set {
            if !seen.insert(s) {
                continue;
            }
            let mut comp = HashSet::from([s]);
            let mut queue = VecDeque::from([s]);
            while let Some(p) = queue.pop_front() {
                for n in &adjacency[&p] {
                    if set.contains(n) && seen.insert(*n) {
                        comp.insert(*n);
                        queue.push_back(*n);
                    }
                }
            }
            out.push(comp);
        }
        out
    };
    let mut covered = HashSet::new();
    let clusters: Vec<HashSet<u64>> = dump["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            c["members"]
                .as_array()
                .unwrap()
                .iter()
                .map(|m| m.as_u64().unwrap())
                .collect()
        })
        .collect();
    for c in &clusters {
        assert!(c.len() <= max, "cluster of {} > {max}", c.len());
        assert!(c.iter().all(|m| ids.contains(m)), "dead member");
        assert_eq!(components(c).len(), 1, "disconnected cluster");
        covered.extend(c.iter().copied());
    }
    assert_eq!(covered, ids, "uncovered particles");
    // No cluster inside (or equal to) another: a container holds the smallest member.
    let mut holding: HashMap<u64, Vec<usize>> = HashMap::new();
    for (i, c) in clusters.iter().enumerate() {
        for m in c {
            holding.entry(*m).or_default().push(i);
        }
    }
    for (i, c) in clusters.iter().enumerate() {
        let smallest = c.iter().min().unwrap();
        for &j in &holding[smallest] {
            assert!(
                j == i || !c.is_subset(&clusters[j]),
                "a cluster of {} lies inside one of {}",
                c.len(),
                clusters[j].len()
            );
        }
    }
    let pieces = components(&ids);
    // No isolated cluster: inside each piece, clusters linked by shared particles.
    for piece in &pieces {
        let inside: Vec<&HashSet<u64>> = clusters
            .iter()
            .filter(|c| c.iter().any(|m| piece.contains(m)))
            .collect();
        let mut reached = vec![false; inside.len()];
        let mut stack = vec![0];
        reached[0] = true;
        while let Some(i) = stack.pop() {
            for j in 0..inside.len() {
                if !reached[j] && !inside[i].is_disjoint(inside[j]) {
                    reached[j] = true;
                    stack.push(j);
                }
            }
        }
        assert!(
            reached.iter().all(|r| *r),
            "isolated cluster in a piece of {}",
            piece.len()
        );
    }
    pieces
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

#[test]
fn drop_rests_on_the_ground_undeformed() {
    let (s, dump) = run("drop", Some(300));
    assert!(s["finite"].as_bool().unwrap());
    assert!(
        f(&s["lowest_particle_y_h"]) >= -0.05,
        "{}",
        s["lowest_particle_y_h"]
    );
    assert!(
        f(&s["lowest_particle_y_h"]) <= 0.05,
        "it must have landed: {}",
        s["lowest_particle_y_h"]
    );
    assert!(
        f(&s["final_shape_error_h"]) <= 0.2,
        "{}",
        s["final_shape_error_h"]
    );
    assert_eq!(check_dump(&dump), 1);
}

/// The `cantilever`'s steady tip sag (frame 600, in h) under the given settings.
fn cantilever_sag(extra: &[&str]) -> f64 {
    let mut args = vec!["--png-every", "0", "--gif-every", "0", "--quiet"];
    args.extend_from_slice(extra);
    let (s, _) = run_with("cantilever", Some(600), &args);
    f(&s["bodies"][0]["tip_drop_h_end"])
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
    assert!(
        f(&s["min_gap_between_pieces_h"]) >= 0.8,
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
    let notch = cleave::io::scene::NOTCH_X as f64;
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
    let (_, straight) = run_with("random", Some(300), &quiet);
    run_with(
        "random",
        Some(100),
        &[&quiet[..], &["--save-state", file]].concat(),
    );
    let (summary, resumed) = run_with(
        "random",
        Some(200),
        &[&quiet[..], &["--load-state", file]].concat(),
    );
    assert_eq!(resumed["frame"], 300);
    assert_eq!(summary["invariant_violations"], 0);
    assert_eq!(particles_of(&resumed), particles_of(&straight));
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
    // squeezed to under 80 % of its height while the plate is down
    let half = &s["bodies"][0]["half_time"]["piece_centroids"];
    assert!(f(&half[0][1]) < 0.8 * 0.35, "{half}");
}

#[test]
fn contact_scenes_are_identical_for_one_and_two_threads() {
    for scene in ["stack", "pile", "press"] {
        let (_, one) = run_with(scene, Some(120), &["--threads", "1"]);
        let (_, two) = run_with(scene, Some(120), &["--threads", "2"]);
        assert_eq!(one.to_string(), two.to_string(), "{scene}");
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
