//! The particle lattice of one body: coordinates, live flags, the 6-neighbourhood and
//! the links between neighbours (the body's edges, as data). Cuts edit it through
//! [`super::edits`]; its pieces are counted in [`super::pieces`]; shapes are voxelised
//! into it in [`super::shape`].

use super::crossings::Crossing;
use super::morton::morton_code;
use crate::error::{CleaveError, Result, check_positive};
use crate::util::bits::set_bits;
use crate::util::radix::sort_by_key_radix;
use glam::{IVec3, UVec3, Vec3};
use wide::u32x8;

/// Marker for "no particle" in the lattice grid.
pub const NO_PARTICLE: u32 = u32::MAX;

/// The six lattice directions (voxel edges).
pub const NEIGHBOUR_OFFSETS: [IVec3; 6] = [
    IVec3::new(-1, 0, 0),
    IVec3::new(1, 0, 0),
    IVec3::new(0, -1, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(0, 0, -1),
    IVec3::new(0, 0, 1),
];

/// Largest number of lattice cells (bounding box) a body may span.
pub const MAX_LATTICE_CELLS: u64 = 1 << 27;

/// The pieces of a body, labelled: every live particle's piece (connected component of
/// the whole body over the lattice's links), numbered from 0 in order of the lowest live
/// particle in each; removed particles get `u32::MAX`.
#[derive(Clone, Debug, Default)]
pub struct PieceLabels {
    /// The piece of each particle, by particle index (`u32::MAX`: removed).
    pub label: Vec<u32>,
    /// How many pieces there are.
    pub count: usize,
}

/// Dense lattice of one body: maps integer coordinates to particle indices and back.
///
/// Particle indices are stable for the life of the body (never reused); a removed
/// particle keeps its coordinate but is no longer *live*.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Lattice {
    pub(super) spacing: f32,
    pub(super) min: IVec3,
    pub(super) dims: UVec3,
    pub(super) grid: Vec<u32>,
    pub(super) coords: Vec<IVec3>,
    /// Bit `i` set while particle `i` is live (a bit per particle keeps the flags of a
    /// whole body in cache; a byte each would spread them over many lines).
    pub(super) live: Vec<u64>,
    pub(super) live_count: usize,
    /// The particle each particle is linked to in each of the six directions of
    /// [`NEIGHBOUR_OFFSETS`], or [`NO_PARTICLE`]: the body's edges, as data. A new
    /// lattice links every pair of live particles in neighbouring cells; removing a
    /// particle unlinks it, and a cut may sever a link between two live particles
    /// ([`Lattice::sever`]) or split a particle in two ([`Lattice::split`]).
    pub(super) links: Vec<[u32; 6]>,
    /// Per particle, how far its rest position lies from its cell's centre, in cells:
    /// zero except for the new halves of split particles (empty until the first split).
    pub(super) rest_shift: Vec<Vec3>,
    /// Bit `i` set once particle `i` has been inside a cutting sphere or capsule in
    /// `sever` mode (empty until the first carve; see [`crate::cut::carve`]).
    pub(super) carved: Vec<u64>,
    /// Where cuts crossed the edges they cut ([`super::crossings`]).
    pub(super) crossings: super::crossings::Crossings,
    /// How many edits of its links, particles or crossings the lattice has had.
    pub(super) edits: u64,
    /// Whether every pair of live particles in neighbouring cells is linked and every
    /// live particle is the one its cell names (nothing severed, nothing split): then
    /// the pieces can be counted from the occupancy grid alone.
    pub(super) intact: bool,
    /// The pieces, labelled once after each edit and kept until the next
    /// ([`Lattice::pieces`]): the cut counts them, contacts, the surface and the
    /// checks read the same labels.
    #[serde(skip)]
    pub(super) pieces: std::sync::OnceLock<PieceLabels>,
}

impl Lattice {
    /// Builds a lattice from a list of distinct coordinates; particle `i` gets `coords[i]`.
    pub fn from_coords(spacing: f32, coords: Vec<IVec3>) -> Result<Self> {
        check_positive("spacing", spacing)?;
        let (min, max) = coords.iter().fold((IVec3::MAX, IVec3::MIN), |(lo, hi), c| {
            (lo.min(*c), hi.max(*c))
        });
        let (min, dims) = if coords.is_empty() {
            (IVec3::ZERO, UVec3::ZERO)
        } else {
            // one empty cell of padding on every side: neighbour cells are always in
            // the grid, so `neighbours` needs no bounds checks
            (min - IVec3::ONE, (max - min + IVec3::splat(3)).as_uvec3())
        };
        let cells = dims.x as u64 * dims.y as u64 * dims.z as u64;
        if cells > MAX_LATTICE_CELLS {
            return Err(CleaveError::TooLarge {
                field: "shape".into(),
                cells,
                max: MAX_LATTICE_CELLS,
            });
        }
        let mut lattice = Self {
            spacing,
            min,
            dims,
            grid: vec![NO_PARTICLE; cells as usize],
            live: live_bits(coords.len()),
            live_count: coords.len(),
            links: vec![[NO_PARTICLE; 6]; coords.len()],
            rest_shift: Vec::new(),
            carved: Vec::new(),
            crossings: Default::default(),
            edits: 0,
            intact: true,
            pieces: std::sync::OnceLock::new(),
            coords,
        };
        for i in 0..lattice.coords.len() {
            let cell = lattice
                .cell(lattice.coords[i])
                .expect("coordinate inside its own bounds");
            if lattice.grid[cell] != NO_PARTICLE {
                return Err(CleaveError::InvalidEntity(format!(
                    "duplicate lattice coordinate {}",
                    lattice.coords[i]
                )));
            }
            lattice.grid[cell] = i as u32;
        }
        for i in 0..lattice.coords.len() {
            let c = lattice.coords[i];
            for (d, offset) in NEIGHBOUR_OFFSETS.iter().enumerate() {
                lattice.links[i][d] = lattice.at(c + *offset).unwrap_or(NO_PARTICLE);
            }
        }
        Ok(lattice)
    }

    /// How many edits of its links, particles or crossings the lattice has had (removals,
    /// severs, splits, relinks, crossings recorded or forgotten): what a surface drawn
    /// from it compares to know whether it is still current.
    pub fn edits(&self) -> u64 {
        self.edits
    }

    /// Lattice spacing h.
    pub fn spacing(&self) -> f32 {
        self.spacing
    }

    /// Number of particles ever created (live or removed).
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    /// True when the lattice never had a particle.
    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// Number of live particles.
    pub fn live_count(&self) -> usize {
        self.live_count
    }

    /// Integer coordinate of particle `i`.
    #[inline]
    pub fn coord(&self, i: u32) -> IVec3 {
        self.coords[i as usize]
    }

    /// The aligned cube of 4×4×4 cells that holds particle `i` (its coordinate over 4,
    /// rounded down): the live particles of one such cube are consecutive in
    /// [`Lattice::live_in_morton_order`], whatever the other cubes hold, because the
    /// Morton code's bits above its lowest six are the cube's.
    #[inline]
    pub fn morton_cube(&self, i: u32) -> IVec3 {
        self.coords[i as usize] >> 2
    }

    /// All particle coordinates by index.
    pub fn coords(&self) -> &[IVec3] {
        &self.coords
    }

    /// Rest position of particle `i` in the body frame: `(coord + ½) × h`, shifted for
    /// the halves of a split particle (see [`Lattice::split`]).
    #[inline]
    pub fn rest_position(&self, i: u32) -> Vec3 {
        (self.coords[i as usize].as_vec3() + Vec3::splat(0.5) + self.split_shift(i)) * self.spacing
    }

    /// Whether particle `i` is a half of a split particle (either half: each rests off
    /// its cell's centre, toward the edges it kept; see [`Lattice::split`]).
    #[inline]
    pub fn is_split_half(&self, i: u32) -> bool {
        self.split_shift(i) != Vec3::ZERO
    }

    /// How far particle `i` rests from its cell's centre, in cells (zero unless it is a
    /// half of a split particle: then toward the edges it holds; see [`Lattice::split`]).
    #[inline]
    pub fn split_shift(&self, i: u32) -> Vec3 {
        self.rest_shift
            .get(i as usize)
            .copied()
            .unwrap_or(Vec3::ZERO)
    }

    /// Whether particle `i` exists and has not been removed.
    #[inline]
    pub fn is_live(&self, i: u32) -> bool {
        self.live
            .get(i as usize / 64)
            .is_some_and(|w| w >> (i % 64) & 1 != 0)
    }

    /// Iterator over live particle indices, ascending.
    pub fn live_particles(&self) -> impl Iterator<Item = u32> + '_ {
        set_bits(&self.live).map(|i| i as u32)
    }

    #[inline]
    pub(super) fn cell(&self, c: IVec3) -> Option<usize> {
        // (a coordinate below the grid wraps to one far beyond it)
        let d = (c - self.min).as_uvec3();
        if d.cmpge(self.dims).any() {
            return None;
        }
        Some(((d.z * self.dims.y + d.y) * self.dims.x + d.x) as usize)
    }

    /// The lowest and highest cells of the lattice's grid (inclusive): every particle's
    /// coordinate lies between them.
    pub fn grid_cells(&self) -> (IVec3, IVec3) {
        (self.min, self.min + self.dims.as_ivec3() - IVec3::ONE)
    }

    /// The live particle at coordinate `c`, if any.
    #[inline]
    pub fn at(&self, c: IVec3) -> Option<u32> {
        let i = self.grid[self.cell(c)?];
        (i != NO_PARTICLE).then_some(i)
    }

    /// Live particles in Z order (Morton order) of their coordinates: particles close in
    /// space are close in the list. The solver lays its arrays out in this order, and
    /// bodies spawn their particle entities in it, so both walk memory the same way.
    pub fn live_in_morton_order(&self) -> Vec<u32> {
        let mut keyed: Vec<(u64, u32)> = Vec::with_capacity(self.live_count);
        keyed.extend(
            self.live_particles()
                .map(|i| (morton_code(self.coord(i)), i)),
        );
        // (codes of distinct coordinates are distinct: the order is unique)
        sort_by_key_radix(&mut keyed);
        keyed.into_iter().map(|(_, i)| i).collect()
    }

    /// The particles linked to particle `i` (its live edges), in the order of
    /// [`NEIGHBOUR_OFFSETS`].
    #[inline(always)]
    pub fn neighbours(&self, i: u32) -> Neighbours {
        let [a, b, c, d, e, f] = self.links[i as usize];
        let ids = [a, b, c, d, e, f, NO_PARTICLE, NO_PARTICLE];
        // one 8-wide compare: bit k set for a missing link
        let empty = u32x8::new(ids)
            .simd_eq(u32x8::splat(NO_PARTICLE))
            .to_bitmask();
        Neighbours {
            ids,
            live: !(empty as u8),
        }
    }

    /// Whether live particle `i` lies on its piece's surface: fewer than six links (a
    /// removed neighbour, a severed edge or the body's outside).
    #[inline]
    pub fn is_surface(&self, i: u32) -> bool {
        self.links[i as usize].contains(&NO_PARTICLE)
    }

    /// The particle linked to particle `i` in each direction of [`NEIGHBOUR_OFFSETS`],
    /// [`NO_PARTICLE`] where there is no edge. Loops that test every direction anyway
    /// (marks, labels) run straight through these six. A removed particle has none.
    #[inline(always)]
    pub fn links(&self, i: u32) -> [u32; 6] {
        self.links[i as usize]
    }

    /// The particle linked to particle `i` in direction `d` (an index into
    /// [`NEIGHBOUR_OFFSETS`]), or [`NO_PARTICLE`].
    ///
    /// # Panics
    /// If `d` is not below 6.
    #[inline]
    pub fn link(&self, i: u32, d: usize) -> u32 {
        self.links[i as usize][d]
    }

    /// Whether nothing was ever severed or split: every pair of live particles in
    /// neighbouring cells is linked.
    pub fn is_intact(&self) -> bool {
        self.intact
    }

    /// All edges `(a, b)` with `a < b`, in ascending order.
    pub fn edges(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for a in self.live_particles() {
            // each edge once: from its end on the negative side, along +x, +y, +z
            for d in [1, 3, 5] {
                let b = self.links[a as usize][d];
                if b != NO_PARTICLE {
                    out.push((a.min(b), a.max(b)));
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// A lattice's edges by place, and where cuts crossed them ([`super::crossings`]).
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
    #[inline]
    pub fn crossing_at(&self, cell: IVec3, axis: usize) -> Option<Crossing> {
        let key = self.cell(cell)? as u32 * 3 + axis as u32;
        self.crossings.get(key)
    }

    /// Where a cut crossed the edge between particles `p` and `q` (in neighbouring
    /// cells), measured from `p`.
    pub fn crossing_between(&self, p: u32, q: u32) -> Option<Crossing> {
        let (key, p_lower) = self.edge_key(self.coord(p), self.coord(q))?;
        let c = self.crossings.get(key)?;
        Some(if p_lower { c } else { c.reversed() })
    }

    /// Number of edges with a crossing.
    pub fn crossing_count(&self) -> usize {
        self.crossings.len()
    }

    /// The first crossing that is not valid ([`Crossing::is_valid`]) or names an edge
    /// outside the grid, as `(edge key, crossing)`: what a loaded save is refused for.
    pub fn invalid_crossing(&self) -> Option<(u32, Crossing)> {
        let edges = self.grid.len() as u64 * 3;
        let mut bad: Vec<(u32, Crossing)> = (self.crossings.iter())
            .filter(|(k, c)| *k as u64 >= edges || !c.is_valid())
            .collect();
        bad.sort_unstable_by_key(|(k, _)| *k);
        bad.first().copied()
    }
}

/// Live flags of `n` particles, all set.
fn live_bits(n: usize) -> Vec<u64> {
    let mut bits = vec![u64::MAX; n.div_ceil(64)];
    if !n.is_multiple_of(64)
        && let Some(last) = bits.last_mut()
    {
        *last = (1 << (n % 64)) - 1;
    }
    bits
}

/// The live neighbours of one particle (see [`Lattice::neighbours`]): the six neighbour
/// cells read at once, then walked by a bit mask of the occupied ones, so that loops
/// over neighbours compile to straight-line code instead of a filtered array iterator.
#[derive(Clone, Copy, Debug)]
pub struct Neighbours {
    ids: [u32; 8],
    live: u8,
}

impl Iterator for Neighbours {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        if self.live == 0 {
            return None;
        }
        let k = self.live.trailing_zeros() as usize;
        self.live &= self.live - 1;
        Some(self.ids[k & 7])
    }

    #[inline]
    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.live.count_ones() as usize;
        (n, Some(n))
    }
}

impl ExactSizeIterator for Neighbours {}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block of `n.x × n.y × n.z` particles at spacing `h`.
    fn block(n: UVec3, h: f32) -> Lattice {
        let coords = (0..n.z as i32)
            .flat_map(|z| {
                (0..n.y as i32).flat_map(move |y| (0..n.x as i32).map(move |x| IVec3::new(x, y, z)))
            })
            .collect();
        Lattice::from_coords(h, coords).expect("a block")
    }

    #[test]
    fn neighbours_are_the_live_particles_at_the_six_offsets() {
        use rand::{Rng, SeedableRng};
        let mut l = block(UVec3::new(7, 5, 4), 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for _ in 0..40 {
            let p = rng.random_range(0..l.len() as u32);
            l.remove(p);
        }
        for i in l.live_particles() {
            let expected: Vec<u32> = NEIGHBOUR_OFFSETS
                .iter()
                .filter_map(|d| l.at(l.coord(i) + *d))
                .collect();
            let found: Vec<u32> = l.neighbours(i).collect();
            assert_eq!(found, expected, "particle {i}");
            assert_eq!(l.neighbours(i).len(), expected.len());
            let cells: Vec<u32> = l
                .links(i)
                .into_iter()
                .filter(|n| *n != NO_PARTICLE)
                .collect();
            assert_eq!(cells, expected);
            let one_by_one: Vec<u32> = (0..6).map(|d| l.link(i, d)).collect();
            assert_eq!(one_by_one, l.links(i));
        }
    }

    #[test]
    fn removal_updates_neighbours() {
        let mut l = block(UVec3::new(3, 1, 1), 1.0);
        let mid = l.at(IVec3::new(1, 0, 0)).unwrap();
        assert_eq!(l.neighbours(mid).count(), 2);
        let left = l.at(IVec3::new(0, 0, 0)).unwrap();
        assert!(l.remove(left));
        assert!(!l.remove(left));
        assert_eq!(l.neighbours(mid).count(), 1);
        assert_eq!(l.live_count(), 2);
    }
}
