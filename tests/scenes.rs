//! End-to-end acceptance of the built-in scenes through the `cleave` binary: summaries
//! and state dumps, the dumps checked by an invariant checker written here against the
//! JSON alone (it shares no code with the engine).

use serde_json::Value;
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::PathBuf;
use std::process::Command;

fn run(scene: &str, frames: Option<u32>) -> (Value, Value) {
    let dir = std::env::temp_dir().join(format!("cleave-test-{scene}-{}", std::process::id()));
    let dump = dir.join("state.json");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_cleave"));
    cmd.args(["run", scene, "--out"])
        .arg(&dir)
        .arg("--dump-state")
        .arg(&dump);
    if let Some(f) = frames {
        cmd.args(["--frames", &f.to_string()]);
    }
    let out = cmd.output().expect("run cleave");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read = |p: PathBuf| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    (read(dir.join("summary.json")), read(dump))
}

/// Independent check of the dump: returns the number of pieces, panics on a violation.
fn check_dump(dump: &Value) -> usize {
    assert_eq!(dump["format"], "cleave-state/1");
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
    pieces.len()
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

#[test]
fn cantilever_sag_is_steady_and_pin_holds() {
    let (s, _) = run("cantilever", Some(600));
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
    assert!(f(&s["piece_separation_end_h"]) >= f(&s["piece_separation_start_h"]) + 1.0);
    for key in ["mean_cluster_size", "memberships_per_particle"] {
        let (b, a) = (f(&s["before"][key]), f(&s["after"][key]));
        assert!((a / b - 1.0).abs() <= 0.25, "{key}: {b} -> {a}");
    }
    assert_eq!(s["invariant_violations"], 0);
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

#[test]
fn random_cuts_keep_invariants() {
    let (s, dump) = run("random", None);
    assert!(s["cut_particles"].as_u64().unwrap() > 0);
    assert_eq!(s["invariant_violations"], 0);
    assert_eq!(check_dump(&dump), s["pieces"].as_u64().unwrap() as usize);
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
