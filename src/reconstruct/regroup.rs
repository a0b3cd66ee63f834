//! SPEC §3.1–3.2: cut clusters fall into pieces (connected components of their live
//! members); each piece merges into a random cluster of one of its adjacent particles,
//! or stays as an independent cluster when it has been cut off the body.

use crate::cluster_store::ClusterStore;
use crate::graph::{connected_components, position_in};
use crate::lattice::Lattice;
use rand::Rng;

/// The first adjacent particle of a sorted member set (members ascending, neighbours
/// in lattice order), if any.
pub fn first_adjacent_particle(members: &[u32], lattice: &Lattice) -> Option<u32> {
    members
        .iter()
        .flat_map(|m| lattice.neighbours(*m))
        .find(|n| position_in(members, *n).is_none())
}

/// Replaces every cut cluster by its pieces, then merges each piece into a neighbour
/// cluster (SPEC §3.2). Returns the clusters this produced — the neighbour clusters that
/// received a merge and the independent pieces — sorted and without duplicates.
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
    // 3.2: merge each pending cluster into a random cluster of an adjacent particle.
    let mut produced: Vec<S::Key> = Vec::new();
    for p in pending {
        let members = store.members(p);
        if members.is_empty() {
            continue; // already merged away (cannot happen: only `p` itself is removed)
        }
        let neighbour = first_adjacent_particle(members, lattice).and_then(|a| {
            let candidates: Vec<S::Key> = store
                .clusters_of(a)
                .iter()
                .copied()
                .filter(|k| *k != p)
                .collect();
            (!candidates.is_empty()).then(|| candidates[rng.random_range(0..candidates.len())])
        });
        match neighbour {
            None => produced.push(p),
            Some(target) => {
                let piece = store.members(p).to_vec();
                store.remove(p);
                store.add_members(target, &piece);
                produced.push(target);
            }
        }
    }
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
