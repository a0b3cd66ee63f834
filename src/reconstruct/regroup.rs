//! SPEC §3.1–3.2: cut clusters fall into pieces (connected components of their live
//! members); each piece merges into a random cluster of one of its adjacent particles,
//! or stays as an independent cluster when it has been cut off the body.
//!
//! The work is split by what it reads. The pieces and their neighbours only read the
//! clusters as the cut left them and the lattice, so they are found in parallel; the
//! merge choices draw from the one random stream, piece by piece in order; the merged
//! member lists are unions, computed in parallel; and the store applies every edit at
//! once. A piece that merges away is never written as a cluster of its own.

use super::local::LocalGraph;
use crate::cluster_edits::ClusterEdits;
use crate::cluster_index::ClusterIndex;
use crate::cluster_store::ClusterStore;
use crate::lattice::{Lattice, NO_PARTICLE};
use rand::Rng;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use smallvec::SmallVec;

/// "None" among piece numbers, particles and labels.
const NONE: u32 = u32::MAX;

/// Cut clusters per parallel task.
const CUT_PER_TASK: usize = 64;

/// Merge groups per parallel task.
const GROUPS_PER_TASK: usize = 64;

/// One piece of a cut cluster (§3.1).
#[derive(Clone, Copy, Debug)]
struct Piece {
    /// Its members, ascending: `particles[start..end]` of its [`Pieces`].
    span: [u32; 2],
    /// Its first adjacent particle — members in order, each one's lattice directions in
    /// order — that belongs to a cluster the cut left intact; `NONE` if there is none.
    intact_neighbour: u32,
}

/// The pieces of a run of cut clusters, back to back.
#[derive(Default)]
struct Pieces {
    particles: Vec<u32>,
    pieces: Vec<Piece>,
    /// Per cut cluster, its number of pieces (in order).
    counts: Vec<u32>,
}

impl Pieces {
    fn members(&self, p: usize) -> &[u32] {
        let [start, end] = self.pieces[p].span;
        &self.particles[start as usize..end as usize]
    }

    /// Appends `other`'s pieces after these.
    fn append(&mut self, other: Pieces) {
        let offset = self.particles.len() as u32;
        self.particles.extend_from_slice(&other.particles);
        self.pieces.extend(other.pieces.into_iter().map(|p| Piece {
            span: p.span.map(|s| s + offset),
            ..p
        }));
        self.counts.extend_from_slice(&other.counts);
    }
}

/// What the search for pieces reads: the lattice, the particle → clusters index and the
/// cut clusters (ascending).
struct CutView<'a> {
    lattice: &'a Lattice,
    index: &'a ClusterIndex,
    cut: &'a [u32],
}

impl CutView<'_> {
    /// Position of `k` among the cut clusters, if it is one.
    fn cut_position(&self, k: u32) -> Option<usize> {
        self.cut.binary_search(&k).ok()
    }

    /// Whether particle `a` belongs to a cluster the cut left intact.
    fn in_intact_cluster(&self, a: u32) -> bool {
        self.index
            .clusters_of(a)
            .iter()
            .any(|k| self.cut_position(*k).is_none())
    }
}

/// Buffers one task reuses from cut cluster to cut cluster.
#[derive(Default)]
struct PieceScratch {
    live: Vec<u32>,
    graph: LocalGraph,
    /// Per vertex its piece (the sentinel's slot reads as already labelled).
    label: Vec<u32>,
    stack: Vec<u32>,
    /// Vertices grouped by piece, in vertex order inside each.
    by_piece: Vec<u32>,
    piece_start: Vec<u32>,
}

impl PieceScratch {
    /// Appends the pieces of the cut cluster with `members` (ascending) to `out`.
    fn find(&mut self, members: &[u32], view: &CutView, out: &mut Pieces) {
        let lattice = view.lattice;
        self.live.clear();
        self.live
            .extend(members.iter().copied().filter(|m| lattice.is_live(*m)));
        let n = self.live.len();
        self.graph.build(&self.live, lattice);
        let count = self.label_pieces();
        out.counts.push(count as u32);
        // vertices by piece (a counting sort: pieces number in order of their smallest
        // vertex, vertices stay in order inside each)
        let Self {
            live,
            graph,
            label,
            by_piece,
            piece_start,
            ..
        } = self;
        piece_start.clear();
        piece_start.resize(count + 1, 0);
        for l in &label[..n] {
            piece_start[*l as usize + 1] += 1;
        }
        for c in 0..count {
            piece_start[c + 1] += piece_start[c];
        }
        by_piece.clear();
        by_piece.resize(n, 0);
        let mut next = piece_start.clone();
        for (v, l) in label[..n].iter().enumerate() {
            by_piece[next[*l as usize] as usize] = v as u32;
            next[*l as usize] += 1;
        }
        for c in 0..count {
            let vertices = &by_piece[piece_start[c] as usize..piece_start[c + 1] as usize];
            let start = out.particles.len() as u32;
            out.particles
                .extend(vertices.iter().map(|v| live[*v as usize]));
            // the first adjacent particle in an intact cluster: a direction without a
            // live member of the cluster leads out of the piece
            let intact_neighbour = vertices
                .iter()
                .flat_map(|&v| {
                    let m = live[v as usize];
                    let row = graph.row(v as usize);
                    (0..6)
                        .filter(move |d| row[*d] as usize == n)
                        .map(move |d| lattice.link(m, d))
                })
                .find(|a| *a != NO_PARTICLE && view.in_intact_cluster(*a))
                .unwrap_or(NONE);
            out.pieces.push(Piece {
                span: [start, out.particles.len() as u32],
                intact_neighbour,
            });
        }
    }

    /// Labels the vertices of `graph` with their connected component, components
    /// numbered in order of their smallest vertex; returns how many there are.
    fn label_pieces(&mut self) -> usize {
        const UNSEEN: u32 = NONE;
        let n = self.graph.len();
        let Self {
            graph,
            label,
            stack,
            ..
        } = self;
        label.clear();
        label.resize(n, UNSEEN);
        // the sentinel reads as labelled: it is never pushed
        label.push(NONE - 1);
        // Every vertex is pushed once, and a visit writes one slot past the top: each
        // neighbour is labelled and pushed without a branch, and kept only if unseen.
        stack.clear();
        stack.resize(n + 1, 0);
        let mut count = 0;
        for start in 0..n {
            if label[start] != UNSEEN {
                continue;
            }
            label[start] = count;
            stack[0] = start as u32;
            let mut top = 1;
            while top > 0 {
                top -= 1;
                for &w in graph.row(stack[top] as usize) {
                    let unseen = label[w as usize] == UNSEEN;
                    label[w as usize] = if unseen { count } else { label[w as usize] };
                    stack[top] = w;
                    top += usize::from(unseen);
                }
            }
            count += 1;
        }
        count as usize
    }
}

/// A cluster a piece can merge into: another piece (its number) or a cluster the cut
/// left intact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Candidate {
    Piece(u32),
    Intact(u32),
}

/// The merge forest of §3.2: pieces are nodes `0..pieces`; a cluster the cut left intact
/// becomes a node when first chosen (it never merges on, so it stays a root).
struct MergeForest {
    parent: Vec<u32>,
    pieces: usize,
    intact: Vec<u32>,
    node_of_intact: FxHashMap<u32, u32>,
}

impl MergeForest {
    fn new(pieces: usize) -> Self {
        Self {
            parent: (0..pieces as u32).collect(),
            pieces,
            intact: Vec::new(),
            node_of_intact: FxHashMap::default(),
        }
    }

    /// Root of `node`, with path halving.
    fn find(&mut self, mut node: u32) -> u32 {
        while self.parent[node as usize] != node {
            let grand = self.parent[self.parent[node as usize] as usize];
            self.parent[node as usize] = grand;
            node = grand;
        }
        node
    }

    /// Merges the root piece `own` into `target`.
    fn merge(&mut self, own: u32, target: Candidate) {
        let node = match target {
            Candidate::Piece(q) => self.find(q),
            Candidate::Intact(k) => {
                let next = self.parent.len() as u32;
                let node = *self.node_of_intact.entry(k).or_insert(next);
                if node == next {
                    self.parent.push(next);
                    self.intact.push(k);
                }
                node
            }
        };
        self.parent[own as usize] = node;
    }

    /// The intact cluster of a root node, or `None` for a piece.
    fn intact_key(&self, root: u32) -> Option<u32> {
        (root as usize >= self.pieces).then(|| self.intact[root as usize - self.pieces])
    }
}

/// Replaces every cut cluster by its pieces, then merges each piece into a neighbour
/// cluster (SPEC §3.2). Returns the clusters this produced — the neighbour clusters that
/// received a merge and the pieces that remain clusters — ascending, without duplicates.
///
/// The adjacent particle a piece merges through is its first one in a cluster the cut
/// left intact, else the first one with a cluster outside the piece's merge set (§3.2
/// leaves the choice open; preferring intact neighbours keeps chains of merges between
/// pieces, and the giant clusters they make, rare). The candidate clusters are the
/// clusters of that particle as the cut left them, a cut cluster standing for its piece
/// that holds the particle, minus the piece's own merge set. Everything that draws from
/// `rng` runs in piece order, so the result does not depend on the thread count.
pub fn regroup<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[u32],
    rng: &mut impl Rng,
) -> Vec<u32> {
    let mut cut: Vec<u32> = cut_clusters.to_vec();
    cut.sort_unstable();
    cut.dedup();
    let view = CutView {
        lattice,
        index: store.index(),
        cut: &cut,
    };
    // 3.1: the pieces of every cut cluster, and their intact neighbours.
    let pieces = {
        let lists: Vec<&[u32]> = cut.iter().map(|k| store.members(*k)).collect();
        let found: Vec<Pieces> = lists
            .par_chunks(CUT_PER_TASK)
            .map_init(PieceScratch::default, |scratch, lists| {
                let mut out = Pieces::default();
                for members in lists {
                    scratch.find(members, &view, &mut out);
                }
                out
            })
            .collect();
        let mut all = Pieces::default();
        for chunk in found {
            all.append(chunk);
        }
        all
    };
    // first piece of each cut cluster
    let mut first = Vec::with_capacity(cut.len() + 1);
    first.push(0u32);
    for c in &pieces.counts {
        first.push(first.last().copied().unwrap_or(0) + c);
    }
    // 3.2: every merge, chosen in piece order over the merge forest.
    let mut forest = choose_merges(&view, &pieces, &first, rng);
    // The merged member lists, group by group, then one batch of edits.
    let mut groups: Vec<(u32, u32)> = (0..pieces.pieces.len() as u32)
        .map(|p| (forest.find(p), p))
        .collect();
    groups.sort_unstable();
    let groups: Vec<&[(u32, u32)]> = groups.chunk_by(|a, b| a.0 == b.0).collect();
    let unions: Vec<(Vec<u32>, Vec<[u32; 2]>)> = groups
        .par_chunks(GROUPS_PER_TASK)
        .map(|groups| {
            let (mut particles, mut spans) = (Vec::new(), Vec::with_capacity(groups.len()));
            for group in groups {
                let start = particles.len();
                for (_, p) in *group {
                    particles.extend_from_slice(pieces.members(*p as usize));
                }
                if group.len() > 1 {
                    let len = sort_dedup(&mut particles[start..]);
                    particles.truncate(start + len);
                }
                spans.push([start as u32, particles.len() as u32]);
            }
            (particles, spans)
        })
        .collect();
    let owner_of_piece = |p: u32| first.partition_point(|f| *f <= p) - 1;
    let mut edits = ClusterEdits::default();
    let mut produced = Vec::with_capacity(groups.len());
    let mut kept = vec![false; cut.len()];
    // (created clusters are listed by their position among the creations)
    let mut created_positions = Vec::new();
    let lists = unions.iter().flat_map(|(particles, spans)| {
        spans
            .iter()
            .map(move |[s, e]| &particles[*s as usize..*e as usize])
    });
    for (group, members) in groups.iter().zip(lists) {
        let root = group[0].0;
        match forest.intact_key(root) {
            Some(k) => {
                edits.extend(k, members);
                produced.push(k);
            }
            None => {
                let c = owner_of_piece(root);
                if first[c] == root {
                    kept[c] = true;
                    edits.replace(cut[c], members);
                    produced.push(cut[c]);
                } else {
                    created_positions.push(produced.len());
                    edits.create(members);
                    // a placeholder until the store names it
                    produced.push(cut[c]);
                }
            }
        }
    }
    for (c, k) in cut.iter().enumerate() {
        if !kept[c] {
            edits.remove(*k);
        }
    }
    let created = store.apply(&edits);
    for (position, k) in created_positions.into_iter().zip(created) {
        produced[position] = k;
    }
    produced.sort_unstable();
    produced.dedup();
    produced
}

/// Sorts `list` and moves its distinct values to the front; returns how many there are.
fn sort_dedup(list: &mut [u32]) -> usize {
    list.sort_unstable();
    let mut len = 0;
    for r in 0..list.len() {
        if len == 0 || list[r] != list[len - 1] {
            list[len] = list[r];
            len += 1;
        }
    }
    len
}

/// §3.2's choices, in piece order: each piece's adjacent particle, its candidate
/// clusters, and a random one of them to merge into.
fn choose_merges(
    view: &CutView,
    pieces: &Pieces,
    first: &[u32],
    rng: &mut impl Rng,
) -> MergeForest {
    let CutView { lattice, index, .. } = *view;
    // the piece of cut cluster `c` that holds live particle `a`
    let piece_holding = |c: usize, a: u32| {
        let (start, end) = (first[c], first[c + 1]);
        if end - start == 1 {
            return start;
        }
        (start..end)
            .find(|p| pieces.members(*p as usize).binary_search(&a).is_ok())
            .unwrap_or(start)
    };
    let mut forest = MergeForest::new(pieces.pieces.len());
    let mut candidates: SmallVec<[Candidate; 8]> = SmallVec::new();
    let candidates_at = |a: u32, own: u32, forest: &mut MergeForest, out: &mut SmallVec<_>| {
        out.clear();
        for &k in index.clusters_of(a) {
            match view.cut_position(k) {
                Some(c) => {
                    let q = piece_holding(c, a);
                    if forest.find(q) != own {
                        out.push(Candidate::Piece(q));
                    }
                }
                None => out.push(Candidate::Intact(k)),
            }
        }
    };
    for (p, piece) in pieces.pieces.iter().enumerate() {
        // a piece has not merged on yet, so it is its own root
        let own = p as u32;
        if piece.intact_neighbour != NONE {
            candidates_at(piece.intact_neighbour, own, &mut forest, &mut candidates);
        } else {
            // the first adjacent particle with a cluster outside the merge set
            let members = pieces.members(p);
            candidates.clear();
            'search: for &m in members {
                for d in 0..6 {
                    let a = lattice.link(m, d);
                    if a == NO_PARTICLE || members.binary_search(&a).is_ok() {
                        continue;
                    }
                    candidates_at(a, own, &mut forest, &mut candidates);
                    if !candidates.is_empty() {
                        break 'search;
                    }
                }
            }
        }
        if !candidates.is_empty() {
            let target = candidates[rng.random_range(0..candidates.len())];
            forest.merge(own, target);
        }
    }
    forest
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
