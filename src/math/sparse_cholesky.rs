//! A sparse Cholesky factor (faer's supernodal factorisation, with its fill-reducing
//! ordering) that knows its size before it is computed, and solves several right-hand
//! sides at once.
//!
//! The symbolic analysis gives the number of values the factor will hold, so a factor
//! that would pass a memory limit is refused before its values are allocated (the
//! numeric factorisation is the expensive part, in time and in memory).
//!
//! The triangular solves are this module's: a factor here is solved many more times
//! than it is computed (projective dynamics solves twice per iteration until its matrix
//! changes), and a matrix whose supernodes are mostly one or two columns wide — the
//! particles of projective dynamics' matrix, each eliminated on its own — spends most
//! of a general solve's time setting up tiny dense products. These walk each
//! supernode's dense block directly, with the right-hand sides of a row side by side
//! (`[f64; K]`), so x, y and z share every load of the factor.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Par, Side};
use std::sync::Arc;

/// Why a matrix has no factor.
#[derive(Clone, Debug, PartialEq)]
pub enum FactorError {
    /// The matrix has no rows.
    Empty,
    /// The factor would take `bytes`, more than the `limit`.
    OverBudget {
        /// Estimated size of the factor (its values and the analysis), bytes.
        bytes: u64,
        /// The limit it was given, bytes.
        limit: u64,
    },
    /// The entries do not make a symmetric positive definite matrix (or faer could not
    /// allocate what it needed).
    NotPositiveDefinite,
    /// An entry is NaN or infinite.
    NotFinite,
}

impl std::fmt::Display for FactorError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FactorError::Empty => write!(f, "the matrix is empty"),
            FactorError::OverBudget { bytes, limit } => write!(
                f,
                "its factor would take {:.1} MB, over the {:.1} MB the memory budget \
                 (memory_budget_gb) leaves it beside its particles",
                *bytes as f64 / 1e6,
                *limit as f64 / 1e6
            ),
            FactorError::NotPositiveDefinite => {
                write!(f, "the matrix is not positive definite")
            }
            FactorError::NotFinite => write!(f, "the matrix has an entry that is not finite"),
        }
    }
}

/// The `LLᵀ` factor of a sparse symmetric positive definite matrix.
#[derive(Clone, Debug)]
pub struct SparseCholesky {
    /// The analysis (shared by copies: it does not change with the values).
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl SparseCholesky {
    /// Factors the `rows × rows` matrix whose lower triangle `entries` gives (duplicates
    /// summed), unless its factor would take more than `limit` bytes. Sequential, so
    /// the factor is the same on any number of threads.
    pub fn new(
        rows: usize,
        entries: &[Triplet<usize, usize, f64>],
        limit: u64,
    ) -> Result<Self, FactorError> {
        if rows == 0 {
            return Err(FactorError::Empty);
        }
        if entries.iter().any(|e| !e.val.is_finite()) {
            return Err(FactorError::NotFinite);
        }
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(rows, rows, entries)
            .map_err(|_| FactorError::NotPositiveDefinite)?;
        let symbolic = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            Default::default(),
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            },
        )
        .map_err(|_| FactorError::NotPositiveDefinite)?;
        let bytes = Self::estimate(&symbolic);
        if bytes > limit {
            return Err(FactorError::OverBudget { bytes, limit });
        }
        let mut values = vec![0.0; symbolic.len_val()];
        let mut scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        )
        .map_err(|_| FactorError::NotPositiveDefinite)?;
        symbolic
            .factorize_numeric_llt(
                &mut values,
                matrix.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|_| FactorError::NotPositiveDefinite)?;
        Ok(Self {
            symbolic: Arc::new(symbolic),
            values,
        })
    }

    /// The factor's size as [`SparseCholesky::new`] estimates it before computing it:
    /// its values, 8 bytes each (a supernodal factor keeps far fewer row indices than
    /// values).
    fn estimate(symbolic: &SymbolicCholesky<usize>) -> u64 {
        8 * symbolic.len_val() as u64
    }

    /// The factor's estimated size in bytes (see [`SparseCholesky::new`]).
    pub fn bytes(&self) -> u64 {
        Self::estimate(&self.symbolic)
    }

    /// Solves `A X = B` with the `K` right-hand sides of each row side by side in
    /// `rhs` (`B` in, `X` out). Sequential: the same on any number of threads.
    ///
    /// # Panics
    /// If `rhs` does not have one entry per row of the matrix.
    pub fn solve_in_place<const K: usize>(&self, rhs: &mut [[f64; K]]) {
        self.solve_in_place_with(rhs, &mut SolveScratch::default());
    }

    /// [`SparseCholesky::solve_in_place`] with buffers kept from one solve to the next
    /// (a solver that solves every iteration allocates nothing).
    pub fn solve_in_place_with<const K: usize>(
        &self,
        rhs: &mut [[f64; K]],
        scratch: &mut SolveScratch<K>,
    ) {
        assert_eq!(
            rhs.len(),
            self.symbolic.nrows(),
            "one right-hand side per row"
        );
        // into the factor's order, where L Lᵀ is the matrix
        let SolveScratch { x, below } = scratch;
        x.clear();
        match self.symbolic.perm() {
            Some(perm) => x.extend(perm.arrays().0.iter().map(|&i| rhs[i])),
            None => x.extend_from_slice(rhs),
        }
        // faer picks a supernodal factor when asked, but a matrix with no elimination
        // work (a single particle, or particles held apart) comes out simplicial
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => {
                supernodal_solve(SupernodalLltRef::new(symbolic, &self.values), x, below)
            }
            SymbolicCholeskyRaw::Simplicial(symbolic) => {
                simplicial_solve(symbolic.col_ptr(), symbolic.row_idx(), &self.values, x)
            }
        }
        match self.symbolic.perm() {
            Some(perm) => {
                for (&i, xi) in perm.arrays().0.iter().zip(x.iter()) {
                    rhs[i] = *xi;
                }
            }
            None => rhs.copy_from_slice(x),
        }
    }
}

/// Solves `L Lᵀ x = b` in place (`x` holds `b`) with a supernodal factor, supernode by
/// supernode.
fn supernodal_solve<const K: usize>(
    factor: SupernodalLltRef<'_, usize, f64>,
    x: &mut [[f64; K]],
    below: &mut Vec<[f64; K]>,
) {
    let symbolic = factor.symbolic();
    // L y = b: each supernode's diagonal block solved in place, then the rows of its
    // pattern updated once
    for s in 0..symbolic.n_supernodes() {
        let node = factor.supernode(s);
        let (block, start, pattern) = (node.val(), node.start(), node.pattern());
        let width = block.ncols();
        below.clear();
        below.resize(pattern.len(), [0.0; K]);
        for c in 0..width {
            let column = column_slice(block, c);
            let xj = x[start + c].map(|v| v / column[c]);
            x[start + c] = xj;
            for r in c + 1..width {
                sub_scaled(&mut x[start + r], column[r], &xj);
            }
            for (b, &l) in below.iter_mut().zip(&column[width..]) {
                sub_scaled(b, l, &xj);
            }
        }
        for (&i, b) in pattern.iter().zip(below.iter()) {
            add(&mut x[i], b);
        }
    }
    // Lᵀ x = y, backwards: each column gathers the rows below it
    for s in (0..symbolic.n_supernodes()).rev() {
        let node = factor.supernode(s);
        let (block, start, pattern) = (node.val(), node.start(), node.pattern());
        let width = block.ncols();
        below.clear();
        below.extend(pattern.iter().map(|&i| x[i]));
        for c in (0..width).rev() {
            let column = column_slice(block, c);
            let mut xj = x[start + c];
            for r in c + 1..width {
                sub_scaled(&mut xj, column[r], &x[start + r]);
            }
            for (b, &l) in below.iter().zip(&column[width..]) {
                sub_scaled(&mut xj, l, b);
            }
            x[start + c] = xj.map(|v| v / column[c]);
        }
    }
}

/// Solves `L Lᵀ x = b` in place (`x` holds `b`) with a simplicial factor: `L` by
/// columns, `col_ptr`, `row_idx` and `values` (each column's diagonal among its rows).
fn simplicial_solve<const K: usize>(
    col_ptr: &[usize],
    row_idx: &[usize],
    values: &[f64],
    x: &mut [[f64; K]],
) {
    let column = |j: usize| {
        let range = col_ptr[j]..col_ptr[j + 1];
        row_idx[range.clone()].iter().zip(&values[range])
    };
    let diagonal = |j: usize| column(j).find(|(i, _)| **i == j).map_or(1.0, |(_, l)| *l);
    for j in 0..x.len() {
        let xj = x[j].map(|v| v / diagonal(j));
        x[j] = xj;
        for (&i, &l) in column(j).filter(|(i, _)| **i > j) {
            sub_scaled(&mut x[i], l, &xj);
        }
    }
    for j in (0..x.len()).rev() {
        let mut xj = x[j];
        for (&i, &l) in column(j).filter(|(i, _)| **i > j) {
            sub_scaled(&mut xj, l, &x[i]);
        }
        x[j] = xj.map(|v| v / diagonal(j));
    }
}

/// The buffers of a solve with `K` right-hand sides per row.
#[derive(Clone, Debug)]
pub struct SolveScratch<const K: usize> {
    /// The right-hand sides in the factor's order, solved there.
    x: Vec<[f64; K]>,
    /// The rows of a supernode's pattern, side by side (gathered once per supernode, so
    /// each column's products run over contiguous memory).
    below: Vec<[f64; K]>,
}

impl<const K: usize> Default for SolveScratch<K> {
    fn default() -> Self {
        Self {
            x: Vec::new(),
            below: Vec::new(),
        }
    }
}

/// Column `c` of a supernode's block (column-major, so contiguous).
#[inline(always)]
fn column_slice(block: faer::MatRef<'_, f64>, c: usize) -> &[f64] {
    block
        .col(c)
        .try_as_col_major()
        .expect("a supernode's block is column-major")
        .as_slice()
}

/// `x += y`, side by side.
#[inline(always)]
fn add<const K: usize>(x: &mut [f64; K], y: &[f64; K]) {
    for (x, y) in x.iter_mut().zip(y) {
        *x += y;
    }
}

/// `x −= l · y`, side by side.
#[inline(always)]
fn sub_scaled<const K: usize>(x: &mut [f64; K], l: f64, y: &[f64; K]) {
    for (x, y) in x.iter_mut().zip(y) {
        *x -= l * y;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lower triangle of the 1-D Laplacian plus `shift` on the diagonal.
    fn path(n: usize, shift: f64) -> Vec<Triplet<usize, usize, f64>> {
        let mut entries: Vec<_> = (0..n).map(|i| Triplet::new(i, i, 2.0 + shift)).collect();
        entries.extend((1..n).map(|i| Triplet::new(i, i - 1, -1.0)));
        entries
    }

    #[test]
    fn the_factor_solves_its_matrix_and_is_refused_past_its_limit() {
        let n = 50;
        let factor = SparseCholesky::new(n, &path(n, 0.1), u64::MAX).unwrap();
        // A x for x = (1, 2, 3, …), then solved back
        let x: Vec<f64> = (0..n).map(|i| i as f64 + 1.0).collect();
        let mut b = vec![[0.0; 2]; n];
        for i in 0..n {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x[i + 1] } else { 0.0 };
            b[i][0] = 2.1 * x[i] - left - right;
            b[i][1] = -b[i][0];
        }
        factor.solve_in_place(&mut b);
        for i in 0..n {
            assert!((b[i][0] - x[i]).abs() < 1e-9, "{i}");
            assert!((b[i][1] + x[i]).abs() < 1e-9, "{i}");
        }
        // a tridiagonal factor holds 2n − 1 values; relaxed supernodes add zeros, but
        // fewer than a dense factor's n(n+1)/2
        assert!(
            factor.bytes() >= 8 * (2 * n - 1) as u64 && factor.bytes() < 8 * (n * n / 2) as u64,
            "{}",
            factor.bytes()
        );
        assert_eq!(
            SparseCholesky::new(n, &path(n, 0.1), factor.bytes() - 1).unwrap_err(),
            FactorError::OverBudget {
                bytes: factor.bytes(),
                limit: factor.bytes() - 1
            }
        );
        assert_eq!(
            SparseCholesky::new(n, &path(n, -3.0), u64::MAX).unwrap_err(),
            FactorError::NotPositiveDefinite
        );
        let mut poisoned = path(n, 0.1);
        poisoned[7].val = f64::NAN;
        assert_eq!(
            SparseCholesky::new(n, &poisoned, u64::MAX).unwrap_err(),
            FactorError::NotFinite
        );
        assert_eq!(
            SparseCholesky::new(0, &[], u64::MAX).unwrap_err(),
            FactorError::Empty
        );
    }

    /// `A x` for the symmetric matrix whose lower triangle `entries` gives.
    fn times(n: usize, entries: &[Triplet<usize, usize, f64>], x: &[f64]) -> Vec<f64> {
        let mut b = vec![0.0; n];
        for e in entries {
            b[e.row] += e.val * x[e.col];
            if e.row != e.col {
                b[e.col] += e.val * x[e.row];
            }
        }
        b
    }

    #[test]
    fn every_shape_of_factor_solves_one_unknown_disconnected_blocks_and_all() {
        // one unknown; unknowns held apart (diagonal); a pair beside single ones; the
        // path: the smallest and the disconnected come out simplicial, the rest not
        let pair_and_singles = vec![
            Triplet::new(0, 0, 2.0),
            Triplet::new(1, 1, 3.0),
            Triplet::new(2, 2, 2.0),
            Triplet::new(2, 1, -1.0),
            Triplet::new(3, 3, 5.0),
        ];
        let diagonal: Vec<_> = (0..6).map(|i| Triplet::new(i, i, 1.0 + i as f64)).collect();
        type Entries = Vec<Triplet<usize, usize, f64>>;
        let cases: Vec<(usize, Entries)> = vec![
            (1, vec![Triplet::new(0, 0, 4.0)]),
            (6, diagonal),
            (4, pair_and_singles),
            (3, path(3, 0.5)),
            (30, path(30, 0.5)),
        ];
        let mut simplicial = 0;
        for (n, entries) in cases {
            let factor = SparseCholesky::new(n, &entries, u64::MAX).unwrap();
            simplicial +=
                matches!(factor.symbolic.raw(), SymbolicCholeskyRaw::Simplicial(_)) as usize;
            let x: Vec<f64> = (0..n).map(|i| 0.5 + i as f64).collect();
            let b = times(n, &entries, &x);
            let mut rhs: Vec<[f64; 3]> = b.iter().map(|&v| [v, -v, 2.0 * v]).collect();
            factor.solve_in_place(&mut rhs);
            for i in 0..n {
                let expected = [x[i], -x[i], 2.0 * x[i]];
                for k in 0..3 {
                    assert!((rhs[i][k] - expected[k]).abs() < 1e-12, "{n}: {i} {k}");
                }
            }
        }
        assert!(
            simplicial >= 2,
            "{simplicial} simplicial factors: the path not exercised"
        );
    }

    #[test]
    fn wide_supernodes_and_several_right_hand_sides_solve_as_the_matrix_says() {
        // the 7-point Laplacian of a 9³ grid plus a shift: its factor fills in into
        // wide supernodes with long patterns
        let n = 9;
        let index = |x: usize, y: usize, z: usize| (z * n + y) * n + x;
        let rows = n * n * n;
        let mut entries = vec![];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let i = index(x, y, z);
                    entries.push(Triplet::new(i, i, 6.5));
                    for j in [
                        (x > 0).then(|| index(x - 1, y, z)),
                        (y > 0).then(|| index(x, y - 1, z)),
                        (z > 0).then(|| index(x, y, z - 1)),
                    ]
                    .into_iter()
                    .flatten()
                    {
                        entries.push(Triplet::new(i, j, -1.0));
                    }
                }
            }
        }
        let factor = SparseCholesky::new(rows, &entries, u64::MAX).unwrap();
        let b: Vec<[f64; 3]> = (0..rows)
            .map(|i| [1.0, (i % 7) as f64 - 3.0, (i as f64 * 0.37).sin()])
            .collect();
        let mut x = b.clone();
        factor.solve_in_place(&mut x);
        // A x, from the entries (lower triangle mirrored), is b again
        let mut ax = vec![[0.0; 3]; rows];
        for e in &entries {
            for k in 0..3 {
                ax[e.row][k] += e.val * x[e.col][k];
                if e.row != e.col {
                    ax[e.col][k] += e.val * x[e.row][k];
                }
            }
        }
        for (got, want) in ax.iter().zip(&b) {
            for k in 0..3 {
                assert!((got[k] - want[k]).abs() < 1e-10, "{got:?} {want:?}");
            }
        }
    }
}
