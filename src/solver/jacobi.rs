//! The Jacobi scheme: every cluster is fitted to the same positions and adds its pull
//! `sₖ (gᵢ − pᵢ)` to each member's accumulator (spatial groups of clusters, the groups
//! of one colour in parallel, so no two tasks write the same accumulator and each
//! particle sums its pulls in a fixed order for any thread count); then every particle
//! moves by the average pull and the colliders apply.

use super::colliders::{Block, Bounds, collide_block};
use super::sweep::Disjoint;
use super::{Colliders, PARTICLES_PER_TASK, SolverLayout};
use glam::Vec3A;
use rayon::prelude::*;

impl SolverLayout {
    /// Cluster pass: fit every cluster (eight at a time) to the positions, which no task
    /// writes in this pass, and add `s (g − p)` to each member's pull.
    pub(super) fn accumulate_pulls(&mut self) {
        let pulls = Disjoint::new(&mut self.pulls);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        this.for_each_batch_by_colour(|b, fit_rows| {
            // A lane in use adds every row, padding too: a padding row's pull is zero
            // and its particle the lane's own first member. An unused lane's particles
            // may belong to other tasks' clusters: it adds nothing. Lanes may share a
            // particle: their pulls are added one after another.
            let used = this.lanes_in_use(b);
            // SAFETY (this block and the two below): this task owns the group's
            // clusters, their rotations and their members' pulls for the colour (see
            // `Disjoint`); `add` is only called with members of the group's clusters,
            // whose indices were bounds-checked when the layout was built.
            // (`move`: a copy of the pointer, which the writes through it cannot change)
            let add = move |at: u32, pull| unsafe {
                pulls.write_at(at, pulls.read_at(at) + pull);
            };
            let positions = this.positions.as_ptr();
            // (two calls rather than a test per lane: most batches are full)
            if used.iter().all(|u| *u) {
                unsafe {
                    this.fit_batch(b, fit_rows, positions, rotations, |row| {
                        for (&at, &pull) in row.at.iter().zip(&row.pull) {
                            add(at, pull);
                        }
                    })
                };
            } else {
                unsafe {
                    this.fit_batch(b, fit_rows, positions, rotations, |row| {
                        let lanes = row.at.iter().zip(&row.pull).zip(&used);
                        for ((&at, &pull), _) in lanes.filter(|(_, in_use)| **in_use) {
                            add(at, pull);
                        }
                    })
                };
            }
        });
    }

    /// Particle pass: `pᵢ += (1/nᵢ) Σₖ sₖ (gᵢₖ − pᵢ)` (pinned particles stay), then the
    /// colliders; clears the accumulators.
    pub(super) fn move_particles_jacobi(&mut self, colliders: &Colliders) {
        let (inv_count, inv_mass, previous) = (&self.inv_count, &self.inv_mass, &self.previous);
        let collide = colliders.ground.is_some() || !colliders.boxes.is_empty();
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.pulls.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, ((positions, corrections), pulls))| {
                let range = task * PARTICLES_PER_TASK..task * PARTICLES_PER_TASK + positions.len();
                let (inv_count, inv_mass) = (&inv_count[range.clone()], &inv_mass[range.clone()]);
                let particles = positions
                    .iter_mut()
                    .zip(corrections.iter_mut())
                    .zip(pulls.iter_mut())
                    .zip(inv_count)
                    .zip(inv_mass);
                // (a fold: a box whose address is taken later would be stored to memory
                // at every step)
                let bounds = particles.fold(
                    Bounds::default(),
                    |mut bounds, ((((p, correction), pull), &inv_count), &inv_mass)| {
                        // a select, not a branch: pinned particles move by zero
                        let scale = if inv_mass == 0.0 { 0.0 } else { inv_count };
                        let step = *pull * scale;
                        *pull = Vec3A::ZERO;
                        // (the sum kept in a register: reading `*p` back costs a load)
                        let moved = *p + step;
                        *p = moved;
                        *correction += step;
                        bounds.add(moved);
                        bounds
                    },
                );
                // (Morton order: a task's particles are a compact block, mostly far
                // from every collider)
                if collide {
                    let block = Block {
                        positions,
                        corrections,
                        previous: &previous[range],
                        inv_mass,
                    };
                    collide_block(block, &bounds, colliders);
                }
            });
    }
}
