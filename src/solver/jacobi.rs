//! The Jacobi scheme: every cluster is fitted to the same positions and adds its pull
//! `sₖ (gᵢ − pᵢ)` to each member's accumulator (clusters of one colour in parallel, so
//! no two write the same accumulator and each particle sums its pulls in a fixed colour
//! order); then every particle moves by the average pull and the colliders apply.

use super::sweep::Disjoint;
use super::{Colliders, PARTICLES_PER_TASK, SolverLayout, resolve_colliders};
use glam::{Quat, Vec3A};
use rayon::prelude::*;

impl SolverLayout {
    /// Cluster pass: fit every cluster and accumulate its pulls.
    pub(super) fn accumulate_pulls(&mut self) {
        let pulls = Disjoint::new(&mut self.pulls);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        this.for_each_cluster_by_colour(|k| this.pull_members(k, pulls, rotations));
    }

    /// Fits cluster `k` to the positions (which no task writes in this pass) and adds
    /// `s (g − p)` to each member's pull.
    #[inline]
    fn pull_members(&self, k: usize, pulls: Disjoint<Vec3A>, rotations: Disjoint<Quat>) {
        // SAFETY: this task owns cluster `k`, and so the pulls of its members, for the
        // colour (see `Disjoint`); indices were bounds-checked when the layout was built.
        let (range, frame, stiffness) =
            unsafe { self.fit_in_sweep(k, |m| self.positions[m], rotations) };
        for (&m, moment) in self.member_particle[range.clone()]
            .iter()
            .zip(&self.member_moment[range])
        {
            let m = m as usize;
            let pull = frame.scaled_goal(Vec3A::from_vec4(*moment)) - self.positions[m] * stiffness;
            // SAFETY: as above.
            unsafe { pulls.write(m, pulls.read(m) + pull) };
        }
    }

    /// Particle pass: `pᵢ += (1/nᵢ) Σₖ sₖ (gᵢₖ − pᵢ)`, then the colliders; clears the
    /// accumulators.
    pub(super) fn move_particles_jacobi(&mut self, colliders: &Colliders) {
        let (inv_count, inv_mass, previous) = (&self.inv_count, &self.inv_mass, &self.previous);
        let collide = colliders.ground.is_some() || !colliders.boxes.is_empty();
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.pulls.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, ((chunk, corrections), pulls))| {
                let base = task * PARTICLES_PER_TASK;
                for (j, ((p, correction), pull)) in
                    chunk.iter_mut().zip(corrections).zip(pulls).enumerate()
                {
                    let i = base + j;
                    let step = *pull * inv_count[i];
                    *pull = Vec3A::ZERO;
                    if inv_mass[i] == 0.0 {
                        continue;
                    }
                    *p += step;
                    *correction += step;
                    if collide {
                        let unconstrained = *p;
                        resolve_colliders(p, previous[i], colliders);
                        *correction += *p - unconstrained;
                    }
                }
            });
    }
}
