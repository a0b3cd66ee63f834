//! The signed distance of a closed triangle mesh, sampled once on a grid so that a
//! collider made of it costs the same per query as a box: trilinear distance, gradient
//! by central differences.
//!
//! Building it costs the grid plus the triangles' footprints, never cells × triangles:
//! - **distance**: each triangle writes its exact nearest point into the cells of a thin
//!   shell around it; sweeps through the grid in the eight diagonal orders then hand
//!   each cell its neighbours' nearest points and keep the closest (closest-point
//!   propagation, exact up to the grid's resolution);
//! - **sign**: along each row of cells in x, the crossings of the row's ray with the
//!   triangles (each triangle visits only the rows its shadow covers) are sorted, and the
//!   cells between the first and second crossing, the third and fourth, … are inside.

use crate::error::allowed::Allowed;
use crate::error::{CleaveError, Result};
use crate::geometry::mesh::TriangleMesh;
use glam::{UVec3, Vec3, Vec3A};

/// Most cells along the longest axis.
pub const MAX_RESOLUTION: u32 = 256;

/// The allowed sampling resolutions, as the API and the scene file state them.
pub const RESOLUTION: Allowed = Allowed::count("resolution", 4, MAX_RESOLUTION);

/// A closed mesh's signed distance on a grid (negative inside).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshSdf {
    /// Position of the first sample.
    origin: Vec3A,
    /// Spacing of the samples.
    cell: f32,
    /// Samples per axis.
    dims: UVec3,
    /// Signed distance per sample, x fastest.
    values: Vec<f32>,
    /// Half size of the box about the origin of the mesh's frame that holds the mesh.
    half_extents: Vec3,
    /// The mesh itself (for pictures).
    mesh: TriangleMesh,
}

impl MeshSdf {
    /// Samples the signed distance of `mesh` with `resolution` cells along its longest
    /// axis (4 ≤ resolution ≤ [`MAX_RESOLUTION`]), two cells of margin on every side.
    pub fn new(mesh: &TriangleMesh, resolution: u32) -> Result<Self> {
        RESOLUTION.check("collider.resolution", resolution)?;
        let (lo, hi) = mesh.bounds();
        let extent = (hi - lo).max_element();
        if !(extent > 0.0 && extent.is_finite()) {
            return Err(CleaveError::InvalidEntity(
                "a mesh collider needs a mesh of non-zero size".into(),
            ));
        }
        let cell = extent / resolution as f32;
        let origin = Vec3A::from(lo) - Vec3A::splat(2.0 * cell);
        let dims = (((hi - lo) / cell).ceil().as_uvec3() + UVec3::splat(5)).max(UVec3::splat(2));
        let half_extents = lo.abs().max(hi.abs());
        let mut sdf = Self {
            origin,
            cell,
            dims,
            values: Vec::new(),
            half_extents,
            mesh: mesh.clone(),
        };
        let nearest = sdf.nearest_points(mesh);
        let inside = sdf.inside_cells(mesh);
        sdf.values = nearest
            .iter()
            .enumerate()
            .map(|(i, q)| {
                let d = (sdf.position(i) - *q).length();
                if inside[i] { -d } else { d }
            })
            .collect();
        Ok(sdf)
    }

    /// Half size of the box about the frame's origin that holds the mesh.
    pub fn half_extents(&self) -> Vec3 {
        self.half_extents
    }

    /// The mesh the distance was sampled from.
    pub fn mesh(&self) -> &TriangleMesh {
        &self.mesh
    }

    fn index(&self, x: u32, y: u32, z: u32) -> usize {
        (x + self.dims.x * (y + self.dims.y * z)) as usize
    }

    fn position(&self, i: usize) -> Vec3A {
        let (nx, ny) = (self.dims.x as usize, self.dims.y as usize);
        let c = Vec3A::new(
            (i % nx) as f32,
            ((i / nx) % ny) as f32,
            (i / (nx * ny)) as f32,
        );
        self.origin + c * self.cell
    }

    /// The nearest mesh point of every sample (see the module docs).
    fn nearest_points(&self, mesh: &TriangleMesh) -> Vec<Vec3A> {
        let mut nearest = vec![Vec3A::splat(f32::INFINITY); self.values_len()];
        let mut best = vec![f32::INFINITY; self.values_len()];
        let grid_max = self.dims.as_ivec3() - 1;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|v| Vec3A::from(mesh.vertices[v as usize]));
            let lo = ((a.min(b).min(c) - self.origin) / self.cell)
                .floor()
                .as_ivec3()
                - 1;
            let hi = ((a.max(b).max(c) - self.origin) / self.cell)
                .ceil()
                .as_ivec3()
                + 1;
            let (lo, hi) = (
                lo.clamp(glam::IVec3::ZERO, grid_max),
                hi.clamp(glam::IVec3::ZERO, grid_max),
            );
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let i = self.index(x as u32, y as u32, z as u32);
                        let p = self.position(i);
                        let q = closest_on_triangle(p, a, b, c);
                        let d = (p - q).length_squared();
                        if d < best[i] {
                            best[i] = d;
                            nearest[i] = q;
                        }
                    }
                }
            }
        }
        // closest-point propagation: in each of the eight diagonal orders, a sample
        // takes a neighbour's nearest point when it is closer than its own
        let (nx, ny, nz) = (self.dims.x as i32, self.dims.y as i32, self.dims.z as i32);
        for _ in 0..2 {
            for order in 0..8 {
                let step = [
                    1 - 2 * (order & 1),
                    1 - ((order >> 1) & 1) * 2,
                    1 - ((order >> 2) & 1) * 2,
                ];
                let range = |n: i32, s: i32| -> Vec<i32> {
                    if s > 0 {
                        (0..n).collect()
                    } else {
                        (0..n).rev().collect()
                    }
                };
                for z in range(nz, step[2]) {
                    for y in range(ny, step[1]) {
                        for x in range(nx, step[0]) {
                            let i = self.index(x as u32, y as u32, z as u32);
                            let p = self.position(i);
                            for (dx, dy, dz) in [(step[0], 0, 0), (0, step[1], 0), (0, 0, step[2])]
                            {
                                let (px, py, pz) = (x - dx, y - dy, z - dz);
                                if px < 0 || py < 0 || pz < 0 || px >= nx || py >= ny || pz >= nz {
                                    continue;
                                }
                                let q = nearest[self.index(px as u32, py as u32, pz as u32)];
                                let d = (p - q).length_squared();
                                if d < best[i] {
                                    best[i] = d;
                                    nearest[i] = q;
                                }
                            }
                        }
                    }
                }
            }
        }
        nearest
    }

    fn values_len(&self) -> usize {
        (self.dims.x * self.dims.y * self.dims.z) as usize
    }

    /// Whether each sample is inside the mesh (see [`TriangleMesh::inside_grid`]).
    fn inside_cells(&self, mesh: &TriangleMesh) -> Vec<bool> {
        mesh.inside_grid(self.origin.into(), self.cell, self.dims)
    }

    /// The sampled value at integer sample coordinates, clamped into the grid.
    fn at(&self, x: i32, y: i32, z: i32) -> f32 {
        let m = self.dims.as_ivec3() - 1;
        let (x, y, z) = (x.clamp(0, m.x), y.clamp(0, m.y), z.clamp(0, m.z));
        self.values[self.index(x as u32, y as u32, z as u32)]
    }

    /// Signed distance at `p` (mesh frame): trilinear inside the grid; outside it, a lower
    /// bound that meets the boundary value continuously (the mesh lies two cells inside
    /// the grid's box, so it is at least the distance to the box plus two cells), which
    /// keeps sphere tracing from stepping over the surface.
    pub fn distance(&self, p: Vec3A) -> f32 {
        let g = (p - self.origin) / self.cell;
        let top = (self.dims.as_vec3() - 1.0).into();
        let clamped = g.clamp(Vec3A::ZERO, top);
        let outside = (g - clamped).length() * self.cell;
        let base = clamped.floor().min(top - 1.0).max(Vec3A::ZERO);
        let f = clamped - base;
        let (x, y, z) = (base.x as i32, base.y as i32, base.z as i32);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(self.at(x, y, z), self.at(x + 1, y, z), f.x);
        let c10 = lerp(self.at(x, y + 1, z), self.at(x + 1, y + 1, z), f.x);
        let c01 = lerp(self.at(x, y, z + 1), self.at(x + 1, y, z + 1), f.x);
        let c11 = lerp(self.at(x, y + 1, z + 1), self.at(x + 1, y + 1, z + 1), f.x);
        let value = lerp(lerp(c00, c10, f.y), lerp(c01, c11, f.y), f.z);
        if outside > 0.0 {
            (value - outside).max(outside + 2.0 * self.cell)
        } else {
            value
        }
    }

    /// Unit gradient of the distance at `p` (the outward normal near the surface).
    pub fn normal(&self, p: Vec3A) -> Vec3A {
        let e = 0.5 * self.cell;
        let g = Vec3A::new(
            self.distance(p + Vec3A::X * e) - self.distance(p - Vec3A::X * e),
            self.distance(p + Vec3A::Y * e) - self.distance(p - Vec3A::Y * e),
            self.distance(p + Vec3A::Z * e) - self.distance(p - Vec3A::Z * e),
        );
        g.try_normalize().unwrap_or(Vec3A::Y)
    }

    /// The first `t ∈ [0, 1]` where `a + t (b − a)` reaches the surface, for `a` outside,
    /// by sphere tracing (steps of the distance, at least a hundredth of a cell).
    pub fn segment_entry(&self, a: Vec3A, b: Vec3A) -> Option<f32> {
        self.segment_entry_within(a, b, 0.0)
    }

    /// [`MeshSdf::segment_entry`] of the surface grown by `margin` (its distance less
    /// `margin`).
    pub fn segment_entry_within(&self, a: Vec3A, b: Vec3A, margin: f32) -> Option<f32> {
        let length = (b - a).length();
        if length == 0.0 {
            return (self.distance(a) - margin <= 0.0).then_some(0.0);
        }
        let mut t = 0.0f32;
        for _ in 0..512 {
            let d = self.distance(a + (b - a) * (t / length)) - margin;
            if d <= 1e-4 * self.cell {
                return Some(t / length);
            }
            t += d.max(0.01 * self.cell);
            if t > length {
                return None;
            }
        }
        None
    }
}

/// The point of triangle `abc` nearest to `p` (Ericson, Real-Time Collision Detection,
/// §5.1.5).
pub fn closest_on_triangle(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> Vec3A {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A closed octahedron of "radius" 1 (|x| + |y| + |z| = 1).
    fn octahedron() -> TriangleMesh {
        let v = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        TriangleMesh::new(v, t, Path::new("octahedron")).expect("closed")
    }

    /// Exact signed distance to the octahedron |x| + |y| + |z| = 1, by brute force over
    /// its faces and the winding number.
    fn exact(mesh: &TriangleMesh, p: Vec3A) -> f32 {
        let d = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| Vec3A::from(mesh.vertices[v as usize]));
                (p - closest_on_triangle(p, a, b, c)).length()
            })
            .fold(f32::INFINITY, f32::min);
        if mesh.contains(p.into()) { -d } else { d }
    }

    #[test]
    fn the_sampled_distance_matches_the_exact_one_within_a_cell() {
        use rand::{Rng, SeedableRng};
        let mesh = octahedron();
        let sdf = MeshSdf::new(&mesh, 40).expect("an sdf");
        let cell = 2.0 / 40.0;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let (mut inside, mut outside) = (0, 0);
        for _ in 0..2000 {
            let p = Vec3A::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
            );
            let (got, want) = (sdf.distance(p), exact(&mesh, p));
            if p.abs().max_element() > 1.0 + 2.0 * cell {
                // outside the grid: a lower bound, never below two cells
                assert!(
                    got <= want + 1e-4 && got >= 2.0 * cell - 1e-4,
                    "{p}: {got} vs {want}"
                );
                continue;
            }
            assert!((got - want).abs() < 0.5 * cell, "{p}: {got} vs {want}");
            if want < -cell {
                inside += 1;
                assert!(got < 0.0);
            } else if want > cell {
                outside += 1;
                assert!(got > 0.0);
            }
        }
        assert!(inside > 50 && outside > 500, "{inside} {outside}");
        // far outside the grid: still a distance that grows
        assert!(sdf.distance(Vec3A::new(5.0, 0.0, 0.0)) > 3.5);
        assert!(sdf.distance(Vec3A::new(9.0, 0.0, 0.0)) > sdf.distance(Vec3A::new(5.0, 0.0, 0.0)));
        // normals point out
        let n = sdf.normal(Vec3A::new(0.3, 0.3, 0.3));
        assert!((n - Vec3A::ONE.normalize()).length() < 0.1, "{n}");
    }

    #[test]
    fn a_segment_enters_the_mesh_at_its_surface() {
        let sdf = MeshSdf::new(&octahedron(), 40).expect("an sdf");
        let t = sdf
            .segment_entry(Vec3A::new(-3.0, 0.1, 0.1), Vec3A::new(3.0, 0.1, 0.1))
            .expect("a hit");
        let x = -3.0 + 6.0 * t;
        assert!((x + 0.8).abs() < 0.03, "entered at x = {x}");
        assert_eq!(
            sdf.segment_entry(Vec3A::new(-3.0, 2.0, 0.0), Vec3A::new(3.0, 2.0, 0.0)),
            None
        );
    }
}
