//! The Jacobi scheme: every cluster is fitted to the same positions and adds its pull
//! `sₖ (gᵢ − pᵢ)` to each member's accumulator (spatial groups of clusters, the groups
//! of one colour in parallel, so no two tasks write the same accumulator and each
//! particle sums its pulls in a fixed order for any thread count); then every particle
//! moves by the average pull.

use super::sweep::Disjoint;
use super::{PARTICLES_PER_TASK, SolverLayout};
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

    /// Particle pass: `pᵢ += (1/nᵢ) Σₖ sₖ (gᵢₖ − pᵢ)` (pinned particles stay); clears
    /// the accumulators.
    pub(super) fn move_particles_jacobi(&mut self) {
        let (inv_count, inv_mass) = (&self.inv_count, &self.inv_mass);
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.pulls.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, ((positions, corrections), pulls))| {
                let range = task * PARTICLES_PER_TASK..task * PARTICLES_PER_TASK + positions.len();
                move_block(
                    positions,
                    corrections,
                    pulls,
                    &inv_count[range.clone()],
                    &inv_mass[range],
                );
            });
    }
}

/// The particle pass over one block: `p += step`, `correction += step` with
/// `step = pull / n` (zero for a pinned particle), pulls cleared. With AVX, two
/// particles at a time: a pair of `Vec3A`s fills one eight-lane vector (their fourth
/// lanes ride along and are never read), so each operation moves two particles. Every
/// lane computes exactly what the one-particle loop does.
fn move_block(
    positions: &mut [Vec3A],
    corrections: &mut [Vec3A],
    pulls: &mut [Vec3A],
    inv_count: &[f32],
    inv_mass: &[f32],
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    let first = pairs::move_pairs(positions, corrections, pulls, inv_count, inv_mass);
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    let first = 0;
    let rest = positions[first..]
        .iter_mut()
        .zip(&mut corrections[first..])
        .zip(&mut pulls[first..])
        .zip(inv_count[first..].iter().zip(&inv_mass[first..]));
    for (((p, correction), pull), (&count, &mass)) in rest {
        let step = *pull * step_scale(mass, count);
        *pull = Vec3A::ZERO;
        *p += step;
        *correction += step;
    }
}

/// A particle's step per unit pull: `1/n`, or zero for a pinned particle (a select, not
/// a branch).
#[inline(always)]
fn step_scale(inv_mass: f32, inv_count: f32) -> f32 {
    if inv_mass == 0.0 { 0.0 } else { inv_count }
}

/// The particle pass two particles at a time (see [`move_block`]).
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
mod pairs {
    use super::step_scale;
    use glam::Vec3A;
    use std::arch::x86_64::*;
    use wide::f32x8;

    /// Moves the particles of `positions` in pairs; returns the index of the first
    /// particle left (the last one of an odd count).
    #[inline(always)]
    pub(super) fn move_pairs(
        positions: &mut [Vec3A],
        corrections: &mut [Vec3A],
        pulls: &mut [Vec3A],
        inv_count: &[f32],
        inv_mass: &[f32],
    ) -> usize {
        let (position_pairs, _) = positions.as_chunks_mut::<2>();
        let (correction_pairs, _) = corrections.as_chunks_mut::<2>();
        let (pull_pairs, _) = pulls.as_chunks_mut::<2>();
        let (count_pairs, _) = inv_count.as_chunks::<2>();
        let (mass_pairs, _) = inv_mass.as_chunks::<2>();
        let done = 2 * position_pairs.len();
        let pairs = position_pairs
            .iter_mut()
            .zip(correction_pairs.iter_mut())
            .zip(pull_pairs.iter_mut())
            .zip(count_pairs.iter().zip(mass_pairs));
        for (((p, correction), pull), (count, mass)) in pairs {
            let (s0, s1) = (step_scale(mass[0], count[0]), step_scale(mass[1], count[1]));
            let step = load(pull) * f32x8::new([s0, s0, s0, s0, s1, s1, s1, s1]);
            *pull = [Vec3A::ZERO; 2];
            let moved = load(p) + step;
            store(p, moved);
            store(correction, load(correction) + step);
        }
        done
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
    fn moved_one_by_one(
        positions: &mut [Vec3A],
        corrections: &mut [Vec3A],
        pulls: &mut [Vec3A],
        inv_count: &[f32],
        inv_mass: &[f32],
    ) {
        for i in 0..positions.len() {
            let scale = if inv_mass[i] == 0.0 {
                0.0
            } else {
                inv_count[i]
            };
            let step = pulls[i] * scale;
            pulls[i] = Vec3A::ZERO;
            positions[i] += step;
            corrections[i] += step;
        }
    }

    #[test]
    fn the_pairwise_pass_moves_every_particle_as_the_one_particle_rule() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut v = || Vec3A::new(rng.random_range(-50.0..50.0), rng.random(), rng.random());
        for n in [0usize, 1, 2, 7, 64] {
            let positions: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let corrections: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let mut pulls: Vec<Vec3A> = (0..n).map(|_| v()).collect();
            let inv_count: Vec<f32> = (0..n).map(|i| 1.0 / (1 + i % 8) as f32).collect();
            // every third particle pinned
            let inv_mass: Vec<f32> = (0..n).map(|i| (i % 3 != 1) as u8 as f32).collect();
            for poison in [false, true] {
                if poison && n > 0 {
                    pulls[n - 1] = Vec3A::new(f32::NAN, 0.0, 0.0);
                    pulls[n / 2] = Vec3A::new(0.0, f32::INFINITY, 0.0);
                }
                let (mut p1, mut c1, mut u1) =
                    (positions.clone(), corrections.clone(), pulls.clone());
                let (mut p2, mut c2, mut u2) =
                    (positions.clone(), corrections.clone(), pulls.clone());
                move_block(&mut p1, &mut c1, &mut u1, &inv_count, &inv_mass);
                moved_one_by_one(&mut p2, &mut c2, &mut u2, &inv_count, &inv_mass);
                let bits = |v: &[Vec3A]| -> Vec<[u32; 3]> {
                    v.iter().map(|x| x.to_array().map(f32::to_bits)).collect()
                };
                assert_eq!(bits(&p1), bits(&p2), "positions, n = {n}");
                assert_eq!(bits(&c1), bits(&c2), "corrections, n = {n}");
                assert_eq!(bits(&u1), bits(&u2), "pulls, n = {n}");
            }
        }
    }
}
