//! Which quad corners of a surface are one vertex: decided around each grid edge, so
//! that every edge of the mesh lies in exactly two triangles.
//!
//! Around a grid edge lie four sub-cells. Going round, each *run* of solid sub-cells,
//! each joined to the next, is bounded by two quads (its first sub-cell's face toward
//! the one before, its last one's toward the one after); those two quads share the
//! edge, so their corners at both ends of the edge are one vertex. The vertices are the
//! classes of quad corners these pairings join.
//!
//! One configuration needs more: a *pinch*, where two runs around an edge are joined
//! to each other around both of its ends (two cells of a piece that touch only along
//! that edge, with the piece closing round on either side). Then both runs' quads
//! would share both end vertices, and the edge would lie in four triangles. The pinched
//! runs' pairings are kept at the edge's lower end only; at its upper end the vertex
//! falls apart into the arcs of its fan between the runs, each arc a vertex of its own.
//! An arc runs from one run's quad to another's, and the two meet the one lower vertex,
//! so the edge appears once per arc, in two triangles wound opposite ways. A third run
//! around the same edge that shares no end pair with another (joined to the others at
//! one end only) keeps both pairings: dropped, its two quads would part at one end and
//! leave the edge open.

use super::cells::{CellOwners, corner_index, face_corners, in_axis_frame};
use crate::util::bits::Bits;
use crate::util::grouping::group_by_key;
use crate::util::union_find::UnionFind;
use glam::IVec3;
use rayon::prelude::*;

/// A face of a solid sub-cell on the surface.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Quad {
    /// The solid sub-cell.
    pub cell: IVec3,
    /// The face's outward direction (an index into the lattice's neighbour offsets).
    pub direction: u8,
    /// The particle that owns the sub-cell.
    pub owner: u32,
}

/// The vertex class of every quad corner of `quads` (see [`VertexClasses`]). The quads
/// of each sub-cell must be consecutive, as an extraction leaves them.
pub fn vertex_classes(owners: &CellOwners, quads: &[Quad]) -> VertexClasses {
    if quads.is_empty() {
        return VertexClasses::of(&mut UnionFind::new(0), 0);
    }
    // every grid edge a quad has, once, in order: keyed by its lower corner's place in
    // the box of the quads' corners (z slowest, then y, then x) and its axis; the box
    // holds at most eight corners per cell of a lattice's bounded grid, so a key fits
    let (lo, hi) = quads.iter().fold((IVec3::MAX, IVec3::MIN), |(lo, hi), q| {
        (lo.min(q.cell), hi.max(q.cell))
    });
    let dims = (hi - lo + IVec3::splat(2)).as_u64vec3();
    let key = |w: IVec3, axis: usize| -> u64 {
        let d = (w - lo).as_u64vec3();
        ((d.z * dims.y + d.y) * dims.x + d.x) * 3 + axis as u64
    };
    let unkey = |k: u64| -> (IVec3, usize) {
        let (corner, axis) = (k / 3, (k % 3) as usize);
        let d = glam::U64Vec3::new(
            corner % dims.x,
            corner / dims.x % dims.y,
            corner / dims.x / dims.y,
        );
        (lo + d.as_ivec3(), axis)
    };
    let index = QuadIndex::new(quads, lo, hi);
    // (a bit per key, three per corner of the box: the keys come out ascending and
    // each once, without a sort)
    let mut marked = Bits::default();
    marked.reset((dims.element_product() * 3) as usize);
    for quad in quads {
        let c = face_corners(quad.cell, quad.direction);
        for k in 0..4 {
            let (a, b) = (c[k], c[(k + 1) % 4]);
            marked.insert(key(a.min(b), (b - a).abs().max_position()) as usize);
        }
    }
    let edges: Vec<u64> = marked.ones().map(|e| e as u64).collect();
    // per edge, its pairings: the slots of both quads at the lower end, then at the
    // upper (an edge's runs are consecutive)
    let pairings: Vec<(u32, [u32; 4])> = edges
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .flat_map_iter(|(e, &k)| {
            let (low, axis) = unkey(k);
            let mut high = low;
            high[axis] += 1;
            let slot = |q: u32, w: IVec3| {
                let quad = &quads[q as usize];
                4 * q + corner_index(quad.cell, quad.direction, w) as u32
            };
            let index = &index;
            let (runs, count) = runs_around(owners, low, axis);
            (runs.into_iter().take(count)).filter_map(move |((cell_a, dir_a), (cell_b, dir_b))| {
                let qa = index.find(cell_a, dir_a)?;
                let qb = index.find(cell_b, dir_b)?;
                Some((
                    e as u32,
                    [slot(qa, low), slot(qb, low), slot(qa, high), slot(qb, high)],
                ))
            })
        })
        .collect();
    let slots = quads.len() * 4;
    let mut all = UnionFind::new(slots);
    for (_, [a, b, c, d]) in &pairings {
        all.union(*a, *b);
        all.union(*c, *d);
    }
    // a run is pinched when another run around its edge has its end vertices too
    let ends: Vec<(u32, u32)> = (pairings.iter())
        .map(|(_, [a, _, c, _])| (all.find(*a), all.find(*c)))
        .collect();
    let mut kept = UnionFind::new(slots);
    let mut first = 0;
    while first < pairings.len() {
        let edge = pairings[first].0;
        let mut end = first + 1;
        while end < pairings.len() && pairings[end].0 == edge {
            end += 1;
        }
        for r in first..end {
            let [a, b, c, d] = pairings[r].1;
            kept.union(a, b);
            let alone = (first..end).all(|o| o == r || ends[o] != ends[r]);
            if alone {
                kept.union(c, d);
            }
        }
        first = end;
    }
    VertexClasses::of(&mut kept, slots)
}

/// The vertex classes of a surface's quad corners (corner `k` of quad `q` is slot
/// `4q + k`): each slot's class, and each class's slots, in order of their first slot.
pub struct VertexClasses {
    /// The class of each slot.
    pub class_of: Vec<u32>,
    /// Class `c`'s slots are `members[start[c]..start[c + 1]]`, ascending.
    start: Vec<u32>,
    members: Vec<u32>,
}

impl VertexClasses {
    /// The classes of `slots` slots joined as `kept` says: numbered in order of their
    /// first slot, each listing its slots in order.
    fn of(kept: &mut UnionFind, slots: usize) -> Self {
        let mut class_of_root = vec![u32::MAX; slots];
        let mut class_of = Vec::with_capacity(slots);
        let mut classes = 0u32;
        for s in 0..slots as u32 {
            let root = kept.find(s) as usize;
            if class_of_root[root] == u32::MAX {
                class_of_root[root] = classes;
                classes += 1;
            }
            class_of.push(class_of_root[root]);
        }
        let (start, members) = group_by_key(classes as usize, || {
            (class_of.iter().enumerate()).map(|(s, &class)| (class, s as u32))
        });
        Self {
            class_of,
            start,
            members,
        }
    }

    /// Number of classes.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// Whether there is no class.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The slots of class `c`, ascending.
    pub fn slots(&self, c: usize) -> &[u32] {
        &self.members[self.start[c] as usize..self.start[c + 1] as usize]
    }
}

/// The quads by sub-cell and direction, found without a hash: a bit per sub-cell of a
/// box one sub-cell wider on every side than the quads' sub-cells (set where quads lie),
/// the set bits before each word, and each set sub-cell's first quad, in the order of
/// the bits. A sub-cell's quads are consecutive in the list, so its first leads to them.
struct QuadIndex<'q> {
    quads: &'q [Quad],
    min: IVec3,
    dims: glam::U64Vec3,
    bits: Vec<u64>,
    /// Set bits in the words before each word.
    before: Vec<u32>,
    /// The first quad of each set sub-cell, by its rank among the set bits.
    first: Vec<u32>,
}

impl<'q> QuadIndex<'q> {
    /// The index of `quads`, whose sub-cells lie from `lo` to `hi`.
    fn new(quads: &'q [Quad], lo: IVec3, hi: IVec3) -> Self {
        let (min, dims) = (lo - IVec3::ONE, (hi - lo + IVec3::splat(3)).as_u64vec3());
        let mut index = Self {
            quads,
            min,
            dims,
            bits: vec![0; (dims.element_product() as usize).div_ceil(64)],
            before: Vec::new(),
            first: Vec::new(),
        };
        for quad in quads {
            let i = index.place(quad.cell);
            index.bits[i / 64] |= 1 << (i % 64);
        }
        let mut count = 0;
        index.before = (index.bits.iter())
            .map(|w| {
                let before = count;
                count += w.count_ones();
                before
            })
            .collect();
        index.first = vec![u32::MAX; count as usize];
        for (q, quad) in quads.iter().enumerate().rev() {
            let rank = index.rank(index.place(quad.cell));
            index.first[rank] = q as u32;
        }
        index
    }

    /// The place of sub-cell `s` (which must lie in the box) among the bits.
    #[inline(always)]
    fn place(&self, s: IVec3) -> usize {
        let d = (s - self.min).as_u64vec3();
        ((d.z * self.dims.y + d.y) * self.dims.x + d.x) as usize
    }

    /// How many set bits come before bit `i`.
    #[inline(always)]
    fn rank(&self, i: usize) -> usize {
        let below = self.bits[i / 64] & ((1u64 << (i % 64)) - 1);
        (self.before[i / 64] + below.count_ones()) as usize
    }

    /// The quad of sub-cell `s` facing `direction`, if there is one (`s` must lie in the
    /// box).
    #[inline(always)]
    fn find(&self, s: IVec3, direction: u8) -> Option<u32> {
        let i = self.place(s);
        if self.bits[i / 64] >> (i % 64) & 1 == 0 {
            return None;
        }
        let mut q = self.first[self.rank(i)] as usize;
        while let Some(quad) = self.quads.get(q).filter(|quad| quad.cell == s) {
            if quad.direction == direction {
                return Some(q as u32);
            }
            q += 1;
        }
        None
    }
}

/// Per axis, the four sub-cells around a grid edge along it, from the edge's lower
/// corner `w`, going round: with `(axis, b, c)` a right-handed cycle of `(x, y, z)`,
/// `(0, 0) → (−1, 0) → (−1, −1) → (0, −1)` in `(b, c)`, each step one face.
const ROUND: [[IVec3; 4]; 3] = {
    let mut table = [[IVec3::ZERO; 4]; 3];
    let round: [(i32, i32); 4] = [(0, 0), (-1, 0), (-1, -1), (0, -1)];
    let mut axis = 0;
    while axis < 3 {
        let mut i = 0;
        while i < 4 {
            table[axis][i] = in_axis_frame(axis, 0, round[i].0, round[i].1);
            i += 1;
        }
        axis += 1;
    }
    table
};

/// Per axis, the direction of each step of [`ROUND`], from sub-cell `i` to `i + 1`.
const ROUND_STEPS: [[usize; 4]; 3] = {
    let mut table = [[0; 4]; 3];
    let mut axis = 0;
    while axis < 3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        table[axis] = [2 * b, 2 * c, 2 * b + 1, 2 * c + 1];
        axis += 1;
    }
    table
};

/// A run's bounding quads `(first, last)`, keyed `(sub-cell, direction)`.
type Run = ((IVec3, u8), (IVec3, u8));

/// The runs of joined solid sub-cells around the grid edge from `w` along `axis` — at
/// most four, one per sub-cell, each ended by a face that is not joined — and how many
/// there are.
#[inline]
fn runs_around(owners: &CellOwners, w: IVec3, axis: usize) -> ([Run; 4], usize) {
    let (round, steps) = (&ROUND[axis], &ROUND_STEPS[axis]);
    let cells = round.map(|o| w + o);
    let own = cells.map(|c| owners.owner(c));
    let mut joined = [false; 4];
    for i in 0..4 {
        if let (Some(p), Some(q)) = (own[i], own[(i + 1) % 4]) {
            joined[i] = owners.joined(cells[i], p, steps[i], q);
        }
    }
    let mut runs = [((IVec3::ZERO, 0), (IVec3::ZERO, 0)); 4];
    let mut count = 0;
    let Some(start) = (0..4).find(|&i| !joined[(i + 3) % 4]) else {
        return (runs, count);
    };
    let mut first = None;
    for k in 0..4 {
        let i = (start + k) % 4;
        if own[i].is_none() {
            continue;
        }
        if !joined[(i + 3) % 4] {
            first = Some((cells[i], (steps[(i + 3) % 4] ^ 1) as u8));
        }
        if !joined[i]
            && let Some(f) = first.take()
        {
            runs[count] = (f, (cells[i], steps[i] as u8));
            count += 1;
        }
    }
    (runs, count)
}

#[cfg(test)]
mod tests {
    use super::QuadIndex;
    use crate::body::lattice::Lattice;
    use crate::surface::extract;
    use glam::IVec3;
    use rustc_hash::FxHashMap;

    /// Panics unless every directed edge of `triangles` appears once and its reverse
    /// once; returns the enclosed volume over `rest`.
    fn closed_volume(lattice: &Lattice) -> f32 {
        let t = extract(lattice);
        let mut directed: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        let mut volume = 0.0;
        for tri in &t.triangles {
            for k in 0..3 {
                *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
            }
            let [a, b, c] = tri.map(|v| t.rest[v as usize]);
            volume += a.dot(b.cross(c)) / 6.0;
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1, "{a}→{b} doubled");
            assert_eq!(directed.get(&(b, a)), Some(&1), "{a}→{b} open");
        }
        volume
    }

    #[test]
    fn the_quad_index_finds_every_quad_by_its_sub_cell_and_direction_and_no_other() {
        // a 3×3×3 block with its centre removed and one edge severed: quads inside and
        // out, several per sub-cell
        let coords: Vec<IVec3> = (0..27)
            .map(|k| IVec3::new(k % 3, k / 3 % 3, k / 9))
            .filter(|&c| c != IVec3::ONE)
            .collect();
        let mut lattice = Lattice::from_coords(1.0, coords).unwrap();
        let (a, b) = (
            lattice.at(IVec3::ZERO).unwrap(),
            lattice.at(IVec3::X).unwrap(),
        );
        assert!(lattice.sever(a, b));
        let quads = extract(&lattice).quads;
        let (lo, hi) = quads.iter().fold((IVec3::MAX, IVec3::MIN), |(lo, hi), q| {
            (lo.min(q.cell), hi.max(q.cell))
        });
        let index = QuadIndex::new(&quads, lo, hi);
        for (q, quad) in quads.iter().enumerate() {
            assert_eq!(index.find(quad.cell, quad.direction), Some(q as u32));
        }
        // every other (sub-cell, direction) of the box, none
        for z in lo.z - 1..=hi.z + 1 {
            for y in lo.y - 1..=hi.y + 1 {
                for x in lo.x - 1..=hi.x + 1 {
                    let s = IVec3::new(x, y, z);
                    for d in 0..6u8 {
                        let held = quads.iter().any(|q| q.cell == s && q.direction == d);
                        assert_eq!(index.find(s, d).is_some(), held);
                    }
                }
            }
        }
    }

    #[test]
    fn two_cells_touching_along_an_edge_inside_a_ring_keep_every_edge_in_two_triangles() {
        // a 2×2×3 column whose middle layer keeps only two diagonal cells: they touch
        // along one vertical edge, and the full layers join them below and above
        let coords: Vec<IVec3> = (0..3)
            .flat_map(|z| (0..2).flat_map(move |y| (0..2).map(move |x| IVec3::new(x, y, z))))
            .filter(|c| c.z != 1 || c.x == c.y)
            .collect();
        let lattice = Lattice::from_coords(1.0, coords).unwrap();
        assert!((closed_volume(&lattice) - 10.0).abs() < 1e-5);
    }

    #[test]
    fn a_pinch_beside_a_third_run_keeps_every_edge_in_two_triangles() {
        // a 2×2×3 column whose middle layer lacks cell (1, 1) and has its three cells
        // severed from each other: around the vertical edge through (1, 1) they are three
        // runs; (1, 0) and (0, 1) are joined through both full layers (a pinch), (0, 0),
        // severed from the cell below it too, through the upper layer only
        let coords: Vec<IVec3> = (0..3)
            .flat_map(|z| (0..2).flat_map(move |y| (0..2).map(move |x| IVec3::new(x, y, z))))
            .filter(|c| c.z != 1 || c.x + c.y < 2)
            .collect();
        let mut lattice = Lattice::from_coords(1.0, coords).unwrap();
        let at = |x, y, z| lattice.at(IVec3::new(x, y, z)).unwrap();
        let (corner, right, front, below) = (at(0, 0, 1), at(1, 0, 1), at(0, 1, 1), at(0, 0, 0));
        for other in [right, front, below] {
            assert!(lattice.sever(corner, other));
        }
        assert!((closed_volume(&lattice) - 11.0).abs() < 1e-5);
    }

    #[test]
    fn four_cells_severed_from_each_other_around_an_edge_are_four_closed_cubes() {
        // a 2×2×1 block whose four cells keep no link: around its middle vertical edge
        // each cell is a run of its own, the most an edge can have
        let coords: Vec<IVec3> = (0..4).map(|k| IVec3::new(k % 2, k / 2, 0)).collect();
        let mut lattice = Lattice::from_coords(1.0, coords).unwrap();
        let at = |x, y| lattice.at(IVec3::new(x, y, 0)).unwrap();
        let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
        for (p, q) in [(a, b), (a, c), (b, d), (c, d)] {
            assert!(lattice.sever(p, q));
        }
        assert_eq!(extract(&lattice).triangles.len(), 4 * 12);
        assert!((closed_volume(&lattice) - 4.0).abs() < 1e-5);
    }

    #[test]
    fn a_severed_edge_inside_a_block_leaves_a_closed_slit() {
        let coords: Vec<IVec3> = (0..27)
            .map(|k| IVec3::new(k % 3, k / 3 % 3, k / 9))
            .collect();
        let mut lattice = Lattice::from_coords(1.0, coords).unwrap();
        let centre = lattice.at(IVec3::ONE).unwrap();
        let above = lattice.at(IVec3::new(1, 1, 2)).unwrap();
        assert!(lattice.sever(centre, above));
        let t = extract(&lattice);
        // the box's 54 faces and the slit's two
        assert_eq!(t.triangles.len(), 2 * (54 + 2));
        assert!((closed_volume(&lattice) - 27.0).abs() < 1e-5);
    }
}
