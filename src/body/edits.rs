//! The edits a cut makes to a lattice: severing and relinking edges, marking carved
//! particles, splitting a particle in two, removing one.

use super::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use glam::Vec3;

impl Lattice {
    /// Severs the edge between particles `a` and `b`; returns false when they are not
    /// linked. Both stay live.
    pub fn sever(&mut self, a: u32, b: u32) -> bool {
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
    /// them.
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
        self.pieces.take();
        true
    }

    /// Splits live particle `i` in two: a new particle (returned) at the same lattice
    /// coordinate takes the edges of the directions where `moves[d]` is set, particle
    /// `i` keeps the others. Like the two halves of a cell cut through its middle, the
    /// new particle rests a quarter cell from the cell's centre toward the edges it took
    /// (their mean direction) and particle `i` a quarter cell the other way, so that
    /// shape matching holds each on its own side of the cut instead of pulling it into
    /// its twin's place. The new particle is live and has the next index; `None` when `i`
    /// is not live.
    pub fn split(&mut self, i: u32, moves: [bool; 6]) -> Option<u32> {
        if !self.is_live(i) {
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
        let shift = if taken.is_empty() {
            Vec3::ZERO
        } else {
            0.25 * taken.iter().sum::<Vec3>() / taken.len() as f32
        };
        self.rest_shift.resize(j as usize, Vec3::ZERO);
        self.rest_shift[i as usize] -= shift;
        self.rest_shift.push(shift);
        if self.live.len() * 64 <= j as usize {
            self.live.push(0);
        }
        self.live[j as usize / 64] |= 1 << (j % 64);
        self.live_count += 1;
        self.intact = false;
        self.pieces.take();
        Some(j)
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
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

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
                        let moves = std::array::from_fn(|_| rng.random_bool(0.5));
                        let before = l.links(p);
                        let q = l.split(p, moves).unwrap();
                        assert_eq!(l.coord(q), l.coord(p));
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
