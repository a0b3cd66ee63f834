//! One substep's solve: the cluster term, the registered terms and the scheme's state,
//! and the iteration that runs them (see [`Solver::solve`]).

use super::clusters::term::ClusterTerm;
use super::particles::{PARTICLES_PER_TASK, Particles};
use super::registry::Terms;
use super::schemes::gauss_seidel::GaussSeidel;
use super::schemes::jacobi::Jacobi;
use super::schemes::projective::Projective;
use super::term::{Substep, Topology};
use crate::config::SolverMode;
use glam::Vec3A;
use rayon::prelude::*;
use std::time::Instant;

/// Relative size of rounding noise: if a particle's total correction over a solve is at
/// most `ROUNDING_FLOOR × (|p|∞ + |x̄|∞)` (16 ulps of the coordinates that enter it), it
/// is rounding, not physics, and the particle keeps its predicted position. So a body at
/// rest stays exactly at rest instead of creeping. Real corrections are orders of
/// magnitude larger (gravity alone moves a particle 7·10⁻⁴ m per substep at 120 Hz).
pub const ROUNDING_FLOOR: f32 = 16.0 * f32::EPSILON;

/// The solver: the cluster term, the other terms, and each scheme's own state (only
/// the scheme the clusters were laid out for runs).
#[derive(Debug, Default)]
pub struct Solver {
    /// Cluster shape matching.
    pub clusters: ClusterTerm,
    /// Every other term, in projection order.
    pub terms: Terms,
    /// The Jacobi scheme's pulls (also projective dynamics' local step).
    pub jacobi: Jacobi,
    /// Gauss–Seidel's per-membership state.
    pub gauss_seidel: GaussSeidel,
    /// Projective dynamics' factor.
    pub projective: Projective,
    /// Seconds the clusters' passes and the global steps have taken.
    seconds: [f64; 2],
}

impl Solver {
    /// A solver of `clusters` and `terms`.
    pub fn new(clusters: ClusterTerm, terms: Terms) -> Self {
        Solver {
            clusters,
            terms,
            ..Default::default()
        }
    }

    /// The scheme the clusters were laid out for.
    pub fn mode(&self) -> SolverMode {
        self.clusters.mode()
    }

    /// One substep's solve: `step.iterations` iterations, each running the scheme's
    /// cluster pass, then every term in registered order (projective dynamics: its
    /// global step over the clusters and the terms with a projective form, then the
    /// others); records each particle's total correction in
    /// [`Particles::corrections`].
    ///
    /// The positions on entry are the inertial predictions `s`. The solve takes one
    /// implicit Euler step of the terms' energy, `min ½|x − s|²_M/dt² + Σ E(x)`,
    /// starting from `s` plus the clusters' correction of the previous substep (warm
    /// start): at a static equilibrium that is already the solution, so a body at rest
    /// holds its shape whatever the iteration count, instead of sagging until an
    /// unconverged iteration happens to balance gravity.
    pub fn solve(&mut self, particles: &mut Particles, step: &Substep) {
        // Called from outside rayon's pool (a user's thread, an ECS executor), each of
        // the solve's many parallel loops would hand its work to the pool and sleep until
        // it is done; the solve moves onto a pool thread once instead.
        rayon::scope(|_| {
            particles.predicted.clone_from(&particles.positions);
            self.begin_substep(particles, step);
            self.iterate(particles, step, step.iterations);
            self.finish_substep(particles, step);
        })
    }

    /// Starts a substep: the clusters' coefficients and warm start, the scheme's state,
    /// every term's substep work.
    fn begin_substep(&mut self, particles: &mut Particles, step: &Substep) {
        let mode = self.mode();
        let Particles {
            positions,
            previous,
            corrections,
            inv_mass,
            ..
        } = particles;
        self.clusters.begin_substep(
            previous,
            positions,
            corrections,
            inv_mass,
            step,
            mode == SolverMode::Projective,
        );
        match mode {
            SolverMode::GaussSeidel => self.gauss_seidel.begin_substep(&self.clusters),
            SolverMode::Projective => {
                self.projective
                    .begin_substep(&self.clusters, inv_mass, step.dt, &self.terms)
            }
            SolverMode::Jacobi => {}
        }
        let mut state = particles.state();
        for (term, seconds) in self.terms.iter_timed() {
            if !term.is_empty() {
                let start = Instant::now();
                term.begin_substep(step, &mut state);
                seconds.setup += start.elapsed().as_secs_f64();
            }
        }
    }

    /// `iterations` iterations of the current substep's solve, continuing from the
    /// current positions toward the predictions the last solve was given. With
    /// [`Self::restart_from`], a static solve can be iterated block by block.
    pub fn iterate(&mut self, particles: &mut Particles, step: &Substep, iterations: u32) {
        let mode = self.mode();
        for _ in 0..iterations {
            let start = Instant::now();
            match mode {
                SolverMode::Jacobi => {
                    self.jacobi
                        .pull_pass(&mut self.clusters, &particles.positions);
                    self.jacobi.move_particles(&mut self.clusters, particles);
                }
                SolverMode::GaussSeidel => {
                    self.gauss_seidel
                        .sweep(&mut self.clusters, particles, step.dt)
                }
                SolverMode::Projective => {
                    self.jacobi
                        .pull_pass(&mut self.clusters, &particles.positions);
                    let global = Instant::now();
                    self.seconds[0] += (global - start).as_secs_f64();
                    self.projective.global_step(
                        &mut self.clusters,
                        particles,
                        &mut self.jacobi,
                        &mut self.terms,
                        step,
                    );
                    self.seconds[1] += global.elapsed().as_secs_f64();
                }
            }
            if mode != SolverMode::Projective {
                self.seconds[0] += start.elapsed().as_secs_f64();
            }
            let mut state = particles.state();
            for (term, seconds) in self.terms.iter_timed() {
                let in_matrix = mode == SolverMode::Projective && term.projective().is_some();
                if !term.is_empty() && !in_matrix {
                    let start = Instant::now();
                    term.project(step, &mut state);
                    seconds.iterations += start.elapsed().as_secs_f64();
                }
            }
        }
    }

    /// Makes `start` the iterate of the current solve, as if the clusters had moved the
    /// particles there from their predictions (Gauss–Seidel's memberships share each
    /// particle's displacement equally).
    pub fn restart_from(&mut self, particles: &mut Particles, start: &[Vec3A]) {
        particles.positions.copy_from_slice(start);
        for ((carry, p), s) in self
            .clusters
            .carry
            .iter_mut()
            .zip(start)
            .zip(&particles.predicted)
        {
            *carry = *p - *s;
        }
        if self.mode() == SolverMode::GaussSeidel {
            self.gauss_seidel.restart(&self.clusters);
        }
    }

    /// Ends a solve: the corrections are the terms' and the clusters' together; rounding
    /// noise is dropped; plastic clusters yield to the solved shape.
    fn finish_substep(&mut self, particles: &mut Particles, step: &Substep) {
        for (c, carry) in particles.corrections.iter_mut().zip(&self.clusters.carry) {
            *c += *carry;
        }
        self.clusters
            .blend_orientations(&mut particles.orientations);
        self.drop_rounding_noise(particles);
        self.clusters.creep(&particles.positions, step.dt);
        for term in self.terms.iter() {
            if !term.is_empty() {
                term.end_substep(step, &particles.velocities, &mut particles.corrections);
            }
        }
    }

    /// Restores the predicted position of every particle whose total correction is below
    /// the rounding floor (see [`ROUNDING_FLOOR`]), and drops its warm start — except
    /// where Gauss–Seidel's memberships hold the warm start's parts: dropping it for one
    /// particle alone would set the two apart, and the memberships would then push the
    /// particle toward a displacement it no longer has.
    fn drop_rounding_noise(&mut self, particles: &mut Particles) {
        let keep_carry = self.mode() == SolverMode::GaussSeidel && self.gauss_seidel.holds_carry();
        let (predicted, rest) = (&particles.predicted, &self.clusters.rest);
        particles
            .positions
            .par_iter_mut()
            .zip(particles.corrections.par_iter_mut())
            .zip(self.clusters.carry.par_iter_mut())
            .zip(predicted.par_iter().zip(rest))
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(((p, correction), carry), (start, rest))| {
                let floor = ROUNDING_FLOOR * (start.abs().max_element() + rest.abs().max_element());
                if correction.abs().max_element() <= floor {
                    *p = *start;
                    *correction = Vec3A::ZERO;
                    if !keep_carry {
                        *carry = Vec3A::ZERO;
                    }
                }
            });
    }

    /// Tells every term of a topology change.
    pub fn topology(&mut self, change: &Topology) {
        self.terms.topology(change);
    }

    /// Gives every particle a term holds kinematic inverse mass 0 in `inv_mass`.
    pub fn hold_kinematic(&self, inv_mass: &mut [f32]) {
        for d in self.terms.kinematic() {
            if let Some(w) = inv_mass.get_mut(d as usize) {
                *w = 0.0;
            }
        }
    }

    /// Seconds each part of the solve has taken so far: the clusters' passes, every
    /// registered term by name, and projective dynamics' global steps.
    pub fn seconds(&self) -> Vec<(&'static str, f64)> {
        let mut out = vec![("clusters", self.seconds[0])];
        out.extend(self.terms.seconds());
        if self.mode() == SolverMode::Projective {
            out.push(("global step", self.seconds[1]));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::GroundPlane;
    use crate::solver::terms::colliders::Colliders;
    use crate::solver::testing::{solver, step};
    use glam::{Quat, Vec3};

    fn bar(n: usize) -> (Vec<Vec3>, Vec<Vec<u32>>) {
        let rest: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let clusters = (0..n - 2)
            .map(|i| vec![i as u32, i as u32 + 1, i as u32 + 2])
            .collect();
        (rest, clusters)
    }

    fn perturbed_bar(mode: SolverMode, terms: Terms) -> (Solver, Particles) {
        let (rest, clusters) = bar(8);
        let (s, mut p) = solver(&rest, &clusters, mode, terms);
        p.positions[3].y += 0.5;
        p.positions[6].z -= 0.3;
        (s, p)
    }

    #[test]
    fn colliders_never_move_a_pinned_particle() {
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let mut terms = Terms::default();
            terms.register(Colliders::new(
                Some(GroundPlane {
                    height: 0.0,
                    friction: 0.0,
                }),
                vec![],
            ));
            let (mut s, mut l) = perturbed_bar(mode, terms);
            // the whole bar sinks below the ground; particle 2 is held there
            for p in &mut l.positions {
                p.y -= 1.0;
            }
            l.inv_mass[2] = 0.0;
            let pinned = l.positions[2];
            s.solve(&mut l, &step(5));
            assert_eq!(l.positions[2], pinned, "{mode:?}");
            assert!(
                l.positions[7].y > -0.5,
                "{mode:?}: the free end is pushed up"
            );
        }
    }

    #[test]
    fn both_schemes_restore_a_perturbed_bar_and_conserve_momentum() {
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let (mut s, mut l) = perturbed_bar(mode, Terms::default());
            let momentum = |l: &Particles| l.positions.iter().copied().sum::<Vec3A>();
            let before = momentum(&l);
            s.solve(&mut l, &step(200));
            assert!((momentum(&l) - before).length() < 1e-4, "{mode:?}");
            // straight again (up to a rigid motion): the ends are 7 apart
            let d = (l.positions[7] - l.positions[0]).length();
            assert!((d - 7.0).abs() < 0.05, "{mode:?}: {d}");
            // corrections add up to the total displacement
            let moved: Vec3A = l.corrections.iter().map(|c| c.abs()).sum();
            assert!(moved.max_element() > 0.1, "{mode:?}");
        }
    }

    /// A 6×3×3 block with 2×2×2 clusters at every cell, twisted about its long axis.
    fn twisted_block(mode: SolverMode) -> (Vec<Vec3>, Solver, Particles) {
        let index = |x: u32, y: u32, z: u32| x * 9 + y * 3 + z;
        let mut rest = vec![];
        for x in 0..6 {
            for y in 0..3 {
                for z in 0..3 {
                    rest.push(Vec3::new(x as f32, y as f32, z as f32));
                }
            }
        }
        let mut clusters = vec![];
        for x in 0..5 {
            for y in 0..2 {
                for z in 0..2 {
                    let mut c = vec![];
                    for (dx, dy, dz) in (0..8).map(|b| (b & 1, (b >> 1) & 1, b >> 2)) {
                        c.push(index(x + dx, y + dy, z + dz));
                    }
                    clusters.push(c);
                }
            }
        }
        let (s, mut l) = solver(&rest, &clusters, mode, Terms::default());
        for (p, r) in l.positions.iter_mut().zip(&rest) {
            let twist = Quat::from_rotation_x(0.15 * r.x);
            *p = Vec3A::from(twist * (*r - Vec3::new(0.0, 1.0, 1.0)));
        }
        (rest, s, l)
    }

    #[test]
    fn gauss_seidel_converges_faster_than_jacobi_on_a_twisted_block() {
        let error = |mode, iterations| {
            let (rest, mut s, mut l) = twisted_block(mode);
            s.solve(&mut l, &step(iterations));
            let current: Vec<Vec3> = l.positions.iter().map(|p| Vec3::from(*p)).collect();
            crate::math::rigid_fit::rigid_fit_error(&rest, &current)
        };
        let start = error(SolverMode::Jacobi, 0);
        for k in [2, 5, 10] {
            let (jacobi, gs) = (
                error(SolverMode::Jacobi, k),
                error(SolverMode::GaussSeidel, k),
            );
            assert!(
                jacobi < start && gs < jacobi,
                "k={k}: start {start} jacobi {jacobi} gs {gs}"
            );
        }
    }
}
