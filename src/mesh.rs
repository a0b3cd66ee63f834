//! Closed triangle meshes read from OBJ files, with an inside test by generalised
//! winding number (robust to small gaps and either orientation).

use crate::error::{CleaveError, Result};
use glam::Vec3;
use std::collections::HashMap;
use std::path::Path;

/// Largest OBJ file read (bytes).
pub const MAX_OBJ_BYTES: u64 = 256 << 20;

/// A closed triangle mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub vertices: Vec<Vec3>,
    /// Triangles as vertex index triples.
    pub triangles: Vec<[u32; 3]>,
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
}
