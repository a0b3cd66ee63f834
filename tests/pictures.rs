//! What `cleave run` writes for people: PNG frames and a GIF in which the pieces of a
//! cut show in different colours (drawn as surfaces or as particles), PLY point clouds
//! that a PLY reader loads, and OBJ and glTF surfaces, read back here: a closed mesh per
//! piece, the same in both.

use std::path::{Path, PathBuf};
use std::process::Command;

fn run_slice(dir: &Path, extra: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["run", "slice", "--out"])
        .arg(dir)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cleave-pictures-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Counts pixels that are clearly blue (piece 0) and clearly orange (piece 1).
fn blue_and_orange(path: &Path) -> (usize, usize) {
    let img = image::open(path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (320, 240));
    let (mut blue, mut orange) = (0, 0);
    for p in img.pixels() {
        let [r, g, b] = p.0.map(i32::from);
        if b > r + 40 && b > g + 10 {
            blue += 1;
        }
        if r > g + 40 && r > b + 60 {
            orange += 1;
        }
    }
    (blue, orange)
}

#[test]
fn frames_show_one_piece_before_the_cut_and_two_after() {
    let dir = temp("png");
    run_slice(
        &dir,
        &[
            "--png-every",
            "150",
            "--gif-every",
            "30",
            "--width",
            "320",
            "--height",
            "240",
        ],
    );
    let (blue, orange) = blue_and_orange(&dir.join("frame_00000.png"));
    assert!(
        blue > 500 && orange == 0,
        "before: blue {blue}, orange {orange}"
    );
    let (blue, orange) = blue_and_orange(&dir.join("frame_00300.png"));
    assert!(
        blue > 300 && orange > 300,
        "after: blue {blue}, orange {orange}"
    );
    // the GIF holds frames 0, 30, …, 300
    let file = std::fs::File::open(dir.join("run.gif")).unwrap();
    let mut decoder = gif::DecodeOptions::new().read_info(file).unwrap();
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!((frame.width, frame.height), (320, 240));
        frames += 1;
    }
    assert_eq!(frames, 11);
}

/// A small PLY reader: the header's vertex count and property names, then the rows.
fn read_ply(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format ascii 1.0"));
    let (mut count, mut names) = (0usize, Vec::new());
    for line in lines.by_ref() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", "vertex", n] => count = n.parse().unwrap(),
            ["property", _, name] => names.push(name.to_string()),
            ["end_header"] => break,
            ["comment", ..] => {}
            other => panic!("unexpected header line {other:?}"),
        }
    }
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split_whitespace().map(|w| w.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), count);
    (names, rows)
}

#[test]
fn ply_frames_load_with_positions_colours_and_pieces() {
    let dir = temp("ply");
    run_slice(
        &dir,
        &[
            "--frames",
            "300",
            "--export",
            "ply",
            "--ply-every",
            "300",
            "--png-every",
            "0",
            "--gif-every",
            "0",
        ],
    );
    let (names, rows) = read_ply(&dir.join("ply/frame_00000.ply"));
    assert_eq!(names, ["x", "y", "z", "red", "green", "blue", "piece"]);
    assert_eq!(rows.len(), 24 * 12 * 12);
    assert!(rows.iter().all(|r| r.len() == 7 && r[6] == 0.0));
    let (_, rows) = read_ply(&dir.join("ply/frame_00300.ply"));
    let pieces: std::collections::BTreeSet<i64> = rows.iter().map(|r| r[6] as i64).collect();
    assert_eq!(pieces.into_iter().collect::<Vec<_>>(), [0, 1]);
    assert!(rows.iter().all(|r| r[..3].iter().all(|v| v.is_finite())));
    assert!(
        rows.iter()
            .all(|r| r[3..6].iter().all(|c| (0.0..=255.0).contains(c)))
    );
}

/// The triangles of each group of an OBJ file, as vertex positions.
fn obj_groups(path: &Path) -> std::collections::BTreeMap<String, Vec<[[f64; 3]; 3]>> {
    let text = std::fs::read_to_string(path).unwrap();
    let (mut vertices, mut groups) = (Vec::new(), std::collections::BTreeMap::new());
    let mut group = String::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let v: Vec<f64> = words.map(|w| w.parse().unwrap()).collect();
                vertices.push([v[0], v[1], v[2]]);
            }
            Some("g") => group = words.next().unwrap().to_string(),
            Some("f") => {
                let corner: Vec<usize> = words
                    .map(|w| w.split("//").next().unwrap().parse::<usize>().unwrap() - 1)
                    .collect();
                assert_eq!(corner.len(), 3, "{line}");
                groups.entry(group.clone()).or_insert_with(Vec::new).push([
                    vertices[corner[0]],
                    vertices[corner[1]],
                    vertices[corner[2]],
                ]);
            }
            _ => {}
        }
    }
    groups
}

#[test]
fn obj_and_gltf_exports_hold_a_closed_surface_per_piece() {
    let dir = temp("obj");
    run_slice(
        &dir,
        &[
            "--frames",
            "120",
            "--png-every",
            "120",
            "--gif-every",
            "0",
            "--export",
            "obj,gltf",
        ],
    );
    let mut volumes = Vec::new();
    for (frame, pieces) in [(0, 1), (120, 2)] {
        let groups = obj_groups(&dir.join(format!("obj/frame_{frame:05}.obj")));
        assert_eq!(groups.len(), pieces, "frame {frame}: {:?}", groups.keys());
        for (name, triangles) in &groups {
            // every edge, by its end positions, once each way
            let key = |p: [f64; 3]| p.map(|x| (x * 1e6).round() as i64);
            let mut directed = std::collections::HashMap::new();
            let mut volume = 0.0;
            for [a, b, c] in triangles {
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    *directed.entry((key(*p), key(*q))).or_insert(0) += 1;
                }
                let cross = [
                    b[1] * c[2] - b[2] * c[1],
                    b[2] * c[0] - b[0] * c[2],
                    b[0] * c[1] - b[1] * c[0],
                ];
                volume += (a[0] * cross[0] + a[1] * cross[1] + a[2] * cross[2]) / 6.0;
            }
            for (&(p, q), &n) in &directed {
                assert_eq!(
                    (n, directed.get(&(q, p))),
                    (1, Some(&1)),
                    "{name}: open at {p:?}"
                );
            }
            volumes.push(volume);
        }
    }
    // the slice takes a layer out of the middle: two halves of the block's volume
    let whole = volumes[0];
    for half in &volumes[1..] {
        assert!((half / whole - 0.5).abs() < 0.05, "{volumes:?}");
    }
    // the glTF of the same frame, read by the `gltf` crate: a mesh per piece, the OBJ's
    // vertices and triangles
    let obj = std::fs::read_to_string(dir.join("obj/frame_00120.obj")).unwrap();
    let count = |prefix: &str| obj.lines().filter(|l| l.starts_with(prefix)).count();
    let glb = std::fs::read(dir.join("gltf/frame_00120.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    assert_eq!(gltf.meshes().count(), 2);
    let mut positions = std::collections::BTreeMap::new();
    let mut indices = 0;
    for mesh in gltf.meshes() {
        for primitive in mesh.primitives() {
            let p = primitive.get(&gltf::Semantic::Positions).unwrap();
            positions.insert(p.index(), p.count());
            assert!(primitive.get(&gltf::Semantic::Normals).is_some());
            indices += primitive.indices().unwrap().count();
        }
    }
    assert_eq!(positions.values().sum::<usize>(), count("v "));
    assert_eq!(indices, 3 * count("f "));
}

#[test]
fn particles_are_drawn_when_asked() {
    let dir = temp("particles");
    let size = ["--width", "320", "--height", "240", "--gif-every", "0"];
    run_slice(
        &dir,
        &[&size[..], &["--frames", "0", "--draw", "particles"]].concat(),
    );
    let (blue, _) = blue_and_orange(&dir.join("frame_00000.png"));
    assert!(blue > 500, "{blue}");
}

#[test]
fn an_export_folder_that_cannot_be_made_is_an_error_naming_it() {
    let dir = temp("blocked");
    std::fs::create_dir_all(&dir).unwrap();
    // a file where the OBJ folder would go
    std::fs::write(dir.join("obj"), b"in the way").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cleave"))
        .args(["run", "slice", "--frames", "1", "--export", "obj", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&dir.join("obj").display().to_string()),
        "{stderr}"
    );
}
