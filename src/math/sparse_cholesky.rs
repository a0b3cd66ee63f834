//! A sparse Cholesky factor (faer's, with its fill-reducing ordering) that knows its
//! size before it is computed: the symbolic analysis gives the number of values the
//! factor will hold, so a factor that would pass a memory limit is refused before its
//! values are allocated (the numeric factorisation is the expensive part, in time and
//! in memory).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, MatMut, Par, Side};
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
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(rows, rows, entries)
            .map_err(|_| FactorError::NotPositiveDefinite)?;
        let symbolic = factorize_symbolic_cholesky(
            matrix.symbolic(),
            Side::Lower,
            Default::default(),
            CholeskySymbolicParams::default(),
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
    /// its values, 8 bytes each (the supernodal factor a large body gets keeps far fewer
    /// row indices than values).
    fn estimate(symbolic: &SymbolicCholesky<usize>) -> u64 {
        8 * symbolic.len_val() as u64
    }

    /// The factor's estimated size in bytes (see [`SparseCholesky::new`]).
    pub fn bytes(&self) -> u64 {
        Self::estimate(&self.symbolic)
    }

    /// Solves `A X = B` for every column of `rhs` (`B` in, `X` out).
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let mut scratch = MemBuffer::new(
            self.symbolic
                .solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
        );
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut scratch),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

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
        let mut b = Mat::<f64>::zeros(n, 2);
        for i in 0..n {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = if i + 1 < n { x[i + 1] } else { 0.0 };
            b[(i, 0)] = 2.1 * x[i] - left - right;
            b[(i, 1)] = -b[(i, 0)];
        }
        factor.solve_in_place(b.as_mut());
        for i in 0..n {
            assert!((b[(i, 0)] - x[i]).abs() < 1e-9, "{i}");
            assert!((b[(i, 1)] + x[i]).abs() < 1e-9, "{i}");
        }
        // a tridiagonal factor holds about 2n values
        assert!(factor.bytes() >= 8 * n as u64 && factor.bytes() <= 8 * 3 * n as u64);
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
        assert_eq!(
            SparseCholesky::new(0, &[], u64::MAX).unwrap_err(),
            FactorError::Empty
        );
    }
}
