//! Shared by the end-to-end tests: running the `cleave` binary on a scene, and an
//! invariant checker of its state dumps written against the JSON alone (it shares no
//! code with the engine).
#![allow(dead_code)] // each test crate uses its own part

use cleave::prelude::Vec3;
use serde_json::Value;
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::PathBuf;
use std::process::Command;

pub fn run(scene: &str, frames: Option<u32>) -> (Value, Value) {
    run_with(scene, frames, &[])
}

/// Runs `scene` with extra arguments; returns the summary and the dump.
pub fn run_with(scene: &str, frames: Option<u32>, extra: &[&str]) -> (Value, Value) {
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
pub fn check_dump(dump: &Value) -> usize {
    pieces_of(dump).len()
}

/// Every piece of every body of a checked dump, as `(body index, particle ids)`.
pub fn pieces_of(dump: &Value) -> Vec<(usize, HashSet<u64>)> {
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
pub fn positions_of(dump: &Value) -> HashMap<u64, [f64; 3]> {
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
pub fn min_distance_between(groups: &[Vec<[f64; 3]>]) -> f64 {
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
pub fn dump_gaps(dump: &Value) -> (f64, f64) {
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
pub fn check_body(dump: &Value) -> Vec<HashSet<u64>> {
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
    if dump["config"]["model"] == "oriented" {
        check_groups(dump, &ids, &adjacency, &components);
        return components(&ids);
    }
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

/// Checks the groups of a body of the oriented model: no clusters; every particle
/// outside the explicit groups centres one group, which is it and the particles its live
/// edges reach; every explicit piece is connected and covers particles no implicit group
/// is centred on.
fn check_groups(
    dump: &Value,
    ids: &HashSet<u64>,
    adjacency: &HashMap<u64, Vec<u64>>,
    components: &dyn Fn(&HashSet<u64>) -> Vec<HashSet<u64>>,
) {
    assert!(
        dump["clusters"].as_array().unwrap().is_empty(),
        "an oriented body holds clusters"
    );
    let mut centred = HashSet::new();
    let mut in_parts = HashSet::new();
    for g in dump["groups"].as_array().expect("groups") {
        let members: HashSet<u64> = g["members"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_u64().unwrap())
            .collect();
        assert!(members.is_subset(ids), "a group holds a dead particle");
        match g["centre"].as_u64() {
            Some(c) => {
                assert!(centred.insert(c), "two groups centred on {c}");
                let mut live: HashSet<u64> = adjacency[&c].iter().copied().collect();
                live.insert(c);
                assert_eq!(
                    members, live,
                    "the group of {c} is not its live neighbourhood"
                );
            }
            None => {
                assert_eq!(components(&members).len(), 1, "a disconnected rigid part");
                in_parts.extend(members);
            }
        }
    }
    assert!(
        centred.is_disjoint(&in_parts),
        "a rigid part's particle centres a group"
    );
    let covered: HashSet<u64> = centred.union(&in_parts).copied().collect();
    assert_eq!(&covered, ids, "particles in no group");
}

pub fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

/// The `cantilever`'s steady tip sag (frame 600, in h) under the given settings.
pub fn cantilever_sag(extra: &[&str]) -> f64 {
    let mut args = vec!["--png-every", "0", "--gif-every", "0", "--quiet"];
    args.extend_from_slice(extra);
    let (s, _) = run_with("cantilever", Some(600), &args);
    f(&s["bodies"][0]["tip_drop_h_end"])
}

/// Runs `cleave run` on `text` written to a file `name` (unique across the tests, which
/// run in parallel and share the directory); returns (exit code, stderr).
pub fn run_file(name: &str, text: &str) -> (Option<i32>, String) {
    let dir = std::env::temp_dir().join(format!("cleave-scene-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["run"])
        .arg(&file)
        .args([
            "--frames",
            "2",
            "--gif-every",
            "0",
            "--png-every",
            "0",
            "--out",
        ])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

pub const GOOD: &str = r#"(
    frames: 2,
    bodies: [(shape: Cells(cells: (4, 4, 4)), spacing: 0.1, position: (0.0, 0.5, 0.0))],
    tools: [(
        shape: Sphere(radius: 0.1),
        cut_width: 0.05,
        path: [(0.0, (position: (0.0, 2.0, 0.0))), (1.0, (position: (0.0, 0.5, 0.0)))],
    )],
)"#;

/// Asserts that `text` (a program's error output) contains every one of `parts`.
pub fn assert_mentions(text: &str, parts: &[&str]) {
    for part in parts {
        assert!(text.contains(part), "`{part}` missing from: {text}");
    }
}

/// A closed octahedron |x| + |y| + |z| = `r`: its vertices and its triangles, wound
/// counter-clockwise seen from outside.
pub fn octahedron(r: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let vertices = vec![
        [r, 0.0, 0.0],
        [-r, 0.0, 0.0],
        [0.0, r, 0.0],
        [0.0, -r, 0.0],
        [0.0, 0.0, r],
        [0.0, 0.0, -r],
    ];
    let triangles = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    (vertices, triangles)
}

/// Per piece, the volume a closed, consistently oriented mesh encloses; panics naming
/// an edge that is open, doubled or turned the wrong way.
pub fn closed_volumes(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    pieces: &[u32],
) -> HashMap<u32, f64> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    let mut volume: HashMap<u32, f64> = HashMap::new();
    for (t, piece) in triangles.iter().zip(pieces) {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
        let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
        *volume.entry(*piece).or_default() += a.dot(b.cross(c)) / 6.0;
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "edge {a}→{b} in {n} triangles the same way");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge {a}→{b} has no single twin"
        );
    }
    volume
}
