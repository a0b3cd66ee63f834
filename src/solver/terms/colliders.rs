//! The collider constraint kind: a ground plane and posed convex shapes (boxes, balls,
//! capsules), static or kinematic, with Coulomb friction against the displacement of the
//! current substep relative to the collider.
//!
//! A collider knows its pose at the start and at the end of the substep. A particle is
//! tested in the collider's frame: its substep-start position mapped by the start pose,
//! its current position by the end pose, so that a moving collider and a moving particle
//! are one relative motion. A particle inside is pushed to the nearest surface point, or
//! back to where its relative motion entered the shape when the nearest point would carry
//! it on through; a particle outside whose relative motion crossed the shape since the
//! substep started (a fast body, or a fast collider) is put back at the entry point. So
//! neither side tunnels, whatever the speed.

use crate::config::{GroundPlane, SimConfig, StaticBox};
use crate::cut::tool::Pose;
use crate::solver::particles::PARTICLES_PER_TASK;
use crate::solver::term::{NO_DENSE, ParticleState, Substep, Term, Topology};
use crate::solver::terms::contacts::ball_radius;
use glam::{BVec3A, Vec3A};
pub use posed::PosedCollider;
use posed::{Pushes, with_friction};
use rayon::prelude::*;
pub use rigid::{RigidMotion, solid_inertia};

mod posed;
pub mod rigid;

/// The ground and every posed collider of one substep.
#[derive(Clone, Debug)]
pub struct Colliders {
    /// Ground plane.
    pub ground: Option<GroundPlane>,
    /// Boxes, balls and capsules, static or moving.
    pub shapes: Vec<PosedCollider>,
    /// The longest push out of a collider, per substep, of the depth a particle already
    /// had when the substep began (spawned there, or pressed in by something else): it
    /// comes out over several substeps, at most this far in each, so that a deep overlap
    /// is resolved at a walk instead of in one jump that the clusters would turn into
    /// velocity for the whole body. What the substep's own motion carried in is pushed
    /// out at once. Infinite by default.
    pub depenetration_step: f32,
    /// Bounds of each block's substep-start positions (see `begin_substep`).
    previous_bounds: Vec<(Vec3A, Vec3A)>,
    /// Each particle's contact radius, by dense index (its material's
    /// `contact_radius`): particles rest on the ground and on colliders with their
    /// balls, not their centres, as they do on each other.
    margins: Vec<f32>,
    /// The largest of `margins`.
    largest_margin: f32,
    /// Each particle's body (its index in the last topology change), by dense index.
    body_of: Vec<u32>,
    /// Which particles had part of a push held back in this substep (see
    /// [`Colliders::depenetration_step`]), by dense index.
    held: Vec<bool>,
    /// Per tagged collider, the impulse the particles put on it since the frame began.
    impulses: Vec<ColliderImpulse>,
}

/// The impulse particles put on a tagged collider over a frame (see
/// [`Colliders::frame_impulses`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ColliderImpulse {
    /// The collider's tag ([`PosedCollider::tagged`]).
    pub tag: u64,
    /// Linear impulse (N·s): minus the momentum its pushes gave the particles.
    pub linear: Vec3A,
    /// Angular impulse about its centre at the end of each substep (N·m·s).
    pub angular: Vec3A,
}

impl Default for Colliders {
    fn default() -> Self {
        Self::new(None, Vec::new())
    }
}

impl Colliders {
    /// Colliders made of a ground plane and posed shapes.
    pub fn new(ground: Option<GroundPlane>, shapes: Vec<PosedCollider>) -> Self {
        Self {
            ground,
            shapes,
            depenetration_step: f32::INFINITY,
            previous_bounds: Vec::new(),
            margins: Vec::new(),
            largest_margin: 0.0,
            body_of: Vec::new(),
            held: Vec::new(),
            impulses: Vec::new(),
        }
    }

    /// Takes the ground, shapes and depenetration step of `placed` (this substep's
    /// placement), keeping the particles' contact radii; at the first substep of a
    /// frame (`frame_start`) the tagged colliders' impulses start again from zero.
    /// A dynamic collider goes on from where the last substep left it, except at a
    /// frame's start, when it takes the pose and motion `placed` gives (the game's).
    pub fn place(&mut self, placed: Colliders, frame_start: bool) {
        self.ground = placed.ground;
        let mut shapes = placed.shapes;
        if !frame_start {
            for shape in shapes.iter_mut().filter(|s| s.rigid.is_some()) {
                let last = (self.shapes.iter()).find(|o| o.tag == shape.tag && o.rigid.is_some());
                if let Some(rigid) = last.and_then(|o| o.rigid.as_ref()) {
                    let tag = shape.tag;
                    *shape =
                        PosedCollider::stepping(shape.shape.clone(), shape.friction, rigid.next());
                    shape.tag = tag;
                }
            }
        }
        self.shapes = shapes;
        self.depenetration_step = placed.depenetration_step;
        if frame_start {
            self.impulses.clear();
        }
        for tag in self.shapes.iter().filter_map(|s| s.tag) {
            if !self.impulses.iter().any(|i| i.tag == tag) {
                self.impulses.push(ColliderImpulse {
                    tag,
                    ..ColliderImpulse::default()
                });
            }
        }
    }

    /// Per tagged collider, the impulse the particles put on it since the frame began
    /// (the colliders' pushes are the only external impulses the particles receive
    /// besides gravity and the ground, and the clusters' pass none between bodies, so
    /// these are what a rigid body standing for the collider must take).
    pub fn frame_impulses(&self) -> &[ColliderImpulse] {
        &self.impulses
    }

    /// Each tagged dynamic collider's pose and motion at the end of the last substep.
    pub fn rigid_bodies(&self) -> impl Iterator<Item = (u64, Pose, RigidMotion)> + '_ {
        self.shapes.iter().filter_map(|s| {
            let rigid = s.rigid.as_ref()?;
            Some((s.tag?, rigid.now, rigid.finished()))
        })
    }

    /// The config's ground and static boxes, and the `moving` colliders.
    pub fn from_config(config: &SimConfig, moving: impl Iterator<Item = PosedCollider>) -> Self {
        let boxes = config.boxes.iter().map(StaticBox::posed);
        Self::new(config.ground, boxes.chain(moving).collect())
    }

    /// Whether a collider may move a ball of radius `margin` at `p` that started the
    /// substep at `previous` ([`Colliders::resolve`] leaves every other ball where it is).
    #[inline]
    fn touches(&self, p: Vec3A, previous: Vec3A, margin: f32) -> bool {
        self.ground.is_some_and(|g| p.y < g.height + margin)
            || self
                .shapes
                .iter()
                .any(|s| s.reaches(p.min(previous), p.max(previous), margin))
    }

    /// Whether a collider may move a ball of radius `margin` whose centre's substep ran
    /// inside `[lo, hi]`.
    fn reaches(&self, lo: Vec3A, hi: Vec3A, margin: f32) -> bool {
        self.ground.is_some_and(|g| lo.y < g.height + margin)
            || self.shapes.iter().any(|s| s.reaches(lo, hi, margin))
    }

    /// Pushes a ball of radius `margin` centred at `p` out of the ground and every
    /// collider, with friction against its displacement since `previous`, the depth it
    /// already had at `previous` by at most [`Colliders::depenetration_step`]; pure, so
    /// the kernel's blocks run it in parallel. Returns the new centre.
    pub fn resolve(&self, p: Vec3A, previous: Vec3A, margin: f32) -> Vec3A {
        self.resolve_holding_back(p, previous, margin).0
    }

    /// [`Colliders::resolve`], and whether part of a push was held back.
    fn resolve_holding_back(&self, p: Vec3A, previous: Vec3A, margin: f32) -> (Vec3A, bool) {
        self.resolve_reporting(p, previous, margin, |_, _| None)
    }

    /// [`Colliders::resolve_holding_back`], giving `pushed` each shape's push (its
    /// index, the displacement the ball needs), which returns the part the ball takes
    /// if it takes only part (a dynamic collider takes the rest).
    fn resolve_reporting(
        &self,
        p: Vec3A,
        previous: Vec3A,
        margin: f32,
        mut pushed: impl FnMut(usize, Vec3A) -> Option<Vec3A>,
    ) -> (Vec3A, bool) {
        let (mut p, mut held) = (p, false);
        if let Some(g) = &self.ground
            && p.y < g.height + margin
        {
            (p, held) = self.on_ground(g, p, previous, margin);
        }
        let (lo, hi) = (p.min(previous), p.max(previous));
        for (i, shape) in self.shapes.iter().enumerate() {
            if shape.reaches(lo, hi, margin)
                && let Some((q, depth_before)) = shape.resolve(p, previous, margin)
            {
                let push = q - p;
                let length = push.length();
                if length > 0.0 {
                    let held_back = self.held_back(length, depth_before);
                    held |= held_back > 0.0;
                    let moved = q - push * (held_back / length);
                    p = match pushed(i, moved - p) {
                        Some(part) => p + part,
                        None => moved,
                    };
                }
            }
        }
        (p, held)
    }

    /// A ball of radius `margin` centred at `p`, below the ground's height by more than
    /// `margin`, pushed out with friction ([`Colliders::resolve_reporting`]'s ground);
    /// whether part of the push was held back.
    fn on_ground(&self, g: &GroundPlane, p: Vec3A, previous: Vec3A, margin: f32) -> (Vec3A, bool) {
        let depth = g.height + margin - p.y;
        let depth_before = g.height + margin - previous.y;
        let held_back = self.held_back(depth, depth_before);
        let out = Vec3A::new(p.x, g.height + margin - held_back, p.z);
        let p = with_friction(out, previous, Vec3A::Y, depth - held_back, g.friction);
        (p, held_back > 0.0)
    }

    /// [`Term::project`] with the ground alone (no posed collider, so nothing to sum): a
    /// particle costs one plane test, and a block's bounds, which spare a posed
    /// collider's dearer tests, are not taken; a body within one block runs on the
    /// calling thread.
    fn project_on_ground(&mut self, state: &mut ParticleState) {
        let Some(ground) = self.ground else {
            return;
        };
        let mut held = std::mem::take(&mut self.held);
        let this = &*self;
        // (above this no ball reaches the ground: one load and one compare per particle)
        let clear = ground.height + self.largest_margin;
        let block =
            |positions: &mut [Vec3A],
             held: &mut [bool],
             corrections: &mut [Vec3A],
             (previous, inv_mass, margins): (&[Vec3A], &[f32], &[f32])| {
                let runs = positions.chunks_mut(CLEAR_RUN).enumerate();
                for (run, points) in runs {
                    // (a run wholly above `clear` is passed over at one test of its
                    // heights together: most of a body resting on the ground)
                    if !any_below(points, clear) {
                        continue;
                    }
                    for (k, p) in points.iter_mut().enumerate() {
                        let i = run * CLEAR_RUN + k;
                        let below = p.y < clear && p.y < ground.height + margins[i];
                        if !below || inv_mass[i] == 0.0 {
                            continue;
                        }
                        let (resolved, held_back) =
                            this.on_ground(&ground, *p, previous[i], margins[i]);
                        held[i] |= held_back;
                        corrections[i] += resolved - *p;
                        *p = resolved;
                    }
                }
            };
        let read = (state.previous, state.inv_mass, this.margins.as_slice());
        if state.positions.len() <= PARTICLES_PER_TASK {
            block(state.positions, &mut held, state.corrections, read);
        } else {
            (state.positions.par_chunks_mut(PARTICLES_PER_TASK))
                .zip(held.par_chunks_mut(PARTICLES_PER_TASK))
                .zip(state.corrections.par_chunks_mut(PARTICLES_PER_TASK))
                .zip(read.0.par_chunks(PARTICLES_PER_TASK))
                .zip(read.1.par_chunks(PARTICLES_PER_TASK))
                .zip(read.2.par_chunks(PARTICLES_PER_TASK))
                .for_each(|(((((p, h), c), previous), w), m)| block(p, h, c, (previous, w, m)));
        }
        self.held = held;
    }

    /// How much of a push of `depth` out of a collider waits for later substeps: of the
    /// depth the particle already had (`depth_before`), what lies beyond one
    /// [`Colliders::depenetration_step`]. What the substep's motion carried in (a
    /// particle resting on the surface, rounding a hair inside, or one that fell in) is
    /// never held back.
    fn held_back(&self, depth: f32, depth_before: f32) -> f32 {
        (depth.min(depth_before) - self.depenetration_step).max(0.0)
    }
}

/// Particles whose heights the ground's pass tests together before it tests any alone.
const CLEAR_RUN: usize = 8;

/// Whether any of `points` lies below `height` (a NaN height is not below, as a
/// particle's own test has it).
#[inline]
fn any_below(points: &[Vec3A], height: f32) -> bool {
    let level = Vec3A::splat(height);
    let below = points
        .iter()
        .fold(BVec3A::FALSE, |any, p| any | p.cmplt(level));
    below.test(1)
}

/// Two blocks' per-shape pushes, added (an empty list adds nothing).
fn add_pushes(mut a: Vec<Pushes>, b: Vec<Pushes>) -> Vec<Pushes> {
    if a.len() < b.len() {
        return add_pushes(b, a);
    }
    for (x, y) in a.iter_mut().zip(b) {
        x.momentum += y.momentum;
        x.angular += y.angular;
        x.shift += y.shift;
        x.spin += y.spin;
        x.contacts += y.contacts;
    }
    a
}

/// The bounds of a block of points; a non-finite point makes them unbounded, so a block
/// holding one is never skipped.
fn bounds(points: &[Vec3A]) -> (Vec3A, Vec3A) {
    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    // Σ 0·p stays zero while every point is finite and turns NaN at the first that is
    // not: a multiply and an add per point where a finiteness test costs several (not
    // glam's `mul_add`: without FMA in the build it calls a software fused multiply-add)
    let mut probe = Vec3A::ZERO;
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
        probe += *p * Vec3A::ZERO;
    }
    if probe.is_nan() {
        (Vec3A::NEG_INFINITY, Vec3A::INFINITY)
    } else {
        (lo, hi)
    }
}

impl Term for Colliders {
    fn name(&self) -> &'static str {
        "colliders"
    }

    fn is_empty(&self) -> bool {
        self.ground.is_none() && self.shapes.is_empty()
    }

    fn topology(&mut self, change: &Topology) {
        let count = change
            .bodies
            .iter()
            .flat_map(|b| b.dense.iter().filter(|d| **d != NO_DENSE))
            .map(|d| *d as usize + 1)
            .max()
            .unwrap_or(0);
        self.margins = vec![0.0; count];
        self.body_of = vec![u32::MAX; count];
        for (b, body) in change.bodies.iter().enumerate() {
            for (i, d) in body.dense.iter().enumerate() {
                if *d != NO_DENSE {
                    self.margins[*d as usize] = ball_radius(body.material, body.lattice, i as u32);
                    self.body_of[*d as usize] = b as u32;
                }
            }
        }
        self.largest_margin = self.margins.iter().copied().fold(0.0, f32::max);
    }

    fn begin_substep(&mut self, _step: &Substep, state: &mut ParticleState) {
        // (a particle the layout holds but no body names has no ball)
        self.margins.resize(state.positions.len(), 0.0);
        self.held.clear();
        self.held.resize(state.positions.len(), false);
        // (the ground alone tests every particle: no block is spared by its bounds)
        if !self.shapes.is_empty() {
            self.previous_bounds = state
                .previous
                .par_chunks(PARTICLES_PER_TASK)
                .map(bounds)
                .collect();
        }
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        if self.shapes.is_empty() {
            self.project_on_ground(state);
            return;
        }
        let mut held = std::mem::take(&mut self.held);
        let this = &*self;
        // (only with a tagged collider is each push summed: the rest run as before)
        let tagged = (this.shapes.iter()).any(|s| s.tag.is_some() || s.rigid.is_some());
        let blocks = state
            .positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(held.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(state.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(state.previous.par_chunks(PARTICLES_PER_TASK))
            .zip(state.inv_mass.par_chunks(PARTICLES_PER_TASK))
            .zip(this.margins.par_chunks(PARTICLES_PER_TASK))
            .zip(this.previous_bounds.par_iter())
            .map(
                |((((((positions, held), corrections), previous), inv_mass), margins), before)| {
                    let mut sums = Vec::new();
                    let (lo, hi) = bounds(positions);
                    if !this.reaches(lo.min(before.0), hi.max(before.1), this.largest_margin) {
                        return sums;
                    }
                    for (i, p) in positions.iter_mut().enumerate() {
                        // (most balls of a resting body touch nothing: they are left
                        // as they are, unwritten)
                        if inv_mass[i] == 0.0 || !this.touches(*p, previous[i], margins[i]) {
                            continue;
                        }
                        let (resolved, held_back) = if tagged {
                            let w = inv_mass[i];
                            let at = *p;
                            this.resolve_reporting(at, previous[i], margins[i], |s, push| {
                                // (a block that pushes nothing allocates nothing)
                                if sums.is_empty() {
                                    sums.resize(this.shapes.len(), Pushes::default());
                                }
                                let sum = &mut sums[s];
                                let part = this.shapes[s].rigid.as_ref().map(|rigid| {
                                    sum.contacts += 1;
                                    let mut share = (sum.shift, sum.spin);
                                    let part = rigid.split(push, at, w, &mut share);
                                    (sum.shift, sum.spin) = share;
                                    part
                                });
                                let momentum = part.unwrap_or(push) / w;
                                sum.momentum += momentum;
                                sum.angular += (at - this.shapes[s].centre()).cross(momentum);
                                part
                            })
                        } else {
                            this.resolve_holding_back(*p, previous[i], margins[i])
                        };
                        held[i] |= held_back;
                        corrections[i] += resolved - *p;
                        *p = resolved;
                    }
                    sums
                },
            );
        // (summed in block order, so that the impulses do not depend on the threads)
        let pushes = if tagged {
            let sums: Vec<_> = blocks.collect();
            sums.into_iter().fold(Vec::new(), add_pushes)
        } else {
            blocks.for_each(drop);
            Vec::new()
        };
        self.held = held;
        // what the particles gained, the colliders lost: the impulse is −m·Δx / h
        let ground = self.ground.map(|g| g.height);
        let mut pushes = pushes;
        pushes.resize(self.shapes.len(), Pushes::default());
        for (shape, pushed) in self.shapes.iter_mut().zip(pushes) {
            shape.apply(&pushed, ground);
            if let Some(sum) =
                (shape.tag).and_then(|t| self.impulses.iter_mut().find(|i| i.tag == t))
            {
                sum.linear -= pushed.momentum / step.dt;
                sum.angular -= pushed.angular / step.dt;
            }
        }
    }

    /// While a body comes out of a collider it began the substep deep in, the clusters
    /// drag its outer particles in after its inner ones and the collider pushes them
    /// out again, substep after substep: its particles are not let speed up past the
    /// depenetration speed ([`Colliders::depenetration_step`] per substep), so that it
    /// leaves at a walk however deep it was (unbounded, a body spawned two thirds inside
    /// a box was flung out at 60 m/s).
    fn end_substep(&self, step: &Substep, velocities: &[Vec3A], corrections: &mut [Vec3A]) {
        if !self.held.contains(&true) {
            return;
        }
        let bodies = self.body_of.iter().filter(|b| **b != u32::MAX).max();
        let mut depenetrating = vec![false; bodies.map_or(0, |&b| b as usize + 1)];
        for (held, body) in self.held.iter().zip(&self.body_of) {
            if *held && *body != u32::MAX {
                depenetrating[*body as usize] = true;
            }
        }
        let limit = self.depenetration_step / step.dt;
        for ((c, v), body) in corrections.iter_mut().zip(velocities).zip(&self.body_of) {
            if depenetrating.get(*body as usize) != Some(&true) {
                continue;
            }
            let after = *v + *c / step.dt;
            let allowed = v.length().max(limit);
            if after.length() > allowed {
                *c = (after * (allowed / after.length()) - *v) * step.dt;
            }
        }
    }
}

#[cfg(test)]
mod tests;
