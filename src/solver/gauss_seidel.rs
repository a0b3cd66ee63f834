//! The coloured Gauss–Seidel scheme: colour after colour, every cluster of the colour is
//! fitted to the current positions and moves its members by `sₖ (gᵢ − pᵢ)` at once.
//! Clusters of one colour share no particle (see [`super::colour_clusters`]), so they
//! run in parallel and the result does not depend on their order or the thread count.

use super::SolverLayout;
use super::sweep::Disjoint;
use glam::{Quat, Vec3A};

impl SolverLayout {
    /// One sweep over all colours.
    pub(super) fn sweep_colours(&mut self) {
        let positions = Disjoint::new(&mut self.positions);
        let corrections = Disjoint::new(&mut self.corrections);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        this.for_each_cluster_by_colour(|k| {
            this.project_cluster(k, positions, corrections, rotations)
        });
    }

    /// Fits cluster `k` and moves its (unpinned) members by `s (g − p)`.
    ///
    /// Reads only `self`'s constant arrays; positions, corrections and rotations go
    /// through the `Disjoint` pointers (no reference to them is alive while a colour
    /// runs).
    #[inline]
    fn project_cluster(
        &self,
        k: usize,
        positions: Disjoint<Vec3A>,
        corrections: Disjoint<Vec3A>,
        rotations: Disjoint<Quat>,
    ) {
        // SAFETY (all blocks below): cluster `k`, its rotation and its members' positions
        // and corrections belong to this task for the colour (see `Disjoint`); indices
        // were bounds-checked when the layout was built.
        let (range, frame, stiffness) =
            unsafe { self.fit_in_sweep(k, |m| positions.read(m), rotations) };
        let members = &self.member_particle[range.clone()];
        let moments = &self.member_moment[range];
        for (&m, moment) in members.iter().zip(moments) {
            let m = m as usize;
            if self.inv_mass[m] == 0.0 {
                continue;
            }
            unsafe {
                let x = positions.read(m);
                let step = frame.scaled_goal(Vec3A::from_vec4(*moment)) - x * stiffness;
                positions.write(m, x + step);
                corrections.write(m, corrections.read(m) + step);
            }
        }
    }
}
