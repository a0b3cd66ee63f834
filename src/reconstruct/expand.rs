//! SPEC §3.4: every rebuilt cluster grows by a few randomly chosen adjacent particles
//! (one BFS layer), so it overlaps its neighbours again.

use crate::cluster_store::ClusterStore;
use crate::graph::adjacent_particles;
use crate::lattice::Lattice;
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Adds up to `count` random adjacent particles to each cluster in `keys`, never
/// beyond `max` members. Returns the number of memberships added.
///
/// The choices only read the clusters and the lattice, so they are made in parallel, each
/// cluster with its own generator seeded from `rng` in key order (the result does not
/// depend on the thread count); the members are then added in key order.
pub fn expand_clusters<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    keys: &[S::Key],
    count: usize,
    max: usize,
    rng: &mut impl Rng,
) -> usize {
    if count == 0 {
        return 0;
    }
    let growing: Vec<(S::Key, &[u32], u64)> = keys
        .iter()
        .map(|k| (*k, store.members(*k)))
        .filter(|(_, m)| m.len() < max)
        .map(|(k, m)| (k, m, rng.random()))
        .collect();
    let additions: Vec<(S::Key, Vec<u32>)> = growing
        .into_par_iter()
        .with_min_len(32)
        .map(|(k, members, seed)| {
            let adjacent = adjacent_particles(members, lattice);
            let take = count.min(max - members.len()).min(adjacent.len());
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut extra: Vec<u32> = sample(&mut rng, adjacent.len(), take)
                .into_iter()
                .map(|i| adjacent[i])
                .collect();
            extra.sort_unstable();
            (k, extra)
        })
        .collect();
    let mut added = 0;
    for (k, extra) in additions {
        added += extra.len();
        store.add_members(k, &extra);
    }
    added
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster_store::ClusterTable;
    use crate::graph::is_connected;
    use crate::lattice::Shape;
    use glam::UVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn expansion_adds_adjacent_particles_up_to_max() {
        let l = Shape::cuboid(UVec3::new(5, 5, 1), 1.0)
            .voxelise(1.0)
            .unwrap();
        let centre = l.at(glam::IVec3::new(0, 0, 0)).unwrap();
        let mut t = ClusterTable::from_clusters(l.len(), vec![vec![centre]]);
        let added = expand_clusters(&mut t, &l, &[0], 3, 10, &mut ChaCha8Rng::seed_from_u64(2));
        assert_eq!(added, 3);
        assert_eq!(t.members(0).len(), 4);
        assert!(is_connected(t.members(0), &l));
        let added = expand_clusters(&mut t, &l, &[0], 100, 6, &mut ChaCha8Rng::seed_from_u64(2));
        assert_eq!(added, 2, "stops at max");
    }
}
