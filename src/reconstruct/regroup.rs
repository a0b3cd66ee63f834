//! SPEC §3.1–3.2: cut clusters fall into pieces (connected components of their live
//! members); each piece merges into a random cluster of one of its adjacent particles,
//! or stays as an independent cluster when it has been cut off the body.

use crate::cluster_store::ClusterStore;
use crate::graph::{connected_components, position_in};
use crate::lattice::Lattice;
use rand::Rng;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};
use smallvec::SmallVec;

/// Particles adjacent to a sorted member set (not in it), in member order then lattice
/// neighbour order; a particle may appear more than once.
pub fn adjacent_in_order<'a>(
    members: &'a [u32],
    lattice: &'a Lattice,
) -> impl Iterator<Item = u32> + 'a {
    members
        .iter()
        .flat_map(|m| lattice.neighbours(*m))
        .filter(|n| position_in(members, *n).is_none())
}

/// Per piece of one cut cluster, its first adjacent particle (in the order of
/// [`adjacent_in_order`]) that belongs to a cluster the cut left intact.
type IntactNeighbours = SmallVec<[Option<u32>; 2]>;

/// The merge forest of §3.2 over local node numbers: the pending clusters are nodes
/// `0..pending`, clusters the cut left intact become nodes when first chosen as a target
/// (they never merge on, so they stay roots).
struct MergeForest<K> {
    node_of: FxHashMap<K, u32>,
    key: Vec<K>,
    parent: Vec<u32>,
}

impl<K: Copy + Eq + std::hash::Hash> MergeForest<K> {
    fn new(pending: &[K]) -> Self {
        Self {
            node_of: pending
                .iter()
                .enumerate()
                .map(|(i, k)| (*k, i as u32))
                .collect(),
            key: pending.to_vec(),
            parent: (0..pending.len() as u32).collect(),
        }
    }

    /// Root node of `node`, with path halving.
    fn find(&mut self, mut node: u32) -> u32 {
        while self.parent[node as usize] != node {
            let grand = self.parent[self.parent[node as usize] as usize];
            self.parent[node as usize] = grand;
            node = grand;
        }
        node
    }

    /// Root node of cluster `k`; `None` for an intact cluster that is not a node yet
    /// (its own root, different from every node's).
    fn root_of(&mut self, k: K) -> Option<u32> {
        let node = *self.node_of.get(&k)?;
        Some(self.find(node))
    }

    /// The node of `k`, created for an intact cluster on first use.
    fn node(&mut self, k: K) -> u32 {
        let next = self.key.len() as u32;
        let node = *self.node_of.entry(k).or_insert(next);
        if node == next {
            self.key.push(k);
            self.parent.push(next);
        }
        node
    }
}

/// Replaces every cut cluster by its pieces, then merges each piece into a neighbour
/// cluster (SPEC §3.2). Returns the clusters this produced — the neighbour clusters that
/// received a merge and the independent pieces — sorted and without duplicates.
///
/// The pieces of all cut clusters are found in parallel (they only read the lattice);
/// everything that draws from `rng` runs in cluster order, so the result does not
/// depend on the thread count. Merges are recorded in a union–find over clusters and the
/// members are moved once at the end, so a chain of merges (a piece merging into a
/// pending cluster that later merges on, which §3.2 allows) costs its total size, not its
/// length × size. A piece looks for its adjacent particle around its own members;
/// particles of pieces already merged into it count as its members, not as neighbours.
pub fn regroup<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[S::Key],
    rng: &mut impl Rng,
) -> Vec<S::Key> {
    let mut cut: Vec<S::Key> = cut_clusters.to_vec();
    cut.sort_unstable();
    cut.dedup();
    // 3.1: pending clusters, and for each the adjacent particle in an intact cluster
    // (see below). Both only read the clusters, so they are found in parallel; a piece
    // sees the index before the cut clusters are replaced by their pieces, which holds
    // the same intact clusters.
    let found: Vec<(Vec<Vec<u32>>, IntactNeighbours)> = {
        let lists: Vec<&[u32]> = cut.iter().map(|k| store.members(*k)).collect();
        let index = store.particle_index();
        let cut_set: FxHashSet<S::Key> = cut.iter().copied().collect();
        lists
            .par_iter()
            .with_min_len(64)
            .map(|members| {
                let pieces = connected_components(members, lattice);
                let intact = pieces
                    .iter()
                    .map(|piece| {
                        adjacent_in_order(piece, lattice).find(|a| {
                            index
                                .get(*a as usize)
                                .is_some_and(|l| l.iter().any(|k| !cut_set.contains(k)))
                        })
                    })
                    .collect();
                (pieces, intact)
            })
            .collect()
    };
    // The first piece keeps the cut cluster's handle, but its list is written only once
    // its fate is known: a piece that merges away is never written back. Until then the
    // index still lists the handle for all of the cut cluster's old members, so
    // `holds_now` reads it as the piece. Later pieces become clusters now.
    let mut pending = Vec::with_capacity(cut.len());
    let mut unwritten: Vec<Option<Vec<u32>>> = Vec::with_capacity(cut.len());
    let mut intact_neighbour = Vec::with_capacity(cut.len());
    for (k, (pieces, intact)) in cut.into_iter().zip(found) {
        intact_neighbour.extend(intact);
        let mut pieces = pieces.into_iter();
        match pieces.next() {
            Some(first) => {
                pending.push(k);
                unwritten.push(Some(first));
            }
            None => store.remove(k),
        }
        for piece in pieces {
            pending.push(store.create(piece));
            unwritten.push(None);
        }
    }
    let first_piece: FxHashMap<S::Key, usize> = pending
        .iter()
        .zip(&unwritten)
        .enumerate()
        .filter(|(_, (_, piece))| piece.is_some())
        .map(|(node, (k, _))| (*k, node))
        .collect();
    // Whether cluster `k`, listed in the index for live particle `a`, holds `a` now.
    let holds_now = |k: &S::Key, a: u32, unwritten: &[Option<Vec<u32>>]| {
        first_piece.get(k).is_none_or(|node| {
            unwritten[*node]
                .as_ref()
                .is_none_or(|piece| piece.binary_search(&a).is_ok())
        })
    };
    // 3.2: choose every merge first, over the merge forest.
    let mut forest = MergeForest::new(&pending);
    let mut merged: Vec<u32> = Vec::new();
    for (own, &p) in pending.iter().enumerate() {
        let chosen = intact_neighbour[own];
        let members = unwritten[own]
            .as_deref()
            .unwrap_or_else(|| store.members(p));
        let own = forest.find(own as u32);
        // The adjacent particle: the first one that belongs to a cluster the cut left
        // intact, else the first one with any cluster outside this piece's merge set.
        // (§3.2 leaves the choice open; preferring intact neighbours keeps chains of
        // merges between pending clusters, and the giant clusters they make, rare.)
        let fallback = match chosen {
            Some(_) => None,
            None => adjacent_in_order(members, lattice).find(|a| {
                store
                    .clusters_of(*a)
                    .iter()
                    .any(|k| holds_now(k, *a, &unwritten) && forest.root_of(*k) != Some(own))
            }),
        };
        let target = chosen.or(fallback).and_then(|a| {
            let candidates: SmallVec<[S::Key; 8]> = store
                .clusters_of(a)
                .iter()
                .copied()
                .filter(|k| holds_now(k, a, &unwritten) && forest.root_of(*k) != Some(own))
                .collect();
            (!candidates.is_empty()).then(|| candidates[rng.random_range(0..candidates.len())])
        });
        if let Some(t) = target {
            let target_node = forest.node(t);
            let root = forest.find(target_node);
            forest.parent[own as usize] = root;
            merged.push(own);
        }
    }
    // Write the first pieces that stay (they may receive merges), then move every merged
    // piece into its final cluster, once, root by root.
    let mut merges_away = vec![false; pending.len()];
    for &p in &merged {
        merges_away[p as usize] = true;
    }
    for (node, piece) in unwritten.iter_mut().enumerate() {
        if !merges_away[node]
            && let Some(piece) = piece.take()
        {
            store.set_members(pending[node], piece);
        }
    }
    let mut moves: Vec<(u32, u32)> = merged.iter().map(|&p| (forest.find(p), p)).collect();
    moves.sort_unstable();
    let mut incoming: Vec<u32> = Vec::new();
    for group in moves.chunk_by(|a, b| a.0 == b.0) {
        incoming.clear();
        for &(_, p) in group {
            let key = pending[p as usize];
            match &unwritten[p as usize] {
                Some(piece) => incoming.extend_from_slice(piece),
                None => incoming.extend_from_slice(store.members(key)),
            }
            store.remove(key);
        }
        incoming.sort_unstable();
        incoming.dedup();
        store.add_members(forest.key[group[0].0 as usize], &incoming);
    }
    let mut produced: Vec<S::Key> = (0..pending.len() as u32)
        .map(|p| {
            let root = forest.find(p);
            forest.key[root as usize]
        })
        .collect();
    produced.sort_unstable();
    produced.dedup();
    produced.retain(|k| !store.members(*k).is_empty());
    produced
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster_store::ClusterTable;
    use crate::graph::is_connected;
    use crate::lattice::Shape;
    use glam::{IVec3, UVec3};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn pieces_merge_into_neighbours_or_stay_independent() {
        // A 6×1×1 bar, clusters {0,1,2}, {2,3,4}, {4,5}; cut particle at x = 1 (index 1)
        let mut l = Shape::cuboid(UVec3::new(6, 1, 1), 1.0)
            .voxelise(1.0)
            .unwrap();
        let idx = |x: i32| l.at(IVec3::new(x - 3, 0, 0)).unwrap();
        let (p0, p1, p2, p3, p4, p5) = (idx(0), idx(1), idx(2), idx(3), idx(4), idx(5));
        let mut t =
            ClusterTable::from_clusters(6, vec![vec![p0, p1, p2], vec![p2, p3, p4], vec![p4, p5]]);
        l.remove(p1);
        let out = regroup(&mut t, &l, &[0], &mut ChaCha8Rng::seed_from_u64(0));
        // piece {p0} has no adjacent particle → independent; piece {p2} merges into {p2,p3,p4}
        let clusters: Vec<Vec<u32>> = t.iter().map(|(_, m)| m.to_vec()).collect();
        assert!(clusters.contains(&vec![p0]));
        assert!(clusters.contains(&vec![p2, p3, p4]));
        assert_eq!(out.len(), 2);
        for (_, m) in t.iter() {
            assert!(is_connected(m, &l));
        }
    }
}
