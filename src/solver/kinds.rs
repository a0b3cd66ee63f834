//! The seam for constraint kinds. The solver's core kind, cluster shape matching, is the
//! dense kernel of this module's parent; every other kind (contacts, colliders, and later
//! distance, oriented-particle or centroid constraints) implements [`ConstraintKind`]
//! and is listed once, in order, in [`ConstraintKinds::in_order`]. Each iteration of a
//! solve runs the cluster pass, then every kind's [`ConstraintKind::project`] in that
//! order, so a kind sees (and corrects) what the kinds before it left.
//!
//! A kind owns its data and its kernel; it reaches particle state only through
//! [`ParticleState`], and adds every move it makes to the particle's correction, from
//! which the engine derives velocities (`v += Σ Δp / dt`).

use super::colliders::Colliders;
use super::contacts::Contacts;
use glam::Vec3A;

/// The solver's particle arrays as a kind sees them (dense solver order).
pub struct ParticleState<'a> {
    /// Positions being solved (predicted at the start of the substep).
    pub positions: &'a mut [Vec3A],
    /// Positions at the start of the substep (friction and swept tests).
    pub previous: &'a [Vec3A],
    /// Inverse masses; 0 pins a particle, which no kind may move.
    pub inv_mass: &'a [f32],
    /// Total correction of each particle in this substep; a kind adds its moves here.
    pub corrections: &'a mut [Vec3A],
}

impl ParticleState<'_> {
    /// Moves particle `i` by `step` and records the move as a correction.
    #[inline]
    pub fn shift(&mut self, i: usize, step: Vec3A) {
        self.positions[i] += step;
        self.corrections[i] += step;
    }
}

/// A kind of constraint projected inside the solver iterations.
pub trait ConstraintKind: Send + Sync {
    /// A short name, for profiles and reports.
    fn name(&self) -> &'static str;

    /// Whether the kind has nothing to project (the solver then skips it).
    fn is_empty(&self) -> bool;

    /// Called once per substep before the iterations, with the predicted positions: the
    /// place for work that the iterations share (finding contact pairs, say).
    fn begin_substep(&mut self, _state: &ParticleState) {}

    /// Projects the kind's constraints once; called after the cluster pass of every
    /// iteration. Must be deterministic for any thread count.
    fn project(&mut self, state: &mut ParticleState);
}

/// Every kind besides cluster shape matching, with its data.
#[derive(Debug, Default)]
pub struct ConstraintKinds {
    /// Particle–particle contacts between bodies, pieces and folds of one piece.
    pub contacts: Contacts,
    /// The ground, static and kinematic colliders.
    pub colliders: Colliders,
    /// Wall-clock seconds each kind has spent in solves, in [`ConstraintKinds::in_order`]
    /// order (for reports; never read by the solver).
    pub seconds: [f64; 2],
}

impl ConstraintKinds {
    /// The kinds in the order they are projected: the one place a kind is registered.
    /// Colliders come last so that no other kind leaves a particle inside one.
    pub fn in_order(&mut self) -> ([&mut dyn ConstraintKind; 2], &mut [f64; 2]) {
        ([&mut self.contacts, &mut self.colliders], &mut self.seconds)
    }
}
