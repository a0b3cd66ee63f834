//! Projective dynamics' global step (Bouaziz et al. 2014).
//!
//! The clusters' rotation fits are the local step (the Jacobi pull pass, which adds
//! each cluster's pull `gᵢₖ − pᵢ` to its members), and so are the projections of every
//! term that gives a [`ProjectiveTerm`](crate::solver::term::ProjectiveTerm)
//! (attachments, edges). The global step then solves the substep's objective for all
//! positions at once with the projections held. Its Hessian (assembled in `matrix.rs`:
//! the masses, each cluster with its centre as an unknown of its own, each term's
//! `w AᵀA`) is constant while the clusters, terms, masses and time step are, so it is
//! factored once ([`SparseCholesky`]) and x, y and z share the factor, solved together.
//! Written for the increment `Δ = x − p`, the right-hand side is the clusters' weighted
//! pulls, the terms' forces `w SᵀAᵀ(p − A S x)`, and the inertia
//! `(mᵢ/dt²)(sᵢ + kᵢ − pᵢ)` — Jacobi is this solve with the clusters' Hessian on the
//! particles replaced by its diagonal. Particles of inverse mass 0 are not unknowns
//! (their increment is 0); the clusters' centres are, with a zero right-hand side (the
//! fitted centres are their energy's minimum), and their increments are dropped.
//!
//! Terms without a projective form (contacts and colliders, whose constraints change
//! every substep) are projected after each global step; their corrections in this
//! substep (`kᵢ`) move each particle's inertial target: a contact's push is an impulse
//! the elastic solve distributes, not a displacement it undoes.
//!
//! A hard constraint (a rigid cluster, a hard edge) has no finite stiffness: the matrix
//! takes it as [`STIFFEST`](crate::solver::term::STIFFEST) times its particles' mean
//! `m/dt²`. A compliant material keeps its stiffness; where `κ dt²/m` is far above
//! `STIFFEST` and contacts push its particles, they can pile up into velocity: such a
//! material wants more substeps, or Jacobi. The factor and its solves are sequential,
//! so the result is the same for any thread count.

mod matrix;

use super::jacobi::Jacobi;
use crate::body::shape::{BYTES_PER_PARTICLE, DEFAULT_MEMORY_BUDGET_GB};
use crate::math::sparse_cholesky::{FactorError, SolveScratch, SparseCholesky};
use crate::solver::clusters::term::ClusterTerm;
use crate::solver::particles::{PARTICLES_PER_TASK, Particles};
use crate::solver::registry::Terms;
use crate::solver::term::{NO_DENSE, Substep, Unknowns};
use glam::{DVec3, Vec3A};
use matrix::{Assembly, assemble};
use rayon::prelude::*;

/// Projective dynamics' state: the factored global matrix and what it was built for.
#[derive(Clone, Debug)]
pub struct Projective {
    /// The factor (built on first use; not saved: a loaded simulation factors the same
    /// matrix again).
    global: Option<GlobalSolve>,
    /// The memory the simulation may take, bytes
    /// ([`crate::config::SimConfig::memory_budget_gb`]): the factor may take what its
    /// particles leave of it ([`BYTES_PER_PARTICLE`] each); a larger one is not built,
    /// and the global step falls back to Jacobi's.
    pub budget_bytes: u64,
    /// Seconds spent building the global factor since this state was made (the engine
    /// reports its growth over a cut).
    pub factor_seconds: f64,
    /// The terms' forces of the current iteration, by particle (scratch).
    forces: Vec<DVec3>,
}

impl Default for Projective {
    fn default() -> Self {
        Self {
            global: None,
            budget_bytes: (DEFAULT_MEMORY_BUDGET_GB as f64 * 1e9) as u64,
            factor_seconds: 0.0,
            forces: Vec::new(),
        }
    }
}

/// The factored global matrix and what it was built for.
#[derive(Clone, Debug)]
struct GlobalSolve {
    /// Per particle: its row in the system, or [`NO_DENSE`].
    row_of: Vec<u32>,
    /// Per row: its particle.
    particle_of: Vec<u32>,
    /// Per row: the weight of the particle's summed pulls in the right-hand side: its
    /// matching weight `wᵢ`, times the ratio of its clusters' stiffnesses in the matrix
    /// to their Jacobi weights, by which the pulls come weighted.
    pull_weight: Vec<f64>,
    /// Per row: `mᵢ/dt²`.
    inertia: Vec<f64>,
    /// The factor, or why there is none (the step then falls back to Jacobi's).
    factor: Result<SparseCholesky, FactorError>,
    /// What it was built for: the time step, the inverse masses, the clusters (their
    /// carry epoch changes with them) and each projective term's version.
    dt: f32,
    inv_mass: Vec<f32>,
    cluster_epoch: u64,
    term_versions: Vec<u64>,
    /// Right-hand sides, x y z side by side per row, and the solve's buffers (reused).
    rhs: Vec<[f64; 3]>,
    scratch: SolveScratch<3>,
}

/// Each projective term's version, in registered order.
fn term_versions(terms: &Terms) -> Vec<u64> {
    terms
        .iter()
        .filter_map(|t| t.projective().map(|p| p.version()))
        .collect()
}

impl Projective {
    /// Why the global step takes Jacobi steps instead of solving with its factor (the
    /// factor would pass the memory budget, or the matrix cannot be factored); `None`
    /// while it has its factor, or before it first needs one.
    pub fn fallback(&self) -> Option<&FactorError> {
        self.global
            .as_ref()
            .and_then(|g| g.factor.as_ref().err())
            .filter(|e| **e != FactorError::Empty)
    }

    /// Drops a factor built for other masses, another time step, other clusters or
    /// other terms.
    pub fn begin_substep(
        &mut self,
        clusters: &ClusterTerm,
        inv_mass: &[f32],
        dt: f32,
        terms: &Terms,
    ) {
        if self.global.as_ref().is_some_and(|g| {
            g.dt != dt
                || g.cluster_epoch != clusters.carry_epoch
                || g.inv_mass != inv_mass
                || g.term_versions != term_versions(terms)
        }) {
            self.global = None;
        }
    }

    /// The global step after a pull pass: solves for every particle's increment and
    /// moves it (particles of inverse mass 0 stay); the step goes to the clusters' carry.
    /// Clears the pulls. Builds the factor if there is none.
    pub fn global_step(
        &mut self,
        clusters: &mut ClusterTerm,
        particles: &mut Particles,
        jacobi: &mut Jacobi,
        terms: &mut Terms,
        step: &Substep,
    ) {
        if self.global.is_none() {
            let start = std::time::Instant::now();
            let global = build(
                clusters,
                &particles.inv_mass,
                terms,
                step,
                self.budget_bytes,
            );
            self.global = Some(global);
            self.factor_seconds += start.elapsed().as_secs_f64();
        }
        let Some(global) = self.global.as_mut() else {
            return;
        };
        let Ok(factor) = &global.factor else {
            // no factor (see `GlobalSolve::factor`): Jacobi's particle step instead
            jacobi.move_particles(clusters, particles);
            return;
        };
        let unknowns = Unknowns {
            row_of: &global.row_of,
            inv_mass: &particles.inv_mass,
        };
        self.forces.clear();
        self.forces.resize(particles.len(), DVec3::ZERO);
        for (term, seconds) in terms.iter_timed() {
            if let Some(form) = term.projective() {
                let start = std::time::Instant::now();
                form.add_forces(
                    step,
                    &unknowns,
                    &particles.positions,
                    &mut particles.orientations,
                    &mut self.forces,
                );
                seconds.iterations += start.elapsed().as_secs_f64();
            }
        }
        let (pulls, forces) = (&jacobi.pulls, &self.forces);
        for (row, &i) in global.particle_of.iter().enumerate() {
            let i = i as usize;
            let r = pulls[i].as_dvec3() * global.pull_weight[row]
                + (particles.predicted[i] + particles.corrections[i] - particles.positions[i])
                    .as_dvec3()
                    * global.inertia[row]
                + forces[i];
            global.rhs[row] = r.to_array();
        }
        // the cluster centres' rows: their gradient is zero at the fitted centres
        global.rhs[global.particle_of.len()..].fill([0.0; 3]);
        factor.solve_in_place_with(&mut global.rhs, &mut global.scratch);
        let (rhs, row_of) = (&global.rhs, &global.row_of);
        particles
            .positions
            .par_iter_mut()
            .zip(clusters.carry.par_iter_mut())
            .zip(jacobi.pulls.par_iter_mut())
            .zip(row_of.par_iter())
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(((p, carry), pull), &row)| {
                *pull = Vec3A::ZERO;
                if row != NO_DENSE {
                    let step = DVec3::from_array(rhs[row as usize]).as_vec3a();
                    *p += step;
                    *carry += step;
                }
            });
    }
}

/// Assembles and factors the global matrix for the current clusters, terms, masses and
/// time step, within `budget_bytes` less its particles' share.
fn build(
    clusters: &ClusterTerm,
    inv_mass: &[f32],
    terms: &Terms,
    step: &Substep,
    budget_bytes: u64,
) -> GlobalSolve {
    let inv_dt2 = 1.0 / (step.dt as f64 * step.dt as f64);
    let Assembly {
        row_of,
        particle_of,
        rows,
        entries,
        stiffness_sum,
    } = assemble(clusters, inv_mass, terms, step);
    // the pulls come weighted by the clusters' Jacobi stiffnesses; the matrix's are the
    // same for compliant clusters and capped for rigid ones, so each particle's pulls
    // are scaled by the ratio of the two sums (exact unless a particle has clusters of
    // both kinds), times its matching weight
    let pull_weight = particle_of
        .iter()
        .map(|&i| {
            let i = i as usize;
            let w = clusters.inv_count[i] as f64;
            let jacobi = clusters.particle_stiffness.get(i).copied().unwrap_or(0.0) as f64;
            if jacobi > 0.0 {
                stiffness_sum[i] / jacobi * w
            } else {
                0.0
            }
        })
        .collect();
    let inertia = particle_of
        .iter()
        .map(|&i| inv_dt2 / inv_mass[i as usize] as f64)
        .collect();
    let limit = budget_bytes.saturating_sub(inv_mass.len() as u64 * BYTES_PER_PARTICLE);
    let start = std::time::Instant::now();
    let factor = SparseCholesky::new(rows, &entries, limit);
    match &factor {
        Err(FactorError::Empty) => {}
        Err(reason) => tracing::warn!(
            "projective dynamics: the global matrix ({rows} rows) is not factored: \
             {reason}; the solver takes Jacobi steps instead"
        ),
        Ok(factor) => tracing::info!(
            "projective dynamics: factored the global matrix ({rows} rows, {:.1} MB) in {:.2} s",
            factor.bytes() as f64 / 1e6,
            start.elapsed().as_secs_f64()
        ),
    }
    GlobalSolve {
        row_of,
        particle_of,
        pull_weight,
        inertia,
        factor,
        dt: step.dt,
        inv_mass: inv_mass.to_vec(),
        cluster_epoch: clusters.carry_epoch,
        term_versions: term_versions(terms),
        rhs: vec![[0.0; 3]; rows],
        scratch: SolveScratch::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::matrix::tests::block;
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::clusters::term::ClusterSpec;
    use crate::solver::solve::Solver;
    use crate::solver::testing::step;
    use glam::Vec3;

    #[test]
    fn a_layout_with_every_particle_held_or_one_particle_has_no_factor_and_stays_finite() {
        let (_, clusters, inv_mass) = block();
        let held = vec![0.0; inv_mass.len()];
        let global = build(&clusters, &held, &Terms::default(), &step(1), u64::MAX);
        assert!(global.factor.is_err());
        let rest: Vec<Vec3> = clusters.rest.iter().map(|r| Vec3::from(*r)).collect();
        let mut particles = Particles::at_rest(&rest);
        particles.inv_mass = held;
        let mut solver = Solver::new(clusters, Terms::default());
        solver.solve(&mut particles, &step(3));
        assert!(particles.positions.iter().all(|p| p.is_finite()));
        let one = [ClusterSpec {
            members: &[0],
            compliance: 0.0,
            rotation: glam::Quat::IDENTITY,
            plastic: None,
        }];
        let term = ClusterTerm::new(&[Vec3::ONE], one, SolverMode::Projective);
        let mut single = Particles::at_rest(&[Vec3::ONE]);
        single.positions[0].y -= 0.1;
        Solver::new(term, Terms::default()).solve(&mut single, &step(3));
        assert!(single.positions[0].is_finite());
    }

    #[test]
    fn a_factor_past_the_memory_budget_is_not_built_and_the_solver_takes_jacobi_steps() {
        let (_, clusters, inv_mass) = block();
        let rest: Vec<Vec3> = clusters.rest.iter().map(|r| Vec3::from(*r)).collect();
        let sag = |budget_bytes: u64| {
            let mut solver = Solver::new(clusters.clone(), Terms::default());
            solver.projective.budget_bytes = budget_bytes;
            let mut particles = Particles::at_rest(&rest);
            particles.inv_mass = inv_mass.clone();
            // the far corner pulled off its place (particle 0 is held), then let go
            let last = rest.len() - 1;
            particles.positions[last].y -= 0.05;
            solver.solve(&mut particles, &step(5));
            (
                solver.projective.fallback().cloned(),
                particles.positions[last],
            )
        };
        let (none, factored) = sag(u64::MAX);
        assert_eq!(none, None);
        // the particles' own share alone passes this budget
        let (reason, jacobi) = sag(inv_mass.len() as u64 * BYTES_PER_PARTICLE);
        assert!(
            matches!(reason, Some(FactorError::OverBudget { limit: 0, .. })),
            "{reason:?}"
        );
        // Jacobi steps pull the particle back too
        let pulled = rest[rest.len() - 1].y - 0.05;
        for x in [jacobi, factored] {
            assert!(x.is_finite() && x.y > pulled + 1e-3, "{x}");
        }
    }
}
