//! Where cuts crossed a lattice's edges: per edge a tool separated, how far along the
//! edge its swept surface passed and that surface's normal there, both in the lattice's
//! rest frame. Written by the cut stage from the detection's exact test, kept while the
//! edge stays cut (a severed edge, or one a split half took), cleared when the edge is
//! linked again; the surface places its cut faces on them
//! ([`crate::surface::placement`]).
//!
//! An edge is named by where it lies, not by its particles (a split hands edges from a
//! particle to its new half): the cell at its lower end along its axis, and the axis.

use super::lattice::{Lattice, NEIGHBOUR_OFFSETS};
use glam::{IVec3, Vec3};
use rustc_hash::FxHashMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Where a tool's swept surface crossed one edge.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Crossing {
    /// How far along the edge, from the centre of its lower cell (0) to the centre of
    /// the other (1).
    pub fraction: f32,
    /// The unit normal of the swept surface there, in the lattice frame (either way
    /// round).
    pub normal: Vec3,
}

impl Crossing {
    /// Whether the fraction lies in `[0, 1]` and the normal is finite and of unit
    /// length (to 1e-3).
    pub fn is_valid(&self) -> bool {
        (0.0..=1.0).contains(&self.fraction)
            && self.normal.is_finite()
            && (self.normal.length() - 1.0).abs() <= 1e-3
    }

    /// The same crossing measured from the edge's other end.
    pub fn reversed(&self) -> Self {
        Self {
            fraction: 1.0 - self.fraction,
            normal: self.normal,
        }
    }
}

/// The crossings of a lattice's edges, by edge key ([`Lattice::edge_key`]). Saved as a
/// list ascending by key, so that a save does not depend on the map's order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Crossings(FxHashMap<u32, Crossing>);

impl Serialize for Crossings {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut list: Vec<(u32, Crossing)> = self.0.iter().map(|(k, c)| (*k, *c)).collect();
        list.sort_unstable_by_key(|(k, _)| *k);
        list.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Crossings {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let list: Vec<(u32, Crossing)> = Vec::deserialize(d)?;
        Ok(Self(list.into_iter().collect()))
    }
}

impl Lattice {
    /// The key of the edge between neighbouring cells `a` and `b`, and whether `a` is its
    /// lower end; `None` unless they are face neighbours inside the lattice's grid.
    pub fn edge_key(&self, a: IVec3, b: IVec3) -> Option<(u32, bool)> {
        let axis = NEIGHBOUR_OFFSETS.iter().position(|o| a + *o == b)? / 2;
        let a_lower = a[axis] < b[axis];
        let lower = if a_lower { a } else { b };
        let cell = self.cell(lower)? as u32;
        Some((cell * 3 + axis as u32, a_lower))
    }

    /// Where a cut crossed the edge from cell `cell` to its neighbour along `axis` (0, 1
    /// or 2), measured from `cell`.
    pub fn crossing_at(&self, cell: IVec3, axis: usize) -> Option<Crossing> {
        let key = self.cell(cell)? as u32 * 3 + axis as u32;
        self.crossings.0.get(&key).copied()
    }

    /// Where a cut crossed the edge between particles `p` and `q` (in neighbouring
    /// cells), measured from `p`.
    pub fn crossing_between(&self, p: u32, q: u32) -> Option<Crossing> {
        let (key, p_lower) = self.edge_key(self.coord(p), self.coord(q))?;
        let c = *self.crossings.0.get(&key)?;
        Some(if p_lower { c } else { c.reversed() })
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
        self.crossings.0.insert(key, stored);
        true
    }

    /// Forgets where a cut crossed the edge between particles `p` and `q`.
    pub fn clear_crossing(&mut self, p: u32, q: u32) {
        if let Some((key, _)) = self.edge_key(self.coord(p), self.coord(q)) {
            self.crossings.0.remove(&key);
        }
    }

    /// Number of edges with a crossing.
    pub fn crossing_count(&self) -> usize {
        self.crossings.0.len()
    }

    /// The first crossing that is not valid ([`Crossing::is_valid`]) or names an edge
    /// outside the grid, as `(edge key, crossing)`: what a loaded save is refused for.
    pub fn invalid_crossing(&self) -> Option<(u32, Crossing)> {
        let edges = self.grid.len() as u64 * 3;
        let mut bad: Vec<(u32, Crossing)> = (self.crossings.0.iter())
            .filter(|(k, c)| **k as u64 >= edges || !c.is_valid())
            .map(|(k, c)| (*k, *c))
            .collect();
        bad.sort_unstable_by_key(|(k, _)| *k);
        bad.first().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn a_crossing_is_kept_by_place_and_read_from_either_end() {
        let mut l = Shape::cuboid(UVec3::new(3, 2, 1)).voxelise(1.0).unwrap();
        let origin = l.coord(0);
        let at = |l: &Lattice, x, y| l.at(origin + IVec3::new(x, y, 0)).unwrap();
        let (a, b) = (at(&l, 1, 0), at(&l, 2, 0));
        let c = Crossing {
            fraction: 0.3,
            normal: Vec3::X,
        };
        assert!(l.sever(a, b));
        assert!(l.set_crossing(b, a, c));
        assert_eq!(l.crossing_between(b, a), Some(c));
        assert_eq!(l.crossing_between(a, b).unwrap().fraction, 0.7);
        assert_eq!(l.crossing_at(l.coord(a), 0).unwrap().fraction, 0.7);
        // not neighbours, or not a crossing: nothing recorded
        let far = at(&l, 0, 0);
        assert!(!l.set_crossing(far, b, c));
        let nan = Crossing {
            fraction: f32::NAN,
            ..c
        };
        assert!(!l.set_crossing(a, b, nan));
        // a split hands the edge to the new half: the crossing stays with the edge
        let taker = l.split(b, [true, false, false, false, false, false]);
        assert!(taker.is_none(), "its −x edge is severed: nothing to take");
        let up = at(&l, 2, 1);
        let half = l
            .split(b, [false, false, false, true, false, false])
            .unwrap();
        assert!(l.set_crossing(b, up, c));
        assert_eq!(l.crossing_between(half, up), Some(c));
        // relinking forgets it
        assert!(l.relink(a, b));
        assert_eq!(l.crossing_between(a, b), None);
        assert_eq!(l.crossing_count(), 1);
        assert_eq!(l.invalid_crossing(), None);
    }

    #[test]
    fn saves_list_crossings_in_key_order_and_refuse_bad_ones() {
        let mut l = Shape::cuboid(UVec3::new(4, 1, 1)).voxelise(1.0).unwrap();
        let order = l.live_in_morton_order();
        for pair in order.windows(2).rev() {
            let c = Crossing {
                fraction: 0.5,
                normal: Vec3::Y,
            };
            l.set_crossing(pair[0], pair[1], c);
        }
        let bytes = postcard::to_stdvec(&l.crossings).unwrap();
        let back: Crossings = postcard::from_bytes(&bytes).unwrap();
        assert_eq!(back, l.crossings);
        assert_eq!(postcard::to_stdvec(&back).unwrap(), bytes);
        let key = *l.crossings.0.keys().next().unwrap();
        l.crossings.0.insert(
            key,
            Crossing {
                fraction: 1.5,
                normal: Vec3::Y,
            },
        );
        assert_eq!(l.invalid_crossing().map(|(k, _)| k), Some(key));
    }
}
