//! The clusters' turn, carried from substep to substep: each substep starts every
//! cluster's rotation fit from its last rotation turned once more by the turn it made in
//! the last substep. The particles of the cluster model turn with their clusters
//! ([`ClusterTerm::blend_orientations`]).
//!
//! The fit takes one warm-started rotation step per solver iteration (Müller et al.
//! 2016), and one step recovers only part of a turn: for a rotation `δ` away from the
//! warm start it turns by `(tr S − S) δ / tr S` with `S` the cluster's moment, two thirds
//! of `δ` for a cube's. A cluster that starts its substep at its last rotation therefore
//! lags a spinning body's predicted positions, and the particles, pulled to the lagging
//! goals in the first iteration, stay there: every substep loses a third of the spin, and
//! a rigid block spun at 1 rad/s in zero gravity stops within a fraction of a second. A
//! warm start turned ahead by the last substep's turn (constant angular velocity, the
//! prediction the particles get) leaves the step only the change of spin to recover.
//!
//! A substep with no last turn to carry — the first after the clusters were built,
//! patched by a cut, or the time step changed — fits every cluster to the particles'
//! positions at its start and to their predictions instead, to convergence: the first
//! fit is where the substep's turn starts from, the second where the fits start. A new
//! cluster's rotation says nothing of its body's turn so far, and a body spawned
//! spinning, or cut while it spins, would otherwise lose that substep's share of its
//! spin.

use super::term::{CLUSTERS_PER_TASK, ClusterTerm};
use crate::math::lanes::LANES;
use crate::math::rotation_lockstep::extract_rotations_lockstep;
use crate::math::simd::{Lane, WithLanes, dispatch};
use crate::solver::particles::PARTICLES_PER_TASK;
use glam::{Mat3A, Quat, Vec3A};
use rayon::prelude::*;

/// The smallest turn per substep carried ahead, as the sine of half its angle: 1e-6
/// (2e-6 rad, 5e-4 rad/s at 240 substeps a second). The rotation fits of a body at rest
/// wander by less.
const SMALLEST_TURN: f32 = 1e-6;

/// Most rotation iterations of a fit when the turn was forgotten (it stops once
/// converged).
const FORGOTTEN_TURN_FIT_ITERATIONS: u32 = 16;

impl ClusterTerm {
    /// Turns every cluster's warm-start rotation ahead by the turn it made over the last
    /// substep, and marks the start of this one (see the module docs).
    pub(in crate::solver) fn turn_warm_starts(&mut self) {
        self.substep_start
            .resize(self.rotations.len(), Quat::IDENTITY);
        self.rotations
            .par_iter_mut()
            .zip(self.substep_start.par_iter_mut())
            .with_min_len(CLUSTERS_PER_TASK)
            .for_each(|(rotation, start)| {
                let last = *rotation;
                // (a turn within rounding is not carried: carried, it would move a body
                // at rest)
                let turn = last * start.conjugate();
                if turn.xyz().length_squared() > SMALLEST_TURN * SMALLEST_TURN {
                    let ahead = (turn * last).normalize();
                    if ahead.is_finite() {
                        *rotation = ahead;
                    }
                }
                *start = last;
            });
    }

    /// Turns every particle that is in a cluster to the blend of its clusters' rotations:
    /// their normalised sum, each taken on the side of the particle's orientation at the
    /// substep's start (a quaternion and its negative are one rotation; the prediction
    /// leaves a particle in a cluster unturned:
    /// [`crate::solver::particles::Particles::predict`]), so a particle in clusters that
    /// turn alike turns with them, and one between clusters turning apart takes the turn
    /// between. The clusters' rotations are their fits' of this substep (the turn from
    /// rest), so a rigid motion turns every particle with it. Particles in no cluster
    /// keep theirs. Memberships are summed in slot order: the same for any thread count.
    pub fn blend_orientations(&self, orientations: &mut [Quat]) {
        // (each particle sums its own clusters, in slot order: the lists are as new as
        // the coefficients, which every substep brings up to date before its solve)
        debug_assert!(!self.coefficients_stale);
        let (slots, rotations) = (&self.particle_slots, &self.rotations);
        orientations
            .par_iter_mut()
            .zip(self.slot_starts.par_windows(2))
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(q, span)| {
                let current = glam::Vec4::from(*q);
                let mut sum = glam::Vec4::ZERO;
                for &k in &slots[span[0] as usize..span[1] as usize] {
                    let r = glam::Vec4::from(rotations[k as usize]);
                    sum += if current.dot(r) < 0.0 { -r } else { r };
                }
                let length = sum.length();
                if length > 1e-6 {
                    *q = Quat::from_vec4(sum / length);
                }
            });
    }

    /// Lists each particle's cluster slots, ascending (a counting sort of the
    /// memberships by the particles' cluster counts, visited in slot order).
    pub(super) fn index_slots_by_particle(&mut self) {
        let mut starts = std::mem::take(&mut self.slot_starts);
        starts.clear();
        starts.push(0);
        let mut total = 0;
        starts.extend(self.member_count.iter().map(|&count| {
            total += count;
            total
        }));
        let mut slots = std::mem::take(&mut self.particle_slots);
        slots.clear();
        slots.resize(total as usize, 0);
        let mut next = starts.clone();
        for (k, range) in self.cluster_range.iter().enumerate() {
            for &m in &self.member_particle[range[0] as usize..range[1] as usize] {
                let at = &mut next[m as usize];
                slots[*at as usize] = k as u32;
                *at += 1;
            }
        }
        self.slot_starts = starts;
        self.particle_slots = slots;
    }

    /// Starts every cluster's turn at its fit to the substep's starting positions
    /// `previous`, and its rotation at its fit to the `predictions`, both to convergence
    /// (see the module docs). Eight clusters are fitted at once, each exactly as
    /// [`ClusterTerm::fit_rotation`] fits it alone.
    pub(in crate::solver) fn fit_turns(&mut self, previous: &[Vec3A], predictions: &[Vec3A]) {
        let mut rotations = std::mem::take(&mut self.rotations);
        let mut start = std::mem::take(&mut self.substep_start);
        start.resize(rotations.len(), Quat::IDENTITY);
        rotations
            .par_chunks_mut(CLUSTERS_PER_TASK)
            .zip(start.par_chunks_mut(CLUSTERS_PER_TASK))
            .enumerate()
            .for_each(|(task, (rotations, start))| {
                dispatch(FitTurns {
                    term: self,
                    first: task * CLUSTERS_PER_TASK,
                    rotations,
                    start,
                    previous,
                    predictions,
                })
            });
        self.rotations = rotations;
        self.substep_start = start;
    }
}

/// [`ClusterTerm::fit_turns`] for the clusters from `first` on, eight at a time.
struct FitTurns<'a> {
    term: &'a ClusterTerm,
    first: usize,
    rotations: &'a mut [Quat],
    start: &'a mut [Quat],
    previous: &'a [Vec3A],
    predictions: &'a [Vec3A],
}

impl WithLanes for FitTurns<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lane>(self) {
        let chunks = self
            .rotations
            .chunks_mut(LANES)
            .zip(self.start.chunks_mut(LANES));
        for (c, (rotations, start)) in chunks.enumerate() {
            let first = self.first + c * LANES;
            let warm = std::array::from_fn(|l| rotations.get(l).copied().unwrap_or_default());
            let clusters = first..first + rotations.len();
            let turned = fit_eight::<L>(self.term, clusters.clone(), self.previous, warm);
            let fitted = fit_eight::<L>(self.term, clusters, self.predictions, turned);
            for (l, (rotation, start)) in rotations.iter_mut().zip(start).enumerate() {
                (*rotation, *start) = (fitted[l], turned[l]);
            }
        }
    }
}

/// The rotations of `clusters` (at most eight) fitted to `positions` from `warm` to
/// convergence, each as [`ClusterTerm::fit_rotation`] fits it: a cluster without
/// members keeps its warm start (as do the lanes past the last cluster).
#[inline(always)]
fn fit_eight<L: Lane>(
    term: &ClusterTerm,
    clusters: std::ops::Range<usize>,
    positions: &[Vec3A],
    warm: [Quat; LANES],
) -> [Quat; LANES] {
    let moments: [Option<Mat3A>; LANES] = std::array::from_fn(|l| {
        let k = clusters.start + l;
        clusters.contains(&k).then(|| term.moment(k, positions))?
    });
    let fitted = extract_rotations_lockstep::<L>(
        &moments.map(Option::unwrap_or_default),
        warm,
        FORGOTTEN_TURN_FIT_ITERATIONS,
    );
    std::array::from_fn(|l| moments[l].map_or(warm[l], |_| fitted[l]))
}
