//! Cluster reconstruction after a cut (SPEC §3–4), as pure functions over a
//! [`crate::cluster_store::ClusterStore`]:
//! [`regroup()`] (pieces and merge, §3.1–3.2), [`split_oversized`] (§3.3 and §4),
//! [`expand_clusters`] (§3.4),
//! then [`cover_rebuilt`] (the local edge-cover repair). [`rebuild_after_cut`] runs all
//! four in order, as the ECS stages do one per system.

pub mod expand;
pub mod pca;
pub mod regroup;
pub mod split;

pub use expand::expand_clusters;
pub use regroup::regroup;
pub use split::{split_cluster, split_oversized};

use crate::cluster_store::ClusterStore;
use crate::clustering::cover_edges;
use crate::config::Material;
use crate::lattice::Lattice;
use rand::Rng;

/// Restores edge cover around the rebuilt clusters `keys` (see [`cover_edges`]): only
/// edges at their members can have lost it.
pub fn cover_rebuilt<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    keys: &[S::Key],
    max: usize,
) -> usize {
    let mut particles: Vec<u32> = keys
        .iter()
        .flat_map(|k| store.members(*k).iter().copied())
        .collect();
    particles.sort_unstable();
    particles.dedup();
    cover_edges(store, lattice, particles, max)
}

/// The whole reconstruction of SPEC §3 for one body whose particles have already been
/// removed from `lattice`: regroup the `cut_clusters`, split what grew too big, expand,
/// and restore edge cover. Returns the rebuilt clusters.
pub fn rebuild_after_cut<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[S::Key],
    material: &Material,
    rng: &mut impl Rng,
) -> Vec<S::Key> {
    let max = material.max_cluster_size as usize;
    let produced = regroup(store, lattice, cut_clusters, rng);
    let produced = split_oversized(store, lattice, &produced, max, rng);
    expand_clusters(
        store,
        lattice,
        &produced,
        material.expand_count as usize,
        max,
        rng,
    );
    cover_rebuilt(store, lattice, &produced, max);
    produced
}
