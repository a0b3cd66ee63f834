//! Keeps the terms in step with the ECS, once at the start of each frame (after the
//! layout, in [`crate::systems::SyncSchedule`]): first every term that takes data from
//! the ECS takes it ([`sync_term`], one system per kind, registered with the kind by
//! [`crate::systems::add_ecs_term`], the built-in ones in
//! [`crate::systems::build_sync_schedule`]);
//! then, when the layout changed or one of them said its particles did, every term
//! hears of the topology ([`sync_terms`]). Writes the solver cache only.

use crate::ecs::components::{Body, BodyLattice};
use crate::ecs::ecs_term::{EcsSubstepTerm, EcsTerm};
use crate::ecs::layout::SolverCache;
use crate::solver::term::{BodyTopology, Topology};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleConfigs;
use bevy_ecs::system::{ScheduleSystem, StaticSystemParam};

/// The systems of the terms that take data from the ECS: before [`sync_terms`]. Each
/// writes only its own term (and asks for the topology), so their order among
/// themselves does not matter.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TermData;

/// Lets the term of kind `T`, if the solver has one, take its data from the ECS.
pub fn sync_term<T: EcsTerm>(mut cache: ResMut<SolverCache>, data: StaticSystemParam<T::Data>) {
    let SolverCache { solver, layout, .. } = &mut *cache;
    let Some(term) = solver.terms.get_mut::<T>() else {
        return;
    };
    if term.sync(data.into_inner()) {
        layout.request_topology();
    }
}

/// The [`sync_term`] system of `T`, in [`TermData`].
pub fn term_data_system<T: EcsTerm>() -> ScheduleConfigs<ScheduleSystem> {
    sync_term::<T>
        .in_set(TermData)
        .ambiguous_with(TermData)
        .into_configs()
}

/// The systems of the terms that take data from the ECS every substep: after predict,
/// before the solve. Each writes only its own term, so their order among themselves
/// does not matter.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TermSubstepData;

/// Lets the term of kind `T`, if the solver has one, take this substep's data.
pub fn substep_term<T: EcsSubstepTerm>(
    mut cache: ResMut<SolverCache>,
    data: StaticSystemParam<T::SubstepData>,
) {
    if let Some(term) = cache.solver.terms.get_mut::<T>() {
        term.substep(data.into_inner());
    }
}

/// The [`substep_term`] system of `T`, in [`TermSubstepData`].
pub fn term_substep_system<T: EcsSubstepTerm>() -> ScheduleConfigs<ScheduleSystem> {
    substep_term::<T>
        .in_set(TermSubstepData)
        .ambiguous_with(TermSubstepData)
        .into_configs()
}

/// Tells every term of the topology when it changed (see the module docs).
pub fn sync_terms(mut cache: ResMut<SolverCache>, bodies: Query<(&Body, &BodyLattice)>) {
    let SolverCache { solver, layout, .. } = &mut *cache;
    let Some(pending) = layout.take_pending_topology() else {
        return;
    };
    let views: Vec<BodyTopology> = layout
        .bodies()
        .iter()
        .filter_map(|b| {
            let (body, lattice) = bodies.get(b.body).ok()?;
            Some(BodyTopology {
                id: b.body.to_bits(),
                lattice: &lattice.lattice,
                dense: &b.dense,
                material: &body.material,
                groups: &body.groups,
                pieces: lattice.pieces,
                changed: pending.relaid || pending.bodies.contains(&b.body),
            })
        })
        .collect();
    solver.topology(&Topology {
        bodies: &views,
        relaid: pending.relaid,
    });
}
