//! The particle lattice of one body: coordinates, the 6-neighbourhood, removal, and
//! voxelisation of shapes into lattice points.

use crate::error::{CleaveError, Result, check_finite_vec, check_positive};
use crate::geometry::mesh::TriangleMesh;
use glam::{IVec3, UVec3, Vec3};
use std::sync::Arc;
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

/// Estimated memory per particle of a running body (entity, components, solver layout,
/// cluster index; measured with `cleave bench` as peak resident memory per particle).
pub const BYTES_PER_PARTICLE: u64 = 600;

/// Memory one body may take by default, in GB ([`crate::config::SimConfig::memory_budget_gb`]);
/// with [`BYTES_PER_PARTICLE`] it bounds the particles of a body before anything is
/// allocated.
pub const DEFAULT_MEMORY_BUDGET_GB: f32 = 2.0;

/// Refuses a shape whose lattice could hold more particles than `budget_gb` allows.
fn check_budget(field: &str, particles: u64, budget_gb: f32) -> Result<()> {
    let max = (budget_gb as f64 * 1e9 / BYTES_PER_PARTICLE as f64) as u64;
    if particles > max {
        return Err(CleaveError::OverBudget {
            field: field.into(),
            particles,
            gigabytes: (particles as f64) * BYTES_PER_PARTICLE as f64 / 1e9,
            bytes_per_particle: BYTES_PER_PARTICLE,
            budget_gigabytes: budget_gb,
            max,
        });
    }
    Ok(())
}

/// Dense lattice of one body: maps integer coordinates to particle indices and back.
///
/// Particle indices are stable for the life of the body (never reused); a removed
/// particle keeps its coordinate but is no longer *live*.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Lattice {
    spacing: f32,
    min: IVec3,
    dims: UVec3,
    grid: Vec<u32>,
    coords: Vec<IVec3>,
    /// Bit `i` set while particle `i` is live (a bit per particle keeps the flags of a
    /// whole body in cache; a byte each would spread them over many lines).
    live: Vec<u64>,
    live_count: usize,
    /// The particle each particle is linked to in each of the six directions of
    /// [`NEIGHBOUR_OFFSETS`], or [`NO_PARTICLE`]: the body's edges, as data. A new
    /// lattice links every pair of live particles in neighbouring cells; removing a
    /// particle unlinks it, and a cut may sever a link between two live particles
    /// ([`Lattice::sever`]) or split a particle in two ([`Lattice::split`]).
    links: Vec<[u32; 6]>,
    /// Per particle, how far its rest position lies from its cell's centre, in cells:
    /// zero except for the new halves of split particles (empty until the first split).
    rest_shift: Vec<Vec3>,
    /// Bit `i` set once particle `i` has been inside a cutting sphere or capsule in
    /// `sever` mode (empty until the first carve; see [`crate::cut::carve`]).
    carved: Vec<u64>,
    /// Whether every pair of live particles in neighbouring cells is linked and every
    /// live particle is the one its cell names (nothing severed, nothing split): then
    /// the pieces can be counted from the occupancy grid alone.
    intact: bool,
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
            intact: true,
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
    pub fn coord(&self, i: u32) -> IVec3 {
        self.coords[i as usize]
    }

    /// All particle coordinates by index.
    pub fn coords(&self) -> &[IVec3] {
        &self.coords
    }

    /// Rest position of particle `i` in the body frame: `(coord + ½) × h`, shifted for
    /// the new half of a split particle (see [`Lattice::split`]).
    pub fn rest_position(&self, i: u32) -> Vec3 {
        let shift = self
            .rest_shift
            .get(i as usize)
            .copied()
            .unwrap_or(Vec3::ZERO);
        (self.coords[i as usize].as_vec3() + Vec3::splat(0.5) + shift) * self.spacing
    }

    /// Whether particle `i` exists and has not been removed.
    pub fn is_live(&self, i: u32) -> bool {
        self.live
            .get(i as usize / 64)
            .is_some_and(|w| w >> (i % 64) & 1 != 0)
    }

    /// Iterator over live particle indices, ascending.
    pub fn live_particles(&self) -> impl Iterator<Item = u32> + '_ {
        self.live.iter().enumerate().flat_map(|(k, &word)| {
            let mut w = word;
            std::iter::from_fn(move || {
                (w != 0).then(|| {
                    let i = k as u32 * 64 + w.trailing_zeros();
                    w &= w - 1;
                    i
                })
            })
        })
    }

    fn cell(&self, c: IVec3) -> Option<usize> {
        let d = c - self.min;
        if d.cmplt(IVec3::ZERO).any() || d.as_uvec3().cmpge(self.dims).any() {
            return None;
        }
        let d = d.as_uvec3();
        Some(((d.z * self.dims.y + d.y) * self.dims.x + d.x) as usize)
    }

    /// The live particle at coordinate `c`, if any.
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
        true
    }

    /// Number of pieces: connected components of the live particles under the
    /// 6-neighbourhood (the count of [`crate::body::graph::body_pieces`], without labelling
    /// every particle). Works on runs of occupied cells along x: one pass over the grid,
    /// then a union–find over the runs, joining each run to the overlapping runs of the
    /// row below and of the slice below — a few operations per run instead of a search
    /// step per particle.
    ///
    /// Once edges were severed or particles split ([`Lattice::is_intact`] false), the
    /// grid no longer tells the edges, and the pieces are labelled over the links.
    pub fn piece_count(&self) -> usize {
        if !self.intact {
            return crate::body::graph::body_pieces(self).1;
        }
        let (nx, ny) = (self.dims.x as usize, self.dims.y as usize);
        if self.live_count == 0 || nx == 0 {
            return 0;
        }
        // runs of occupied cells per row (`first`, `last` x, inclusive); the grid's
        // padding keeps every run inside its row
        let mut runs: Vec<(u32, u32)> = Vec::new();
        let mut row_start: Vec<u32> = Vec::with_capacity(self.grid.len() / nx + 1);
        for row in self.grid.chunks_exact(nx) {
            row_start.push(runs.len() as u32);
            let mut x = 0;
            while x < nx {
                if row[x] == NO_PARTICLE {
                    x += 1;
                    continue;
                }
                let first = x;
                while x < nx && row[x] != NO_PARTICLE {
                    x += 1;
                }
                runs.push((first as u32, (x - 1) as u32));
            }
        }
        row_start.push(runs.len() as u32);
        let mut parent: Vec<u32> = (0..runs.len() as u32).collect();
        let find = |parent: &mut [u32], mut i: u32| {
            while parent[i as usize] != i {
                let grand = parent[parent[i as usize] as usize];
                parent[i as usize] = grand;
                i = grand;
            }
            i
        };
        let mut pieces = runs.len();
        let range = |r: usize| row_start[r] as usize..row_start[r + 1] as usize;
        for r in 0..row_start.len() - 1 {
            // the row at y − 1 (same slice) and the row at z − 1 (same y)
            let below = [(r % ny != 0).then(|| r - 1), r.checked_sub(ny)];
            for other in below.into_iter().flatten() {
                let (mut i, mut j) = (range(r).start, range(other).start);
                let (end_i, end_j) = (range(r).end, range(other).end);
                while i < end_i && j < end_j {
                    let (a, b) = (runs[i], runs[j]);
                    if a.1 < b.0 {
                        i += 1;
                    } else if b.1 < a.0 {
                        j += 1;
                    } else {
                        let (ra, rb) = (find(&mut parent, i as u32), find(&mut parent, j as u32));
                        if ra != rb {
                            parent[ra.max(rb) as usize] = ra.min(rb);
                            pieces -= 1;
                        }
                        if a.1 < b.1 {
                            i += 1;
                        } else {
                            j += 1;
                        }
                    }
                }
            }
        }
        pieces
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

/// A signed-distance function (negative inside) with the box that bounds its inside.
#[derive(Clone)]
pub struct SdfShape {
    /// The function; non-finite values count as outside.
    pub sdf: Arc<dyn Fn(Vec3) -> f32 + Send + Sync>,
    /// Lower corner of a box containing the inside.
    pub min: Vec3,
    /// Upper corner of a box containing the inside.
    pub max: Vec3,
}

impl std::fmt::Debug for SdfShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SdfShape")
            .field("min", &self.min)
            .field("max", &self.max)
            .finish()
    }
}

/// A shape to voxelise, in its local frame (centred on the origin for primitives).
#[derive(Clone, Debug)]
pub enum Shape {
    /// Axis-aligned box with the given half extents.
    Box {
        /// Half size along each axis.
        half_extents: Vec3,
    },
    /// Exactly `cells.x × cells.y × cells.z` lattice points, centred on the origin for
    /// even counts and offset by h/2 along axes with an odd count.
    Cells {
        /// Particles along each axis.
        cells: UVec3,
    },
    /// Sphere of the given radius.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// Capsule along the local X axis.
    Capsule {
        /// Radius of the round ends and the shaft.
        radius: f32,
        /// Half length of the shaft (without the caps).
        half_length: f32,
    },
    /// Any signed-distance function.
    Sdf(SdfShape),
    /// A closed triangle mesh (inside by winding number).
    Mesh(Arc<TriangleMesh>),
}

impl Shape {
    /// A box holding exactly `cells.x × cells.y × cells.z` particles at spacing `h`.
    pub fn cuboid(cells: UVec3, _h: f32) -> Self {
        Shape::Cells { cells }
    }

    /// Lattice coordinate range `[lo, hi)` of a [`Shape::Cells`] block.
    fn cells_range(cells: UVec3) -> (IVec3, IVec3) {
        let lo = -(cells / 2).as_ivec3();
        (lo, lo + cells.as_ivec3())
    }

    fn bounds(&self) -> Result<(Vec3, Vec3)> {
        Ok(match self {
            Shape::Box { half_extents } => {
                check_finite_vec("shape.half_extents", *half_extents)?;
                (-*half_extents, *half_extents)
            }
            Shape::Cells { .. } => (Vec3::ZERO, Vec3::ZERO),
            Shape::Sphere { radius } => {
                check_positive("shape.radius", *radius)?;
                (Vec3::splat(-radius), Vec3::splat(*radius))
            }
            Shape::Capsule {
                radius,
                half_length,
            } => {
                check_positive("shape.radius", *radius)?;
                crate::error::check_range(
                    "shape.half_length",
                    *half_length,
                    0.0,
                    f32::MAX,
                    "finite and ≥ 0",
                )?;
                let e = Vec3::new(radius + half_length, *radius, *radius);
                (-e, e)
            }
            Shape::Sdf(s) => {
                check_finite_vec("shape.min", s.min)?;
                check_finite_vec("shape.max", s.max)?;
                (s.min, s.max)
            }
            Shape::Mesh(m) => m.bounds(),
        })
    }

    /// Signed distance (negative inside); non-finite values mean outside.
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        match self {
            Shape::Box { half_extents } => {
                let q = p.abs() - *half_extents;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            // In lattice units (h = 1): cells are placed on the lattice directly.
            Shape::Cells { cells } => {
                let (lo, hi) = Self::cells_range(*cells);
                let centre = (lo + hi).as_vec3() * 0.5;
                let q = (p - centre).abs() - cells.as_vec3() * 0.5;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            Shape::Sphere { radius } => p.length() - radius,
            Shape::Capsule {
                radius,
                half_length,
            } => {
                let x = p.x.clamp(-half_length, *half_length);
                (p - Vec3::new(x, 0.0, 0.0)).length() - radius
            }
            Shape::Sdf(s) => (s.sdf)(p),
            // (voxelising a mesh tests whole rows instead, see `voxelise`)
            Shape::Mesh(m) => {
                if m.contains(p) {
                    -1.0
                } else {
                    1.0
                }
            }
        }
    }

    /// Voxelises the shape at spacing `h`: lattice point `k` sits at `(k + ½)·h` in the
    /// shape's frame and is kept when it lies inside (signed distance ≤ 10⁻⁴·h). A shape
    /// whose bounding box holds more cells than [`DEFAULT_MEMORY_BUDGET_GB`] allows is
    /// refused before anything is allocated.
    pub fn voxelise(&self, h: f32) -> Result<Lattice> {
        self.voxelise_within(h, DEFAULT_MEMORY_BUDGET_GB)
    }

    /// [`Shape::voxelise`] within a memory budget of `budget_gb` gigabytes.
    pub fn voxelise_within(&self, h: f32, budget_gb: f32) -> Result<Lattice> {
        check_positive("spacing", h)?;
        if let Shape::Cells { cells } = self {
            let total = cells.x as u64 * cells.y as u64 * cells.z as u64;
            if total == 0 {
                return Err(CleaveError::EmptyShape {
                    field: "shape.cells".into(),
                    spacing: h,
                });
            }
            check_budget("shape.cells", total, budget_gb)?;
            if total > MAX_LATTICE_CELLS {
                return Err(CleaveError::TooLarge {
                    field: "shape.cells".into(),
                    cells: total,
                    max: MAX_LATTICE_CELLS,
                });
            }
            let (lo, hi) = Self::cells_range(*cells);
            let mut coords = Vec::with_capacity(total as usize);
            for z in lo.z..hi.z {
                for y in lo.y..hi.y {
                    for x in lo.x..hi.x {
                        coords.push(IVec3::new(x, y, z));
                    }
                }
            }
            return Lattice::from_coords(h, coords);
        }
        let (lo, hi) = self.bounds()?;
        let kmin = (lo / h - Vec3::splat(0.5)).floor();
        let kmax = (hi / h - Vec3::splat(0.5)).ceil();
        let extent = (kmax - kmin + Vec3::ONE).max(Vec3::ZERO);
        let cells = extent.x as f64 * extent.y as f64 * extent.z as f64;
        if cells.is_finite() {
            check_budget("shape", cells as u64, budget_gb)?;
        }
        if !cells.is_finite() || cells > MAX_LATTICE_CELLS as f64 {
            return Err(CleaveError::TooLarge {
                field: "shape".into(),
                cells: if cells.is_finite() {
                    cells as u64
                } else {
                    u64::MAX
                },
                max: MAX_LATTICE_CELLS,
            });
        }
        let (kmin, kmax) = (kmin.as_ivec3(), kmax.as_ivec3());
        let tolerance = 1e-4 * h;
        let coords = match self {
            // a whole grid at once: a winding number per point costs cells × triangles
            Shape::Mesh(mesh) => {
                let dims = (kmax - kmin + IVec3::ONE).as_uvec3();
                let origin = (kmin.as_vec3() + Vec3::splat(0.5)) * h;
                let (nx, ny) = (dims.x as usize, dims.y as usize);
                let inside = mesh.inside_grid(origin, h, dims);
                let cell = |i: usize| {
                    kmin + IVec3::new((i % nx) as i32, (i / nx % ny) as i32, (i / nx / ny) as i32)
                };
                (0..inside.len()).filter(|&i| inside[i]).map(cell).collect()
            }
            _ => {
                let mut coords = Vec::new();
                for z in kmin.z..=kmax.z {
                    for y in kmin.y..=kmax.y {
                        for x in kmin.x..=kmax.x {
                            let k = IVec3::new(x, y, z);
                            let p = (k.as_vec3() + Vec3::splat(0.5)) * h;
                            let d = self.signed_distance(p);
                            if d.is_finite() && d <= tolerance {
                                coords.push(k);
                            }
                        }
                    }
                }
                coords
            }
        };
        if coords.is_empty() {
            return Err(CleaveError::EmptyShape {
                field: "shape".into(),
                spacing: h,
            });
        }
        Lattice::from_coords(h, coords)
    }
}

/// Sorts `(key, value)` pairs by key; pairs with equal keys keep their order (so a list
/// ordered by value comes out ordered by key, then value, as `sort_unstable` orders it).
/// A least-significant-digit radix sort over 11-bit digits of the key (skipping digits
/// that every key shares) for long lists, a comparison sort for short ones.
fn sort_by_key_radix(items: &mut Vec<(u64, u32)>) {
    const BITS: u32 = 11;
    const DIGITS: usize = 64_u32.div_ceil(BITS) as usize;
    const BUCKETS: usize = 1 << BITS;
    if items.len() < 4 * BUCKETS {
        items.sort_by_key(|(key, _)| *key);
        return;
    }
    let digit = |key: u64, d: usize| ((key >> (d as u32 * BITS)) as usize) & (BUCKETS - 1);
    let mut counts = vec![[0u32; BUCKETS]; DIGITS];
    for (key, _) in items.iter() {
        for (d, count) in counts.iter_mut().enumerate() {
            count[digit(*key, d)] += 1;
        }
    }
    let mut spare = vec![(0, 0); items.len()];
    for (d, count) in counts.iter_mut().enumerate() {
        if count.iter().any(|c| *c as usize == items.len()) {
            continue; // every key has this digit: the pass would change nothing
        }
        let mut start = 0;
        for c in count.iter_mut() {
            (*c, start) = (start, start + *c);
        }
        for &(key, value) in items.iter() {
            let slot = &mut count[digit(key, d)];
            spare[*slot as usize] = (key, value);
            *slot += 1;
        }
        std::mem::swap(items, &mut spare);
    }
}

/// Interleaves the bits of a lattice coordinate (offset to non-negative) into a
/// Z-order key: bit `b` of x, y, z lands at bit `3b`, `3b + 1`, `3b + 2`.
fn morton_code(c: IVec3) -> u64 {
    /// A coordinate offset to non-negative (21 bits), its bits spread three apart.
    fn spread(v: i32) -> u64 {
        let mut x = (v as i64 + (1 << 20)) as u64 & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    }
    spread(c.x) | (spread(c.y) << 1) | (spread(c.z) << 2)
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

    #[test]
    fn morton_codes_interleave_the_coordinate_bits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        // the lowest coordinate offsets to 0; one step in x, y, z sets bit 0, 1, 2
        let origin = IVec3::splat(-(1 << 20));
        assert_eq!(morton_code(origin), 0);
        assert_eq!(morton_code(origin + IVec3::X), 1);
        assert_eq!(morton_code(origin + IVec3::Y), 2);
        assert_eq!(morton_code(origin + IVec3::Z), 4);
        assert_eq!(morton_code(origin + IVec3::new(2, 0, 0)), 8);
        // bit by bit
        let reference = |c: IVec3| {
            let offset = (c + IVec3::splat(1 << 20)).to_array().map(|v| v as u64);
            (0..21).fold(0u64, |code, b| {
                (0..3).fold(code, |code, axis| {
                    code | (offset[axis] >> b & 1) << (3 * b + axis)
                })
            })
        };
        for _ in 0..10_000 {
            let c = IVec3::new(
                rng.random_range(-5000..5000),
                rng.random_range(-5000..5000),
                rng.random_range(-5000..5000),
            );
            assert_eq!(morton_code(c), reference(c), "{c}");
        }
    }

    #[test]
    fn radix_sort_agrees_with_a_comparison_sort() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        for len in [0, 5, 9000, 40_000] {
            // keys in a narrow band (few digits differ) and over all 64 bits
            for spread in [1u64 << 20, u64::MAX] {
                let base: u64 = rng.random();
                let mut items: Vec<(u64, u32)> = (0..len)
                    .map(|i| (base.wrapping_add(rng.random_range(0..=spread / 2)), i))
                    .collect();
                let mut expected = items.clone();
                expected.sort_unstable();
                sort_by_key_radix(&mut items);
                assert_eq!(items, expected, "{len} keys, spread {spread}");
            }
        }
    }

    #[test]
    fn neighbours_are_the_live_particles_at_the_six_offsets() {
        use rand::{Rng, SeedableRng};
        let mut l = Shape::cuboid(UVec3::new(7, 5, 4), 1.0)
            .voxelise(1.0)
            .unwrap();
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
    fn cuboid_has_exact_counts_and_edges() {
        let l = Shape::cuboid(UVec3::new(4, 3, 2), 0.1)
            .voxelise(0.1)
            .unwrap();
        assert_eq!(l.live_count(), 24);
        // edges of a 4×3×2 grid: 3·3·2 + 4·2·2 + 4·3·1
        assert_eq!(l.edges().len(), 18 + 16 + 12);
        let centre: Vec3 = l.live_particles().map(|i| l.rest_position(i)).sum::<Vec3>() / 24.0;
        // even axes (x, z) are centred; the odd axis (y) is offset by h/2
        assert!(
            (centre - Vec3::new(0.0, 0.05, 0.0)).length() < 1e-5,
            "centre {centre}"
        );
    }

    #[test]
    fn removal_updates_neighbours() {
        let mut l = Shape::cuboid(UVec3::new(3, 1, 1), 1.0)
            .voxelise(1.0)
            .unwrap();
        let mid = l.at(IVec3::new(0, 0, 0)).unwrap();
        assert_eq!(l.neighbours(mid).count(), 2);
        let left = l.at(IVec3::new(-1, 0, 0)).unwrap();
        assert!(l.remove(left));
        assert!(!l.remove(left));
        assert_eq!(l.neighbours(mid).count(), 1);
        assert_eq!(l.live_count(), 2);
    }

    #[test]
    fn severing_and_splitting_keep_the_links_symmetric_and_the_pieces_counted() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let mut counts = std::collections::BTreeSet::new();
        for case in 0..200 {
            let mut l = Shape::cuboid(UVec3::new(5, 4, 3), 1.0)
                .voxelise(1.0)
                .unwrap();
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

    #[test]
    fn sphere_and_capsule_are_symmetric() {
        let s = Shape::Sphere { radius: 3.0 }.voxelise(1.0).unwrap();
        let c: Vec3 = s.live_particles().map(|i| s.rest_position(i)).sum();
        assert!(c.length() < 1e-3);
        let cap = Shape::Capsule {
            radius: 1.0,
            half_length: 2.0,
        }
        .voxelise(0.5)
        .unwrap();
        assert!(cap.live_count() > 0);
    }

    #[test]
    fn bad_shapes_are_errors() {
        assert!(Shape::Sphere { radius: -1.0 }.voxelise(1.0).is_err());
        assert!(Shape::Sphere { radius: 1.0 }.voxelise(0.0).is_err());
        assert!(Shape::Sphere { radius: 1.0 }.voxelise(f32::NAN).is_err());
        let e = Shape::Box {
            half_extents: Vec3::ZERO,
        }
        .voxelise(1.0);
        assert!(matches!(e, Err(CleaveError::EmptyShape { .. })), "{e:?}");
        assert!(Shape::Sphere { radius: 1e9 }.voxelise(1e-3).is_err());
    }
}
