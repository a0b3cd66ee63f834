//! Cluster reconstruction after a cut, as pure functions over a
//! [`crate::clusters::store::ClusterStore`]. The *cut clusters* are those that held a
//! removed particle or both ends of a severed edge.
//!
//! 1. **Pieces** ([`regroup()`]): each cut cluster falls into its connected pieces. A
//!    piece whose particles and edges all lie in other clusters is redundant and goes;
//!    a piece whose rest shape is a point or a line (a *fragment*, which cannot fix a
//!    rotation) merges into the neighbour cluster that holds most of it; the other
//!    pieces stay clusters — they are what a fresh clustering builds there.
//! 2. **Split** ([`split_oversized`]): a cluster larger than the initial clustering's
//!    largest is split in two, and the halves again, on rest positions: the plane
//!    across the long axis of the members' covariance, a connected half grown from a
//!    random member toward that plane, and a repair that leaves both halves connected
//!    ([`split`]).
//! 3. **Expand** ([`expand_clusters`]): the parts of a split grow by a few adjacent
//!    particles, so they overlap their neighbours again.
//! 4. **Repair**: every lattice edge a split separated is covered by a cluster again
//!    ([`crate::clusters::clustering::cover_edge_list`]), so no cluster is isolated from the
//!    ones around it, and no cluster is left inside another ([`remove_contained`]).
//!
//! After a `split` cut, step 1's clusters are grown again from the body's seed grid
//! ([`reseed()`]): the pieces of a cluster a blade split through its particles are not
//! what a fresh clustering of the two sides builds (the ECS stages do this; it is not
//! part of [`rebuild_after_cut`], which knows no splits).
//!
//! Everything is topology: which side of a cut a particle is on is never decided by
//! geometry, so any number of partial, curved or disconnected cuts work alike; the
//! price is that every cluster must stay connected, which all four steps keep.
//! [`rebuild_after_cut`] runs them in order, as the ECS stages do.

pub mod expand;
pub mod local;
mod merge;
pub mod pca;
mod pieces;
pub mod regroup;
pub mod reseed;
pub mod split;

use crate::clusters::contained::remove_contained;
pub use expand::expand_clusters;
pub use regroup::regroup;
pub use reseed::reseed;
pub use split::{SplitOutcome, split_cluster, split_oversized};

use crate::body::lattice::Lattice;
use crate::clusters::clustering::cover_edge_list;
use crate::clusters::store::ClusterStore;
use crate::config::Material;
use rand::Rng;

/// The whole reconstruction for one body whose particles have already been
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
    let produced = regroup(store, lattice, cut_clusters, rng);
    let split = split_oversized(
        store,
        lattice,
        &produced,
        material.split_size() as usize,
        rng,
    );
    expand_and_repair(
        store,
        lattice,
        &split.clusters,
        &split.parts,
        &split.cut_edges,
        material,
        rng,
    )
}

/// Steps 3 and 4 after steps 1–2 produced `clusters`: expands the split `parts`, covers
/// the `cut_edges` the splits separated again, and removes the clusters that lie inside
/// others around them. Returns the rebuilt clusters that remain, ascending.
pub fn expand_and_repair<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    clusters: &[u32],
    parts: &[u32],
    cut_edges: &[(u32, u32)],
    material: &Material,
    rng: &mut impl Rng,
) -> Vec<u32> {
    let max = material.max_cluster_size as usize;
    expand_clusters(
        store,
        lattice,
        parts,
        material.expand_count as usize,
        max,
        rng,
    );
    let mut rebuilt = clusters.to_vec();
    rebuilt.extend(cover_edge_list(store, lattice, cut_edges, max));
    rebuilt.sort_unstable();
    rebuilt.dedup();
    let removed = remove_contained(store, lattice.len(), &rebuilt);
    rebuilt.retain(|k| removed.binary_search(k).is_err());
    rebuilt
}
