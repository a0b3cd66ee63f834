//! Which particle owns each piece of a body's space, and which neighbouring pieces are
//! joined: the solid whose boundary [`mod@super::extract`] draws.
//!
//! Each live particle owns the cube of its lattice cell. A split particle shares its
//! cell with its other half (or halves), so once a body holds split particles every cell
//! is drawn as 2×2×2 *sub-cells* (octants), and the octants of a shared cell are dealt
//! out in turns: each half, in index order, takes the free octant it rests furthest
//! toward (its [`Lattice::split_shift`] has the largest component along the octant's
//! direction; ties break on a fixed order of the axes). Two halves of a cell cut along
//! x own the four octants on their own side each, the twins of a cell cut along a
//! diagonal four each, and a cell split three ways still gives every half a share.
//!
//! Two face-adjacent sub-cells are *joined* — their common face is inside the solid —
//! when one particle owns both, or when their owners lie in neighbouring cells and are
//! linked across that face. Everything else is surface: the body's outside, a removed
//! particle, a severed edge, the two halves of a split particle.

use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use glam::{IVec3, Vec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use smallvec::SmallVec;

/// Weights of the axes that break ties between octants a half rests equally far
/// toward: the one it leans furthest toward along x first, then along y, then z. Twins
/// lean opposite ways, so of two octants they tie on, each takes one.
const TIE_BREAK: Vec3 = Vec3::new(1.0, 0.01, 0.0001);

/// The owners of a lattice's sub-cells (see the module docs).
pub struct CellOwners<'a> {
    lattice: &'a Lattice,
    resolution: i32,
    /// The owner of each octant (numbered like [`octant`]) of each cell that holds a
    /// split particle.
    shared: FxHashMap<IVec3, [u32; 8]>,
    /// With octants, their owners over the box of sub-cells from `dense_min`, `dense_dims`
    /// wide ([`NO_PARTICLE`] where none): a lookup instead of a hash per sub-cell. Empty
    /// (and the hash consulted) for one sub-cell per cell, or a box too large to fill.
    dense: Vec<u32>,
    dense_min: IVec3,
    dense_dims: IVec3,
}

/// Most sub-cells the dense owner box may hold (256 MB of owners).
const MAX_DENSE: i64 = 1 << 26;

impl<'a> CellOwners<'a> {
    /// The owners of `lattice`'s live particles' cells.
    pub fn new(lattice: &'a Lattice) -> Self {
        Self::looked_up_in(lattice, IVec3::MIN, IVec3::MAX)
    }

    /// The owners of `lattice`'s live particles' cells, looked up mostly in the cells
    /// from `lo` to `hi` (inclusive): the same owners everywhere, found fastest there.
    pub fn looked_up_in(lattice: &'a Lattice, lo: IVec3, hi: IVec3) -> Self {
        let mut members: FxHashMap<IVec3, Vec<u32>> = FxHashMap::default();
        for p in lattice
            .live_particles()
            .filter(|&p| lattice.is_split_half(p))
        {
            members.entry(lattice.coord(p)).or_default().push(p);
        }
        let shared: FxHashMap<IVec3, [u32; 8]> = members
            .into_iter()
            .map(|(cell, mut members)| {
                if let Some(p) = lattice.at(cell).filter(|p| !members.contains(p)) {
                    members.push(p);
                }
                members.sort_unstable();
                (cell, deal_octants(lattice, &members))
            })
            .collect();
        let resolution = if shared.is_empty() { 1 } else { 2 };
        let mut owners = Self {
            lattice,
            resolution,
            shared,
            dense: Vec::new(),
            dense_min: IVec3::ZERO,
            dense_dims: IVec3::ZERO,
        };
        if resolution == 2 {
            owners.fill_dense(lo, hi);
        }
        owners
    }

    /// Fills the dense owner box of the octants of the lattice's cells from `lo` to `hi`
    /// (unless it would pass [`MAX_DENSE`]).
    fn fill_dense(&mut self, lo: IVec3, hi: IVec3) {
        let lattice = self.lattice;
        let (grid_lo, grid_hi) = lattice.grid_cells();
        let (lo, hi) = (lo.max(grid_lo), hi.min(grid_hi));
        if lo.cmpgt(hi).any() {
            return;
        }
        let dims = (hi - lo + IVec3::ONE) * 2;
        let count = dims.as_i64vec3().element_product();
        if count > MAX_DENSE {
            return;
        }
        let mut dense = vec![NO_PARTICLE; count as usize];
        // (a layer of cells along z is two layers of sub-cells, filled in parallel)
        let per_layer = (2 * dims.y * dims.x) as usize;
        let shared = &self.shared;
        (dense.par_chunks_mut(per_layer).enumerate()).for_each(|(along_z, layer)| {
            let z = lo.z + along_z as i32;
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let c = IVec3::new(x, y, z);
                    let octants = match (shared.get(&c), lattice.at(c)) {
                        (Some(dealt), _) => *dealt,
                        (None, Some(p)) => [p; 8],
                        (None, None) => continue,
                    };
                    for (k, p) in (0..8u32).zip(octants) {
                        let d = (c - lo) * 2 + octant(k);
                        layer[((d.z % 2 * dims.y + d.y) * dims.x + d.x) as usize] = p;
                    }
                }
            }
        });
        self.dense = dense;
        self.dense_min = lo * 2;
        self.dense_dims = dims;
    }

    /// The lattice.
    pub fn lattice(&self) -> &'a Lattice {
        self.lattice
    }

    /// Sub-cells per cell along each axis: 1, or 2 once a particle was split.
    pub fn resolution(&self) -> i32 {
        self.resolution
    }

    /// The lattice cell sub-cell `s` lies in.
    #[inline]
    pub fn cell_of(&self, s: IVec3) -> IVec3 {
        // (an arithmetic shift rounds toward −∞, like the division it stands for)
        s >> (self.resolution - 1)
    }

    /// Whether every face of `p`'s sub-cells is either inside its cell or against a
    /// sub-cell of a particle it is linked to, so that none can be on the surface: `p`
    /// has all six links and no particle of its cell or the six around it was split.
    pub fn is_enclosed(&self, p: u32) -> bool {
        let lattice = self.lattice;
        if lattice.is_surface(p) {
            return false;
        }
        if self.shared.is_empty() {
            return true;
        }
        let c = lattice.coord(p);
        !self.shared.contains_key(&c)
            && NEIGHBOUR_OFFSETS
                .iter()
                .all(|o| !self.shared.contains_key(&(c + *o)))
    }

    /// The sub-cells `p` owns.
    pub fn owned_by(&self, p: u32) -> impl Iterator<Item = IVec3> + '_ {
        let base = self.lattice.coord(p) * self.resolution;
        let count = (self.resolution * self.resolution * self.resolution) as u32;
        (0..count)
            .map(move |k| base + octant(k) * (self.resolution - 1))
            .filter(move |&s| self.owner(s) == Some(p))
    }

    /// The live particle that owns sub-cell `s`, if any.
    #[inline]
    pub fn owner(&self, s: IVec3) -> Option<u32> {
        // (the common case, a cell per particle, inlined into every caller)
        if self.resolution == 1 {
            self.lattice.at(s)
        } else {
            self.octant_owner(s)
        }
    }

    /// [`Self::owner`] with octants.
    fn octant_owner(&self, s: IVec3) -> Option<u32> {
        // (a sub-cell outside the dense box is looked up as if there were none)
        let d = s - self.dense_min;
        if !self.dense.is_empty() && d.cmpge(IVec3::ZERO).all() && d.cmplt(self.dense_dims).all() {
            let dims = self.dense_dims;
            let p = self.dense[((d.z * dims.y + d.y) * dims.x + d.x) as usize];
            return (p != NO_PARTICLE).then_some(p);
        }
        let cell = self.cell_of(s);
        let Some(octants) = self.shared.get(&cell) else {
            return self.lattice.at(cell);
        };
        let k = (s - cell * self.resolution).dot(IVec3::new(1, 2, 4));
        Some(octants[k as usize])
    }

    /// The live particles owning sub-cells of lattice cell `cell`: the particle there,
    /// or the halves a split dealt its octants to (each once, in the order of the
    /// octants they own first); none for an empty cell.
    pub fn particles_in(&self, cell: IVec3) -> SmallVec<[u32; 8]> {
        let mut found = SmallVec::new();
        match self.shared.get(&cell) {
            Some(octants) => {
                for &p in octants {
                    if !found.contains(&p) {
                        found.push(p);
                    }
                }
            }
            None => found.extend(self.lattice.at(cell)),
        }
        found
    }

    /// Whether sub-cell `a`, owned by `p`, and its neighbour in direction `d` (an index
    /// into [`NEIGHBOUR_OFFSETS`]), owned by `q`, are joined.
    pub fn joined(&self, a: IVec3, p: u32, d: usize, q: u32) -> bool {
        if p == q {
            return true;
        }
        let b = a + NEIGHBOUR_OFFSETS[d];
        self.cell_of(a) != self.cell_of(b) && self.lattice.link(p, d) == q
    }
}

/// The octants of a cell dealt out among its live particles `members` (ascending), in
/// turns (see the module docs).
fn deal_octants(lattice: &Lattice, members: &[u32]) -> [u32; 8] {
    let mut dealt = [u32::MAX; 8];
    for turn in 0..8 {
        let p = members[turn % members.len()];
        let shift = lattice.split_shift(p);
        let lean = |k: u32| {
            let toward = (octant(k) * 2 - IVec3::ONE).as_vec3();
            (shift.dot(toward), (shift * toward).dot(TIE_BREAK))
        };
        let best = (0..8u32)
            .filter(|&k| dealt[k as usize] == u32::MAX)
            .max_by(|&a, &b| {
                let (la, lb) = (lean(a), lean(b));
                la.0.total_cmp(&lb.0)
                    .then(la.1.total_cmp(&lb.1))
                    .then(b.cmp(&a))
            })
            .expect("eight turns for eight octants");
        dealt[best as usize] = p;
    }
    dealt
}

/// The corner offset in `{0, 1}³` numbered `k` (bit 0: x, bit 1: y, bit 2: z).
pub fn octant(k: u32) -> IVec3 {
    IVec3::new((k & 1) as i32, (k >> 1 & 1) as i32, (k >> 2 & 1) as i32)
}

/// The grid corners of the face of sub-cell `s` in direction `d`, counter-clockwise seen
/// from outside (along the direction).
#[inline]
pub fn face_corners(s: IVec3, d: u8) -> [IVec3; 4] {
    FACE_CORNERS[d as usize].map(|o| s + o)
}

/// Which of [`face_corners`]`(s, d)` grid corner `w` is (`w` must be one of them).
#[inline]
pub fn corner_index(s: IVec3, d: u8, w: IVec3) -> usize {
    let o = w - s;
    CORNER_INDEX[d as usize][(o.x | o.y << 1 | o.z << 2) as usize & 7] as usize
}

/// Per direction, the offsets of a face's corners from its sub-cell's lowest corner, in
/// the order of [`face_corners`]. With `(axis, b, c)` a right-handed cycle of
/// `(x, y, z)`, the face of direction `2 axis + 1` lies one sub-cell along `axis` and
/// runs `(0,0) (1,0) (1,1) (0,1)` in `(b, c)`, that of `2 axis` runs `(0,1) (1,1) (1,0)
/// (0,0)`: opposite faces take opposite diagonals (a quad's triangles meet along the
/// diagonal from its first corner), so the two faces of a slit (a severed edge inside a
/// piece), which share all four corners, share no diagonal.
const FACE_CORNERS: [[IVec3; 4]; 6] = {
    let mut table = [[IVec3::ZERO; 4]; 6];
    let mut d = 0;
    while d < 6 {
        let (axis, positive) = (d / 2, d % 2 == 1);
        let order: [(i32, i32); 4] = if positive {
            [(0, 0), (1, 0), (1, 1), (0, 1)]
        } else {
            [(0, 1), (1, 1), (1, 0), (0, 0)]
        };
        let mut k = 0;
        while k < 4 {
            table[d][k] = in_axis_frame(axis, positive as i32, order[k].0, order[k].1);
            k += 1;
        }
        d += 1;
    }
    table
};

/// The offset that is `along` along `axis`, and `i`, `j` along the axes after it, `b`
/// and `c` (`(axis, b, c)` a right-handed cycle of `(x, y, z)`): the frame the corner
/// and edge tables are written in.
pub(super) const fn in_axis_frame(axis: usize, along: i32, i: i32, j: i32) -> IVec3 {
    let mut o = [0i32; 3];
    o[axis] = along;
    o[(axis + 1) % 3] = i;
    o[(axis + 2) % 3] = j;
    IVec3::new(o[0], o[1], o[2])
}

/// Per direction, the index in [`FACE_CORNERS`] of the corner at each offset `x + 2y +
/// 4z` from the sub-cell (offsets that are no corner of the face read 0).
const CORNER_INDEX: [[u8; 8]; 6] = {
    let mut table = [[0u8; 8]; 6];
    let mut d = 0;
    while d < 6 {
        let mut k = 0;
        while k < 4 {
            let o = FACE_CORNERS[d][k];
            table[d][(o.x + 2 * o.y + 4 * o.z) as usize] = k as u8;
            k += 1;
        }
        d += 1;
    }
    table
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn an_intact_box_is_one_cell_per_particle() {
        let l = Shape::cuboid(UVec3::new(3, 2, 2)).voxelise(1.0).unwrap();
        let owners = CellOwners::new(&l);
        assert_eq!(owners.resolution(), 1);
        for p in l.live_particles() {
            assert_eq!(owners.owned_by(p).collect::<Vec<_>>(), vec![l.coord(p)]);
        }
    }

    #[test]
    fn halves_of_a_split_own_the_octants_on_their_side() {
        let mut l = Shape::cuboid(UVec3::new(3, 1, 1)).voxelise(1.0).unwrap();
        let middle = l.at(l.coord(0) + IVec3::X).unwrap();
        // the new half takes the +x edge
        let half = l
            .split(middle, [false, true, false, false, false, false])
            .unwrap();
        let owners = CellOwners::new(&l);
        assert_eq!(owners.resolution(), 2);
        let base = l.coord(middle) * 2;
        let x_of = |p: u32| {
            let xs: Vec<i32> = owners.owned_by(p).map(|s| s.x - base.x).collect();
            assert_eq!(xs.len(), 4);
            xs
        };
        assert!(x_of(half).iter().all(|&x| x == 1));
        assert!(x_of(middle).iter().all(|&x| x == 0));
        // the far particle owns its whole cell, and the half is joined to it
        let far = l.link(half, 1);
        assert_eq!(owners.owned_by(far).count(), 8);
        let s = base + IVec3::new(1, 0, 0);
        assert!(owners.joined(s, half, 1, far));
        assert!(!owners.joined(s, half, 0, middle));
    }

    #[test]
    fn a_face_runs_counter_clockwise_round_its_side_of_the_sub_cell() {
        let s = IVec3::new(-4, 7, 2);
        for (d, outward) in NEIGHBOUR_OFFSETS.iter().enumerate() {
            let c = face_corners(s, d as u8);
            // every corner on the face's plane, on the sub-cell's cube
            let centre = s.as_vec3() + Vec3::splat(0.5);
            for w in c {
                let from_centre = w.as_vec3() - centre;
                assert_eq!(from_centre.abs(), Vec3::splat(0.5));
                assert_eq!(from_centre.dot(outward.as_vec3()), 0.5);
            }
            // the four corners go round the face once, turning left seen from outside
            for k in 0..4 {
                let (a, b, e) = (c[k], c[(k + 1) % 4], c[(k + 2) % 4]);
                assert_eq!((b - a).abs().element_sum(), 1);
                assert_eq!((b - a).cross(e - b), *outward);
            }
        }
    }

    #[test]
    fn corner_index_finds_each_corner_of_every_face() {
        let s = IVec3::new(3, -2, 5);
        for d in 0..6u8 {
            for (k, w) in face_corners(s, d).into_iter().enumerate() {
                assert_eq!(corner_index(s, d, w), k);
            }
        }
    }

    #[test]
    fn owners_looked_up_in_a_box_are_the_owners_everywhere() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut l = Shape::cuboid(UVec3::new(6, 5, 4)).voxelise(1.0).unwrap();
        let live: Vec<u32> = l.live_particles().collect();
        for &p in live.iter().step_by(3) {
            let moves: [bool; 6] = std::array::from_fn(|_| rng.random_bool(0.5));
            l.split(p, moves);
        }
        l.remove(live[1]);
        let everywhere = CellOwners::new(&l);
        assert_eq!(everywhere.resolution(), 2);
        let (lo, hi) = l.grid_cells();
        for _ in 0..20 {
            let mut corner = || {
                IVec3::new(
                    rng.random_range(-2..8),
                    rng.random_range(-2..7),
                    rng.random_range(-2..6),
                )
            };
            let (a, b) = (corner(), corner());
            let near = CellOwners::looked_up_in(&l, a.min(b), a.max(b));
            // every sub-cell of the grid and a cell around it, inside the box or not
            for z in 2 * lo.z - 2..2 * hi.z + 4 {
                for y in 2 * lo.y - 2..2 * hi.y + 4 {
                    for x in 2 * lo.x - 2..2 * hi.x + 4 {
                        let s = IVec3::new(x, y, z);
                        assert_eq!(near.owner(s), everywhere.owner(s), "{s}");
                    }
                }
            }
            for c in [a, b, lo, hi] {
                assert_eq!(near.particles_in(c), everywhere.particles_in(c));
            }
        }
    }

    #[test]
    fn a_diagonal_split_shares_its_octants_four_and_four() {
        let mut l = Shape::cuboid(UVec3::new(3, 3, 1)).voxelise(1.0).unwrap();
        let centre = l.at(l.coord(0) + IVec3::new(1, 1, 0)).unwrap();
        // the new half takes the -x and -y edges: it rests toward (-1, -1, 0)
        let half = l
            .split(centre, [true, false, true, false, false, false])
            .unwrap();
        let owners = CellOwners::new(&l);
        assert_eq!(owners.owned_by(half).count(), 4);
        assert_eq!(owners.owned_by(centre).count(), 4);
    }
}
