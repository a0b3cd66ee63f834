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
    for rebuilt in &mut rebuilt.bodies {
        let Ok((body, lattice, mut index)) = bodies.get_mut(rebuilt.body) else {
            continue;
        };
        let max = body.material.max_cluster_size as usize;
        let mut store = EcsClusterStore::new(
            rebuilt.body,
            body.material.stiffness,
            &mut index.0,
            &mut clusters,
            &mut commands,
        );
        let outcome = reconstruct::split_oversized(
            &mut store,
            &lattice.lattice,
            &rebuilt.clusters,
            max,
            &mut rng.0,
        );
        rebuilt.clusters = outcome.clusters;
        rebuilt.cut_edges = outcome.cut_edges;
        store.finish();
    }
    timings.current_ms += start.elapsed().as_secs_f64() * 1e3;
}
