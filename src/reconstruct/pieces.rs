//! Reconstruction step 1, first half: the pieces of the cut clusters — the connected
//! components of each one's live members — with, for each piece, a particle it shares
//! with a cluster the cut left intact. Read-only over the clusters and the lattice, so
//! the cut clusters are split into pieces in parallel (see [`super::regroup`]).

use super::local::LocalGraph;
use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::clusters::index::ClusterIndex;
use rustc_hash::FxHashMap;

/// "None" among piece numbers, particles and labels.
pub(super) const NONE: u32 = u32::MAX;

/// One piece of a cut cluster (§3.1).
#[derive(Clone, Copy, Debug)]
pub(super) struct Piece {
    /// Its members, ascending: `particles[start..end]` of its [`Pieces`].
    pub(super) span: [u32; 2],
    /// Its first adjacent particle — members in order, each one's lattice directions in
    /// order — that belongs to a cluster the cut left intact; `NONE` if there is none.
    pub(super) intact_neighbour: u32,
}

/// The pieces of a run of cut clusters, back to back.
#[derive(Default)]
pub(super) struct Pieces {
    pub(super) particles: Vec<u32>,
    pub(super) pieces: Vec<Piece>,
    /// Per cut cluster, its number of pieces (in order).
    pub(super) counts: Vec<u32>,
}

impl Pieces {
    pub(super) fn members(&self, p: usize) -> &[u32] {
        let [start, end] = self.pieces[p].span;
        &self.particles[start as usize..end as usize]
    }

    /// Appends `other`'s pieces after these.
    pub(super) fn append(&mut self, other: Pieces) {
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
/// cut clusters' positions (in ascending key order) by key.
pub(super) struct CutView<'a> {
    pub(super) lattice: &'a Lattice,
    pub(super) index: &'a ClusterIndex,
    /// (hashed, not searched for in the sorted keys: the test for redundant pieces looks
    /// up every cluster of every member of every piece, and a big cut has thousands)
    position: FxHashMap<u32, u32>,
}

impl<'a> CutView<'a> {
    /// The view of the cut clusters `cut` (ascending, without duplicates).
    pub(super) fn new(lattice: &'a Lattice, index: &'a ClusterIndex, cut: &[u32]) -> Self {
        let position = (cut.iter().enumerate())
            .map(|(c, k)| (*k, c as u32))
            .collect();
        Self {
            lattice,
            index,
            position,
        }
    }

    /// Position of `k` among the cut clusters, if it is one.
    pub(super) fn cut_position(&self, k: u32) -> Option<usize> {
        self.position.get(&k).map(|c| *c as usize)
    }

    /// Whether particle `a` belongs to a cluster the cut left intact.
    pub(super) fn in_intact_cluster(&self, a: u32) -> bool {
        self.index
            .clusters_of(a)
            .iter()
            .any(|k| self.cut_position(*k).is_none())
    }
}

/// Buffers one task reuses from cut cluster to cut cluster.
#[derive(Default)]
pub(super) struct PieceScratch {
    pub(super) live: Vec<u32>,
    pub(super) graph: LocalGraph,
    /// Per vertex its piece (the sentinel's slot reads as already labelled).
    pub(super) label: Vec<u32>,
    pub(super) stack: Vec<u32>,
    /// Vertices grouped by piece, in vertex order inside each.
    pub(super) by_piece: Vec<u32>,
    pub(super) piece_start: Vec<u32>,
}

impl PieceScratch {
    /// Appends the pieces of the cut cluster with `members` (ascending) to `out`.
    pub(super) fn find(&mut self, members: &[u32], view: &CutView, out: &mut Pieces) {
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
    pub(super) fn label_pieces(&mut self) -> usize {
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
