//! Stage regroup (SPEC §3.1–3.2): cut clusters → pieces → merged into neighbours.
//! Writes cluster data only.

use super::ecs_store::EcsClusterStore;
use crate::components::{Body, BodyLattice, ClusterMembers, ParticleClusters};
use crate::reconstruct;
use crate::resources::{CutReport, CutTimings, RebuiltBody, RebuiltClusters, SimRng};
use bevy_ecs::prelude::*;
use std::time::Instant;

/// Runs [`reconstruct::regroup()`] on every body that lost particles.
pub fn regroup(
    mut commands: Commands,
    report: Res<CutReport>,
    mut rng: ResMut<SimRng>,
    mut rebuilt: ResMut<RebuiltClusters>,
    mut timings: ResMut<CutTimings>,
    mut bodies: Query<(&Body, &BodyLattice, &mut ParticleClusters)>,
    mut clusters: Query<&mut ClusterMembers>,
) {
    rebuilt.bodies.clear();
    if report.bodies.is_empty() {
        return;
    }
    let start = Instant::now();
    for cut in &report.bodies {
        let Ok((body, lattice, mut index)) = bodies.get_mut(cut.body) else {
            continue;
        };
        let mut store = EcsClusterStore::new(
            cut.body,
            body.material.stiffness,
            &mut index.0,
            &mut clusters,
            &mut commands,
        );
        let produced =
            reconstruct::regroup(&mut store, &lattice.lattice, &cut.cut_clusters, &mut rng.0);
        store.finish();
        rebuilt.bodies.push(RebuiltBody {
            body: cut.body,
            clusters: produced,
            cut_edges: Vec::new(),
        });
    }
    timings.current_ms = start.elapsed().as_secs_f64() * 1e3;
}
