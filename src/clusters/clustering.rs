//! Initial distance-based clustering and the edge-cover repair that keeps every
//! piece's clusters linked (no isolated cluster).
//!
//! Clusters are Chebyshev balls of radius `r` around seeds on a sub-lattice of stride
//! `2r + 1 − overlap`, grown by BFS inside the ball so each is connected, truncated at
//! `max_cluster_size`. Particles left uncovered (concave shapes) seed clusters of their
//! own. Then [`cover_edges`] makes every lattice edge lie inside some cluster, and the
//! clusters that lie inside others are removed.

use crate::body::graph::with_slots;
use crate::body::lattice::Lattice;
use crate::clusters::contained::remove_contained;
use crate::clusters::store::{ClusterStore, ClusterTable};
use crate::config::Material;
use glam::IVec3;
use rand::Rng;
use std::collections::VecDeque;

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

/// Builds the initial clusters of a body, on a seed grid placed at random. Deterministic
/// for a given `rng` state.
pub fn initial_clusters(
    lattice: &Lattice,
    material: &Material,
    rng: &mut impl Rng,
) -> ClusterTable {
    clusters_on_grid(lattice, material, seed_grid_offset(material, rng))
}

/// A random placement of the seed grid: where its first seed lies within one stride.
pub fn seed_grid_offset(material: &Material, rng: &mut impl Rng) -> IVec3 {
    let stride = material.cluster_stride() as i32;
    IVec3::new(
        rng.random_range(0..stride),
        rng.random_range(0..stride),
        rng.random_range(0..stride),
    )
}

/// The initial clustering of `lattice` with its seed grid at `offset` (see
/// [`seed_grid_offset`]): the clusters a body of this geometry gets when it is spawned,
/// and the fresh-clustering reference for a body that was cut to this geometry. A body
/// of the oriented model has no clusters (its groups are its lattice neighbourhoods).
pub fn clusters_on_grid(lattice: &Lattice, material: &Material, offset: IVec3) -> ClusterTable {
    let stride = material.cluster_stride() as i32;
    let max = material.max_cluster_size as usize;
    let mut table = ClusterTable::new(lattice.len());
    if material.model == crate::config::Model::Oriented {
        return table;
    }
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
    cover_edges(
        &mut table,
        lattice,
        lattice.live_particles().collect::<Vec<_>>(),
        max,
    );
    // (truncated balls in thin or concave places may lie inside their neighbours)
    let all: Vec<u32> = table.iter().map(|(k, _)| k).collect();
    remove_contained(&mut table, lattice.len(), &all);
    table
}

/// True when the sorted cluster lists `a` and `b` have a cluster in common.
fn share_a_cluster<K: Ord>(a: &[K], b: &[K]) -> bool {
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => return true,
        }
    }
    false
}

/// Makes every live lattice edge at the given particles *covered*: both ends in a
/// common cluster. Returns the clusters that grew or were created for it, ascending.
///
/// Edge coverage implies what expansion aims at (no isolated cluster): inside a connected
/// piece any two particles are joined by a lattice path whose consecutive particles
/// share a cluster, so the piece's cluster-overlap graph is connected. Unlike that global
/// property, coverage can be restored locally: after a cut only the edges a split
/// separated can have lost their cover (see [`cover_edge_list`]).
pub fn cover_edges<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    particles: impl IntoIterator<Item = u32>,
    max: usize,
) -> Vec<u32> {
    let particles: Vec<u32> = particles
        .into_iter()
        .filter(|p| lattice.is_live(*p))
        .collect();
    let mut changed = with_slots(lattice.len(), |listed| {
        for &p in &particles {
            listed[p as usize] = 0;
        }
        let mut changed = Vec::new();
        for &a in &particles {
            for b in lattice.neighbours(a) {
                // an edge between two listed particles is looked at once, from its lower end
                if !(listed[b as usize] == 0 && b < a) {
                    changed.extend(cover_edge(store, a, b, max));
                }
            }
        }
        for &p in &particles {
            listed[p as usize] = u32::MAX;
        }
        changed
    });
    changed.sort_unstable();
    changed.dedup();
    changed
}

/// Makes every given live particle covered: each lattice edge at it lies in some
/// cluster ([`cover_edges`]), and a particle still in no cluster (it has no live edge)
/// gets a cluster of its own. Returns the clusters that grew or were created, ascending.
pub fn cover_particles<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    particles: &[u32],
    max: usize,
) -> Vec<u32> {
    let mut changed = cover_edges(store, lattice, particles.iter().copied(), max);
    for &p in particles {
        if lattice.is_live(p) && store.clusters_of(p).is_empty() {
            changed.push(store.create(vec![p]));
        }
    }
    changed.sort_unstable();
    changed.dedup();
    changed
}

/// Makes each of the given live lattice edges covered (see [`cover_edges`]); returns
/// the clusters that grew or were created for it, ascending.
///
/// After a cut these are the edges [`crate::reconstruct::split_oversized`] reports: the
/// pieces of a cut cluster keep every live edge among their members (an edge joins its
/// ends into one piece), merging and expanding only add members, so a split is the only
/// step that can separate the two ends of a covered edge.
pub fn cover_edge_list<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    edges: &[(u32, u32)],
    max: usize,
) -> Vec<u32> {
    let mut changed: Vec<u32> = edges
        .iter()
        .filter(|(a, b)| lattice.is_live(*a) && lattice.is_live(*b))
        .filter_map(|&(a, b)| cover_edge(store, a, b, max))
        .collect();
    changed.sort_unstable();
    changed.dedup();
    changed
}

/// Covers the edge `(a, b)` if no cluster holds both ends: adds the other end to the
/// smallest cluster of `a` or `b` that has room (it stays connected through the edge),
/// or, when all are full, creates the two-particle cluster `{a, b}`. Returns the cluster
/// it grew or created, if a bridge was needed.
fn cover_edge<S: ClusterStore>(store: &mut S, a: u32, b: u32, max: usize) -> Option<u32> {
    if share_a_cluster(store.clusters_of(a), store.clusters_of(b)) {
        return None;
    }
    let size = |k: &u32| store.members(*k).len();
    let roomy = |p: u32, other: u32| {
        store
            .clusters_of(p)
            .iter()
            .filter(|k| size(k) < max)
            .map(|k| (size(k), *k, other))
            .min()
    };
    Some(match roomy(a, b).into_iter().chain(roomy(b, a)).min() {
        Some((_, k, other)) => {
            store.add_members(k, &[other]);
            k
        }
        None => store.create(vec![a.min(b), a.max(b)]),
    })
}

/// The live lattice edges that no cluster covers, ascending (empty when the edge-cover
/// invariant holds).
pub fn uncovered_edges<S: ClusterStore>(store: &S, lattice: &Lattice) -> Vec<(u32, u32)> {
    lattice
        .edges()
        .into_iter()
        .filter(|(a, b)| !share_a_cluster(store.clusters_of(*a), store.clusters_of(*b)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn box_clusters_are_27_cubes_in_the_interior() {
        let l = Shape::cuboid(UVec3::new(8, 8, 8)).voxelise(1.0).unwrap();
        let t = initial_clusters(&l, &Material::default(), &mut ChaCha8Rng::seed_from_u64(1));
        let sizes: Vec<usize> = t.iter().map(|(_, m)| m.len()).collect();
        assert!(sizes.contains(&27));
        assert!(sizes.iter().all(|s| *s <= 27));
        let memberships: usize = sizes.iter().sum();
        let per_particle = memberships as f32 / l.live_count() as f32;
        assert!((2.0..5.0).contains(&per_particle), "{per_particle}");
    }

    #[test]
    fn covering_bridges_uncovered_edges() {
        let l = Shape::cuboid(UVec3::new(4, 1, 1)).voxelise(1.0).unwrap();
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(cover_edges(&mut t, &l, 0..4, 3), [0]);
        assert_eq!(t.members(0), &[0, 1, 2]);
        assert_eq!(
            cover_edges(&mut t, &l, 0..4, 3),
            Vec::<u32>::new(),
            "idempotent"
        );
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(cover_edges(&mut t, &l, 0..4, 2), [2]);
        assert_eq!(
            t.members(2),
            &[1, 2],
            "full clusters get a new 2-particle bridge"
        );
        // only edges at the given particles are looked at
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        assert_eq!(cover_edges(&mut t, &l, [0, 3], 3), Vec::<u32>::new());
        // a particle in no cluster and with no edge gets a cluster of its own
        let mut l = l;
        l.sever(1, 2);
        let mut t = ClusterTable::from_clusters(4, vec![vec![0, 1], vec![2, 3]]);
        l.sever(0, 1);
        let mut t2 = ClusterTable::from_clusters(4, vec![vec![0], vec![2, 3]]);
        assert_eq!(cover_particles(&mut t2, &l, &[0, 1], 3), [2]);
        assert_eq!(t2.members(2), &[1]);
        assert_eq!(
            cover_particles(&mut t, &l, &[0, 1, 2, 3], 3),
            Vec::<u32>::new()
        );
    }
}
