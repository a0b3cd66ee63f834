//! The edits a cut makes to a lattice: severing and relinking edges, marking carved
//! particles, splitting a particle in two, removing one.

use super::crossings::Crossing;
use super::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use glam::Vec3;

/// How far a split half rests from its cell's centre, in cells, where its edges would
/// put it at the centre (see [`Lattice::split`]): enough to deal it its share of its
/// cell's octants ([`crate::surface::cells`]), too little to strain its edges.
pub const TIE_SHIFT: f32 = 1.0 / 64.0;

impl Lattice {
    /// Severs the edge between particles `a` and `b`; returns false when they are not
    /// linked. Both stay live.
    pub fn sever(&mut self, a: u32, b: u32) -> bool {
        if b == NO_PARTICLE {
            return false;
        }
        let Some(d) = self
            .links
            .get(a as usize)
            .and_then(|l| l.iter().position(|&n| n == b))
        else {
            return false;
        };
        self.links[a as usize][d] = NO_PARTICLE;
        self.links[b as usize][d ^ 1] = NO_PARTICLE;
        self.intact = false;
        self.pieces.take();
        self.edits += 1;
        true
    }

    /// Marks particle `i` carved; returns whether it was not before.
    pub fn carve(&mut self, i: u32) -> bool {
        let (word, bit) = (i as usize / 64, 1u64 << (i % 64));
        if self.carved.len() <= word {
            self.carved.resize(word + 1, 0);
        }
        let new = self.carved[word] & bit == 0;
        self.carved[word] |= bit;
        new
    }

    /// Whether particle `i` has been carved ([`Lattice::carve`]).
    pub fn is_carved(&self, i: u32) -> bool {
        self.carved
            .get(i as usize / 64)
            .is_some_and(|w| w >> (i % 64) & 1 != 0)
    }

    /// Links live particles `a` and `b` again after [`Lattice::sever`]: they must lie in
    /// neighbouring cells with both of the facing slots free. Returns whether it linked
    /// them; a crossing recorded on the edge is forgotten.
    pub fn relink(&mut self, a: u32, b: u32) -> bool {
        if !(self.is_live(a) && self.is_live(b)) {
            return false;
        }
        let Some(d) = NEIGHBOUR_OFFSETS
            .iter()
            .position(|o| self.coord(a) + *o == self.coord(b))
        else {
            return false;
        };
        if self.links[a as usize][d] != NO_PARTICLE || self.links[b as usize][d ^ 1] != NO_PARTICLE
        {
            return false;
        }
        self.links[a as usize][d] = b;
        self.links[b as usize][d ^ 1] = a;
        self.clear_crossing(a, b);
        self.pieces.take();
        self.edits += 1;
        true
    }

    /// Splits live particle `i` in two: a new particle (returned) at the same lattice
    /// coordinate takes the edges of the directions where `moves[d]` is set, particle
    /// `i` keeps the others. Like the two halves of a cell cut through its middle, the
    /// new particle rests a quarter cell from the cell's centre toward the edges it took
    /// (their mean direction) and particle `i` a quarter cell the other way, so that
    /// shape matching holds each on its own side of the cut instead of pulling it into
    /// its twin's place. Neither half rests exactly at the centre, so that both count as
    /// halves: a new particle whose edges point every way (their mean direction is zero:
    /// a bent body cut through a particle whose opposite neighbours lie on one side)
    /// rests [`TIE_SHIFT`] toward its first edge instead, and a particle `i` that the
    /// split would bring back to the centre (split before the other way) rests
    /// [`TIE_SHIFT`] away from its new half. The new particle is live and has the next index; `None`
    /// when `i` is not live or no direction of `moves` has an edge to take (a split would
    /// leave a particle of no edge sharing `i`'s place).
    pub fn split(&mut self, i: u32, moves: [bool; 6]) -> Option<u32> {
        let takes = |d: usize| moves[d] && self.links[i as usize][d] != NO_PARTICLE;
        if !self.is_live(i) || !(0..6).any(takes) {
            return None;
        }
        let j = self.coords.len() as u32;
        self.coords.push(self.coords[i as usize]);
        let mut links = [NO_PARTICLE; 6];
        for (d, &moved) in moves.iter().enumerate() {
            let n = self.links[i as usize][d];
            if moved && n != NO_PARTICLE {
                links[d] = n;
                self.links[i as usize][d] = NO_PARTICLE;
                self.links[n as usize][d ^ 1] = j;
            }
        }
        self.links.push(links);
        let taken: Vec<Vec3> = (0..6)
            .filter(|&d| links[d] != NO_PARTICLE)
            .map(|d| NEIGHBOUR_OFFSETS[d].as_vec3())
            .collect();
        let mean = taken.iter().sum::<Vec3>() / taken.len() as f32;
        let shift = if mean == Vec3::ZERO {
            TIE_SHIFT * taken[0]
        } else {
            0.25 * mean
        };
        self.rest_shift.resize(j as usize, Vec3::ZERO);
        self.rest_shift[i as usize] -= shift;
        if self.rest_shift[i as usize] == Vec3::ZERO {
            self.rest_shift[i as usize] = -shift * (TIE_SHIFT / shift.length());
        }
        self.rest_shift.push(shift);
        if self.live.len() * 64 <= j as usize {
            self.live.push(0);
        }
        self.live[j as usize / 64] |= 1 << (j % 64);
        self.live_count += 1;
        self.intact = false;
        self.pieces.take();
        self.edits += 1;
        Some(j)
    }

    /// Records where a cut crossed the edge between particles `p` and `q` (in
    /// neighbouring cells), `crossing` measured from `p`; returns false (and records
    /// nothing) when they are not neighbours or the crossing is not valid.
    pub fn set_crossing(&mut self, p: u32, q: u32, crossing: Crossing) -> bool {
        let Some((key, p_lower)) = self.edge_key(self.coord(p), self.coord(q)) else {
            return false;
        };
        if !crossing.is_valid() {
            return false;
        }
        let stored = if p_lower {
            crossing
        } else {
            crossing.reversed()
        };
        self.crossings.insert(key, stored);
        self.edits += 1;
        true
    }

    /// Forgets where a cut crossed the edge between particles `p` and `q`.
    pub fn clear_crossing(&mut self, p: u32, q: u32) {
        if let Some((key, _)) = self.edge_key(self.coord(p), self.coord(q)) {
            self.crossings.remove(key);
            self.edits += 1;
        }
    }

    /// Removes particle `i`; returns false if it was not live.
    pub fn remove(&mut self, i: u32) -> bool {
        if !self.is_live(i) {
            return false;
        }
        let cell = self
            .cell(self.coords[i as usize])
            .expect("live particle inside bounds");
        // (a split particle shares its cell with the particle it came from)
        if self.grid[cell] == i {
            self.grid[cell] = NO_PARTICLE;
        }
        for (d, n) in std::mem::replace(&mut self.links[i as usize], [NO_PARTICLE; 6])
            .into_iter()
            .enumerate()
        {
            if n != NO_PARTICLE {
                self.links[n as usize][d ^ 1] = NO_PARTICLE;
            }
        }
        self.live[i as usize / 64] &= !(1 << (i % 64));
        self.live_count -= 1;
        self.pieces.take();
        self.edits += 1;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn a_split_takes_an_edge_and_both_halves_count_as_halves() {
        let mut l = Shape::cuboid(UVec3::new(3, 1, 1)).voxelise(1.0).unwrap();
        let middle = (l.live_particles())
            .find(|&p| l.neighbours(p).count() == 2)
            .unwrap();
        let right = l.link(middle, 1);
        assert_ne!(right, NO_PARTICLE);
        assert!(!l.sever(middle, NO_PARTICLE));
        assert!(l.sever(middle, right));
        // its only moved direction severed: nothing to take
        assert_eq!(
            l.split(middle, [false, true, false, false, false, false]),
            None
        );
        assert!(l.relink(middle, right));
        // both edges, opposite ways: the new half still rests off the centre
        let new = l
            .split(middle, [true, true, false, false, false, false])
            .unwrap();
        assert!(l.is_split_half(new) && l.is_split_half(middle));
        assert_eq!(l.split_shift(new), -l.split_shift(middle));
        assert_eq!(l.links(middle), [NO_PARTICLE; 6]);
    }

    #[test]
    fn severing_and_splitting_keep_the_links_symmetric_and_the_pieces_counted() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let mut counts = std::collections::BTreeSet::new();
        for case in 0..200 {
            let mut l = Shape::cuboid(UVec3::new(5, 4, 3)).voxelise(1.0).unwrap();
            for _ in 0..rng.random_range(1..30) {
                let live: Vec<u32> = l.live_particles().collect();
                let p = live[rng.random_range(0..live.len())];
                match rng.random_range(0..3) {
                    0 => {
                        if let Some(n) = l.neighbours(p).next() {
                            assert!(l.sever(p, n) && !l.sever(p, n));
                        }
                    }
                    1 => {
                        let moves: [bool; 6] = std::array::from_fn(|_| rng.random_bool(0.5));
                        let before = l.links(p);
                        let Some(q) = l.split(p, moves) else {
                            // (nothing to take)
                            assert!((0..6).all(|d| !moves[d] || before[d] == NO_PARTICLE));
                            continue;
                        };
                        assert_eq!(l.coord(q), l.coord(p));
                        assert!(l.is_split_half(p) && l.is_split_half(q), "case {case}");
                        for d in 0..6 {
                            let kept = if moves[d] { l.link(q, d) } else { l.link(p, d) };
                            assert_eq!(kept, before[d], "case {case}");
                        }
                    }
                    _ => {
                        if live.len() > 1 {
                            l.remove(p);
                        }
                    }
                }
            }
            // every link is live and answered by the opposite link
            for a in l.live_particles() {
                for (d, b) in l.links(a).into_iter().enumerate() {
                    if b != NO_PARTICLE {
                        assert!(l.is_live(b) && l.link(b, d ^ 1) == a, "case {case}");
                        assert_eq!(l.coord(b) - l.coord(a), NEIGHBOUR_OFFSETS[d]);
                    }
                }
            }
            // pieces by an independent union–find over the edge list
            let mut graph = petgraph::graph::UnGraph::<(), ()>::new_undirected();
            let nodes: Vec<_> = (0..l.len()).map(|_| graph.add_node(())).collect();
            for (a, b) in l.edges() {
                graph.add_edge(nodes[a as usize], nodes[b as usize], ());
            }
            let dead = l.len() - l.live_count();
            let pieces = petgraph::algo::connected_components(&graph) - dead;
            assert_eq!(l.piece_count(), pieces, "case {case}");
            counts.insert(pieces.min(3));
        }
        assert_eq!(counts.into_iter().collect::<Vec<_>>(), [1, 2, 3]);
    }
}
