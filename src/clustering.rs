//! Initial distance-based clustering (SPEC §1) and the overlap repair that keeps every
//! piece's clusters linked (no isolated cluster).
//!
//! Clusters are Chebyshev balls of radius `r` around seeds on a sub-lattice of stride
//! `2r + 1 − overlap`, grown by BFS inside the ball so each is connected, truncated at
//! `max_cluster_size`. Particles left uncovered (concave shapes) seed clusters of their
//! own. Finally [`link_isolated_clusters`] joins overlap components inside each piece.

use crate::cluster_store::{ClusterStore, ClusterTable};
use crate::config::Material;
use crate::lattice::Lattice;
use glam::IVec3;
use petgraph::unionfind::UnionFind;
use rand::Rng;
use std::collections::{HashMap, VecDeque};

/// Particles reachable from `seed` by lattice edges without leaving the Chebyshev ball
/// of radius `radius` around it, nearest (in graph distance) first, at most `max`.
pub fn ball_cluster(lattice: &Lattice, seed: u32, radius: u32, max: usize) -> Vec<u32> {
    let centre = lattice.coord(seed);
    let r = radius as i32;
    let mut visited = vec![seed];
    let mut queue = VecDeque::from([seed]);
    let mut members = Vec::new();
    while let Some(p) = queue.pop_front() {
        if members.len() >= max {
            break;
        }
        members.push(p);
        for n in lattice.neighbours(p) {
            let d = (lattice.coord(n) - centre).abs().max_element();
            if d <= r && !visited.contains(&n) {
                visited.push(n);
                queue.push_back(n);
            }
        }
    }
    members.sort_unstable();
    members
}

/// Builds the initial clusters of a body. Deterministic for a given `rng` state.
pub fn initial_clusters(
    lattice: &Lattice,
    material: &Material,
    rng: &mut impl Rng,
) -> ClusterTable {
    let stride = material.cluster_stride() as i32;
    let max = material.max_cluster_size as usize;
    let offset = IVec3::new(
        rng.random_range(0..stride),
        rng.random_range(0..stride),
        rng.random_range(0..stride),
    );
    let mut table = ClusterTable::new(lattice.len());
    let mut covered = vec![false; lattice.len()];
    let on_grid = |c: IVec3| (c - offset).rem_euclid(IVec3::splat(stride)) == IVec3::ZERO;
    let seeds: Vec<u32> = lattice
        .live_particles()
        .filter(|p| on_grid(lattice.coord(*p)))
        .collect();
    let add = |table: &mut ClusterTable, covered: &mut [bool], seed: u32| {
        let members = ball_cluster(lattice, seed, material.cluster_radius, max);
        for &m in &members {
            covered[m as usize] = true;
        }
        table.create(members);
    };
    for s in seeds {
        add(&mut table, &mut covered, s);
    }
    for p in lattice.live_particles() {
        if !covered[p as usize] {
            add(&mut table, &mut covered, p);
        }
    }
    link_isolated_clusters(&mut table, lattice, max);
    table
}

/// Makes the cluster-overlap graph of every piece connected (SPEC §3.4's goal, enforced).
///
/// Particles are joined in a union–find whenever they share a cluster. Then every live
/// lattice edge `(a, b)` whose ends are still in different sets is bridged: `b` joins the
/// smallest cluster of `a` that has room (the cluster stays connected through the edge),
/// or, when all are full, a new two-particle cluster `{a, b}` is made. Returns the
/// number of bridges added. Cost: O(memberships + edges).
pub fn link_isolated_clusters<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    max: usize,
) -> usize {
    let mut sets = UnionFind::<u32>::new(lattice.len());
    for p in lattice.live_particles() {
        for &k in store.clusters_of(p) {
            if let Some(&first) = store.members(k).first() {
                sets.union(p, first);
            }
        }
    }
    let mut bridges = 0;
    let mut grown: HashMap<S::Key, Vec<u32>> = HashMap::new();
    for (a, b) in lattice.edges() {
        if sets.equiv(a, b) {
            continue;
        }
        let size = |k: &S::Key| grown.get(k).map_or(store.members(*k).len(), Vec::len);
        let roomy = store
            .clusters_of(a)
            .iter()
            .copied()
            .filter(|k| size(k) < max)
            .min_by_key(|k| (size(k), *k));
        match roomy {
            Some(k) => {
                let members = grown.entry(k).or_insert_with(|| store.members(k).to_vec());
                members.push(b);
                members.sort_unstable();
            }
            None => {
                store.create(vec![a, b]);
            }
        }
        sets.union(a, b);
        bridges += 1;
    }
    let mut grown: Vec<_> = grown.into_iter().collect();
    grown.sort_unstable_by_key(|(k, _)| *k);
    for (k, members) in grown {
        store.set_members(k, members);
    }
    bridges
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Shape;
    use glam::UVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn box_clusters_are_27_cubes_in_the_interior() {
        let l = Shape::cuboid(UVec3::new(8, 8, 8), 1.0)
            .voxelise(1.0)
            .unwrap();
        let t = initial_clusters(&l, &Material::default(), &mut ChaCha8Rng::seed_from_u64(1));
        let sizes: Vec<usize> = t.iter().map(|(_, m)| m.len()).collect();
        assert!(sizes.contains(&27));
        assert!(sizes.iter().all(|s| *s <= 27));
        let memberships: usize = sizes.iter().sum();
        let per_particle = memberships as f32 / l.live_count() as f32;
        assert!((2.0..5.0).contains(&per_particle), "{per_particle}");
    }

    #[test]
    fn linking_bridges_two_disjoint_clusters() {
        let l = Shape::cuboid(UVec3::new(4, 1, 1), 1.0)
            .voxelise(1.0)
            .unwrap();
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(link_isolated_clusters(&mut t, &l, 3), 1);
        assert_eq!(t.members(0), &[0, 1, 2]);
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(link_isolated_clusters(&mut t, &l, 2), 1);
        assert_eq!(
            t.members(2),
            &[1, 2],
            "full clusters get a new 2-particle bridge"
        );
    }
}
