//! The Jacobi scheme: every cluster is fitted to the same positions and adds its pull
//! `κ (gᵢ − pᵢ)`, weighted by its stiffness `κ` (`ClusterTerm`'s `pull_weight`), to each
//! member's accumulator (spatial groups of clusters, the groups of one colour in
//! parallel, so no two tasks write the same accumulator and each particle sums its pulls
//! in a fixed order for any thread count); then every particle moves by its step (see
//! `ClusterTerm`'s `step_coefficients`). With matching weights `1/nᵢ` (FastLSM) every
//! cluster's pull has zero momentum, so the scheme conserves linear momentum when the
//! clusters share one compliance.
//! Projective dynamics uses the same pull pass as its local step.

use crate::math::simd::Lane;
use crate::solver::clusters::fit::BatchKernel;
use crate::solver::clusters::rows::FitRow;
use crate::solver::clusters::term::ClusterTerm;
#[cfg(doc)]
use crate::solver::clusters::term::step_coefficients;
use crate::solver::disjoint::Disjoint;
use crate::solver::particles::{PARTICLES_PER_TASK, Particles};
use glam::{Quat, Vec3A};
use rayon::prelude::*;

/// The Jacobi scheme's scratch: the clusters' pulls of the current iteration.
#[derive(Clone, Debug, Default)]
pub struct Jacobi {
    /// Per particle, the sum of its clusters' pulls in this iteration.
    pub(in crate::solver) pulls: Vec<Vec3A>,
}

impl Jacobi {
    /// Cluster pass: fits every cluster (eight at a time) to `positions`, which no task
    /// writes in this pass, and adds `κ (g − p)` to each member's pull.
    pub fn pull_pass(&mut self, clusters: &mut ClusterTerm, positions: &[Vec3A]) {
        self.pulls.resize(positions.len(), Vec3A::ZERO);
        let pulls = Disjoint::new(&mut self.pulls);
        let rotations = Disjoint::new(&mut clusters.rotations);
        let clusters = &*clusters;
        clusters.for_each_batch_by_colour(&PullKernel {
            clusters,
            positions,
            pulls,
            rotations,
        });
    }

    /// Particle pass: `pᵢ += σᵢ Σₖ (gᵢₖ − pᵢ) + aᵢ (sᵢ + kᵢ − pᵢ)` with the coefficients
    /// of `step_coefficients` (particles of inverse mass 0 stay), where `kᵢ` is what
    /// the other terms have moved the particle so far this substep: their pushes count as
    /// impulses that move the particle's inertial target, so that the pull toward it does
    /// not undo them. The clusters' share goes to their carry. Clears the pulls.
    pub fn move_particles(&mut self, clusters: &mut ClusterTerm, particles: &mut Particles) {
        let (scale, anchor) = (&clusters.step_scale, &clusters.anchor);
        let (predicted, corrections) = (&particles.predicted, &particles.corrections);
        let compliant = clusters.compliant;
        particles
            .positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(clusters.carry.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.pulls.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, ((positions, carry), pulls))| {
                let range = task * PARTICLES_PER_TASK..task * PARTICLES_PER_TASK + positions.len();
                let moving = Moving {
                    positions,
                    carry,
                    pulls,
                };
                let c = Coefficients {
                    predicted: &predicted[range.clone()],
                    pushed: &corrections[range.clone()],
                    scale: &scale[range.clone()],
                    anchor: &anchor[range],
                };
                // (rigid clusters only: every `a` is 0, and the pass skips its term)
                if compliant {
                    move_block::<true>(moving, c);
                } else {
                    move_block::<false>(moving, c);
                }
            });
    }
}

/// The arrays a particle pass writes: positions, the clusters' share of the
/// corrections, and the pull accumulators (cleared).
struct Moving<'a> {
    positions: &'a mut [Vec3A],
    carry: &'a mut [Vec3A],
    pulls: &'a mut [Vec3A],
}

/// The arrays a particle pass reads: predictions, the other constraint kinds'
/// corrections so far and step coefficients.
#[derive(Clone, Copy)]
struct Coefficients<'a> {
    predicted: &'a [Vec3A],
    pushed: &'a [Vec3A],
    scale: &'a [f32],
    anchor: &'a [f32],
}

/// The particle pass over one block: `p += step`, `carry += step` with
/// `step = σ·pull + a·(s + k − p)`, pulls cleared. `ANCHORED`: whether the `a` term is
/// computed (when every `a` is 0 it adds nothing).
fn move_block<const ANCHORED: bool>(moving: Moving, c: Coefficients) {
    let Moving {
        positions,
        carry,
        pulls,
    } = moving;
    let particles = positions
        .iter_mut()
        .zip(carry)
        .zip(pulls)
        .zip(c.predicted.iter().zip(c.pushed))
        .zip(c.scale.iter().zip(c.anchor));
    for ((((p, carry), pull), (&s, &pushed)), (&scale, &anchor)) in particles {
        let mut step = *pull * scale;
        if ANCHORED {
            step += (s + pushed - *p) * anchor;
        }
        *pull = Vec3A::ZERO;
        *p += step;
        *carry += step;
    }
}

/// The cluster pass's work on one batch (see [`Jacobi::pull_pass`]).
struct PullKernel<'a> {
    clusters: &'a ClusterTerm,
    /// The positions the clusters are fitted to.
    positions: &'a [Vec3A],
    /// Per particle: the sum of its clusters' pulls.
    pulls: Disjoint<Vec3A>,
    /// Per cluster: its warm-start rotation.
    rotations: Disjoint<Quat>,
}

impl BatchKernel for PullKernel<'_> {
    #[inline(always)]
    fn batch<L: Lane>(&self, b: usize, fit_rows: &mut Vec<FitRow>) {
        let (this, pulls) = (self.clusters, self.pulls);
        // A lane in use adds every row, padding too: a padding row's pull is zero and
        // its particle the lane's own first member. An unused lane's particles may
        // belong to other tasks' clusters: it adds nothing. Lanes may share a particle:
        // their pulls are added one after another.
        let used = this.lanes_in_use(b);
        // SAFETY (this block and the two below): this task owns the group's clusters,
        // their rotations and their members' pulls for the colour (see `Disjoint`);
        // `add` is only called with members of the group's clusters, whose indices were
        // bounds-checked when the layout was built.
        // (`move`: a copy of the pointer, which the writes through it cannot change)
        let add = move |at: u32, pull| unsafe {
            pulls.write_at(at, pulls.read_at(at) + pull);
        };
        let positions = self.positions.as_ptr();
        // (separate calls rather than tests per lane: most batches are full, and most
        // layouts' clusters share one compliance, whose pulls go unweighted)
        match (this.lane_stiffness(b), used.iter().all(|u| *u)) {
            (None, true) => unsafe {
                this.fit_batch::<L>(b, fit_rows, positions, self.rotations, |row| {
                    for (&at, &pull) in row.at.iter().zip(&row.pull) {
                        add(at, pull);
                    }
                })
            },
            (Some(weights), true) => unsafe {
                this.fit_batch::<L>(b, fit_rows, positions, self.rotations, |row| {
                    for ((&at, &pull), &k) in row.at.iter().zip(&row.pull).zip(&weights) {
                        add(at, pull * k);
                    }
                })
            },
            (weights, false) => unsafe {
                // (an unused lane weighs 0, and adds nothing)
                let weights = weights.unwrap_or(used.map(f32::from));
                this.fit_batch::<L>(b, fit_rows, positions, self.rotations, |row| {
                    let lanes = row.at.iter().zip(&row.pull).zip(&weights).zip(&used);
                    for (((&at, &pull), &k), _) in lanes.filter(|(_, in_use)| **in_use) {
                        add(at, pull * k);
                    }
                })
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_unanchored_pass_equals_the_anchored_one_when_every_anchor_is_zero() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let mut v = || Vec3A::new(rng.random_range(-50.0..50.0), rng.random(), rng.random());
        let n = 33;
        let (positions, carry, pulls, predicted, pushed): (Vec<_>, Vec<_>, Vec<_>, Vec<_>, Vec<_>) =
            (0..n).map(|_| (v(), v(), v(), v(), v())).fold(
                Default::default(),
                |mut a: (Vec<_>, Vec<_>, Vec<_>, Vec<_>, Vec<_>), x| {
                    a.0.push(x.0);
                    a.1.push(x.1);
                    a.2.push(x.2);
                    a.3.push(x.3);
                    a.4.push(x.4);
                    a
                },
            );
        let scale: Vec<f32> = (0..n).map(|i| 1.0 / (1 + i % 8) as f32).collect();
        let anchor = vec![0.0; n];
        let c = Coefficients {
            predicted: &predicted,
            pushed: &pushed,
            scale: &scale,
            anchor: &anchor,
        };
        let run = |anchored: bool| {
            let (mut p, mut k, mut u) = (positions.clone(), carry.clone(), pulls.clone());
            let moving = Moving {
                positions: &mut p,
                carry: &mut k,
                pulls: &mut u,
            };
            if anchored {
                move_block::<true>(moving, c);
            } else {
                move_block::<false>(moving, c);
            }
            (p, k)
        };
        assert_eq!(run(true), run(false));
    }
}
