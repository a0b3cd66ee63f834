//! The linear subspace's weights `W = SᵀJ − Tᵀ(T A Tᵀ)⁻¹ T A SᵀJ` (SPEC §6.3): one row
//! per particle, one column per handle parameter, computed once per body and handle
//! set, and the real-time pose `V = V̄ + W (H − H̄)`.
//!
//! The pose is written as a displacement from the rest positions `V̄` (which `W H̄`
//! reproduces exactly: the energy is linearly precise) so that single-precision
//! weights lose nothing of the rest shape, only of the displacement.
//!
//! A piece whose handles do not pin every affine function on it (no handle, or handle
//! particles that do not span the piece: all on a line of a solid piece, say) has a
//! singular `T A Tᵀ`: its particles follow their nearest handle instead — by
//! translation for a point handle, by the region's affine map for a region — and leave
//! the solve.

use super::handles::HandleSet;
use super::smoothness::{SymmetricMatrix, smoothness_matrix};
use crate::body::lattice::Lattice;
use crate::error::{CleaveError, Result};
use crate::math::lanes::{LANES, Vec3x8};
use crate::math::simd::Lane;
use crate::math::sparse_cholesky::{FactorError, SolveScratch, SparseCholesky};
use faer::sparse::Triplet;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Right-hand sides solved side by side.
const BATCH: usize = 4;

/// How each particle's row of `W` is made.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Row {
    /// Removed: no row.
    Removed,
    /// Moved by handle `k` (its own particle, or one of a piece that follows it).
    Follows(usize),
    /// Solved for: its index among the unknowns.
    Free(usize),
}

/// The weights of a body's handle subspace, eight particles to a block.
#[derive(Clone, Debug)]
pub struct Weights {
    columns: usize,
    particles: usize,
    /// Per block of eight particles (by index), its `columns` lanes of weights.
    blocks: Vec<f32x8>,
    /// Per block, the rest positions.
    rest: Vec<Vec3x8>,
}

impl Weights {
    /// Computes the weights of `handles` on `lattice`, whose particles rest at `rest`
    /// (by index; the positions `V̄` the handles' targets are given against). Refuses a
    /// factor over `limit` bytes.
    pub fn compute(
        lattice: &Lattice,
        rest: &[Vec3],
        handles: &HandleSet,
        limit: u64,
    ) -> Result<Self> {
        let n = lattice.len();
        let a = smoothness_matrix(lattice);
        let rows = classify(lattice, rest, handles);
        // the unknowns in the order `classify` numbered them
        let mut free = Vec::new();
        for (i, row) in rows.iter().enumerate() {
            if let Row::Free(f) = *row {
                free.resize(free.len().max(f + 1), 0);
                free[f] = i as u32;
            }
        }
        let h = handles.columns();
        let mut dense = vec![0.0f64; n * h];
        for i in 0..n as u32 {
            if let Row::Follows(k) = rows[i as usize] {
                let first = handles.first_column(k);
                let j = handles.coefficients(k, i, rest);
                let width = handles.handles()[k].columns();
                dense[i as usize * h + first..][..width].copy_from_slice(&j[..width]);
            }
        }
        if !free.is_empty() {
            let solved = solve_free(&a, &rows, &free, &dense, h, limit)?;
            for (f, &i) in free.iter().enumerate() {
                dense[i as usize * h..][..h].copy_from_slice(&solved[f * h..][..h]);
            }
        }
        Ok(Self::from_dense(&dense, h, rest))
    }

    /// Weights from a dense row-major `W` (`columns` entries per particle) for
    /// particles resting at `rest`, laid out in blocks of eight particles.
    pub fn from_dense(dense: &[f64], columns: usize, rest: &[Vec3]) -> Self {
        let particles = rest.len();
        let block_count = particles.div_ceil(LANES);
        let mut blocks = vec![f32x8::ZERO; block_count * columns];
        let mut rest_blocks = vec![Vec3x8::default(); block_count];
        for b in 0..block_count {
            let lanes = b * LANES..((b + 1) * LANES).min(particles);
            for c in 0..columns {
                let mut lane = [0.0f32; LANES];
                for (l, i) in lanes.clone().enumerate() {
                    lane[l] = dense[i * columns + c] as f32;
                }
                blocks[b * columns + c] = f32x8::from(lane);
            }
            let mut lane = [Vec3A::ZERO; LANES];
            for (l, i) in lanes.enumerate() {
                lane[l] = rest[i].into();
            }
            rest_blocks[b] = Vec3x8::from_lanes(lane);
        }
        Self {
            columns,
            particles,
            blocks,
            rest: rest_blocks,
        }
    }

    /// The parameters per coordinate (handle columns).
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// Particle `i`'s row of `W`, into `out` (one entry per column).
    pub fn row_into(&self, i: u32, out: &mut [f64]) {
        let (b, l) = (i as usize / LANES, i as usize % LANES);
        for (c, o) in out.iter_mut().enumerate().take(self.columns) {
            *o = self.blocks[b * self.columns + c].to_array()[l] as f64;
        }
    }

    /// Particle `i`'s row of `W`.
    pub fn row(&self, i: u32) -> Vec<f64> {
        let mut out = vec![0.0; self.columns];
        self.row_into(i, &mut out);
        out
    }

    /// The posed positions `V = V̄ + W ΔH` (by particle index; removed particles at
    /// rest) for the parameters' displacements `dh` (one per column,
    /// [`HandleSet::displacements`]). Parallel over blocks; the same on any number of
    /// threads.
    ///
    /// # Panics
    /// If `dh` or `out` have the wrong length.
    pub fn pose(&self, dh: &[Vec3], out: &mut [Vec3]) {
        assert_eq!(dh.len(), self.columns, "one displacement per column");
        assert_eq!(out.len(), self.particles, "one position per particle");
        let dh: Vec<Vec3x8> = dh.iter().map(|&d| Vec3x8::splat(d.into())).collect();
        out.par_chunks_mut(LANES * 64)
            .enumerate()
            .for_each(|(chunk, out)| {
                for (k, out) in out.chunks_mut(LANES).enumerate() {
                    let b = chunk * 64 + k;
                    let w = &self.blocks[b * self.columns..][..self.columns];
                    let v = pose_block::<f32x8>(Vec3x8::load(&self.rest[b]), w, &dh);
                    for (o, x) in out.iter_mut().zip(v.to_lanes()) {
                        *o = x.into();
                    }
                }
            });
    }
}

/// `v̄ + Σ_c w_c Δh_c` for eight particles: their rest positions `rest`, their weights
/// `w` (one lane set per column) and the columns' displacements `dh`.
#[inline(always)]
fn pose_block<L: Lane>(rest: Vec3x8<L>, w: &[f32x8], dh: &[Vec3x8]) -> Vec3x8<L> {
    w.iter().zip(dh).fold(rest, |v, (&w, d)| {
        Vec3x8::load(d).mul_add(L::from_stored(w), v)
    })
}

/// Which particles follow a handle (its own, and those of pieces the handles do not
/// pin) and which are solved for.
fn classify(lattice: &Lattice, rest: &[Vec3], handles: &HandleSet) -> Vec<Row> {
    let mut rows = vec![Row::Removed; lattice.len()];
    for (k, p) in handles.constrained() {
        rows[p as usize] = Row::Follows(k);
    }
    let labels = lattice.pieces();
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); labels.count];
    for i in lattice.live_particles() {
        members[labels.label[i as usize] as usize].push(i);
    }
    let tolerance = 0.25 * lattice.spacing();
    let mut free = 0;
    for piece in &members {
        let held: Vec<Vec3> = piece
            .iter()
            .filter(|&&i| rows[i as usize] != Row::Removed)
            .map(|&i| rest[i as usize])
            .collect();
        let all: Vec<Vec3> = piece.iter().map(|&i| rest[i as usize]).collect();
        if affine_dimension(&held, tolerance) == affine_dimension(&all, tolerance) {
            for &i in piece {
                if rows[i as usize] == Row::Removed {
                    rows[i as usize] = Row::Free(free);
                    free += 1;
                }
            }
        } else {
            for &i in piece {
                if rows[i as usize] == Row::Removed {
                    rows[i as usize] =
                        Row::Follows(nearest_handle(rest[i as usize], handles, rest));
                }
            }
        }
    }
    rows
}

/// The handle with the particle nearest `x` at rest (the lowest index among equals).
fn nearest_handle(x: Vec3, handles: &HandleSet, rest: &[Vec3]) -> usize {
    let mut best = (f32::INFINITY, 0);
    for (k, p) in handles.constrained() {
        let d = rest[p as usize].distance_squared(x);
        if d < best.0 {
            best = (d, k);
        }
    }
    best.1
}

/// The dimension of the affine span of `points` (−1 for none), to `tolerance`: the
/// farthest point from the first, from their line, from their plane.
fn affine_dimension(points: &[Vec3], tolerance: f32) -> i32 {
    let Some(&o) = points.first() else { return -1 };
    let farthest = |f: &dyn Fn(Vec3) -> f32| {
        points
            .iter()
            .map(|&p| (f(p), p))
            .fold((0.0f32, o), |a, b| if b.0 > a.0 { b } else { a })
    };
    let (d1, p1) = farthest(&|p| p.distance(o));
    if d1 <= tolerance {
        return 0;
    }
    let u = (p1 - o) / d1;
    let (d2, p2) = farthest(&|p| (p - o).reject_from_normalized(u).length());
    if d2 <= tolerance {
        return 1;
    }
    let n = u.cross(p2 - o).normalize();
    let (d3, _) = farthest(&|p| (p - o).dot(n).abs());
    if d3 <= tolerance { 2 } else { 3 }
}

/// Solves `(T A Tᵀ) X = −T A Sᵀ J` for the free particles (row-major, `h` columns);
/// `dense` holds the rows `J` of the particles that follow handles.
fn solve_free(
    a: &SymmetricMatrix,
    rows: &[Row],
    free: &[u32],
    dense: &[f64],
    h: usize,
    limit: u64,
) -> Result<Vec<f64>> {
    let index = |j: u32| match rows[j as usize] {
        Row::Free(f) => Some(f),
        _ => None,
    };
    let mut rhs = vec![0.0f64; free.len() * h];
    let mut entries = Vec::new();
    for (f, &i) in free.iter().enumerate() {
        for (j, v) in a.row(i) {
            match index(j) {
                Some(g) if g <= f => entries.push(Triplet::new(f, g, v)),
                Some(_) => {}
                None => {
                    for c in 0..h {
                        rhs[f * h + c] -= v * dense[j as usize * h + c];
                    }
                }
            }
        }
    }
    let factor = factor_or_regularised(free.len(), entries, limit)?;
    let mut solved = vec![0.0f64; free.len() * h];
    let batches: Vec<usize> = (0..h).step_by(BATCH).collect();
    let columns: Vec<Vec<[f64; BATCH]>> = batches
        .par_iter()
        .map(|&first| {
            let width = BATCH.min(h - first);
            let mut b = vec![[0.0f64; BATCH]; free.len()];
            for (f, row) in b.iter_mut().enumerate() {
                row[..width].copy_from_slice(&rhs[f * h + first..][..width]);
            }
            factor.solve_in_place_with(&mut b, &mut SolveScratch::default());
            b
        })
        .collect();
    for (&first, b) in batches.iter().zip(&columns) {
        for (f, x) in b.iter().enumerate() {
            for c in 0..BATCH.min(h - first) {
                solved[f * h + first + c] = x[c];
            }
        }
    }
    Ok(solved)
}

/// Factors the free block; a block that is singular all the same (a piece whose
/// lattice hinges at a particle with no stencil across it) is factored again with
/// 10⁻⁸ of its largest entry added to the diagonal, which picks the minimiser with the
/// smallest weights.
fn factor_or_regularised(
    n: usize,
    mut entries: Vec<Triplet<usize, usize, f64>>,
    limit: u64,
) -> Result<SparseCholesky> {
    let fail = |e: FactorError| {
        CleaveError::InvalidEntity(format!(
            "handles: the smoothness system cannot be solved: {e}"
        ))
    };
    match SparseCholesky::new(n, &entries, limit) {
        Err(FactorError::NotPositiveDefinite) => {
            let scale = entries.iter().fold(0.0f64, |m, e| m.max(e.val.abs()));
            entries.extend((0..n).map(|i| Triplet::new(i, i, 1e-8 * scale)));
            SparseCholesky::new(n, &entries, limit).map_err(fail)
        }
        other => other.map_err(fail),
    }
}
