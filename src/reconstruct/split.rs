//! Splitting an oversized cluster in two (SPEC §3.3, §4): PCA normal on rest positions
//! (§4.1), geometric partition grown from a random vertex with the normal flip (§4.2),
//! and topological repair so both halves are connected (§4.3).

use super::pca::split_normal;
use crate::cluster_store::ClusterStore;
use crate::graph::with_slots;
use crate::lattice::Lattice;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

/// Spare capacity of each half a split returns: the expansion (SPEC §3.4) adds a few
/// particles to it next, which would otherwise reallocate the list.
const HALF_HEADROOM: usize = 8;

/// Heap key ordering frontier vertices by signed distance, ties by local index.
#[derive(Clone, Copy, PartialEq)]
struct ByDistance(f32, usize);
impl Eq for ByDistance {}
impl PartialOrd for ByDistance {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for ByDistance {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

/// The lattice graph induced on a member set, in compressed rows; vertices are indices
/// into the member list.
#[derive(Clone, Debug, Default)]
struct LocalGraph {
    /// Vertex `i`'s neighbours are `next[row[i]..row[i + 1]]`.
    row: Vec<u32>,
    /// Neighbour lists back to back; entries past `row`'s last end are scratch.
    next: Vec<u32>,
}

impl LocalGraph {
    /// Makes this the graph of `members`, reusing its buffers.
    fn rebuild(&mut self, members: &[u32], lattice: &Lattice) {
        // one slot more than particles: an empty cell reads that one, which is never set
        with_slots(lattice.len() + 1, |local| {
            self.build(members, lattice, local)
        });
    }

    fn build(&mut self, members: &[u32], lattice: &Lattice, local: &mut [u32]) {
        for (i, &m) in members.iter().enumerate() {
            local[m as usize] = i as u32;
        }
        let (row, next) = (&mut self.row, &mut self.next);
        row.clear();
        row.reserve(members.len() + 1);
        // Room for all six neighbour cells of every member: each cell is written and
        // kept only if it holds a member, without a branch (whether it does is data and
        // would mispredict). Entries past the last row's end are never read.
        if next.len() < 6 * members.len() {
            next.resize(6 * members.len(), 0);
        }
        let unset = local.len() - 1;
        let mut len = 0;
        row.push(0);
        for &m in members {
            for n in lattice.neighbour_cells(m) {
                // (an empty cell, `NO_PARTICLE`, reads the unset last slot)
                let slot = local[(n as usize).min(unset)];
                next[len] = slot;
                len += usize::from(slot != u32::MAX);
            }
            row.push(len as u32);
        }
        for &m in members {
            local[m as usize] = u32::MAX;
        }
    }

    /// Neighbours of vertex `i`.
    #[inline]
    fn neighbours(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.next[self.row[i] as usize..self.row[i + 1] as usize]
            .iter()
            .map(|j| *j as usize)
    }
}

/// Buffers one thread reuses from split to split: once they have grown, a split
/// allocates only the two halves it returns.
#[derive(Default)]
pub struct SplitScratch {
    /// Rest positions of the members.
    points: Vec<Vec3>,
    graph: LocalGraph,
    /// Signed distance of every member to the plane through the start vertex.
    distance: Vec<f32>,
    in_s: Vec<bool>,
    in_m: Vec<bool>,
    visited: Vec<bool>,
    negative: Vec<usize>,
    frontier: BinaryHeap<Reverse<ByDistance>>,
    label: Vec<u32>,
    stack: Vec<usize>,
    sizes: Vec<usize>,
}

impl SplitScratch {
    /// [`split_cluster`] with these buffers.
    pub fn split(
        &mut self,
        members: &[u32],
        lattice: &Lattice,
        rng: &mut impl Rng,
    ) -> (Vec<u32>, Vec<u32>) {
        if members.len() < 2 {
            return (members.to_vec(), Vec::new());
        }
        self.points.clear();
        self.points
            .extend(members.iter().map(|m| lattice.coord(*m).as_vec3()));
        self.graph.rebuild(members, lattice);
        let normal = split_normal(&self.points);
        let start = rng.random_range(0..members.len());
        self.geometric_partition(start, normal);
        self.topological_repair();
        let pick = |flags: &[bool]| {
            // sized up front (a filtered collect would grow it by reallocation), with
            // room for the few particles the expansion adds next (SPEC §3.4)
            let size = flags.iter().filter(|f| **f).count();
            let mut half = Vec::with_capacity(size + HALF_HEADROOM);
            half.extend(
                members
                    .iter()
                    .zip(flags)
                    .filter(|(_, f)| **f)
                    .map(|(m, _)| *m),
            );
            half
        };
        (pick(&self.in_s), pick(&self.in_m))
    }

    /// Appends the lattice edges between `members` (the list the last [`Self::split`]
    /// split in two) whose ends went to different halves, as `(lower, higher)` particle
    /// pairs in no particular order, read off that split's local graph.
    fn separated_edges(&self, members: &[u32], edges: &mut Vec<(u32, u32)>) {
        // Each edge is seen from its end in S. Room for every edge from S, filled
        // without a branch on the far end's side (data, which would mispredict), then
        // cut to what was kept.
        let mut len = edges.len();
        let directed = self.graph.row.last().map_or(0, |r| *r as usize);
        edges.resize(len + directed, (0, 0));
        for (i, &a) in members.iter().enumerate() {
            if !self.in_s[i] {
                continue;
            }
            for j in self.graph.neighbours(i) {
                let b = members[j];
                edges[len] = (a.min(b), a.max(b));
                len += usize::from(!self.in_s[j]);
            }
        }
        edges.truncate(len);
    }

    /// SPEC §4.2: grows a connected set S (`in_s`) from vertex `start` whose boundary
    /// approximates the plane through `start` with normal `normal`.
    fn geometric_partition(&mut self, start: usize, normal: Vec3) {
        let Self {
            points,
            graph,
            distance,
            in_s,
            visited,
            negative,
            frontier,
            ..
        } = self;
        let g = points.len();
        // signed distance to the plane through `start`, before the flip (the flip negates)
        distance.clear();
        distance.extend(points.iter().map(|p| normal.dot(*p - points[start])));
        in_s.resize(g, false);
        visited.resize(g, false);
        // (each vertex enters each list at most once per flip)
        negative.reserve(g);
        frontier.reserve(g);
        for flip in [1.0f32, -1.0] {
            let d = |i: usize| flip * distance[i];
            in_s.fill(false);
            visited.fill(false);
            negative.clear();
            frontier.clear();
            let mut size = 1;
            in_s[start] = true;
            visited[start] = true;
            let discover = |i: usize,
                            visited: &mut [bool],
                            negative: &mut Vec<usize>,
                            frontier: &mut BinaryHeap<_>| {
                for n in graph.neighbours(i) {
                    if !visited[n] {
                        visited[n] = true;
                        let dn = d(n);
                        if dn < 0.0 {
                            negative.push(n);
                        } else {
                            frontier.push(Reverse(ByDistance(dn, n)));
                        }
                    }
                }
            };
            discover(start, visited, negative, frontier);
            // Step 3: absorb every reachable vertex on the negative side.
            while let Some(x) = negative.pop() {
                in_s[x] = true;
                size += 1;
                discover(x, visited, negative, frontier);
            }
            // Step 4: grow by smallest signed distance until |S| + 1 ≥ |G| / 2.
            while 2 * (size + 1) < g {
                let Some(Reverse(ByDistance(_, x))) = frontier.pop() else {
                    break;
                };
                in_s[x] = true;
                size += 1;
                discover(x, visited, negative, frontier);
                while let Some(y) = negative.pop() {
                    // Only reachable after a flip: keep S connected, take it in order.
                    frontier.push(Reverse(ByDistance(d(y), y)));
                }
            }
            // Step 5: too big → flip the normal and start again (at most once is
            // needed: both sides cannot each hold more than half the vertices).
            if 2 * size <= g + 2 {
                break;
            }
        }
    }

    /// SPEC §4.3: moves every component of G − S but the largest into S (`in_s`); the
    /// remaining component is M (`in_m`).
    fn topological_repair(&mut self) {
        // label: IN_S for S, UNSEEN for G − S not reached yet, else the component id
        const UNSEEN: u32 = u32::MAX;
        const IN_S: u32 = u32::MAX - 1;
        let Self {
            graph,
            in_s,
            in_m,
            label,
            stack,
            sizes,
            ..
        } = self;
        let g = in_s.len();
        label.clear();
        label.extend(in_s.iter().map(|s| if *s { IN_S } else { UNSEEN }));
        sizes.clear();
        // Every vertex is pushed once, and a visit writes one slot past the top: each
        // neighbour is labelled and pushed without a branch (whether it is unseen is
        // data, and would mispredict), and kept only if it was.
        stack.clear();
        stack.resize(g + 1, 0);
        // components numbered in order of their smallest vertex
        for start in 0..g {
            if label[start] != UNSEEN {
                continue;
            }
            let id = sizes.len() as u32;
            label[start] = id;
            stack[0] = start;
            let (mut top, mut size) = (1, 0);
            while top > 0 {
                top -= 1;
                let i = stack[top];
                size += 1;
                for n in graph.neighbours(i) {
                    let unseen = label[n] == UNSEEN;
                    label[n] = if unseen { id } else { label[n] };
                    stack[top] = n;
                    top += usize::from(unseen);
                }
            }
            sizes.push(size);
        }
        // Largest stays as M (first one on ties); the rest join S. (With G − S empty,
        // `keep` is UNSEEN, which no vertex is labelled any more.)
        let keep = (0..sizes.len())
            .max_by_key(|&c| (sizes[c], Reverse(c)))
            .map_or(UNSEEN, |c| c as u32);
        in_m.clear();
        in_m.extend(label.iter().map(|l| *l == keep));
        for (s, l) in in_s.iter_mut().zip(label.iter()) {
            *s = *l != keep;
        }
    }
}

/// Splits a connected cluster (sorted members, at least 2) into two connected, disjoint
/// halves that cover it, using rest (lattice) positions (SPEC §4).
pub fn split_cluster(
    members: &[u32],
    lattice: &Lattice,
    rng: &mut impl Rng,
) -> (Vec<u32>, Vec<u32>) {
    SplitScratch::default().split(members, lattice, rng)
}

/// The parts of one connected cluster split (SPEC §3.3) until none has more than `max`
/// members, and the lattice edges between members that ended in different parts — the
/// only edges a split can leave without a common cluster — as sorted `(lower, higher)`
/// particle pairs.
pub fn split_until_fits(
    members: &[u32],
    lattice: &Lattice,
    max: usize,
    rng: &mut impl Rng,
    scratch: &mut SplitScratch,
) -> (Vec<Vec<u32>>, Vec<(u32, u32)>) {
    // a cluster of up to twice `max` members (the usual case) splits once
    let mut parts = Vec::with_capacity(4);
    let mut queue = VecDeque::with_capacity(4);
    let mut edges = Vec::new();
    queue.push_back(members.to_vec());
    while let Some(part) = queue.pop_front() {
        if part.len() <= max {
            parts.push(part);
            continue;
        }
        let (a, b) = scratch.split(&part, lattice, rng);
        if b.is_empty() {
            parts.push(a);
        } else {
            // an edge ends in different final parts exactly when one split separated it
            scratch.separated_edges(&part, &mut edges);
            queue.push_back(a);
            queue.push_back(b);
        }
    }
    edges.sort_unstable();
    (parts, edges)
}

/// What [`split_oversized`] produced.
#[derive(Clone, Debug, Default)]
pub struct SplitOutcome<K> {
    /// Every resulting cluster: the inputs (first parts keep their handle) and the new ones.
    pub clusters: Vec<K>,
    /// Lattice edges whose ends ended in different parts of a split; they may need a
    /// bridge (see [`crate::clustering::cover_edge_list`]).
    pub cut_edges: Vec<(u32, u32)>,
}

/// SPEC §3.3: splits every cluster in `keys` above `max` members, and the halves again,
/// until all are at most `max`.
///
/// The splits only read their cluster and the lattice, so they run in parallel, each with
/// its own generator seeded from `rng` in key order: the result does not depend on the
/// thread count.
pub fn split_oversized<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    keys: &[S::Key],
    max: usize,
    rng: &mut impl Rng,
) -> SplitOutcome<S::Key> {
    let oversized: Vec<(S::Key, &[u32], u64)> = keys
        .iter()
        .map(|k| (*k, store.members(*k)))
        .filter(|(_, m)| m.len() > max)
        .map(|(k, m)| (k, m, rng.random()))
        .collect();
    let splits: Vec<_> = oversized
        .into_par_iter()
        .map_init(SplitScratch::default, |scratch, (k, members, seed)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            (
                k,
                split_until_fits(members, lattice, max, &mut rng, scratch),
            )
        })
        .collect();
    let mut outcome = SplitOutcome {
        clusters: keys.to_vec(),
        cut_edges: Vec::new(),
    };
    for (k, (parts, edges)) in splits {
        let mut parts = parts.into_iter();
        if let Some(first) = parts.next() {
            store.set_members(k, first);
        }
        outcome
            .clusters
            .extend(parts.map(|part| store.create(part)));
        outcome.cut_edges.extend(edges);
    }
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::is_connected;
    use crate::lattice::Shape;
    use glam::UVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn spread(members: &[u32], lattice: &Lattice, n: Vec3) -> f32 {
        let d: Vec<f32> = members
            .iter()
            .map(|m| n.dot(lattice.coord(*m).as_vec3()))
            .collect();
        let mean = d.iter().sum::<f32>() / d.len() as f32;
        d.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / d.len() as f32
    }

    #[test]
    fn halves_connected_disjoint_covering_balanced_and_tighter() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut ratios = Vec::new();
        for dims in [
            UVec3::new(6, 3, 3),
            UVec3::new(4, 4, 4),
            UVec3::new(7, 5, 2),
            UVec3::new(9, 2, 2),
        ] {
            let lattice = Shape::cuboid(dims, 1.0).voxelise(1.0).unwrap();
            let members: Vec<u32> = lattice.live_particles().collect();
            let points: Vec<Vec3> = members
                .iter()
                .map(|m| lattice.coord(*m).as_vec3())
                .collect();
            let n = split_normal(&points);
            for _ in 0..50 {
                let (a, b) = split_cluster(&members, &lattice, &mut rng);
                assert!(is_connected(&a, &lattice) && is_connected(&b, &lattice));
                let mut all = [a.clone(), b.clone()].concat();
                all.sort_unstable();
                assert_eq!(all, members, "disjoint and covering");
                let (small, large) = (a.len().min(b.len()), a.len().max(b.len()));
                ratios.push(small as f32 / large as f32);
                let parent = spread(&members, &lattice, n);
                assert!(spread(&a, &lattice, n) < parent && spread(&b, &lattice, n) < parent);
            }
        }
        ratios.sort_by(f32::total_cmp);
        let median = ratios[ratios.len() / 2];
        assert!(
            median >= 0.75,
            "median smaller/larger {median}, min {}",
            ratios[0]
        );
    }

    #[test]
    fn split_oversized_respects_max() {
        let lattice = Shape::cuboid(UVec3::new(10, 6, 3), 1.0)
            .voxelise(1.0)
            .unwrap();
        let mut table = crate::cluster_store::ClusterTable::from_clusters(
            lattice.len(),
            vec![lattice.live_particles().collect()],
        );
        let out = split_oversized(
            &mut table,
            &lattice,
            &[0],
            11,
            &mut ChaCha8Rng::seed_from_u64(1),
        );
        assert!(out.clusters.len() >= 6);
        // the cut edges are exactly the lattice edges no cluster covers any more
        let mut uncovered = crate::clustering::uncovered_edges(&table, &lattice);
        let mut cut_edges = out.cut_edges.clone();
        uncovered.sort_unstable();
        cut_edges.sort_unstable();
        assert!(!cut_edges.is_empty());
        assert_eq!(uncovered, cut_edges);
        for k in out.clusters {
            let m = table.members(k);
            assert!(m.len() <= 11 && is_connected(m, &lattice));
        }
    }
}
