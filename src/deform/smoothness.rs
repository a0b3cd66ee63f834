//! The linearly precise smoothness energy `A = Kᵀ M⁻¹ K` of a body's lattice (SPEC
//! §6.3), over its live edges, so a cut or a removed particle changes it.
//!
//! # K on a voxel lattice
//!
//! The paper's `K = L + N` is the Laplacian integrated over each vertex's cell: the
//! flux `∂u/∂n` through the cell's faces. Inside, the flux through the face between
//! `i` and its neighbour `j` is `(u_j − u_i)/h`. Where the face lies on the body's
//! surface (a missing or severed link), the cotangent Laplacian leaves the flux out —
//! a Neumann condition `∂u/∂n = 0` that a linear function breaks — and `N` puts it
//! back from an estimate of the normal derivative. On the lattice that estimate is the
//! one-sided difference through the opposite face, `(u_i − u_opposite)/h`, which is
//! exact for linear functions. With it, the two faces of an axis along which `i` has
//! one link cancel: along an axis `K`'s row holds the central second difference
//! `u₋ − 2u_i + u₊` where `i` has both links, and nothing otherwise. Every row is then
//! exact for linear functions, boundary rows included, so `A·1 = 0` and `A·x = 0`.
//!
//! # Why the rows are kept apart
//!
//! Summing the three axes' rows (the Laplacian proper) leaves every discrete harmonic
//! function the stencils reproduce exactly — `xy`, `x² − y²`, `xyz`, … — in `K`'s
//! kernel, so `T A Tᵀ` is singular for a few point handles that a body's affine maps
//! would pin. Keeping the axes as separate rows and adding the mixed second
//! differences of the lattice's squares makes `K` the discrete Hessian: `Kᵀ K` is the
//! Hessian energy `∫ ‖∇²u‖²`, whose kernel is the affine functions alone and whose
//! Euler–Lagrange equation inside the body is the same biharmonic `Δ²u = 0` as the
//! squared Laplacian's (the two differ only in their natural boundary conditions;
//! Stein et al. 2018 prefer the Hessian's). A mixed row `u₁₁ − u₁₀ − u₀₁ + u₀₀`
//! counts twice in the Frobenius norm, so it has weight √2. `M` is the cells' volume,
//! the same for every particle of the lattice: it scales `A` and leaves `W` as it is,
//! so it is taken as 1.

use crate::body::lattice::{Lattice, NO_PARTICLE};

/// A sparse symmetric matrix over a body's particles, both triangles stored by rows.
#[derive(Clone, Debug, Default)]
pub struct SymmetricMatrix {
    /// Where each row's entries start in `columns` and `values` (one more than rows).
    pub row_start: Vec<usize>,
    /// Each entry's column.
    pub columns: Vec<u32>,
    /// Each entry's value.
    pub values: Vec<f64>,
}

impl SymmetricMatrix {
    /// The `n × n` matrix `Σ w · r rᵀ` over `rows` (each `(weight, entries)`).
    pub fn from_outer_products<'a>(
        n: usize,
        rows: impl Iterator<Item = (f64, &'a [(u32, f64)])>,
    ) -> Self {
        let mut entries: Vec<(u64, f64)> = Vec::new();
        for (w, row) in rows {
            for &(i, a) in row {
                for &(j, b) in row {
                    entries.push(((i as u64) << 32 | j as u64, w * a * b));
                }
            }
        }
        entries.sort_unstable_by_key(|e| e.0);
        let mut m = SymmetricMatrix {
            row_start: vec![0; n + 1],
            ..Default::default()
        };
        let mut last = u64::MAX;
        for (key, v) in entries {
            if key == last {
                *m.values.last_mut().expect("an entry with this key") += v;
                continue;
            }
            last = key;
            m.columns.push(key as u32);
            m.values.push(v);
            m.row_start[(key >> 32) as usize + 1] += 1;
        }
        for i in 0..n {
            m.row_start[i + 1] += m.row_start[i];
        }
        m
    }

    /// Row `i`: its `(column, value)` entries.
    pub fn row(&self, i: u32) -> impl Iterator<Item = (u32, f64)> + '_ {
        let range = self.row_start[i as usize]..self.row_start[i as usize + 1];
        self.columns[range.clone()]
            .iter()
            .copied()
            .zip(self.values[range].iter().copied())
    }

    /// `A x` for one scalar per particle.
    pub fn mul(&self, x: &[f64]) -> Vec<f64> {
        (0..self.row_start.len() - 1)
            .map(|i| self.row(i as u32).map(|(j, a)| a * x[j as usize]).sum())
            .collect()
    }

    /// The largest absolute entry.
    pub fn max_abs(&self) -> f64 {
        self.values.iter().fold(0.0, |m, v| m.max(v.abs()))
    }
}

/// The rows of `K` (the lattice's discrete Hessian, see the module doc): three axis
/// rows per particle where it has both links, and one mixed row per lattice square
/// whose four edges are live, each `(weight², entries)`.
pub fn hessian_rows(lattice: &Lattice) -> Vec<(f64, Vec<(u32, f64)>)> {
    let mut rows = Vec::new();
    for i in lattice.live_particles() {
        let links = lattice.links(i);
        for a in 0..3 {
            let (minus, plus) = (links[2 * a], links[2 * a + 1]);
            if minus != NO_PARTICLE && plus != NO_PARTICLE {
                rows.push((1.0, vec![(minus, 1.0), (plus, 1.0), (i, -2.0)]));
            }
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let (j, k) = (links[2 * a + 1], links[2 * b + 1]);
            if j == NO_PARTICLE || k == NO_PARTICLE {
                continue;
            }
            let l = lattice.link(j, 2 * b + 1);
            if l != NO_PARTICLE && lattice.link(k, 2 * a + 1) == l {
                rows.push((2.0, vec![(l, 1.0), (j, -1.0), (k, -1.0), (i, 1.0)]));
            }
        }
    }
    rows
}

/// The smoothness energy's matrix `A = Kᵀ M⁻¹ K` over all the lattice's particles
/// (removed ones have empty rows).
pub fn smoothness_matrix(lattice: &Lattice) -> SymmetricMatrix {
    let rows = hessian_rows(lattice);
    SymmetricMatrix::from_outer_products(
        lattice.len(),
        rows.iter().map(|(w, r)| (*w, r.as_slice())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::{DVec3, UVec3, Vec3};

    /// The largest `|A·f|` for f = 1, x, y, z (rest positions), relative to `‖A‖·‖f‖`.
    fn worst_linear_residual(lattice: &Lattice) -> f64 {
        let a = smoothness_matrix(lattice);
        // rest positions in f64: (coordinate + ½) h
        let h = lattice.spacing() as f64;
        let rest: Vec<DVec3> = (0..lattice.len() as u32)
            .map(|i| (lattice.coord(i).as_dvec3() + DVec3::splat(0.5)) * h)
            .collect();
        let fields: [fn(DVec3) -> f64; 4] = [|_| 1.0, |p| p.x, |p| p.y, |p| p.z];
        let mut worst: f64 = 0.0;
        for f in fields {
            let x: Vec<f64> = rest.iter().map(|&p| f(p)).collect();
            let scale = a.max_abs() * x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let ax = a.mul(&x);
            let r = ax.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            worst = worst.max(r / scale);
        }
        worst
    }

    #[test]
    fn linear_functions_have_no_energy_on_a_sphere_a_bar_and_a_notched_block() {
        let sphere = Shape::Sphere { radius: 0.5 }.voxelise(0.1).unwrap();
        let bar = Shape::cuboid(UVec3::new(32, 4, 4)).voxelise(0.1).unwrap();
        let mut notched = Shape::cuboid(UVec3::new(12, 8, 6)).voxelise(0.1).unwrap();
        // a notch: a slot of removed particles, and a cut of severed links beside it
        let removed: Vec<u32> = notched
            .live_particles()
            .filter(|&i| {
                let c = notched.coord(i);
                c.x == 0 && c.y >= 0
            })
            .collect();
        for i in removed {
            notched.remove(i);
        }
        let severed: Vec<(u32, u32)> = notched
            .edges()
            .into_iter()
            .filter(|&(a, b)| {
                let (ca, cb) = (notched.coord(a), notched.coord(b));
                ca.x == 2 && cb.x == 3 && ca.y <= -1
            })
            .collect();
        assert!(!severed.is_empty());
        for (a, b) in severed {
            notched.sever(a, b);
        }
        for (name, lattice) in [("sphere", sphere), ("bar", bar), ("notched", notched)] {
            let r = worst_linear_residual(&lattice);
            eprintln!("{name}: |A·f| = {r:e} of ‖A‖·‖f‖");
            assert!(r < 1e-10, "{name}: |A·f| = {r:e} of ‖A‖·‖f‖");
        }
    }

    #[test]
    fn only_affine_functions_have_no_energy() {
        // x·y and x² − y² are harmonic: a summed Laplacian would not see them
        let lattice = Shape::cuboid(UVec3::new(6, 5, 4)).voxelise(0.1).unwrap();
        let a = smoothness_matrix(&lattice);
        for f in [
            |p: Vec3| (p.x * p.y) as f64,
            |p: Vec3| (p.x * p.x - p.y * p.y) as f64,
        ] {
            let x: Vec<f64> = (0..lattice.len() as u32)
                .map(|i| f(lattice.rest_position(i)))
                .collect();
            let energy: f64 = a.mul(&x).iter().zip(&x).map(|(a, b)| a * b).sum();
            assert!(energy > 1e-6, "energy {energy:e}");
        }
    }
}
