//! Stage expand (reconstruction steps 3 and 4): the parts of split clusters grow by
//! random adjacent particles; then every lattice edge a split separated is covered by a
//! cluster again, which guarantees what expansion aims at (no isolated cluster), and the
//! clusters that lie inside others are removed. Writes cluster data only.

use super::ecs_store::BodyClusters;
use crate::ecs::resources::{ClustersRebuilt, CutTimings, RebuiltClusters, SimRng};
use crate::reconstruct;
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::expand_and_repair`] on what regroup and split produced.
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
        let keys = reconstruct::expand_and_repair(
            &mut store,
            lattice,
            &rebuilt.clusters,
            &rebuilt.split_parts,
            &rebuilt.cut_edges,
            m,
            &mut rng.0,
        );
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
