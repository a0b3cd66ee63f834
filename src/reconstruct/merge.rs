//! Reconstruction step 1, second half: which pieces are dropped as redundant and which
//! fragments merge where (§3.2, with the departures [`super::regroup`] explains), as a
//! merge forest over the pieces.

use super::pieces::{CutView, NONE, Pieces};
use crate::body::lattice::{Lattice, NO_PARTICLE};
use glam::IVec3;
use rand::Rng;
use rustc_hash::FxHashMap;

/// A cluster a piece can merge into: another piece (its number) or a cluster the cut
/// left intact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Candidate {
    Piece(u32),
    Intact(u32),
}

/// The merge forest of §3.2: pieces are nodes `0..pieces`; a cluster the cut left intact
/// becomes a node when first chosen (it never merges on, so it stays a root).
pub(super) struct MergeForest {
    pub(super) parent: Vec<u32>,
    /// Per piece, whether it was dropped as redundant (it stays a root nobody joins).
    pub(super) dropped: Vec<bool>,
    pub(super) pieces: usize,
    pub(super) intact: Vec<u32>,
    pub(super) node_of_intact: FxHashMap<u32, u32>,
}

impl MergeForest {
    pub(super) fn new(pieces: usize) -> Self {
        Self {
            parent: (0..pieces as u32).collect(),
            dropped: vec![false; pieces],
            pieces,
            intact: Vec::new(),
            node_of_intact: FxHashMap::default(),
        }
    }

    /// Root of `node`, with path halving.
    pub(super) fn find(&mut self, mut node: u32) -> u32 {
        while self.parent[node as usize] != node {
            let grand = self.parent[self.parent[node as usize] as usize];
            self.parent[node as usize] = grand;
            node = grand;
        }
        node
    }

    /// Merges the root piece `own` into `target`.
    pub(super) fn merge(&mut self, own: u32, target: Candidate) {
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

    /// Drops piece `p` (a root nobody has joined).
    pub(super) fn drop(&mut self, p: u32) {
        self.dropped[p as usize] = true;
    }

    /// Whether `node` is a dropped piece.
    pub(super) fn is_dropped(&self, node: u32) -> bool {
        self.dropped.get(node as usize).copied().unwrap_or(false)
    }

    /// The intact cluster of a root node, or `None` for a piece.
    pub(super) fn intact_key(&self, root: u32) -> Option<u32> {
        (root as usize >= self.pieces).then(|| self.intact[root as usize - self.pieces])
    }
}

/// Whether the members' lattice coordinates lie on one line (a point included): such a
/// cluster's shape matching cannot fix a rotation.
pub(super) fn collinear(members: &[u32], lattice: &Lattice) -> bool {
    let Some(&first) = members.first() else {
        return true;
    };
    let origin = lattice.coord(first);
    let mut axis = IVec3::ZERO;
    for &m in members {
        let d = lattice.coord(m) - origin;
        if axis == IVec3::ZERO {
            axis = d;
        } else if axis.cross(d) != IVec3::ZERO {
            return false;
        }
    }
    true
}

/// §3.2's choices over the pieces of a cut event.
pub(super) struct MergeChooser<'a> {
    pub(super) view: &'a CutView<'a>,
    pub(super) pieces: &'a Pieces,
    /// First piece of each cut cluster (and one past the last).
    pub(super) first: &'a [u32],
    /// Members of a cluster the cut left intact.
    pub(super) size_of: &'a dyn Fn(u32) -> usize,
}

impl MergeChooser<'_> {
    /// The piece of cut cluster `c` that holds live particle `a`.
    pub(super) fn piece_holding(&self, c: usize, a: u32) -> u32 {
        let (start, end) = (self.first[c], self.first[c + 1]);
        if end - start == 1 {
            return start;
        }
        (start..end)
            .find(|p| self.pieces.members(*p as usize).binary_search(&a).is_ok())
            .unwrap_or(start)
    }

    /// Appends to `out` the clusters besides those of `own`'s merge set that hold
    /// particle `a` and are not dropped (a cut cluster as its piece holding `a`).
    pub(super) fn clusters_at(
        &self,
        a: u32,
        own: u32,
        forest: &mut MergeForest,
        out: &mut Vec<Candidate>,
    ) {
        for &k in self.view.index.clusters_of(a) {
            match self.view.cut_position(k) {
                Some(c) => {
                    let q = self.piece_holding(c, a);
                    if !forest.is_dropped(q) && forest.find(q) != own {
                        out.push(Candidate::Piece(q));
                    }
                }
                None => out.push(Candidate::Intact(k)),
            }
        }
    }

    /// Members of a candidate as the cut left it.
    pub(super) fn size(&self, candidate: Candidate) -> usize {
        match candidate {
            Candidate::Piece(q) => self.pieces.members(q as usize).len(),
            Candidate::Intact(k) => (self.size_of)(k),
        }
    }

    /// Every choice, in piece order: the redundant pieces, then each fragment's
    /// neighbour cluster.
    pub(super) fn choose(&self, rng: &mut impl Rng) -> MergeForest {
        let mut forest = MergeForest::new(self.pieces.pieces.len());
        self.drop_redundant(&mut forest);
        let lattice = self.view.lattice;
        let mut candidates = Vec::new();
        let mut scores: Vec<(Candidate, usize)> = Vec::new();
        for (p, piece) in self.pieces.pieces.iter().enumerate() {
            let members = self.pieces.members(p);
            if forest.is_dropped(p as u32) || !collinear(members, lattice) {
                continue;
            }
            // a piece has not merged on yet, so it is its own root
            let own = p as u32;
            // the clusters holding its particles, by how many they hold
            scores.clear();
            for &m in members {
                candidates.clear();
                self.clusters_at(m, own, &mut forest, &mut candidates);
                for &c in &candidates {
                    match scores.iter_mut().find(|(s, _)| *s == c) {
                        Some((_, n)) => *n += 1,
                        None => scores.push((c, 1)),
                    }
                }
            }
            candidates.clear();
            let key = |(c, n): (Candidate, usize)| (n, std::cmp::Reverse(self.size(c)));
            if let Some(best) = scores.iter().map(|s| key(*s)).max() {
                candidates.extend(scores.iter().filter(|s| key(**s) == best).map(|s| s.0));
            } else {
                // shares no particle: through its first adjacent particle with a cluster
                // outside the merge set, preferring one in an intact cluster
                let adjacent = std::iter::once(piece.intact_neighbour)
                    .filter(|a| *a != NONE)
                    .chain(members.iter().flat_map(|&m| lattice.links(m)))
                    .filter(|a| *a != NO_PARTICLE && members.binary_search(a).is_err());
                for a in adjacent {
                    self.clusters_at(a, own, &mut forest, &mut candidates);
                    if !candidates.is_empty() {
                        break;
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

    /// Drops the redundant pieces, smallest first (ties in piece order): those whose
    /// every member and every lattice edge between members lies in another cluster that
    /// is not dropped. Each drop leaves what it relied on in place, so at the end every
    /// particle and edge of a dropped piece is still in some cluster.
    pub(super) fn drop_redundant(&self, forest: &mut MergeForest) {
        let lattice = self.view.lattice;
        let mut order: Vec<u32> = (0..self.pieces.pieces.len() as u32).collect();
        order.sort_by_key(|p| (self.pieces.members(*p as usize).len(), *p));
        // per member, the other clusters holding it: `held[start[i]..start[i + 1]]`
        let (mut held, mut start) = (Vec::new(), Vec::new());
        for p in order {
            let members = self.pieces.members(p as usize);
            held.clear();
            start.clear();
            let mut redundant = true;
            for &m in members {
                start.push(held.len());
                let before = held.len();
                // (its own cut cluster stands for this piece, which is not another)
                self.clusters_at(m, p, forest, &mut held);
                if held.len() == before {
                    redundant = false;
                    break;
                }
            }
            if !redundant {
                continue;
            }
            start.push(held.len());
            let of = |i: usize| &held[start[i]..start[i + 1]];
            let edges_covered = members.iter().enumerate().all(|(i, &a)| {
                lattice.links(a).iter().all(|b| {
                    match members.binary_search(b) {
                        // each edge once, from its lower end
                        Ok(j) if *b > a => of(i).iter().any(|c| of(j).contains(c)),
                        _ => true,
                    }
                })
            });
            if edges_covered {
                forest.drop(p);
            }
        }
    }
}
