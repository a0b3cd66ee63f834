//! Splitting an oversized cluster in two (reconstruction step 2): PCA normal on rest positions
//! (§4.1), geometric partition grown from a random vertex with the normal flip (§4.2),
//! and topological repair so both halves are connected (§4.3).

use super::local::LocalGraph;
use super::pca::split_normal;
use crate::body::lattice::Lattice;
use crate::clusters::edits::ClusterEdits;
use crate::clusters::store::ClusterStore;
use crate::util::bits::Bits;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::VecDeque;

/// Buffers one thread reuses from split to split: once they have grown, a split
/// allocates only the two halves it returns.
#[derive(Default)]
pub struct SplitScratch {
    /// Rest positions of the members.
    points: Vec<Vec3>,
    graph: LocalGraph,
    /// Signed distance of every member to the plane through the start vertex.
    distance: Vec<f32>,
    /// Per vertex `(sortable signed distance, vertex)`: §4.2 takes the frontier vertex
    /// with the smallest key (smallest distance, ties by vertex).
    keys: Vec<u64>,
    /// Vertices with a negative signed distance.
    negative: Bits,
    /// Vertices discovered (the sentinel counts as discovered), and the frontier.
    visited: Bits,
    frontier: Bits,
    /// By vertex, with the sentinel's slot set: S, then (after the repair) M.
    in_s: Vec<bool>,
    in_m: Vec<bool>,
    label: Vec<u32>,
    stack: Vec<u32>,
    sizes: Vec<usize>,
}

/// `x`'s bits mapped so that unsigned order is [`f32::total_cmp`]'s order.
#[inline]
fn sortable(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    }
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
        self.graph.build(members, lattice);
        let normal = split_normal(&self.points);
        let start = rng.random_range(0..members.len());
        self.geometric_partition(start, normal);
        self.topological_repair();
        let g = members.len();
        let pick = |flags: &[bool]| {
            // sized up front (a filtered collect would grow it by reallocation)
            let size = flags[..g].iter().filter(|f| **f).count();
            let mut half = Vec::with_capacity(size);
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
        // Each edge is seen from its end in S. Room for every neighbour slot of S,
        // filled without a branch on the far end's side (data, which would
        // mispredict), then cut to what was kept; the sentinel counts as in S.
        let mut len = edges.len();
        let g = members.len();
        let from_s = self.in_s[..g].iter().filter(|s| **s).count();
        edges.resize(len + 6 * from_s, (0, 0));
        for (i, &a) in members.iter().enumerate() {
            if !self.in_s[i] {
                continue;
            }
            for &j in self.graph.row(i) {
                let b = members.get(j as usize).copied().unwrap_or(a);
                edges[len] = (a.min(b), a.max(b));
                len += usize::from(!self.in_s[j as usize]);
            }
        }
        edges.truncate(len);
    }

    /// Grows a connected set S (`in_s`) from vertex `start` whose boundary
    /// approximates the plane through `start` with normal `normal`.
    ///
    /// The frontier is a bit set. Step 3 takes any frontier vertex on the negative side
    /// (the set it ends with does not depend on the order); step 4 scans the frontier
    /// for the smallest `(signed distance, vertex)` key, which the frontier's few
    /// vertices make cheaper than keeping them in a heap.
    fn geometric_partition(&mut self, start: usize, normal: Vec3) {
        let Self {
            points,
            graph,
            distance,
            keys,
            negative,
            visited,
            frontier,
            in_s,
            ..
        } = self;
        let g = points.len();
        // signed distance to the plane through `start`, before the flip (the flip negates)
        distance.clear();
        distance.extend(points.iter().map(|p| normal.dot(*p - points[start])));
        for flip in [1.0f32, -1.0] {
            keys.clear();
            keys.extend(
                distance
                    .iter()
                    .enumerate()
                    .map(|(i, d)| (sortable(flip * d) as u64) << 32 | i as u64),
            );
            negative.reset(g + 1);
            for (i, d) in distance.iter().enumerate() {
                if flip * d < 0.0 {
                    negative.insert(i);
                }
            }
            visited.reset(g + 1);
            frontier.reset(g + 1);
            in_s.clear();
            in_s.resize(g, false);
            // the sentinel counts as discovered: it never enters the frontier
            visited.insert(g);
            visited.insert(start);
            let mut take = |i: usize, frontier: &mut Bits| {
                in_s[i] = true;
                for &n in graph.row(i) {
                    visited.insert_new_into(n as usize, frontier);
                }
            };
            take(start, frontier);
            let mut size = 1;
            // Step 3: absorb every reachable vertex on the negative side.
            while let Some(i) = frontier.lowest_common(negative) {
                frontier.remove(i);
                take(i, frontier);
                size += 1;
            }
            // Step 4: grow by smallest signed distance until |S| + 1 ≥ |G| / 2.
            while 2 * (size + 1) < g {
                let Some(i) = frontier.min_by_key(keys) else {
                    break;
                };
                frontier.remove(i);
                take(i, frontier);
                size += 1;
            }
            // Step 5: too big → flip the normal and start again (at most once is
            // needed: both sides cannot each hold more than half the vertices).
            if 2 * size <= g + 2 {
                break;
            }
        }
        in_s.push(true);
    }

    /// The topological repair: moves every component of G − S but the largest into S (`in_s`); the
    /// remaining component is M (`in_m`).
    fn topological_repair(&mut self) {
        // label: IN_S for S (and the sentinel), UNSEEN for G − S not reached yet, else
        // the component id
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
        let g = graph.len();
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
            stack[0] = start as u32;
            let (mut top, mut size) = (1, 0);
            while top > 0 {
                top -= 1;
                let i = stack[top] as usize;
                size += 1;
                for &n in graph.row(i) {
                    let unseen = label[n as usize] == UNSEEN;
                    label[n as usize] = if unseen { id } else { label[n as usize] };
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
/// halves that cover it, using rest (lattice) positions (see the module docs).
pub fn split_cluster(
    members: &[u32],
    lattice: &Lattice,
    rng: &mut impl Rng,
) -> (Vec<u32>, Vec<u32>) {
    SplitScratch::default().split(members, lattice, rng)
}

/// The parts of one connected cluster split until none has more than `max`
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
pub struct SplitOutcome {
    /// Every resulting cluster: the inputs (first parts keep their handle) and the new ones.
    pub clusters: Vec<u32>,
    /// Lattice edges whose ends ended in different parts of a split; they may need a
    /// bridge (see [`crate::clusters::clustering::cover_edge_list`]).
    pub cut_edges: Vec<(u32, u32)>,
    /// The parts of the clusters that were split (the expansion grows
    /// these).
    pub parts: Vec<u32>,
}

/// Reconstruction step 2: splits every cluster in `keys` above `max` members, and the halves again,
/// until all are at most `max` (after a cut, `max` is [`crate::config::Material::split_size`]).
///
/// The splits only read their cluster and the lattice, so they run in parallel, each with
/// its own generator seeded from `rng` in key order: the result does not depend on the
/// thread count.
pub fn split_oversized<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    keys: &[u32],
    max: usize,
    rng: &mut impl Rng,
) -> SplitOutcome {
    let oversized: Vec<(u32, &[u32], u64)> = keys
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
    let mut edits = ClusterEdits::default();
    let mut cut_edges = Vec::new();
    for (k, (parts, edges)) in &splits {
        edits.replace(*k, &parts[0]);
        for part in &parts[1..] {
            edits.create(part);
        }
        cut_edges.extend_from_slice(edges);
    }
    let created = store.apply(&edits);
    let mut parts: Vec<u32> = splits.iter().map(|(k, _)| *k).collect();
    parts.extend_from_slice(&created);
    let mut clusters = keys.to_vec();
    clusters.extend(created);
    SplitOutcome {
        clusters,
        cut_edges,
        parts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::graph::is_connected;
    use crate::body::shape::Shape;
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
            let lattice = Shape::cuboid(dims).voxelise(1.0).unwrap();
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
        let lattice = Shape::cuboid(UVec3::new(10, 6, 3)).voxelise(1.0).unwrap();
        let mut table = crate::clusters::store::ClusterTable::from_clusters(
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
        let mut uncovered = crate::clusters::clustering::uncovered_edges(&table, &lattice);
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
