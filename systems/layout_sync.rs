//! Keeps the solver's dense layout in step with the ECS, once at the start of each
//! frame ([`sync_solver`], in its own [`crate::systems::SyncSchedule`] so that saving a
//! simulation can bring the layout up to date the same way): it gathers what changed
//! since the last run and hands it to [`crate::ecs::layout::SolverLayout::sync`] — a
//! full rebuild when bodies appear or vanish, otherwise a patch of only the clusters
//! that changed (after a cut) and the particles that were cut. What changed is left for
//! the terms ([`super::term_sync`]) to hear.

use crate::ecs::components::*;
use crate::ecs::layout::{BodyItem, ClusterItem, LayoutChanges, SolverCache};
use crate::ecs::resources::{CutReport, SimSettings};
use bevy_ecs::prelude::*;

/// Clusters that changed (or appeared) since the last run (any body).
type ChangedClusters<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static ClusterMembers,
        &'static ClusterOf,
        &'static Compliance,
    ),
    Or<(Changed<ClusterMembers>, Changed<Compliance>)>,
>;

/// Brings the solver layout up to date with what changed in the ECS since the last run:
/// cuts, rebuilt clusters, bodies spawned or despawned, a solver setting changed. Writes
/// the solver cache only.
///
/// After a simulation is loaded, its restored layout already matches the ECS: the first
/// run only takes note of the loaded entities as seen.
#[allow(clippy::too_many_arguments)]
pub fn sync_solver(
    settings: Res<SimSettings>,
    mut cache: ResMut<SolverCache>,
    cut: Res<CutReport>,
    bodies: Query<BodyItem>,
    indices: Query<(Entity, &ParticleClusters)>,
    changed_bodies: Query<Entity, Changed<BodyLattice>>,
    clusters: Query<ClusterItem>,
    changed_clusters: ChangedClusters,
    mut removed_clusters: RemovedComponents<ClusterMembers>,
    mut removed_bodies: RemovedComponents<BodyLattice>,
) {
    let config = &settings.0;
    let SolverCache {
        particles,
        solver,
        layout,
    } = &mut *cache;
    let removed: Vec<Entity> = removed_clusters.read().collect();
    let bodies_removed = removed_bodies.read().count() > 0;
    let changed = solver.mode() != config.solver
        || !removed.is_empty()
        || !changed_bodies.is_empty()
        || !changed_clusters.is_empty();
    if layout.wants_update(bodies_removed, changed) {
        let changed_bodies: Vec<Entity> = changed_bodies.iter().collect();
        let changes = LayoutChanges {
            bodies: &changed_bodies,
            cut: &cut.bodies,
            clusters: changed_clusters.iter().collect(),
            removed: &removed,
            indices: {
                let mut list: Vec<_> = indices.iter().collect();
                list.sort_unstable_by_key(|(b, _)| *b);
                list
            },
        };
        layout.sync(
            solver,
            particles,
            &bodies,
            changes,
            clusters.iter(),
            config.solver,
        );
    }
    // (a rebuilt or a loaded solver starts from the default)
    solver.projective.budget_bytes = config.memory_budget_bytes();
}
