//! Where cuts crossed a lattice's edges: per edge a tool separated, how far along the
//! edge its swept surface passed and that surface's normal there, both in the lattice's
//! rest frame. Written by the cut stage from the detection's exact test, kept while the
//! edge stays cut (a severed edge, or one a split half took), cleared when the edge is
//! linked again; the surface places its cut faces on them
//! ([`crate::surface::placement`]).
//!
//! An edge is named by where it lies, not by its particles (a split hands edges from a
//! particle to its new half): the cell at its lower end along its axis, and the axis
//! ([`crate::body::lattice::Lattice::edge_key`]; the lattice reads and writes its
//! crossings by particles or cells).

use glam::Vec3;
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

/// The crossings of a lattice's edges, by edge key ([`Lattice::edge_key`](crate::body::lattice::Lattice::edge_key)). Saved as a
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

impl Crossings {
    /// The crossing of edge `key`.
    #[inline]
    pub fn get(&self, key: u32) -> Option<Crossing> {
        self.0.get(&key).copied()
    }

    /// Records the crossing of edge `key`.
    pub fn insert(&mut self, key: u32, crossing: Crossing) {
        self.0.insert(key, crossing);
    }

    /// Forgets the crossing of edge `key`.
    pub fn remove(&mut self, key: u32) {
        self.0.remove(&key);
    }

    /// Number of edges with a crossing.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether no edge has a crossing.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The crossings, by edge key, in no particular order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, Crossing)> + '_ {
        self.0.iter().map(|(k, c)| (*k, *c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::lattice::Lattice;
    use crate::body::shape::Shape;
    use glam::{IVec3, UVec3};

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
