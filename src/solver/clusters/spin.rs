//! The clusters' turn, carried from substep to substep: each substep starts every
//! cluster's rotation fit from its last rotation turned once more by the turn it made in
//! the last substep.
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

use super::term::{CLUSTERS_PER_TASK, ClusterTerm};
use glam::Quat;
use rayon::prelude::*;

/// The smallest turn per substep carried ahead, as the sine of half its angle: 1e-6
/// (2e-6 rad, 5e-4 rad/s at 240 substeps a second). The rotation fits of a body at rest
/// wander by less.
const SMALLEST_TURN: f32 = 1e-6;

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
}
