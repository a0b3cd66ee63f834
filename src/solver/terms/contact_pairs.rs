//! Finding contact pairs: the cell search that builds the candidate list of
//! [`super::contact_list`].
//!
//! **Who takes part.** Only particles on a piece's surface (fewer than six live lattice
//! neighbours): balls of radius h/2 on a lattice of spacing h touch, so a surface is a
//! closed wall of balls and nothing reaches an inner particle without first meeting the
//! surface. This skips most particles of a large body.
//!
//! **Pairs (when the list is built).** Sorted cells: each taking-part particle gets the
//! key of its cell (cells of side `2.5 r_max` plus the list's skin, the key linear in the
//! cell coordinates, x fastest), the particles are sorted by key, and each cell meets the
//! particles of its forward half of neighbour cells (x + 1 in its row, three cells in
//! each of the four rows after it: each pair once) as five runs of consecutive keys.
//! Because the key of each run is the cell's key plus a constant, the cells are visited
//! in key order with one cursor per run that only moves forward: no hashing, no search,
//! cost linear in particles. Each substep's pairs are then listed under both their
//! particles by a counting sort ([`super::contacts`]).
//! A pair is kept when its balls are closer than the sum of their radii plus a margin of
//! `r_max / 2` (the iterations move particles), and when the particles are in different
//! groups (pieces), or in one group with self-contact on and more than two lattice cells
//! apart along some axis (closer ones are the material's own neighbours).

use glam::{IVec3, Vec3A, Vec4};
use rayon::prelude::*;

/// Contact particles per parallel task.
const PER_TASK: usize = 1024;

/// Offset that makes cell coordinates non-negative in a key (21 bits per axis).
const CELL_BIAS: i64 = 1 << 20;

/// Margin, in units of the largest radius, by which a pair may be apart when the pairs
/// are found and still be kept for the substep's iterations (which move particles). A
/// pair that closes faster than this within one substep is found in the next one.
pub(super) const PAIR_MARGIN: f32 = 0.5;

/// Lattice distance (cells, largest axis) up to which two particles of one piece are
/// neighbours in the material and never a contact pair.
pub const SELF_CONTACT_EXCLUSION: i32 = 2;

/// Whether balls at `a` and `b` whose radii and margin add up to `reach` are close
/// enough to pair: the test both the search and the candidate filter of
/// [`super::contact_list`] decide by.
#[inline]
pub(super) fn within(a: Vec3A, b: Vec3A, reach: f32) -> bool {
    (a - b).length_squared() < reach * reach
}

/// Whether two distinct particles tagged `a` and `b` (group, lattice coordinate) may
/// form a pair, ignoring distance: of different groups, or of one group with
/// self-contact and more than [`SELF_CONTACT_EXCLUSION`] cells apart along some axis.
#[inline]
fn pairable(groups: &[ContactGroup], a: (u32, IVec3), b: (u32, IVec3)) -> bool {
    a.0 != b.0
        || groups[a.0 as usize].self_contact
            && (a.1 - b.1).abs().max_element() > SELF_CONTACT_EXCLUSION
}

/// Contact properties of one group (a piece of a body).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactGroup {
    /// Whether particles of this group collide with each other (far apart in the lattice).
    pub self_contact: bool,
    /// Static friction coefficient: a tangential slip below `static × depth` is cancelled.
    pub static_friction: f32,
    /// Dynamic friction coefficient: a larger slip is shortened by `dynamic × depth`.
    pub dynamic_friction: f32,
}

/// One particle taking part in contacts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactBall {
    /// Its dense index.
    pub dense: u32,
    /// Its group (a piece of a body).
    pub group: u32,
    /// Its body (any number the particles of one body share).
    pub body: u32,
    /// Its lattice coordinate.
    pub coord: IVec3,
    /// Where it rests in its body's lattice frame.
    pub rest: Vec3A,
    /// Its ball's radius.
    pub radius: f32,
}

/// The particles that take part in contacts, in the solver's dense order.
#[derive(Clone, Debug, Default)]
pub struct ContactParticles {
    pub(super) dense: Vec<u32>,
    pub(super) group: Vec<u32>,
    pub(super) body: Vec<u32>,
    pub(super) coord: Vec<IVec3>,
    pub(super) rest: Vec<Vec3A>,
    pub(super) radius: Vec<f32>,
}

impl ContactParticles {
    /// Adds a particle.
    pub fn push(&mut self, ball: ContactBall) {
        self.dense.push(ball.dense);
        self.group.push(ball.group);
        self.body.push(ball.body);
        self.coord.push(ball.coord);
        self.rest.push(ball.rest);
        self.radius.push(ball.radius);
    }

    /// How close the balls of contact particles `a` and `b` may come: the sum of their
    /// radii, or, for two particles of one body, their distance at rest when that is
    /// less (by more than its rounding) — so that nothing pushes apart two particles
    /// that rest closer than their balls reach (the halves of a split particle;
    /// neighbours across a cut when the material's contact radius passes half a cell).
    #[inline]
    pub(super) fn reach(&self, a: usize, b: usize) -> f32 {
        let sum = self.radius[a] + self.radius[b];
        if self.body[a] != self.body[b] {
            return sum;
        }
        let rest = self.rest[a].distance(self.rest[b]);
        if rest < sum * (1.0 - 1e-4) { rest } else { sum }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.dense.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.dense.is_empty()
    }

    /// Whether contact particles `a` and `b` may form a pair (ignoring distance).
    #[inline]
    pub(super) fn may_pair(&self, groups: &[ContactGroup], a: usize, b: usize) -> bool {
        a != b && pairable(groups, self.tag(a), self.tag(b))
    }

    /// What decides whether particle `k` may pair with another: its group and lattice
    /// coordinate (see [`pairable`]).
    #[inline]
    fn tag(&self, k: usize) -> (u32, IVec3) {
        (self.group[k], self.coord[k])
    }

    /// Every pair of particles that may touch and whose balls at `points` (one per
    /// particle, by contact index) are closer than their radii plus `margin`, each once,
    /// in an order fixed for any thread count (per task, in the order the task met
    /// them). `grid` sorts the same points into cells no smaller than the largest reach.
    pub(super) fn close_pairs(
        &self,
        groups: &[ContactGroup],
        grid: &CellGrid,
        points: &[Vec3A],
        margin: f32,
    ) -> Vec<Vec<(u32, u32)>> {
        let p = self;
        let sorted = &grid.sorted[..];
        // tasks start on a cell boundary, so each cell is handled by one task
        let mut task_starts = vec![0usize];
        while let Some(&last) = task_starts.last() {
            let mut next = (last + PER_TASK).min(sorted.len());
            while next < sorted.len() && sorted[next].0 == sorted[next - 1].0 {
                next += 1;
            }
            if next >= sorted.len() {
                break;
            }
            task_starts.push(next);
        }
        task_starts.push(sorted.len());
        // each particle's ball and tag in sorted order, read in sequence below
        let ball: Vec<(Vec4, (u32, IVec3))> = sorted
            .par_iter()
            .map(|(_, k)| {
                let k = *k as usize;
                (points[k].extend(p.radius[k]), p.tag(k))
            })
            .collect();
        // the forward half of the 26 neighbour cells, so that each pair is met once:
        // x + 1 in the cell's own row, and x − 1 … x + 1 in the four rows after it
        let forward: [(i64, i64); 5] = [
            (1, 1),
            ((1 << 21) - 1, 3),
            ((1 << 42) - (1 << 21) - 1, 3),
            ((1 << 42) - 1, 3),
            ((1 << 42) + (1 << 21) - 1, 3),
        ];
        task_starts
            .par_windows(2)
            .map(|w| {
                let mut pairs = Vec::new();
                let mut cursors: Vec<usize> = Vec::new();
                let mut i = w[0];
                // sorted entries i and j; the tags first: most neighbours of a surface
                // particle are its own piece's, and most of those too near in the
                // lattice to pair
                let check = |i: usize, j: usize, pairs: &mut Vec<(u32, u32)>| {
                    let ((x, tx), (y, ty)) = (ball[i], ball[j]);
                    if pairable(groups, tx, ty)
                        && within(Vec3A::from_vec4(x), Vec3A::from_vec4(y), x.w + y.w + margin)
                    {
                        pairs.push((sorted[i].1, sorted[j].1));
                    }
                };
                while i < w[1] {
                    let key = sorted[i].0;
                    let mut end = i + 1;
                    while end < w[1] && sorted[end].0 == key {
                        end += 1;
                    }
                    if cursors.is_empty() {
                        cursors = forward
                            .iter()
                            .map(|(o, _)| sorted.partition_point(|e| e.0 < key + *o as u64))
                            .collect();
                    }
                    // pairs inside the cell
                    for a in i..end {
                        for b in a + 1..end {
                            check(a, b, &mut pairs);
                        }
                    }
                    // pairs with the forward cells, as runs of consecutive keys
                    for (cursor, &(offset, span)) in cursors.iter_mut().zip(&forward) {
                        let lo = key + offset as u64;
                        while *cursor < sorted.len() && sorted[*cursor].0 < lo {
                            *cursor += 1;
                        }
                        let mut stop = *cursor;
                        while stop < sorted.len() && sorted[stop].0 < lo + span as u64 {
                            stop += 1;
                        }
                        for a in i..end {
                            for b in *cursor..stop {
                                check(a, b, &mut pairs);
                            }
                        }
                    }
                    i = end;
                }
                pairs
            })
            .collect()
    }
}

/// Particles sorted by the cell their point lies in (cubes of one side, the key linear
/// in the cell coordinates, x fastest), so that a cell's neighbours are found as runs of
/// consecutive keys.
#[derive(Clone, Debug, Default)]
pub(super) struct CellGrid {
    inv_cell: f32,
    /// `(cell key, particle)`, ascending; particles at non-finite points are left out.
    sorted: Vec<(u64, u32)>,
}

impl CellGrid {
    /// The particles at `points` (by index) in cells of side `cell`.
    pub(super) fn new(points: &[Vec3A], cell: f32) -> Self {
        let mut grid = Self {
            inv_cell: 1.0 / cell,
            sorted: Vec::new(),
        };
        grid.sorted = points
            .par_iter()
            .enumerate()
            .map(|(k, x)| (grid.key(*x), k as u32))
            .filter(|(key, _)| *key != u64::MAX)
            .collect();
        grid.sorted.par_sort_unstable();
        grid
    }

    /// The key of the cell `x` lies in (`u64::MAX` for a non-finite `x`).
    fn key(&self, x: Vec3A) -> u64 {
        if !x.is_finite() {
            return u64::MAX;
        }
        let c = (x * self.inv_cell).floor();
        let axis = |v: f32| (v as i64 + CELL_BIAS).clamp(1, 2 * CELL_BIAS - 2) as u64;
        axis(c.x) | axis(c.y) << 21 | axis(c.z) << 42
    }

    /// Moves the particles flagged in `moved` to the cells of their `points` now.
    pub(super) fn update(&mut self, moved: &[u32], flagged: &[bool], points: &[Vec3A]) {
        let mut fresh: Vec<(u64, u32)> = moved
            .iter()
            .map(|&k| (self.key(points[k as usize]), k))
            .filter(|(key, _)| *key != u64::MAX)
            .collect();
        fresh.sort_unstable();
        let kept = self.sorted.iter().filter(|(_, k)| !flagged[*k as usize]);
        let mut merged = Vec::with_capacity(self.sorted.len());
        let mut fresh = fresh.into_iter().peekable();
        for entry in kept {
            while let Some(f) = fresh.next_if(|f| f < entry) {
                merged.push(f);
            }
            merged.push(*entry);
        }
        merged.extend(fresh);
        self.sorted = merged;
    }

    /// The entries of the particles `flagged`, in cell order.
    pub(super) fn flagged(&self, flagged: &[bool]) -> Vec<(u64, u32)> {
        self.sorted
            .iter()
            .filter(|(_, k)| flagged[*k as usize])
            .copied()
            .collect()
    }

    /// Calls `f(k, j)` for each entry `(key, k)` of `entries` (in cell order, as
    /// [`Self::flagged`] gives them) and every particle `j` in the cell `key` and its 26
    /// neighbours. The nine rows of three cells around consecutive entries start at
    /// keys that only grow, so each row is followed by one cursor that only moves
    /// forward: no search per entry.
    pub(super) fn around_each(&self, entries: &[(u64, u32)], mut f: impl FnMut(u32, u32)) {
        let Some(&(first, _)) = entries.first() else {
            return;
        };
        let rows: [i64; 9] = std::array::from_fn(|r| {
            let (dy, dz) = (r as i64 % 3 - 1, r as i64 / 3 - 1);
            (dy << 21) + (dz << 42) - 1
        });
        let sorted = &self.sorted;
        let mut cursors =
            rows.map(|row| sorted.partition_point(|e| e.0 < (first as i64 + row) as u64));
        for &(key, k) in entries {
            for (cursor, row) in cursors.iter_mut().zip(rows) {
                let lo = (key as i64 + row) as u64;
                while *cursor < sorted.len() && sorted[*cursor].0 < lo {
                    *cursor += 1;
                }
                for &(_, j) in sorted[*cursor..].iter().take_while(|e| e.0 <= lo + 2) {
                    f(k, j);
                }
            }
        }
    }
}
