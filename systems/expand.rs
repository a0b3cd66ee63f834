//! Stage expand (SPEC §3.4): rebuilt clusters grow by random adjacent particles; then
//! every lattice edge a split separated is covered by a cluster again, which guarantees
//! what §3.4 aims at (no isolated cluster).
//! Writes cluster data only.

use super::ecs_store::EcsClusterStore;
use crate::clustering::cover_edge_list;
use crate::components::{Body, BodyLattice, ClusterMembers, ParticleClusters};
use crate::reconstruct;
use crate::resources::{ClustersRebuilt, CutTimings, RebuiltClusters, SimRng};
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::expand_clusters`], then [`cover_edge_list`] on the edges the
/// splits separated.
pub fn expand(
    mut commands: Commands,
    mut rng: ResMut<SimRng>,
    rebuilt: Res<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut bodies: Query<(&Body, &BodyLattice, &mut ParticleClusters)>,
    mut clusters: Query<&mut ClusterMembers>,
    mut messages: MessageWriter<ClustersRebuilt>,
) {
    if rebuilt.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for rebuilt in &rebuilt.bodies {
        let Ok((body, lattice, mut index)) = bodies.get_mut(rebuilt.body) else {
            continue;
        };
        let m = &body.material;
        let mut store = EcsClusterStore::new(
            rebuilt.body,
            m.stiffness,
            &mut index.0,
            &mut clusters,
            &mut commands,
        );
        reconstruct::expand_clusters(
            &mut store,
            &lattice.lattice,
            &rebuilt.clusters,
            m.expand_count as usize,
            m.max_cluster_size as usize,
            &mut rng.0,
        );
        cover_edge_list(
            &mut store,
            &lattice.lattice,
            &rebuilt.cut_edges,
            m.max_cluster_size as usize,
        );
        store.finish();
        messages.write(ClustersRebuilt {
            body: rebuilt.body,
            clusters: rebuilt.clusters.clone(),
        });
    }
    let total = timings.current_ms + start.elapsed().as_secs_f64() * 1e3;
    timings.event_ms.push(total);
    timings.current_ms = 0.0;
}
