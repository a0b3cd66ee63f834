//! The Jacobi scheme: every cluster is fitted to the same positions and adds its pull
//! `gᵢ − pᵢ` to each member's accumulator (spatial groups of clusters, the groups
//! of one colour in parallel, so no two tasks write the same accumulator and each
//! particle sums its pulls in a fixed order for any thread count); then every particle
//! moves by its step (see [`step_coefficients`]).

use super::batch::{BatchKernel, FitRow};
use super::sweep::Disjoint;
use super::{PARTICLES_PER_TASK, SolverLayout};
use crate::simd::Lane;
use glam::{Quat, Vec3A};
use rayon::prelude::*;

impl SolverLayout {
    /// Cluster pass: fit every cluster (eight at a time) to the positions, which no task
    /// writes in this pass, and add `s (g − p)` to each member's pull.
    pub(super) fn accumulate_pulls(&mut self) {
        let pulls = Disjoint::new(&mut self.pulls);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        this.for_each_batch_by_colour(&PullKernel {
            layout: this,
            pulls,
            rotations,
        });
    }

    /// Particle pass: `pᵢ += σᵢ Σₖ (gᵢₖ − pᵢ) + aᵢ (sᵢ + kᵢ − pᵢ)` with the coefficients
    /// of [`step_coefficients`] (pinned particles stay), where `kᵢ` is what the other
    /// constraint kinds (contacts, colliders) have moved the particle so far this
    /// substep: their pushes count as impulses that move the particle's inertial
    /// target, so that the pull toward it does not undo them. Clears the accumulators.
    pub(super) fn move_particles_jacobi(&mut self) {
        let (scale, anchor) = (&self.step_scale, &self.anchor);
        let (predicted, corrections) = (&self.predicted, &self.corrections);
        let compliant = self.compliant;
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.carry.par_chunks_mut(PARTICLES_PER_TASK))
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

/// A particle's step coefficients `(σ, a)`: its step is `σ Σₖ (gₖ − p) + a (s + k − p)`
/// (see [`SolverLayout::move_particles_jacobi`]).
///
/// Setting the gradient of the substep's objective to zero for particle `i` alone,
/// with its clusters' goals held, gives `(mᵢ/dt²)(pᵢ − sᵢ) + Σₖ κ wᵢ (pᵢ − gᵢₖ) = 0`
/// (wᵢ = 1/nᵢ); with `γ = mᵢ/(dt² κ wᵢ)` = `nᵢ · compliance · mᵢ / dt²` (the argument
/// `inertia_per_cluster` is `compliance · mᵢ / dt²`) the step is
/// `σ = 1/(nᵢ + γ)`, `a = γ σ`. A rigid cluster (compliance 0) gives `σ = 1/nᵢ`,
/// `a = 0`: the average of the goals. A pinned particle, or one in no cluster, does not
/// move.
#[inline]
pub(super) fn step_coefficients(
    inv_count: f32,
    inertia_per_cluster: f32,
    inv_mass: f32,
) -> (f32, f32) {
    if inv_mass == 0.0 || inv_count == 0.0 {
        return (0.0, 0.0);
    }
    let count = 1.0 / inv_count;
    let inertia = count * inertia_per_cluster;
    if inertia == 0.0 {
        (inv_count, 0.0)
    } else {
        let scale = 1.0 / (count + inertia);
        (scale, inertia * scale)
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
/// `step = σ·pull + a·(s + k − p)`, pulls cleared. With AVX, two particles at a time: a
/// pair of `Vec3A`s fills one eight-lane vector (their fourth lanes ride along and are
/// never read), so each operation moves two particles. Every lane computes exactly
/// what the one-particle loop does. `ANCHORED`: whether the `a` term is computed (when
/// every `a` is 0 it adds nothing).
fn move_block<const ANCHORED: bool>(moving: Moving, c: Coefficients) {
    let Moving {
        positions,
        carry,
        pulls,
    } = moving;
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    let first = pairs::move_pairs::<ANCHORED>(positions, carry, pulls, c);
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    let first = 0;
    let rest = positions[first..]
        .iter_mut()
        .zip(&mut carry[first..])
        .zip(&mut pulls[first..])
        .zip(c.predicted[first..].iter().zip(&c.pushed[first..]))
        .zip(c.scale[first..].iter().zip(&c.anchor[first..]));
    for ((((p, carry), pull), (&s, &pushed)), (&scale, &anchor)) in rest {
        let mut step = *pull * scale;
        if ANCHORED {
            step += (s + pushed - *p) * anchor;
        }
        *pull = Vec3A::ZERO;
        *p += step;
        *carry += step;
    }
}

/// The cluster pass's work on one batch (see [`SolverLayout::accumulate_pulls`]).
struct PullKernel<'a> {
    layout: &'a SolverLayout,
    /// Per particle: the sum of its clusters' pulls.
    pulls: Disjoint<Vec3A>,
    /// Per cluster: its warm-start rotation.
    rotations: Disjoint<Quat>,
}

impl BatchKernel for PullKernel<'_> {
    #[inline(always)]
    fn batch<L: Lane>(&self, b: usize, fit_rows: &mut Vec<FitRow>) {
        let (this, pulls) = (self.layout, self.pulls);
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
        let positions = this.positions.as_ptr();
        // (two calls rather than a test per lane: most batches are full)
        if used.iter().all(|u| *u) {
            unsafe {
                this.fit_batch::<L>(b, fit_rows, positions, self.rotations, |row| {
                    for (&at, &pull) in row.at.iter().zip(&row.pull) {
                        add(at, pull);
                    }
                })
            };
        } else {
            unsafe {
                this.fit_batch::<L>(b, fit_rows, positions, self.rotations, |row| {
                    let lanes = row.at.iter().zip(&row.pull).zip(&used);
                    for ((&at, &pull), _) in lanes.filter(|(_, in_use)| **in_use) {
                        add(at, pull);
                    }
                })
            };
        }
    }
}

/// The particle pass two particles at a time (see [`move_block`]).
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
mod pairs {
    use super::Coefficients;
    use glam::Vec3A;
    use std::arch::x86_64::*;
    use wide::f32x8;

    /// Moves the particles of `positions` in pairs; returns the index of the first
    /// particle left (the last one of an odd count).
    #[inline(always)]
    pub(super) fn move_pairs<const ANCHORED: bool>(
        positions: &mut [Vec3A],
        carry: &mut [Vec3A],
        pulls: &mut [Vec3A],
        c: Coefficients,
    ) -> usize {
        let (position_pairs, _) = positions.as_chunks_mut::<2>();
        let (carry_pairs, _) = carry.as_chunks_mut::<2>();
        let (pull_pairs, _) = pulls.as_chunks_mut::<2>();
        let (predicted_pairs, _) = c.predicted.as_chunks::<2>();
        let (pushed_pairs, _) = c.pushed.as_chunks::<2>();
        let (scale_pairs, _) = c.scale.as_chunks::<2>();
        let (anchor_pairs, _) = c.anchor.as_chunks::<2>();
        let done = 2 * position_pairs.len();
        let pairs = position_pairs
            .iter_mut()
            .zip(carry_pairs.iter_mut())
            .zip(pull_pairs.iter_mut())
            .zip(predicted_pairs.iter().zip(pushed_pairs))
            .zip(scale_pairs.iter().zip(anchor_pairs));
        for ((((p, carry), pull), (s, pushed)), (scale, anchor)) in pairs {
            let position = load(p);
            let mut step = load(pull) * widen(scale);
            if ANCHORED {
                let target = load(s) + load(pushed);
                step += (target - position) * widen(anchor);
            }
            *pull = [Vec3A::ZERO; 2];
            store(p, position + step);
            store(carry, load(carry) + step);
        }
        done
    }

    /// Two particles' scalars, each over its particle's four lanes.
    #[inline(always)]
    fn widen(x: &[f32; 2]) -> f32x8 {
        f32x8::new([x[0], x[0], x[0], x[0], x[1], x[1], x[1], x[1]])
    }

    /// Two `Vec3A`s as one eight-lane vector.
    #[inline(always)]
    fn load(v: &[Vec3A; 2]) -> f32x8 {
        // SAFETY: AVX is enabled at compile time (the module's cfg).
        unsafe { _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(v[0].into()), v[1].into()) }
            .into()
    }

    /// The two halves of an eight-lane vector into two `Vec3A`s.
    #[inline(always)]
    fn store(v: &mut [Vec3A; 2], x: f32x8) {
        let x: __m256 = x.into();
        // SAFETY: AVX is enabled at compile time (the module's cfg).
        unsafe {
            v[0] = _mm256_castps256_ps128(x).into();
            v[1] = _mm256_extractf128_ps::<1>(x).into();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The one-particle rule the pass applies to every particle.
    fn moved_one_by_one(moving: Moving, c: Coefficients) {
        for i in 0..moving.positions.len() {
            let p = moving.positions[i];
            let target = c.predicted[i] + c.pushed[i];
            let step = moving.pulls[i] * c.scale[i] + (target - p) * c.anchor[i];
            // (`+ 0·x` is exact: the unanchored pass may skip it)
            moving.pulls[i] = Vec3A::ZERO;
            moving.positions[i] = p + step;
            moving.carry[i] += step;
        }
    }

    #[test]
    fn the_pairwise_pass_moves_every_particle_as_the_one_particle_rule() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut v = || Vec3A::new(rng.random_range(-50.0..50.0), rng.random(), rng.random());
        for n in [0usize, 1, 2, 7, 64] {
            let positions: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let carry: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let predicted: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let pushed: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let mut pulls: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            // every third particle pinned, every other one compliant
            let (scale, anchor): (Vec<f32>, Vec<f32>) = (0..n)
                .map(|i| {
                    let inv_mass = (i % 3 != 1) as u8 as f32;
                    let inertia = if i % 2 == 0 { 0.0 } else { 0.3 * i as f32 };
                    step_coefficients(1.0 / (1 + i % 8) as f32, inertia, inv_mass)
                })
                .unzip();
            let c = Coefficients {
                predicted: &predicted,
                pushed: &pushed,
                scale: &scale,
                anchor: &anchor,
            };
            for poison in [false, true] {
                if poison && n > 0 {
                    pulls[n - 1] = Vec3A::new(f32::NAN, 0.0, 0.0);
                    pulls[n / 2] = Vec3A::new(0.0, f32::INFINITY, 0.0);
                }
                let (mut p1, mut c1, mut u1) = (positions.clone(), carry.clone(), pulls.clone());
                let (mut p2, mut c2, mut u2) = (positions.clone(), carry.clone(), pulls.clone());
                let moving = |positions, carry, pulls| Moving {
                    positions,
                    carry,
                    pulls,
                };
                move_block::<true>(moving(&mut p1, &mut c1, &mut u1), c);
                moved_one_by_one(moving(&mut p2, &mut c2, &mut u2), c);
                let bits = |v: &[Vec3A]| -> Vec<[u32; 3]> {
                    v.iter().map(|x| x.to_array().map(f32::to_bits)).collect()
                };
                assert_eq!(bits(&p1), bits(&p2), "positions, n = {n}");
                assert_eq!(bits(&c1), bits(&c2), "carry, n = {n}");
                assert_eq!(bits(&u1), bits(&u2), "pulls, n = {n}");
            }
        }
    }

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

    #[test]
    fn step_coefficients_average_the_goals_when_rigid_and_weigh_inertia_when_compliant() {
        assert_eq!(step_coefficients(0.25, 0.0, 1.0), (0.25, 0.0));
        assert_eq!(step_coefficients(0.25, 1.0, 0.0), (0.0, 0.0), "pinned");
        assert_eq!(
            step_coefficients(0.0, 1.0, 1.0),
            (0.0, 0.0),
            "in no cluster"
        );
        // 4 clusters, inertia 2 per cluster: σ = 1/(4 + 8), a = 8/12
        let (scale, anchor) = step_coefficients(0.25, 2.0, 1.0);
        assert!((scale - 1.0 / 12.0).abs() < 1e-7 && (anchor - 8.0 / 12.0).abs() < 1e-7);
    }
}
