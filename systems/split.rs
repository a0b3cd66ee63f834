//! Stage split (SPEC §3.3, §4): splits rebuilt clusters above `max_cluster_size`.
//! Writes cluster data only.

use super::ecs_store::EcsClusterStore;
use crate::components::{Body, BodyLattice, ClusterMembers, ParticleClusters};
use crate::reconstruct;
use crate::resources::{CutTimings, RebuiltClusters, SimRng};
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::split_oversized`] on the clusters regroup produced.
pub fn split(
    mut commands: Commands,
    mut rng: ResMut<SimRng>,
    mut rebuilt: ResMut<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut bodies: Query<(&Body, &BodyLattice, &mut ParticleClusters)>,
    mut clusters: Query<&mut ClusterMembers>,
) {
    if rebuilt.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for (body_entity, keys) in &mut rebuilt.bodies {
        let Ok((body, lattice, mut index)) = bodies.get_mut(*body_entity) else {
            continue;
        };
        let max = body.material.max_cluster_size as usize;
        let mut store = EcsClusterStore::new(
            *body_entity,
            body.material.stiffness,
            &mut index.0,
            &mut clusters,
            &mut commands,
        );
        *keys = reconstruct::split_oversized(&mut store, &lattice.lattice, keys, max, &mut rng.0);
        store.finish();
    }
    timings.current_ms += start.elapsed().as_secs_f64() * 1e3;
}
