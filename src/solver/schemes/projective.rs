//! Projective dynamics' global step (Bouaziz et al. 2014).
//!
//! The clusters' rotation fits are the local step (the Jacobi pull pass, which adds
//! each cluster's pull `gᵢₖ − pᵢ` to its members), and so are the projections of every
//! term that gives a [`ProjectiveTerm`](crate::solver::term::ProjectiveTerm) (attachments, edges). The global step then
//! solves the substep's objective for all positions at once with the projections held:
//! its Hessian `A = M/dt² + Σₖ κₖ (Wₖ − wₖ wₖᵀ / Σwₖ) + Σ_terms w AᵀA` (each cluster
//! adds a weighted complete-graph Laplacian on its members, each term its constant
//! `w AᵀA`) is constant while the clusters, terms, masses and time step are, so it is
//! factored once (sparse Cholesky, faer, with its fill-reducing ordering) and x, y and z
//! share the factor. Written for the increment `Δ = x − p`, the right-hand side is the
//! clusters' weighted pulls, the terms' forces `w SᵀAᵀ(p − A S x)`, and the inertia
//! `(mᵢ/dt²)(sᵢ + kᵢ − pᵢ)` — Jacobi is this solve with `A` replaced by a diagonal.
//! Particles of inverse mass 0 are not unknowns (their increment is 0).
//!
//! Terms without a projective form (contacts and colliders, whose constraints change
//! every substep) are projected after each global step; their corrections in this
//! substep (`kᵢ`) move each particle's inertial target: a contact's push is an impulse
//! the elastic solve distributes, not a displacement it undoes.
//!
//! A hard constraint (a rigid cluster, a hard edge) has no finite stiffness: the matrix
//! takes it as [`STIFFEST`] times its particles' mean `m/dt²`. A compliant material
//! keeps its stiffness; where `κ dt²/m` is far above [`STIFFEST`] and contacts push its
//! particles, they can pile up into velocity: such a material wants more substeps, or
//! Jacobi. The factor is sequential (faer without threads), so the result is the same
//! for any thread count.

use super::jacobi::Jacobi;
use crate::body::shape::{BYTES_PER_PARTICLE, DEFAULT_MEMORY_BUDGET_GB};
use crate::math::sparse_cholesky::{FactorError, SparseCholesky};
use crate::solver::clusters::term::ClusterTerm;
use crate::solver::particles::{PARTICLES_PER_TASK, Particles};
use crate::solver::registry::Terms;
use crate::solver::term::{NO_DENSE, STIFFEST, Substep, Unknowns};
use faer::Mat;
use faer::sparse::Triplet;
use glam::{DVec3, Vec3A};
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
    /// Per row: `κᵢ wᵢ`, the weight of the particle's summed pulls in the right-hand
    /// side (its clusters' mean stiffness times its Jacobi weight).
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
    /// Right-hand sides (rows × 3), reused.
    rhs: Mat<f64>,
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
                form.add_forces(step, &unknowns, &particles.positions, &mut self.forces);
                *seconds += start.elapsed().as_secs_f64();
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
            for axis in 0..3 {
                global.rhs[(row, axis)] = r[axis];
            }
        }
        factor.solve_in_place(global.rhs.as_mut());
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
}

/// The global matrix's lower triangle and what it was built from.
pub(in crate::solver) struct Assembly {
    pub(in crate::solver) row_of: Vec<u32>,
    pub(in crate::solver) particle_of: Vec<u32>,
    pub(in crate::solver) entries: Vec<Triplet<usize, usize, f64>>,
    /// Per particle: the sum of its clusters' stiffnesses.
    stiffness_sum: Vec<f64>,
}

/// The global matrix (lower triangle, duplicates to be summed) for the clusters, the
/// terms' projective forms and the masses `1/inv_mass`, at the substep's time step.
pub(in crate::solver) fn assemble(
    clusters: &ClusterTerm,
    inv_mass: &[f32],
    terms: &Terms,
    step: &Substep,
) -> Assembly {
    let n = inv_mass.len();
    let inv_dt2 = 1.0 / (step.dt as f64 * step.dt as f64);
    let mass = |i: usize| 1.0 / inv_mass[i] as f64;
    let mut row_of = vec![NO_DENSE; n];
    let mut particle_of = Vec::new();
    for (i, &w) in inv_mass.iter().enumerate() {
        if w > 0.0 {
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
    for (k, members) in clusters.clusters() {
        let free: Vec<u32> = members
            .iter()
            .copied()
            .filter(|&m| row_of[m as usize] != NO_DENSE)
            .collect();
        if free.is_empty() {
            continue;
        }
        let mean_mass = free.iter().map(|&m| mass(m as usize)).sum::<f64>() / free.len() as f64;
        let compliance = clusters.compliance[k] as f64;
        let kappa = if compliance > 0.0 {
            1.0 / compliance
        } else {
            STIFFEST * mean_mass * inv_dt2
        };
        let total: f64 = members.iter().map(|&m| clusters.weight(m) as f64).sum();
        for &m in members {
            stiffness_sum[m as usize] += kappa;
        }
        // κ (W − w wᵀ/Σw) on the free members, lower triangle
        for &a in &free {
            let (wa, ra) = (clusters.weight(a) as f64, row_of[a as usize] as usize);
            for &b in &free {
                let (wb, rb) = (clusters.weight(b) as f64, row_of[b as usize] as usize);
                if rb > ra {
                    continue;
                }
                let diagonal = if a == b { wa } else { 0.0 };
                entries.push(Triplet::new(ra, rb, kappa * (diagonal - wa * wb / total)));
            }
        }
    }
    let unknowns = Unknowns {
        row_of: &row_of,
        inv_mass,
    };
    let mut term_entries = Vec::new();
    for term in terms.iter() {
        if let Some(form) = term.projective() {
            form.add_hessian(step, &unknowns, &mut term_entries);
        }
    }
    entries.extend(
        term_entries
            .into_iter()
            .map(|(row, col, value)| Triplet::new(row, col, value)),
    );
    Assembly {
        row_of,
        particle_of,
        entries,
        stiffness_sum,
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
        entries,
        stiffness_sum,
    } = assemble(clusters, inv_mass, terms, step);
    let rows = particle_of.len();
    let pull_weight = particle_of
        .iter()
        .map(|&i| {
            let w = clusters.inv_count[i as usize] as f64;
            // mean stiffness over its clusters (n = 1/w of them), times w
            stiffness_sum[i as usize] * w * w
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
        rhs: Mat::zeros(rows, 3),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use crate::config::{Material, SolverMode};
    use crate::cut::tool::Pose;
    use crate::solver::clusters::term::ClusterSpec;
    use crate::solver::solve::Solver;
    use crate::solver::term::{BodyTopology, ParticleKey, Topology};
    use crate::solver::terms::attachments::{Attachment, Attachments};
    use crate::solver::terms::edges::Edges;
    use crate::solver::testing::{TEST_DT, step};
    use faer::Conj;
    use faer::Mat;
    use faer::linalg::solvers::SolveCore;
    use glam::{UVec3, Vec3};

    /// A 4×3×3 lattice block (dense index = lattice index) with 2×2×2 clusters at every
    /// cell, compliant; particle 0 held still.
    fn block() -> (crate::body::lattice::Lattice, ClusterTerm, Vec<f32>) {
        let lattice = Shape::cuboid(UVec3::new(4, 3, 3))
            .voxelise(0.1)
            .expect("a block");
        let rest: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|i| lattice.rest_position(i))
            .collect();
        let mut clusters = vec![];
        for i in 0..lattice.len() as u32 {
            let c = lattice.coord(i);
            let cell: Option<Vec<u32>> = (0..8)
                .map(|b| lattice.at(c + glam::IVec3::new(b & 1, (b >> 1) & 1, b >> 2)))
                .collect();
            clusters.extend(cell);
        }
        let specs = clusters.iter().map(|m| ClusterSpec {
            members: m,
            compliance: 1e-3,
            rotation: glam::Quat::IDENTITY,
        });
        let term = ClusterTerm::new(&rest, specs, SolverMode::Projective);
        let mut inv_mass = vec![1.0; rest.len()];
        inv_mass[0] = 0.0;
        (lattice, term, inv_mass)
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
        let (_, clusters, inv_mass) = block();
        let a = assemble(&clusters, &inv_mass, &Terms::default(), &step(1));
        let rows = a.particle_of.len();
        assert_eq!(rows, inv_mass.len() - 1, "the held particle is no unknown");
        let matrix = dense(rows, &a.entries);
        // positive definite: a dense Cholesky succeeds with a positive diagonal
        let llt = matrix.llt(faer::Side::Lower).expect("positive definite");
        assert!((0..rows).all(|i| llt.L()[(i, i)] > 0.0));
        let factor = SparseCholesky::new(rows, &a.entries, u64::MAX).expect("a factor");
        let rhs = Mat::<f64>::from_fn(rows, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let mut sparse = rhs.clone();
        factor.solve_in_place(sparse.as_mut());
        let residual = (&matrix * &sparse - &rhs).norm_max();
        assert!(residual < 1e-9 * rhs.norm_max(), "{residual}");
    }

    #[test]
    fn the_matrix_holds_the_attachments_and_edges_as_their_own_forms_give_them() {
        let (lattice, clusters, inv_mass) = block();
        let dense_map: Vec<u32> = (0..lattice.len() as u32).collect();
        let material = Material {
            edge_compliance: Some(2e-5),
            ..Material::default()
        };
        let body = BodyTopology {
            id: 7,
            lattice: &lattice,
            dense: &dense_map,
            material: &material,
            pieces: 1,
            changed: true,
        };
        let topology = Topology {
            bodies: &[body],
            relaid: true,
        };
        let mut terms = Terms::builtin();
        terms.topology(&topology);
        // a soft attachment of the far end (x = 1), one of compliance 1e-3 m/N
        let far: Vec<u32> = (0..lattice.len() as u32)
            .filter(|&i| lattice.coord(i).x == 1)
            .collect();
        let attachment = Attachment {
            particles: far
                .iter()
                .map(|&local| ParticleKey { body: 7, local })
                .collect(),
            offsets: far.iter().map(|&i| lattice.rest_position(i)).collect(),
            compliance: 1e-3,
            from: Pose::at(Vec3::ZERO),
            to: Pose::at(Vec3::ZERO),
            velocity: None,
        };
        let attachments = terms.get_mut::<Attachments>().expect("built in");
        attachments.set(vec![attachment], &topology);
        let edges = terms.get::<Edges>().expect("built in");
        assert_eq!(edges.len(), 3 * 3 * 3 + 4 * 2 * 3 + 4 * 3 * 2);
        // the dense matrix from scratch: masses, clusters (as the cluster term alone
        // gives them), and each term's constraints by their definitions
        let without = assemble(&clusters, &inv_mass, &Terms::default(), &step(1));
        let rows = without.particle_of.len();
        let mut expected = dense(rows, &without.entries);
        let row = |i: u32| without.row_of[i as usize];
        for (a, b, rest, compliance) in edges.iter() {
            assert!((rest - 0.1).abs() < 1e-6 && (compliance - 2e-4).abs() < 1e-9);
            let w = 1.0 / compliance as f64;
            for (i, j, sign) in [(a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)] {
                if row(i) != NO_DENSE && row(j) != NO_DENSE {
                    expected[(row(i) as usize, row(j) as usize)] += sign * w;
                }
            }
        }
        for &i in &far {
            expected[(row(i) as usize, row(i) as usize)] += 1.0 / 1e-3f32 as f64;
        }
        let with = assemble(&clusters, &inv_mass, &terms, &step(1));
        let matrix = dense(rows, &with.entries);
        let difference = (&matrix - &expected).norm_max();
        assert!(difference < 1e-9 * expected.norm_max(), "{difference}");
        // and the sparse factor solves it as a dense solve does
        let factor = SparseCholesky::new(rows, &with.entries, u64::MAX).expect("a factor");
        let rhs = Mat::<f64>::from_fn(rows, 3, |i, j| ((i * 5 + j) % 7) as f64 - 3.0);
        let mut sparse = rhs.clone();
        factor.solve_in_place(sparse.as_mut());
        let mut reference = rhs.clone();
        expected
            .llt(faer::Side::Lower)
            .expect("positive definite")
            .solve_in_place_with_conj(Conj::No, reference.as_mut());
        let error = (&sparse - &reference).norm_max();
        assert!(error < 1e-9 * reference.norm_max(), "{error}");
    }

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
        }];
        let term = ClusterTerm::new(&[Vec3::ONE], one, SolverMode::Projective);
        let mut single = Particles::at_rest(&[Vec3::ONE]);
        single.positions[0].y -= 0.1;
        Solver::new(term, Terms::default()).solve(&mut single, &step(3));
        assert!(single.positions[0].is_finite());
        let _ = TEST_DT;
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
