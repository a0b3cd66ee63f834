//! Closed triangle meshes read from OBJ files, with an inside test by generalised
//! winding number (robust to small gaps and either orientation) and a whole grid's
//! inside test by row crossings (for voxelising and for the distance grid).

use crate::error::{CleaveError, Result};
use glam::{UVec3, Vec3, Vec3A};
use std::collections::HashMap;
use std::path::Path;

/// Largest OBJ file read (bytes).
pub const MAX_OBJ_BYTES: u64 = 256 << 20;

/// A closed triangle mesh.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub vertices: Vec<Vec3>,
    /// Triangles as vertex index triples.
    pub triangles: Vec<[u32; 3]>,
    /// Where it came from (its file, or a name), for errors about it.
    #[serde(default)]
    pub source: std::path::PathBuf,
}

impl TriangleMesh {
    /// Builds a mesh and checks it is closed: every edge is shared by exactly two
    /// triangles, and every index and coordinate is valid.
    pub fn new(vertices: Vec<Vec3>, triangles: Vec<[u32; 3]>, name: &Path) -> Result<Self> {
        let fail = |reason: String| CleaveError::Mesh {
            path: name.to_path_buf(),
            reason,
        };
        if triangles.is_empty() {
            return Err(fail("no triangles".into()));
        }
        if let Some(v) = vertices.iter().find(|v| !v.is_finite()) {
            return Err(fail(format!("non-finite vertex {v}")));
        }
        let bound = crate::error::MAX_COORDINATE;
        if let Some(v) = vertices.iter().find(|v| v.abs().max_element() > bound) {
            return Err(fail(format!(
                "vertex {v} is beyond the world's bounds (allowed: |x|, |y|, |z| ≤ 1e6 metres)"
            )));
        }
        let mut edge_uses: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &triangles {
            if t.iter().any(|&i| i as usize >= vertices.len()) {
                return Err(fail(format!(
                    "triangle {t:?} indexes past {} vertices",
                    vertices.len()
                )));
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edge_uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let mut open: Vec<_> = edge_uses.iter().filter(|(_, n)| **n != 2).collect();
        if !open.is_empty() {
            open.sort();
            let ((a, b), n) = open[0];
            return Err(fail(format!(
                "not closed: {} edge(s) not shared by exactly two triangles, e.g. edge {a}-{b} used {n} time(s)",
                open.len()
            )));
        }
        Ok(Self {
            vertices,
            triangles,
            source: name.to_path_buf(),
        })
    }

    /// Reads every object of an OBJ file into one closed mesh. The file must be a regular
    /// file of at most [`MAX_OBJ_BYTES`] (an endless stream such as `/dev/zero` would be
    /// read until memory ran out).
    pub fn load_obj(path: &Path) -> Result<Self> {
        let fail = |reason: String| CleaveError::Mesh {
            path: path.to_path_buf(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot open: {e}")))?;
        if !meta.is_file() {
            return Err(fail("not a regular file".into()));
        }
        if meta.len() > MAX_OBJ_BYTES {
            return Err(fail(format!(
                "{} bytes (allowed: at most {MAX_OBJ_BYTES})",
                meta.len()
            )));
        }
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let (models, _) = tobj::load_obj(path, &options).map_err(|e| CleaveError::Mesh {
            path: path.to_path_buf(),
            reason: format!("cannot read OBJ: {e}"),
        })?;
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for model in models {
            let base = vertices.len() as u32;
            let m = model.mesh;
            vertices.extend(
                m.positions
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2])),
            );
            triangles.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
        }
        Self::new(vertices, triangles, path)
    }

    /// Axis-aligned bounds of the vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.vertices
            .iter()
            .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            })
    }

    /// Generalised winding number of `p` (≈ ±1 inside, ≈ 0 outside).
    pub fn winding_number(&self, p: Vec3) -> f32 {
        let mut total = 0.0f64;
        for t in &self.triangles {
            let a = self.vertices[t[0] as usize] - p;
            let b = self.vertices[t[1] as usize] - p;
            let c = self.vertices[t[2] as usize] - p;
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            // Van Oosterom–Strackee solid angle.
            let num = a.dot(b.cross(c));
            let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            total += 2.0 * (num as f64).atan2(den as f64);
        }
        (total / (4.0 * std::f64::consts::PI)) as f32
    }

    /// Whether `p` is inside (|winding number| > ½, so either orientation works).
    pub fn contains(&self, p: Vec3) -> bool {
        self.winding_number(p).abs() > 0.5
    }

    /// Whether each point `origin + (x, y, z)·cell` of a `dims` grid is inside, x
    /// fastest: by the parity of the crossings of the mesh with each row of the grid.
    ///
    /// Each triangle visits only the rows its shadow covers, so the cost is that plus
    /// one pass over the grid — not cells × triangles, as a winding number per point
    /// would be. For a closed mesh without self-intersections it agrees with
    /// [`Self::contains`].
    pub fn inside_grid(&self, origin: Vec3, cell: f32, dims: UVec3) -> Vec<bool> {
        let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
        // rows are nudged off the samples by an odd fraction of a cell, so that a ray
        // through a mesh vertex or edge (a common case on axis-aligned meshes) is rare
        let shift = Vec3A::from(origin) + Vec3A::new(0.0, 0.000_131, 0.000_173) * cell;
        let mut crossings: Vec<Vec<f32>> = vec![Vec::new(); ny * nz];
        for t in &self.triangles {
            let [a, b, c] = t.map(|v| Vec3A::from(self.vertices[v as usize]) - shift);
            let lo = (a.min(b).min(c) / cell).ceil().max(Vec3A::ZERO);
            let hi = (a.max(b).max(c) / cell).floor();
            if hi.y < 0.0 || hi.z < 0.0 {
                continue;
            }
            for z in lo.z as usize..=(hi.z as usize).min(nz.saturating_sub(1)) {
                for y in lo.y as usize..=(hi.y as usize).min(ny.saturating_sub(1)) {
                    let (py, pz) = (y as f32 * cell, z as f32 * cell);
                    if let Some(x) = row_crossing(a, b, c, py, pz) {
                        crossings[y + ny * z].push(x);
                    }
                }
            }
        }
        let mut inside = vec![false; nx * ny * nz];
        for (row, xs) in crossings.iter_mut().enumerate() {
            xs.sort_unstable_by(f32::total_cmp);
            for pair in xs.chunks_exact(2) {
                let first = (pair[0] / cell).ceil().max(0.0) as i64;
                let last = ((pair[1] / cell).floor() as i64).min(nx as i64 - 1);
                for x in first..=last {
                    inside[x as usize + row * nx] = true;
                }
            }
        }
        inside
    }
}

/// The x at which the ray `(·, py, pz)` crosses triangle `abc`, if it does (half-open
/// edge rules so that a ray through a shared edge counts it once).
fn row_crossing(a: Vec3A, b: Vec3A, c: Vec3A, py: f32, pz: f32) -> Option<f32> {
    // barycentric coordinates of (py, pz) in the triangle's yz shadow
    let (ya, za, yb, zb, yc, zc) = (a.y, a.z, b.y, b.z, c.y, c.z);
    let area = (yb - ya) * (zc - za) - (yc - ya) * (zb - za);
    if area == 0.0 {
        return None;
    }
    let w0 = ((yb - py) * (zc - pz) - (yc - py) * (zb - pz)) / area;
    let w1 = ((yc - py) * (za - pz) - (ya - py) * (zc - pz)) / area;
    let w2 = 1.0 - w0 - w1;
    (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 && (w0 > 0.0 || w1 > 0.0))
        .then(|| w0 * a.x + w1 * b.x + w2 * c.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let v: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let t = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (v, t)
    }

    /// A UV sphere of radius 1 with a dent (not convex): `rings × segments` quads.
    fn dented_sphere(rings: u32, segments: u32) -> TriangleMesh {
        let mut vertices = vec![Vec3::Y, -Vec3::Y];
        for r in 1..rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                let dir = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                // a dent on the +x side
                let radius = 1.0 - 0.5 * dir.x.max(0.0).powi(4);
                vertices.push(dir * radius);
            }
        }
        let ring = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
        let mut triangles = vec![];
        for s in 0..segments {
            triangles.push([0, ring(1, s + 1), ring(1, s)]);
            triangles.push([1, ring(rings - 1, s), ring(rings - 1, s + 1)]);
            for r in 1..rings - 1 {
                let (a, b, c, d) = (
                    ring(r, s),
                    ring(r, s + 1),
                    ring(r + 1, s + 1),
                    ring(r + 1, s),
                );
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        TriangleMesh::new(vertices, triangles, Path::new("dented")).unwrap()
    }

    #[test]
    fn the_row_crossing_grid_agrees_with_the_winding_number() {
        for mesh in [dented_sphere(12, 24), {
            let (v, t) = cube();
            TriangleMesh::new(v, t, Path::new("cube")).unwrap()
        }] {
            // a grid reaching past the mesh, its points off the cube's faces
            let (origin, cell, dims) = (Vec3::splat(-1.23), 0.0917, UVec3::splat(29));
            let inside = mesh.inside_grid(origin, cell, dims);
            let mut disagree = 0;
            let mut count = 0;
            for (i, &grid) in inside.iter().enumerate() {
                let (x, y, z) = (i % 29, i / 29 % 29, i / 29 / 29);
                let p = origin + Vec3::new(x as f32, y as f32, z as f32) * cell;
                let winding = mesh.winding_number(p).abs();
                // (points within a hair of the surface may go either way)
                if (winding - 0.5).abs() > 0.05 {
                    count += usize::from(grid);
                    disagree += usize::from(grid != (winding > 0.5));
                }
            }
            assert!(count > 50, "the grid sees the inside: {count}");
            assert_eq!(disagree, 0);
        }
    }

    #[test]
    fn cube_inside_outside() {
        let (v, t) = cube();
        let m = TriangleMesh::new(v, t, Path::new("cube")).unwrap();
        assert!(m.contains(Vec3::splat(0.5)));
        assert!(m.contains(Vec3::new(0.1, 0.9, 0.2)));
        assert!(!m.contains(Vec3::new(1.5, 0.5, 0.5)));
        assert!(!m.contains(Vec3::new(-0.1, 0.5, 0.5)));
    }

    #[test]
    fn open_mesh_is_rejected() {
        let (v, mut t) = cube();
        t.pop();
        let e = TriangleMesh::new(v, t, Path::new("open.obj"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("open.obj") && e.contains("not closed"), "{e}");
    }

    #[test]
    fn missing_file_is_an_error() {
        let e = TriangleMesh::load_obj(Path::new("/nonexistent/x.obj"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/nonexistent/x.obj") && e.contains("cannot open"),
            "{e}"
        );
    }

    #[test]
    fn an_endless_stream_or_a_folder_is_refused_before_reading() {
        for path in ["/dev/zero", "/tmp"] {
            let e = TriangleMesh::load_obj(Path::new(path))
                .unwrap_err()
                .to_string();
            assert!(e.contains(path) && e.contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn a_mesh_beyond_the_worlds_bounds_is_refused_naming_its_file() {
        let (mut v, t) = cube();
        v[7] = Vec3::new(1e30, 1.0, 1.0);
        let e = TriangleMesh::new(v, t, Path::new("huge.obj"))
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("huge.obj") && e.contains("beyond the world's bounds"),
            "{e}"
        );
    }
}
