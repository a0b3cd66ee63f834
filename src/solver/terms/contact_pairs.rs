//! Finding contact pairs: the cell search that builds the candidate list of
//! [`super::contact_list`].
//!
//! **Who takes part.** Only particles on a piece's surface (fewer than six live lattice
//! neighbours): balls of radius h/2 on a lattice of spacing h touch, so a surface is a
//! closed wall of balls and nothing reaches an inner particle without first meeting the
//! surface. This skips most particles of a large body.
//!
//! **Pairs (when the list is built).** The particles are sorted into cells of side
//! `2.5 r_max` plus the list's skin (in the grid of `contact_grid.rs`), and each cell meets
//! itself and its forward half of neighbour cells, each pair of cells once, passing
//! over cells whose particles cannot pair with its own. Each substep's pairs are then
//! listed under both their particles by a counting sort ([`super::contacts`]).
//! A pair is kept when its balls are closer than the sum of their radii plus a margin of
//! `r_max / 2` (the iterations move particles), and when the particles are in different
//! groups (pieces), or in one group with self-contact on and more than two lattice cells
//! apart along some axis (closer ones are the material's own neighbours).

use super::contact_grid::{CellGrid, NO_KIN};
use glam::{IVec3, Vec3A, Vec4};
use rayon::prelude::*;

/// Contact particles per parallel task.
const PER_TASK: usize = 1024;

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

    /// Each particle's kin (see [`super::contact_grid`]): its group, when the group
    /// has no self-contact, else [`NO_KIN`].
    pub(super) fn kin(&self, groups: &[ContactGroup]) -> Vec<u32> {
        self.group
            .iter()
            .map(|&g| {
                if groups[g as usize].self_contact {
                    NO_KIN
                } else {
                    g
                }
            })
            .collect()
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
        let sorted = grid.sorted();
        // each particle's ball and tag in sorted order, read in sequence below
        let ball: Vec<(Vec4, (u32, IVec3))> = sorted
            .par_iter()
            .map(|(_, k)| {
                let k = *k as usize;
                (points[k].extend(p.radius[k]), p.tag(k))
            })
            .collect();
        grid.tasks(PER_TASK)
            .par_windows(2)
            .map(|w| {
                let mut pairs = Vec::new();
                // the tags first: most neighbours of a surface particle in a cell that
                // may pair are still its own piece's, and most of those too near in the
                // lattice to pair
                grid.forward_blocks(w[0]..w[1], |mine, theirs| {
                    let same = mine == theirs;
                    for a in mine {
                        let (x, tx) = ball[a];
                        let from = if same { a + 1 } else { theirs.start };
                        for b in from..theirs.end {
                            let (y, ty) = ball[b];
                            if pairable(groups, tx, ty)
                                && within(
                                    Vec3A::from_vec4(x),
                                    Vec3A::from_vec4(y),
                                    x.w + y.w + margin,
                                )
                            {
                                pairs.push((sorted[a].1, sorted[b].1));
                            }
                        }
                    }
                });
                pairs
            })
            .collect()
    }
}
