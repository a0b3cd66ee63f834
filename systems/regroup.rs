//! Stage regroup (SPEC §3.1–3.2): cut clusters → pieces; redundant pieces dropped,
//! fragments merged into neighbours (after giving the new halves of split particles
//! their clusters). Writes cluster data only.

use super::ecs_store::{BodyClusters, keys_of};
use crate::cluster_store::ClusterStore;
use crate::reconstruct;
use crate::resources::{CutReport, CutTimings, RebuiltBody, RebuiltClusters, SimRng};
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::regroup()`] on every body that lost particles.
pub fn regroup(
    report: Res<CutReport>,
    mut rng: ResMut<SimRng>,
    mut rebuilt: ResMut<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut clusters: BodyClusters,
) {
    rebuilt.bodies.clear();
    if report.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for cut in &report.bodies {
        let Some((mut store, _, lattice)) = clusters.open(cut.body) else {
            continue;
        };
        // a split particle's new half joins each of its clusters; the pieces below part
        // the halves by their edges
        for &(old, new) in &cut.splits {
            for k in store.clusters_of(old).to_vec() {
                store.add_members(k, &[new]);
            }
        }
        let cut_clusters = keys_of(&cut.cut_clusters);
        let produced = reconstruct::regroup(&mut store, lattice, &cut_clusters, &mut rng.0);
        let produced = store.entities_of(produced);
        store.finish();
        rebuilt.bodies.push(RebuiltBody {
            body: cut.body,
            clusters: produced,
            cut_edges: cut.relinked.clone(),
            split_parts: Vec::new(),
        });
    }
    timings.current_ms = start.elapsed().as_secs_f64() * 1e3;
}
