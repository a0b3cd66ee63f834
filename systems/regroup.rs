//! Stage regroup (reconstruction step 1): cut clusters → pieces; redundant pieces dropped,
//! fragments merged into neighbours (after giving the new halves of split particles
//! their clusters); after a split, what that produced grown again from the seed grid
//! ([`reconstruct::reseed()`]). Writes cluster data only.
//!
//! A cluster entity despawned from outside (by a game, say) is forgotten here first:
//! its particles and edges are covered again, so the body stays legal.

use super::ecs_store::BodyClusters;
use crate::clusters::clustering::cover_particles;
use crate::clusters::store::ClusterStore;
use crate::ecs::components::ClusterMembers;
use crate::ecs::resources::{CutReport, CutTimings, RebuiltBody, RebuiltClusters, SimRng};
use crate::reconstruct;
use bevy_ecs::prelude::*;
use rustc_hash::FxHashSet;
use std::time::Instant;

/// Repairs around clusters despawned from outside, then runs [`reconstruct::regroup()`]
/// on every body that lost particles or edges.
pub fn regroup(
    report: Res<CutReport>,
    mut rng: ResMut<SimRng>,
    mut rebuilt: ResMut<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut removed: RemovedComponents<ClusterMembers>,
    mut clusters: BodyClusters,
) {
    rebuilt.bodies.clear();
    let gone: FxHashSet<Entity> = removed.read().collect();
    for (body, lost) in clusters.lost_clusters(&gone) {
        let Some((mut store, material, lattice)) = clusters.open(body) else {
            continue;
        };
        let held = store.forget(&lost);
        let max = material.max_cluster_size as usize;
        let changed = cover_particles(&mut store, lattice, &held, max);
        store.finish();
        rebuilt.bodies.push(RebuiltBody {
            body,
            clusters: changed,
            cut_edges: Vec::new(),
            split_parts: Vec::new(),
        });
    }
    if report.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for cut in &report.bodies {
        let grid = clusters.seed_grid(cut.body).unwrap_or_default();
        let Some((mut store, material, lattice)) = clusters.open(cut.body) else {
            continue;
        };
        // a split particle's new half joins each of its clusters; the pieces below part
        // the halves by their edges
        for &(old, new) in &cut.splits {
            for k in store.clusters_of(old).to_vec() {
                store.add_members(k, &[new]);
            }
        }
        let mut produced = reconstruct::regroup(&mut store, lattice, &cut.cut_clusters, &mut rng.0);
        if !cut.splits.is_empty() {
            produced = reconstruct::reseed(&mut store, lattice, material, grid, &produced);
        }
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
