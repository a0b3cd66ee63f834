//! Stage expand (reconstruction steps 3 and 4): the parts of split clusters grow by random adjacent
//! particles; then every lattice edge a split separated is covered by a cluster again,
//! which guarantees what §3.4 aims at (no isolated cluster), and the clusters that lie
//! inside others are removed. Writes cluster data only.

use super::ecs_store::BodyClusters;
use crate::clustering::cover_edge_list;
use crate::reconstruct;
use crate::resources::{ClustersRebuilt, CutTimings, RebuiltClusters, SimRng};
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::expand_clusters`] on the split parts, [`cover_edge_list`] on the
/// edges the splits separated, and [`reconstruct::remove_contained`] on every cluster
/// the cut event touched.
pub fn expand(
    mut rng: ResMut<SimRng>,
    rebuilt: Res<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut clusters: BodyClusters,
    mut messages: MessageWriter<ClustersRebuilt>,
) {
    if rebuilt.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for rebuilt in &rebuilt.bodies {
        let Some((mut store, m, lattice)) = clusters.open(rebuilt.body) else {
            continue;
        };
        let max = m.max_cluster_size as usize;
        reconstruct::expand_clusters(
            &mut store,
            lattice,
            &rebuilt.split_parts,
            m.expand_count as usize,
            max,
            &mut rng.0,
        );
        let mut keys = rebuilt.clusters.clone();
        keys.extend(cover_edge_list(
            &mut store,
            lattice,
            &rebuilt.cut_edges,
            max,
        ));
        let removed = reconstruct::remove_contained(&mut store, lattice.len(), &keys);
        keys.retain(|k| removed.binary_search(k).is_err());
        keys.sort_unstable();
        keys.dedup();
        let clusters = store.entities_of(keys);
        store.finish();
        messages.write(ClustersRebuilt {
            body: rebuilt.body,
            clusters,
        });
    }
    let total = timings.current_ms + start.elapsed().as_secs_f64() * 1e3;
    timings.event_ms.push(total);
    timings.current_ms = 0.0;
}
