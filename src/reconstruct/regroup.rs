//! SPEC §3.1–3.2: cut clusters fall into pieces (connected components of their live
//! members); each piece merges into a random cluster of one of its adjacent particles,
//! or stays as an independent cluster when it has been cut off the body.

use crate::cluster_store::ClusterStore;
use crate::graph::{connected_components, position_in};
use crate::lattice::Lattice;
use rand::Rng;
use smallvec::SmallVec;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::hash::Hash;

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

/// Root of `k` in the merge forest, with path compression.
fn find<K: Copy + Eq + Hash>(parent: &mut HashMap<K, K>, k: K) -> K {
    let mut root = k;
    while let Some(&p) = parent.get(&root) {
        root = p;
    }
    let mut x = k;
    while let Some(&p) = parent.get(&x) {
        if p == root {
            break;
        }
        parent.insert(x, root);
        x = p;
    }
    root
}

/// Replaces every cut cluster by its pieces, then merges each piece into a neighbour
/// cluster (SPEC §3.2). Returns the clusters this produced — the neighbour clusters that
/// received a merge and the independent pieces — sorted and without duplicates.
///
/// Merges are recorded in a union–find over clusters and the members are moved once at
/// the end, so a chain of merges (a piece merging into a pending cluster that later
/// merges on, which §3.2 allows) costs its total size, not its length × size. A piece
/// looks for its adjacent particle around its own members; particles of pieces already
/// merged into it count as its members, not as neighbours.
pub fn regroup<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[S::Key],
    rng: &mut impl Rng,
) -> Vec<S::Key> {
    let mut cut: Vec<S::Key> = cut_clusters.to_vec();
    cut.sort_unstable();
    cut.dedup();
    // 3.1: pending clusters. The first piece reuses the cut cluster's handle.
    let mut pending = Vec::new();
    for k in cut {
        let mut pieces = connected_components(store.members(k), lattice).into_iter();
        match pieces.next() {
            Some(first) => {
                store.set_members(k, first);
                pending.push(k);
            }
            None => store.remove(k),
        }
        for piece in pieces {
            pending.push(store.create(piece));
        }
    }
    // 3.2: choose every merge first, over the merge forest.
    let mut parent: HashMap<S::Key, S::Key> = HashMap::new();
    let mut produced: Vec<S::Key> = Vec::new();
    let mut merged: Vec<S::Key> = Vec::new();
    let is_pending: HashSet<S::Key> = pending.iter().copied().collect();
    for &p in &pending {
        let own = find(&mut parent, p);
        // The adjacent particle: the first one that belongs to a cluster the cut left
        // intact, else the first one with any cluster outside this piece's merge set.
        // (§3.2 leaves the choice open; preferring intact neighbours keeps chains of
        // merges between pending clusters, and the giant clusters they make, rare.)
        let mut fallback = None;
        let mut chosen = None;
        for a in adjacent_in_order(store.members(p), lattice) {
            let clusters = store.clusters_of(a);
            if clusters.iter().any(|k| !is_pending.contains(k)) {
                chosen = Some(a);
                break;
            }
            if fallback.is_none() && clusters.iter().any(|k| find(&mut parent, *k) != own) {
                fallback = Some(a);
            }
        }
        let target = chosen.or(fallback).and_then(|a| {
            let candidates: SmallVec<[S::Key; 8]> = store
                .clusters_of(a)
                .iter()
                .copied()
                .filter(|k| find(&mut parent, *k) != own)
                .collect();
            (!candidates.is_empty()).then(|| candidates[rng.random_range(0..candidates.len())])
        });
        match target {
            None => produced.push(p),
            Some(t) => {
                let root = find(&mut parent, t);
                parent.insert(own, root);
                merged.push(p);
                produced.push(root);
            }
        }
    }
    // Move every merged piece into its final cluster, once.
    let mut incoming: BTreeMap<S::Key, Vec<u32>> = BTreeMap::new();
    for &p in &merged {
        let root = find(&mut parent, p);
        incoming
            .entry(root)
            .or_default()
            .extend_from_slice(store.members(p));
        store.remove(p);
    }
    for (root, mut members) in incoming {
        members.sort_unstable();
        members.dedup();
        store.add_members(root, &members);
    }
    let mut produced: Vec<S::Key> = produced.into_iter().map(|k| find(&mut parent, k)).collect();
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
