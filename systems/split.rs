//! Stage split (reconstruction step 2): splits rebuilt clusters larger than the material's
//! [`crate::config::Material::split_size`]. Writes cluster data only.

use super::ecs_store::BodyClusters;
use crate::ecs::resources::{CutTimings, RebuiltClusters, SimRng};
use crate::reconstruct;
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::split_oversized`] on the clusters regroup produced.
pub fn split(
    mut rng: ResMut<SimRng>,
    mut rebuilt: ResMut<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut clusters: BodyClusters,
) {
    if rebuilt.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for rebuilt in &mut rebuilt.bodies {
        let Some((mut store, material, lattice)) = clusters.open(rebuilt.body) else {
            continue;
        };
        let too_big = material.split_size() as usize;
        let keys = &rebuilt.clusters;
        let outcome = reconstruct::split_oversized(&mut store, lattice, keys, too_big, &mut rng.0);
        rebuilt.clusters = outcome.clusters;
        rebuilt.split_parts = outcome.parts;
        // (after the edges a carve linked again, which regroup listed)
        rebuilt.cut_edges.extend(outcome.cut_edges);
        store.finish();
    }
    timings.current_ms += start.elapsed().as_secs_f64() * 1e3;
}
