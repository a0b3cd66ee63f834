//! The lattice graph induced on one cluster's members, with local vertex numbers, and
//! small bit sets over those numbers: the common ground of the per-cluster algorithms
//! of a cut event (pieces §3.1, split §4), which run thousands of times per cut on sets
//! of tens of particles.

use crate::body::graph::with_slots;
use crate::body::lattice::Lattice;
use glam::IVec3;

/// Cells of the largest box a member set is numbered in locally; bigger (sprawling) sets
/// go through the per-thread particle slots instead.
const BOX_CELLS: usize = 1 << 14;

/// The lattice graph induced on a member list. Vertex `i` is the member at position
/// `i`; its row holds, per lattice direction (the order of
/// [`crate::body::lattice::NEIGHBOUR_OFFSETS`]), the vertex in the neighbouring cell, or the
/// sentinel [`LocalGraph::len`] when that cell holds no member. Per-vertex arrays with
/// one slot more, set for the sentinel, let loops over the six neighbours run without a
/// branch on whether a neighbour exists.
#[derive(Clone, Debug, Default)]
pub struct LocalGraph {
    rows: Vec<[u32; 6]>,
    /// The vertex in each cell of the members' bounding box (padded by one cell on
    /// every side), the sentinel where there is none.
    cells: Vec<u32>,
}

impl LocalGraph {
    /// Makes this the graph of `members` (distinct live particles of `lattice`),
    /// reusing its buffers.
    ///
    /// The members are numbered in a box around them, so the graph is found from their
    /// coordinates alone, without reading the lattice's grid (whose cells around a cut
    /// are scattered over memory).
    pub fn build(&mut self, members: &[u32], lattice: &Lattice) {
        let n = members.len() as u32;
        self.rows.clear();
        let Some(&first) = members.first() else {
            return;
        };
        let coords = lattice.coords();
        let (mut lo, mut hi) = (coords[first as usize], coords[first as usize]);
        for &m in members {
            lo = lo.min(coords[m as usize]);
            hi = hi.max(coords[m as usize]);
        }
        let size = (hi - lo + IVec3::splat(3)).as_uvec3();
        let (dx, dy) = (size.x as usize, size.x as usize * size.y as usize);
        // (once edges are severed or particles split, coordinates no longer tell the
        // edges: only the links do)
        if (dy as u64) * size.z as u64 > BOX_CELLS as u64 || !lattice.is_intact() {
            return self.build_sprawling(members, lattice);
        }
        let cells = &mut self.cells;
        cells.clear();
        cells.resize(dy * size.z as usize, n);
        let origin = lo - IVec3::ONE;
        let cell = |m: u32| {
            let c = (coords[m as usize] - origin).as_uvec3();
            (c.z as usize * size.y as usize + c.y as usize) * dx + c.x as usize
        };
        for (i, &m) in members.iter().enumerate() {
            cells[cell(m)] = i as u32;
        }
        self.rows.reserve(members.len());
        // (the padding keeps every neighbour cell inside the box)
        self.rows.extend(members.iter().map(|&m| {
            let c = cell(m);
            [
                cells[c - 1],
                cells[c + 1],
                cells[c - dx],
                cells[c + dx],
                cells[c - dy],
                cells[c + dy],
            ]
        }));
    }

    /// [`Self::build`] for members spread over too big a box, or in a lattice that is
    /// no longer intact: numbered in the per-thread particle slots, neighbours read from
    /// the lattice's links.
    fn build_sprawling(&mut self, members: &[u32], lattice: &Lattice) {
        let n = members.len() as u32;
        self.rows.reserve(members.len());
        // one slot more than particles: an empty cell (`NO_PARTICLE`) reads that one,
        // which is never set
        with_slots(lattice.len() + 1, |local| {
            let unset = local.len() - 1;
            for (i, &m) in members.iter().enumerate() {
                local[m as usize] = i as u32;
            }
            for &m in members {
                let cells = lattice.links(m);
                // a cell without a member reads `u32::MAX`, which becomes the sentinel
                self.rows
                    .push(cells.map(|c| local[(c as usize).min(unset)].min(n)));
            }
            for &m in members {
                local[m as usize] = u32::MAX;
            }
        });
    }

    /// Number of vertices (also the sentinel's number).
    #[inline]
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True for the graph of no members.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The neighbour slots of vertex `i` (the sentinel where a cell holds no member).
    #[inline]
    pub fn row(&self, i: usize) -> &[u32; 6] {
        &self.rows[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::lattice::NEIGHBOUR_OFFSETS;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn rows_name_the_member_in_each_direction_or_the_sentinel() {
        let mut lattice = Shape::cuboid(UVec3::new(4, 3, 3)).voxelise(1.0).unwrap();
        lattice.remove(5);
        // every third particle is a member (5 is dead, so not one)
        let members: Vec<u32> = (0..lattice.len() as u32)
            .filter(|p| p % 3 != 1 && lattice.is_live(*p))
            .collect();
        let mut graph = LocalGraph::default();
        graph.build(&members, &lattice);
        assert_eq!(graph.len(), members.len());
        for (i, &m) in members.iter().enumerate() {
            for (d, offset) in NEIGHBOUR_OFFSETS.iter().enumerate() {
                let there = lattice.at(lattice.coord(m) + *offset);
                let expected = there
                    .and_then(|p| members.iter().position(|x| *x == p))
                    .unwrap_or(members.len());
                assert_eq!(
                    graph.row(i)[d] as usize,
                    expected,
                    "member {m} direction {d}"
                );
            }
        }
        // a set spread over a box too big to number it in: the same rows, found
        // through the lattice's grid
        let mut far = Lattice::from_coords(
            1.0,
            vec![
                glam::IVec3::ZERO,
                glam::IVec3::X,
                glam::IVec3::new(40, 0, 0),
                glam::IVec3::new(40, 40, 0),
                glam::IVec3::new(40, 40, 40),
                glam::IVec3::new(40, 40, 41),
            ],
        )
        .unwrap();
        far.remove(3);
        let spread = [0, 1, 2, 4, 5];
        graph.build(&spread, &far);
        let s = spread.len() as u32;
        assert_eq!(graph.row(0), &[s, 1, s, s, s, s]);
        assert_eq!(graph.row(1), &[0, s, s, s, s, s]);
        assert_eq!(graph.row(2), &[s; 6]);
        assert_eq!(graph.row(3), &[s, s, s, s, s, 4]);
        assert_eq!(graph.row(4), &[s, s, s, s, 3, s]);
        // the scratch is clean afterwards: an empty graph has no rows
        graph.build(&[], &lattice);
        assert!(graph.is_empty());
    }
}
