//! The coloured Gauss–Seidel scheme: colour after colour, every cluster of the colour is
//! fitted to the current positions and moves its members by `sₖ (gᵢ − pᵢ)` at once.
//! Clusters of one colour share no particle (see [`super::colour_clusters`]), so they
//! run in parallel and the result does not depend on their order or the thread count.

use super::SolverLayout;
use super::batch::PARTICLE_BYTES;
use super::sweep::Disjoint;
use crate::lanes::LANES;

impl SolverLayout {
    /// One sweep over all colours: every cluster (eight at a time) is fitted to the
    /// current positions and moves its unpinned members by `s (g − p)`.
    pub(super) fn sweep_colours(&mut self) {
        let positions = Disjoint::new(&mut self.positions);
        let corrections = Disjoint::new(&mut self.corrections);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        // `self`'s other arrays are only read; positions, corrections and rotations go
        // through the `Disjoint` pointers (no reference to them is alive in a colour).
        this.for_each_batch_by_colour(|b, fit_rows| {
            // SAFETY (both blocks): this task owns the batch's clusters, their rotations
            // and their members' positions and corrections for the colour (see
            // `Disjoint`); member indices were bounds-checked when the layout was built.
            unsafe {
                this.fit_batch(b, fit_rows, positions.as_ptr(), rotations, |row| {
                    for l in 0..LANES {
                        let m = (row.at[l] / PARTICLE_BYTES) as usize;
                        if row.row < row.size[l] as usize && this.inv_mass[m] != 0.0 {
                            let step = row.pull[l];
                            positions.write(m, row.position.lane(l) + step);
                            corrections.write(m, corrections.read(m) + step);
                        }
                    }
                })
            };
        });
    }
}
