//! Projective dynamics' global step (Bouaziz et al. 2014).
//!
//! The clusters' rotation fits are the local step (the Jacobi cluster pass, which adds
//! each cluster's pull `gᵢₖ − pᵢ` to its members). The global step then solves the
//! substep's objective `½|x − s|²_M/dt² + Σₖ (κₖ/2) Σᵢ wᵢ |xᵢ − cₖ(x) − Rₖ oᵢₖ|²` for
//! all positions at once with the rotations held: its Hessian
//! `A = M/dt² + Σₖ κₖ (Wₖ − wₖ wₖᵀ / Σwₖ)` (each cluster adds a weighted
//! complete-graph Laplacian on its members) is constant while the clusters, masses and
//! time step are, so it is factored once (sparse Cholesky, faer, with its fill-reducing
//! ordering) and x, y and z share the factor. Written for the increment `Δ = x − p`,
//! the right-hand side is the Jacobi particle step's numerator,
//! `rᵢ = Σₖ κₖ wᵢ (gᵢₖ − pᵢ) + (mᵢ/dt²)(sᵢ + kᵢ − pᵢ)` — Jacobi is this solve with `A`
//! replaced by a diagonal. Pinned particles are not unknowns (their increment is 0).
//!
//! Colliders and contacts, which are not in the constant matrix, are projected after
//! each global step, like every other constraint kind (see [`super::ConstraintKinds`]).
//!
//! A rigid cluster (compliance 0) has no finite stiffness: the matrix takes it as
//! [`STIFFEST`] times its members' mean `m/dt²` — so under this solver a rigid
//! material is about as stiff as a rubber of ~10 MPa at the built-in scenes' spacing
//! and time step. A compliant material keeps its stiffness; where `κ dt²/m` is far
//! above [`STIFFEST`] and contacts push its particles, they can pile up into velocity
//! (see there): such a material wants more substeps, or Jacobi. The factor is sequential (faer without
//! threads), so the result is the same for any thread count.
//!
//! The other constraint kinds' corrections in this substep (`kᵢ`) move each particle's
//! inertial target, `(mᵢ/dt²)(sᵢ + kᵢ − pᵢ)`: a contact's push is an impulse the
//! elastic solve distributes, not a displacement it undoes.

use super::{PARTICLES_PER_TASK, SolverLayout};
use faer::linalg::solvers::SolveCore;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Side};
use glam::Vec3A;
use rayon::prelude::*;

/// Stiffness given to a rigid cluster, relative to its members' mean `m/dt²`.
///
/// Contacts and colliders are projected after the global step and push single
/// particles. A body far stiffer than `m/dt²` answers such a push only through its
/// inertia: the pair is still penetrating at the next iteration, is pushed again, and
/// the pushes pile up into velocity. This cap is the largest that keeps every built-in
/// scene's outcome and lets its bodies come to rest.
pub const STIFFEST: f64 = 100.0;

/// Marker: a particle that is not an unknown (pinned).
const NOT_UNKNOWN: u32 = u32::MAX;

/// The factored global matrix and what it was built for.
#[derive(Clone, Debug)]
pub(super) struct GlobalSolve {
    /// Per particle: its row in the system, or [`NOT_UNKNOWN`].
    row_of: Vec<u32>,
    /// Per row: its particle.
    particle_of: Vec<u32>,
    /// Per row: `κᵢ wᵢ`, the weight of the particle's summed pulls in the right-hand
    /// side (its clusters' mean stiffness times its Jacobi weight).
    pull_weight: Vec<f64>,
    /// Per row: `mᵢ/dt²`.
    inertia: Vec<f64>,
    /// The factor; `None` when it could not be computed (the step then falls back to
    /// Jacobi's).
    factor: Option<Llt<usize, f64>>,
    /// The substep time step and the inverse masses the matrix was built with.
    dt: f32,
    inv_mass: Vec<f32>,
    /// Right-hand sides (rows × 3), reused.
    rhs: Mat<f64>,
}

impl SolverLayout {
    /// The projective global step after a cluster pass: solves for every particle's
    /// increment and moves it (pinned particles stay); clears the pull accumulators.
    /// Builds the factor if there is none (the substep drops one built for other
    /// clusters, masses or time step).
    pub(super) fn global_step(&mut self, dt: f32) {
        if self.global.is_none() {
            let start = std::time::Instant::now();
            self.global = Some(self.build_global(dt));
            self.factor_seconds += start.elapsed().as_secs_f64();
        }
        let Some(global) = self.global.as_mut() else {
            return;
        };
        let Some(factor) = &global.factor else {
            // no factor (see `GlobalSolve::factor`): Jacobi's particle step instead
            self.move_particles_jacobi();
            return;
        };
        for (row, &i) in global.particle_of.iter().enumerate() {
            let i = i as usize;
            let r = self.pulls[i].as_dvec3() * global.pull_weight[row]
                + (self.predicted[i] + self.corrections[i] - self.positions[i]).as_dvec3()
                    * global.inertia[row];
            for axis in 0..3 {
                global.rhs[(row, axis)] = r[axis];
            }
        }
        factor.solve_in_place_with_conj(Conj::No, global.rhs.as_mut());
        let (rhs, row_of) = (&global.rhs, &global.row_of);
        self.positions
            .par_iter_mut()
            .zip(self.carry.par_iter_mut())
            .zip(self.pulls.par_iter_mut())
            .zip(row_of.par_iter())
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(((p, carry), pull), &row)| {
                *pull = Vec3A::ZERO;
                if row != NOT_UNKNOWN {
                    let row = row as usize;
                    let step = Vec3A::new(
                        rhs[(row, 0)] as f32,
                        rhs[(row, 1)] as f32,
                        rhs[(row, 2)] as f32,
                    );
                    *p += step;
                    *carry += step;
                }
            });
    }

    /// Assembles and factors the global matrix for the current clusters, masses and
    /// time step.
    fn build_global(&self, dt: f32) -> GlobalSolve {
        let inv_dt2 = 1.0 / (dt as f64 * dt as f64);
        let mass = |i: usize| 1.0 / self.inv_mass[i] as f64;
        let Assembly {
            row_of,
            particle_of,
            entries,
            stiffness_sum,
        } = self.assemble(dt);
        let rows = particle_of.len();
        let pull_weight = particle_of
            .iter()
            .map(|&i| {
                let w = self.inv_count[i as usize] as f64;
                // mean stiffness over its clusters (n = 1/w of them), times w
                stiffness_sum[i as usize] * w * w
            })
            .collect();
        let inertia = particle_of
            .iter()
            .map(|&i| mass(i as usize) * inv_dt2)
            .collect();
        let factor = factor_lower(rows, &entries);
        if factor.is_none() && rows > 0 {
            tracing::warn!(
                rows,
                "projective dynamics: the global matrix could not be factored; \
                 using Jacobi steps"
            );
        }
        GlobalSolve {
            row_of,
            particle_of,
            pull_weight,
            inertia,
            factor,
            dt,
            inv_mass: self.inv_mass.clone(),
            rhs: Mat::zeros(rows, 3),
        }
    }
}

/// The global matrix's lower triangle and what it was built from.
struct Assembly {
    row_of: Vec<u32>,
    particle_of: Vec<u32>,
    entries: Vec<Triplet<usize, usize, f64>>,
    /// Per particle: the sum of its clusters' stiffnesses.
    stiffness_sum: Vec<f64>,
}

impl SolverLayout {
    /// The global matrix (lower triangle, duplicates to be summed) for time step `dt`.
    fn assemble(&self, dt: f32) -> Assembly {
        let n = self.positions.len();
        let inv_dt2 = 1.0 / (dt as f64 * dt as f64);
        let mass = |i: usize| 1.0 / self.inv_mass[i] as f64;
        let mut row_of = vec![NOT_UNKNOWN; n];
        let mut particle_of = Vec::new();
        for (i, &inv_mass) in self.inv_mass.iter().enumerate() {
            if inv_mass > 0.0 {
                row_of[i] = particle_of.len() as u32;
                particle_of.push(i as u32);
            }
        }
        let mut entries: Vec<Triplet<usize, usize, f64>> = particle_of
            .iter()
            .enumerate()
            .map(|(row, &i)| Triplet::new(row, row, mass(i as usize) * inv_dt2))
            .collect();
        let mut stiffness_sum = vec![0.0f64; n];
        for (k, range) in self.cluster_range.iter().enumerate() {
            let members = &self.member_particle[range[0] as usize..range[1] as usize];
            let free: Vec<u32> = members
                .iter()
                .copied()
                .filter(|&m| row_of[m as usize] != NOT_UNKNOWN)
                .collect();
            if free.is_empty() {
                continue;
            }
            let mean_mass = free.iter().map(|&m| mass(m as usize)).sum::<f64>() / free.len() as f64;
            let rigid = STIFFEST * mean_mass * inv_dt2;
            let compliance = self.compliance[k] as f64;
            let kappa = if compliance > 0.0 {
                1.0 / compliance
            } else {
                rigid
            };
            let total: f64 = members.iter().map(|&m| self.weight(m) as f64).sum();
            for &m in members {
                stiffness_sum[m as usize] += kappa;
            }
            // κ (W − w wᵀ/Σw) on the free members, lower triangle
            for &a in &free {
                let (wa, ra) = (self.weight(a) as f64, row_of[a as usize] as usize);
                for &b in &free {
                    let (wb, rb) = (self.weight(b) as f64, row_of[b as usize] as usize);
                    if rb > ra {
                        continue;
                    }
                    let diagonal = if a == b { wa } else { 0.0 };
                    entries.push(Triplet::new(ra, rb, kappa * (diagonal - wa * wb / total)));
                }
            }
        }
        Assembly {
            row_of,
            particle_of,
            entries,
            stiffness_sum,
        }
    }

    /// Test access to the matrix: its size and lower-triangle entries.
    #[cfg(test)]
    fn global_entries(&self, dt: f32) -> (usize, Vec<Triplet<usize, usize, f64>>) {
        let a = self.assemble(dt);
        (a.particle_of.len(), a.entries)
    }
}

impl GlobalSolve {
    /// Whether this was built for time step `dt` and these inverse masses.
    pub(super) fn built_for(&self, dt: f32, inv_mass: &[f32]) -> bool {
        self.dt == dt && self.inv_mass == inv_mass
    }
}

/// The Cholesky factor of the symmetric matrix whose lower triangle `entries` gives
/// (duplicates summed); `None` for an empty matrix or one that is not positive definite.
fn factor_lower(rows: usize, entries: &[Triplet<usize, usize, f64>]) -> Option<Llt<usize, f64>> {
    if rows == 0 {
        return None;
    }
    let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(rows, rows, entries).ok()?;
    let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower).ok()?;
    Llt::try_new_with_symbolic(symbolic, matrix.as_ref(), Side::Lower).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::{ClusterSpec, TEST_DT};
    use faer::Mat;
    use glam::Vec3;

    /// A 4×3×3 block with 2×2×2 clusters at every cell, compliant, one corner pinned.
    fn block() -> SolverLayout {
        let index = |x: u32, y: u32, z: u32| x * 9 + y * 3 + z;
        let rest: Vec<Vec3> = (0..4)
            .flat_map(|x| {
                (0..3)
                    .flat_map(move |y| (0..3).map(move |z| Vec3::new(x as f32, y as f32, z as f32)))
            })
            .collect();
        let mut clusters = vec![];
        for x in 0..3 {
            for y in 0..2 {
                for z in 0..2 {
                    clusters.push(
                        (0..8)
                            .map(|b| index(x + (b & 1), y + ((b >> 1) & 1), z + (b >> 2)))
                            .collect::<Vec<u32>>(),
                    );
                }
            }
        }
        let specs = clusters.iter().map(|m| ClusterSpec {
            members: m,
            compliance: 1e-3,
            rotation: glam::Quat::IDENTITY,
        });
        let mut l = SolverLayout::new(&rest, specs, SolverMode::Projective);
        l.inv_mass[0] = 0.0;
        l
    }

    /// The full matrix of the lower-triangle entries, summed.
    fn dense(rows: usize, entries: &[Triplet<usize, usize, f64>]) -> Mat<f64> {
        let mut a = Mat::<f64>::zeros(rows, rows);
        for e in entries {
            a[(e.row, e.col)] += e.val;
            if e.row != e.col {
                a[(e.col, e.row)] += e.val;
            }
        }
        a
    }

    #[test]
    fn the_global_matrix_is_symmetric_positive_definite_and_its_factor_solves_it() {
        let l = block();
        let (rows, entries) = l.global_entries(TEST_DT);
        assert_eq!(
            rows,
            l.particle_count() - 1,
            "the pinned particle is no unknown"
        );
        let a = dense(rows, &entries);
        // symmetric by construction; positive definite: a dense Cholesky succeeds and
        // every diagonal entry of its factor is positive
        let llt = a.llt(faer::Side::Lower).expect("positive definite");
        assert!((0..rows).all(|i| llt.L()[(i, i)] > 0.0));
        // the sparse factor's solve equals the dense one
        let factor = factor_lower(rows, &entries).expect("a factor");
        let rhs = Mat::<f64>::from_fn(rows, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let mut sparse = rhs.clone();
        factor.solve_in_place_with_conj(Conj::No, sparse.as_mut());
        let mut dense_solution = rhs.clone();
        llt.solve_in_place_with_conj(Conj::No, dense_solution.as_mut());
        let error = (&sparse - &dense_solution).norm_max();
        assert!(error < 1e-9 * dense_solution.norm_max(), "{error}");
        // and it solves the system
        let residual = (&a * &sparse - &rhs).norm_max();
        assert!(residual < 1e-9 * rhs.norm_max(), "{residual}");
    }

    #[test]
    fn a_layout_with_every_particle_pinned_or_one_particle_has_no_factor_and_stays_finite() {
        let mut l = block();
        l.inv_mass.iter_mut().for_each(|w| *w = 0.0);
        let global = l.build_global(TEST_DT);
        assert!(global.factor.is_none());
        let mut kinds = crate::solver::ConstraintKinds::default();
        l.solve(3, TEST_DT, &mut kinds);
        assert!(l.positions.iter().all(|p| p.is_finite()));
        let one = [ClusterSpec {
            members: &[0],
            compliance: 0.0,
            rotation: glam::Quat::IDENTITY,
        }];
        let mut single = SolverLayout::new(&[Vec3::ONE], one, SolverMode::Projective);
        single.positions[0].y -= 0.1;
        single.solve(3, TEST_DT, &mut kinds);
        assert!(single.positions[0].is_finite());
    }
}
