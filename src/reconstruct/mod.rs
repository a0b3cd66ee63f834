//! Cluster reconstruction after a cut (SPEC §3–4), as pure functions over a
//! [`crate::cluster_store::ClusterStore`]:
//! [`regroup()`] (pieces and merge, §3.1–3.2), [`split_oversized`] (§3.3 and §4),
//! [`expand_clusters`] (§3.4),
//! then [`crate::clustering::cover_edge_list`] (the local edge-cover repair).
//! [`rebuild_after_cut`] runs all four in order, as the ECS stages do one per system.

pub mod expand;
pub mod local;
pub mod pca;
pub mod regroup;
pub mod split;

pub use expand::expand_clusters;
pub use regroup::regroup;
pub use split::{SplitOutcome, split_cluster, split_oversized};

use crate::cluster_store::ClusterStore;
use crate::clustering::cover_edge_list;
use crate::config::Material;
use crate::lattice::Lattice;
use rand::Rng;

/// The whole reconstruction of SPEC §3 for one body whose particles have already been
/// removed from `lattice`: regroup the `cut_clusters`, split what grew too big, expand,
/// and restore the cover of the edges the splits separated. Returns the rebuilt clusters.
pub fn rebuild_after_cut<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[u32],
    material: &Material,
    rng: &mut impl Rng,
) -> Vec<u32> {
    let max = material.max_cluster_size as usize;
    let produced = regroup(store, lattice, cut_clusters, rng);
    let split = split_oversized(store, lattice, &produced, max, rng);
    expand_clusters(
        store,
        lattice,
        &split.clusters,
        material.expand_count as usize,
        max,
        rng,
    );
    cover_edge_list(store, lattice, &split.cut_edges, max);
    split.clusters
}
