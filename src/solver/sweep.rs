//! Colour sweeps: the clusters of one colour share no particle, so their tasks may write
//! their members' entries in parallel. [`Disjoint`] carries those writes; the sweep runs
//! the colours one after another and fits each cluster for the caller.

use super::fit::{ClusterFrame, fit_cluster};
use super::{CLUSTERS_PER_TASK, SolverLayout};
use glam::{Quat, Vec3A};
use rayon::prelude::*;

/// A per-particle or per-cluster array written by the tasks of one colour.
///
/// Soundness rests on the colouring: the clusters of one colour have pairwise disjoint
/// member sets, and a task writes only the entries of its own clusters and of their
/// members, so no entry is written by two tasks, nor read by one task while another
/// writes it. No reference to the array is alive while a colour runs.
#[derive(Clone, Copy)]
pub(super) struct Disjoint<T>(*mut T);

// SAFETY: see the type's docs; tasks of one colour touch pairwise disjoint entries.
unsafe impl<T> Send for Disjoint<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for Disjoint<T> {}

impl<T: Copy> Disjoint<T> {
    pub(super) fn new(v: &mut [T]) -> Self {
        Self(v.as_mut_ptr())
    }

    /// Reads entry `i`.
    ///
    /// # Safety
    /// `i` is in bounds and no other task writes entry `i` during this colour.
    #[inline(always)]
    pub(super) unsafe fn read(self, i: usize) -> T {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.add(i).read() }
    }

    /// Writes entry `i`.
    ///
    /// # Safety
    /// `i` is in bounds and belongs to the calling task during this colour.
    #[inline(always)]
    pub(super) unsafe fn write(self, i: usize, value: T) {
        // SAFETY: guaranteed by the caller.
        unsafe { self.0.add(i).write(value) }
    }
}

impl SolverLayout {
    /// Fits cluster `k` inside a colour sweep, reading positions through `position` and
    /// updating its warm-start rotation through `rotations`. Returns the member range
    /// (into `member_particle` and `member_moment`), the frame and the stiffness.
    ///
    /// # Safety
    /// The caller is the task that owns cluster `k` in the current colour.
    #[inline(always)]
    pub(super) unsafe fn fit_in_sweep(
        &self,
        k: usize,
        position: impl Fn(usize) -> Vec3A,
        rotations: Disjoint<Quat>,
    ) -> (std::ops::Range<usize>, ClusterFrame, f32) {
        let [start, end] = self.cluster_range[k];
        let range = start as usize..end as usize;
        let constants = self.constants(k);
        // SAFETY: rotation `k` belongs to the calling task (the caller's contract).
        let mut rotation = unsafe { rotations.read(k) };
        let frame = fit_cluster(
            &self.member_particle[range.clone()],
            &self.member_moment[range.clone()],
            position,
            constants,
            &mut rotation,
        );
        // SAFETY: as above.
        unsafe { rotations.write(k, rotation) };
        (range, frame, constants.stiffness)
    }

    /// Runs `f(k)` for every cluster `k`, colour after colour; the clusters of one colour
    /// run in parallel (they share no particle).
    pub(super) fn for_each_cluster_by_colour(&self, f: impl Fn(usize) + Sync) {
        for colour in self.colour_start.windows(2) {
            self.colour_order[colour[0] as usize..colour[1] as usize]
                .par_chunks(CLUSTERS_PER_TASK)
                .for_each(|chunk| chunk.iter().for_each(|&k| f(k as usize)));
        }
    }
}
