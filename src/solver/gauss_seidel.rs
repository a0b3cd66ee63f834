//! The coloured Gauss–Seidel scheme: colour after colour, every cluster of the colour is
//! fitted to the current positions and moves its members by `sₖ (gᵢ − pᵢ)` at once.
//! Clusters of one colour share no particle (see [`super::colour_clusters`]), so they
//! run in parallel and the result does not depend on their order or the thread count.

use super::{CLUSTERS_PER_TASK, SolverLayout, fit_cluster};
use glam::{Quat, Vec3A};
use rayon::prelude::*;

/// The arrays a colour's tasks write, as raw pointers.
///
/// Soundness rests on the colouring: the clusters of one colour have pairwise disjoint
/// member sets, and each task reads and writes only the members and the rotation of its
/// own clusters, so no element is accessed by two tasks. No reference to these arrays
/// exists while a colour runs; every access goes through the pointers.
#[derive(Clone, Copy)]
struct Disjoint {
    positions: *mut Vec3A,
    corrections: *mut Vec3A,
    rotations: *mut Quat,
}

// SAFETY: see the type's docs; tasks of one colour access pairwise disjoint elements.
unsafe impl Send for Disjoint {}
// SAFETY: as above.
unsafe impl Sync for Disjoint {}

impl SolverLayout {
    /// One sweep over all colours.
    pub(super) fn sweep_colours(&mut self) {
        let shared = Disjoint {
            positions: self.positions.as_mut_ptr(),
            corrections: self.corrections.as_mut_ptr(),
            rotations: self.rotations.as_mut_ptr(),
        };
        let this = &*self;
        for colour in this.colour_start.windows(2) {
            this.colour_order[colour[0] as usize..colour[1] as usize]
                .par_chunks(CLUSTERS_PER_TASK)
                .for_each(|chunk| {
                    for &k in chunk {
                        this.project_cluster(k as usize, shared);
                    }
                });
        }
    }

    /// Fits cluster `k` and moves its (unpinned) members by `s (g − p)`.
    ///
    /// Reads only `self`'s constant arrays; positions, corrections and rotations go
    /// through `shared` (no reference to them is alive while a colour runs).
    #[inline]
    fn project_cluster(&self, k: usize, shared: Disjoint) {
        let range = self.cluster_start[k] as usize..self.cluster_start[k + 1] as usize;
        let members = &self.member_particle[range.clone()];
        // SAFETY (all blocks below): `k` belongs to this task; its rotation and its
        // members' positions and corrections are touched by no other task of the colour
        // (see `Disjoint`). Member indices were bounds-checked when the layout was built.
        let rotation = unsafe { &mut *shared.rotations.add(k) };
        let constants = self.constants(k);
        let frame = fit_cluster(
            members,
            &self.member_moment[range],
            |m| unsafe { shared.positions.add(m).read() },
            constants,
            rotation,
        );
        for &m in members {
            let m = m as usize;
            if self.inv_mass[m] == 0.0 {
                continue;
            }
            unsafe {
                let p = shared.positions.add(m);
                let x = p.read();
                let step = frame.scaled_goal(self.rest[m]) - x * constants.stiffness;
                p.write(x + step);
                let correction = shared.corrections.add(m);
                correction.write(correction.read() + step);
            }
        }
    }
}
