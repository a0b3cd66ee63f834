//! Cluster reconstruction after a cut (SPEC §3–4), as pure functions over a
//! [`crate::cluster_store::ClusterStore`]:
//! [`regroup()`] (pieces, dropped when redundant, fragments merged, §3.1–3.2),
//! [`split_oversized`] (§3.3 and §4), [`expand_clusters`] (§3.4), then
//! [`crate::clustering::cover_edge_list`] (the local edge-cover repair) and
//! [`remove_contained`] (no cluster inside another).
//! [`rebuild_after_cut`] runs them in order, as the ECS stages do.

pub mod contained;
pub mod expand;
pub mod local;
pub mod pca;
pub mod regroup;
pub mod split;

pub use contained::remove_contained;
pub use expand::expand_clusters;
pub use regroup::regroup;
pub use split::{SplitOutcome, split_cluster, split_oversized};

use crate::cluster_store::ClusterStore;
use crate::clustering::cover_edge_list;
use crate::config::Material;
use crate::lattice::Lattice;
use rand::Rng;

/// The whole reconstruction of SPEC §3 for one body whose particles have already been
/// removed from `lattice`: regroup the `cut_clusters`, split what grew bigger than
/// [`Material::split_size`], expand the split parts, restore the cover of the edges the
/// splits separated, and remove the clusters that lie inside others. Returns the
/// rebuilt clusters that remain.
pub fn rebuild_after_cut<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[u32],
    material: &Material,
    rng: &mut impl Rng,
) -> Vec<u32> {
    let max = material.max_cluster_size as usize;
    let produced = regroup(store, lattice, cut_clusters, rng);
    let split = split_oversized(
        store,
        lattice,
        &produced,
        material.split_size() as usize,
        rng,
    );
    expand_clusters(
        store,
        lattice,
        &split.parts,
        material.expand_count as usize,
        max,
        rng,
    );
    let mut rebuilt = split.clusters;
    rebuilt.extend(cover_edge_list(store, lattice, &split.cut_edges, max));
    let removed = remove_contained(store, lattice.len(), &rebuilt);
    rebuilt.retain(|k| removed.binary_search(k).is_err());
    rebuilt
}
