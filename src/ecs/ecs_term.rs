//! A term's ECS side: the seam through which a constraint kind takes its data from the
//! ECS. A kind that reads components implements [`EcsTerm`] beside its kernel — the
//! data it reads as a [`bevy_ecs::system::SystemParam`], what it does with them in
//! [`EcsTerm::sync`] — and is registered by one call:
//! [`crate::sim::simulation::Simulation::add_ecs_term`], or
//! [`crate::systems::add_ecs_term`] on a bare world. The schedule runs its sync once a
//! frame, after the layout is brought up to date and before the terms hear of what
//! changed; a kind that needs the ECS every substep implements [`EcsSubstepTerm`]. What
//! a kind carries from frame to frame is saved through
//! [`crate::solver::term::Term::saved_state`]; a stage that hands what a term found back
//! to the ECS reads it through [`TermOf`].

use crate::ecs::layout::SolverCache;
use crate::solver::term::Term;
use bevy_ecs::system::{ReadOnlySystemParam, SystemParamItem};

/// A constraint kind that takes its data from the ECS (see the module docs).
pub trait EcsTerm: Term + Sized {
    /// What the term reads: queries and resources, read-only.
    type Data: ReadOnlySystemParam + 'static;

    /// Takes this frame's data. Runs at the start of every frame (and when a simulation
    /// is saved or loaded), the layout already up to date. Returns true when the
    /// particles the term acts on changed: every term then hears the topology again this
    /// frame, where the term resolves its particles' dense indices ([`Term::topology`]).
    fn sync(&mut self, data: SystemParamItem<Self::Data>) -> bool;
}

/// A constraint kind that takes data from the ECS at every substep (the colliders
/// placed where they are over it), after predict and before the solve. Registered by
/// [`crate::sim::simulation::Simulation::add_ecs_substep_term`] (the built-ins: with
/// [`crate::systems::term_sync::term_substep_system`] in the substep schedule).
pub trait EcsSubstepTerm: Term + Sized {
    /// What the term reads each substep: queries and resources, read-only (and its own
    /// `Local` state).
    type SubstepData: ReadOnlySystemParam + 'static;

    /// Takes this substep's data (the substep's index: [`crate::ecs::resources::SubstepClock`]).
    fn substep(&mut self, data: SystemParamItem<Self::SubstepData>);
}

/// Read access to the solver's term of kind `T` from a system: the stage that hands
/// what a term found back to the ECS reads it through this.
#[derive(bevy_ecs::system::SystemParam)]
pub struct TermOf<'w, T: Term> {
    cache: bevy_ecs::prelude::Res<'w, SolverCache>,
    kind: std::marker::PhantomData<T>,
}

impl<T: Term> TermOf<'_, T> {
    /// The solver's term of kind `T`, if it has one.
    pub fn get(&self) -> Option<&T> {
        self.cache.solver.terms.get::<T>()
    }
}
