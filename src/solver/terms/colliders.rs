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
use crate::geometry::collider::ColliderShape;
use crate::solver::particles::PARTICLES_PER_TASK;
use crate::solver::term::{NO_DENSE, ParticleState, Substep, Term, Topology};
use crate::solver::terms::contacts::ball_radius;
use glam::{Affine3A, Vec3A};
use rayon::prelude::*;

/// Depth (relative to the coordinates' size) below which the middle of a chord through a
/// collider counts as a graze of its surface, not a pass through it.
const GRAZE: f32 = 1e-5;

/// A collider placed for one substep.
#[derive(Clone, Debug)]
pub struct PosedCollider {
    /// Shape in the local frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient (≥ 0).
    pub friction: f32,
    /// World → local at the start of the substep.
    start_inverse: Affine3A,
    /// Local → world at the end of the substep.
    end: Affine3A,
    /// World → local at the end of the substep.
    end_inverse: Affine3A,
    /// World bounds of the shape over the substep (both poses).
    lo: Vec3A,
    hi: Vec3A,
}

impl PosedCollider {
    /// `shape` moving from pose `start` to pose `end` during the substep.
    pub fn new(shape: ColliderShape, friction: f32, start: Pose, end: Pose) -> Self {
        let affine =
            |p: Pose| Affine3A::from_rotation_translation(p.rotation.normalize(), p.position);
        let (start, end) = (affine(start), affine(end));
        let half = Vec3A::from(shape.local_half_extents());
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for pose in [start, end] {
            // the world box of the rotated local box: |R|·half about the centre
            let m = pose.matrix3;
            let extent =
                m.x_axis.abs() * half.x + m.y_axis.abs() * half.y + m.z_axis.abs() * half.z;
            lo = lo.min(pose.translation - extent);
            hi = hi.max(pose.translation + extent);
        }
        Self {
            shape,
            friction,
            start_inverse: start.inverse(),
            end,
            end_inverse: end.inverse(),
            lo,
            hi,
        }
    }

    /// A static collider at `pose`.
    pub fn fixed(shape: ColliderShape, friction: f32, pose: Pose) -> Self {
        Self::new(shape, friction, pose, pose)
    }

    /// Whether the collider's swept bounds, grown by `margin`, meet the box `[lo, hi]`.
    fn reaches(&self, lo: Vec3A, hi: Vec3A, margin: f32) -> bool {
        hi.cmpge(self.lo - margin).all() && lo.cmple(self.hi + margin).all()
    }

    /// The position `p` of a ball of radius `margin` (which started the substep at
    /// `previous`) resolved against this collider, and how deep inside it the ball
    /// started the substep (0 outside); `None` when the collider does not touch it.
    pub fn resolve(&self, p: Vec3A, previous: Vec3A, margin: f32) -> Option<(Vec3A, f32)> {
        let (from, to) = (
            self.start_inverse.transform_point3a(previous),
            self.end_inverse.transform_point3a(p),
        );
        let shape = &self.shape;
        let moved = to - from;
        let (distance, normal) = shape.nearest_surface(to);
        let distance = distance - margin;
        let entry = || {
            let t = shape.segment_entry_within(from, to, margin)?;
            let at = from + moved * t;
            Some((at, shape.nearest_surface(at).1))
        };
        let start = shape.signed_distance(from) - margin;
        let (target, normal) = if distance < 0.0 {
            let nearest = to - normal * distance;
            // pushing it out forward would carry it through the shape: it came in behind
            let through = (nearest - to).dot(moved) > 0.0 && start >= 0.0;
            match through.then(entry).flatten() {
                Some(hit) => hit,
                None => (nearest, normal),
            }
        } else {
            // outside now; if it was outside at the start, did its motion pass through
            // the shape (the middle of the chord it cut lies inside; a graze along a
            // face, as a particle resting on it slides, cuts none)?
            let reach = start + distance;
            if start < 0.0 || moved.length_squared() <= reach * reach {
                return None;
            }
            let enter = shape.segment_entry_within(from, to, margin)?;
            let exit = 1.0 - shape.segment_entry_within(to, from, margin)?;
            let middle = from + moved * (0.5 * (enter + exit));
            if shape.signed_distance(middle) - margin >= -GRAZE * (1.0 + middle.abs().max_element())
            {
                return None;
            }
            entry()?
        };
        let depth = (target - to).length();
        let resolved = with_friction(target, from, normal, depth, self.friction);
        Some((self.end.transform_point3a(resolved), (-start).max(0.0)))
    }
}

impl StaticBox {
    /// The box as a collider shape and the pose of its centre.
    pub fn shape_and_pose(&self) -> (ColliderShape, Pose) {
        let shape = ColliderShape::Box {
            half_extents: 0.5 * (self.max - self.min),
        };
        (shape, Pose::at(0.5 * (self.min + self.max)))
    }

    /// The box as a posed collider.
    pub fn posed(&self) -> PosedCollider {
        let (shape, pose) = self.shape_and_pose();
        PosedCollider::fixed(shape, self.friction, pose)
    }
}

/// `target` with its tangential displacement since `from` cancelled inside the friction
/// cone (`|tangential| ≤ friction × depth`) and shortened by `friction × depth` outside it.
#[inline]
fn with_friction(target: Vec3A, from: Vec3A, normal: Vec3A, depth: f32, friction: f32) -> Vec3A {
    let moved = target - from;
    let tangential = moved - normal * moved.dot(normal);
    let length = tangential.length();
    let limit = friction * depth;
    if length <= limit {
        target - tangential
    } else if length > 0.0 {
        target - tangential * (limit / length)
    } else {
        target
    }
}

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
        }
    }

    /// Takes the ground, shapes and depenetration step of `placed` (this substep's
    /// placement), keeping the particles' contact radii.
    pub fn place(&mut self, placed: Colliders) {
        self.ground = placed.ground;
        self.shapes = placed.shapes;
        self.depenetration_step = placed.depenetration_step;
    }

    /// The config's ground and static boxes, and the `moving` colliders.
    pub fn from_config(config: &SimConfig, moving: impl Iterator<Item = PosedCollider>) -> Self {
        let boxes = config.boxes.iter().map(StaticBox::posed);
        Self::new(config.ground, boxes.chain(moving).collect())
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
        let (mut p, mut held) = (p, false);
        if let Some(g) = &self.ground
            && p.y < g.height + margin
        {
            let depth = g.height + margin - p.y;
            let depth_before = g.height + margin - previous.y;
            let held_back = self.held_back(depth, depth_before);
            held |= held_back > 0.0;
            p.y = g.height + margin - held_back;
            p = with_friction(p, previous, Vec3A::Y, depth - held_back, g.friction);
        }
        let (lo, hi) = (p.min(previous), p.max(previous));
        for shape in &self.shapes {
            if shape.reaches(lo, hi, margin)
                && let Some((q, depth_before)) = shape.resolve(p, previous, margin)
            {
                let push = q - p;
                let length = push.length();
                if length > 0.0 {
                    let held_back = self.held_back(length, depth_before);
                    held |= held_back > 0.0;
                    p = q - push * (held_back / length);
                }
            }
        }
        (p, held)
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
        self.previous_bounds = state
            .previous
            .par_chunks(PARTICLES_PER_TASK)
            .map(bounds)
            .collect();
    }

    fn project(&mut self, _step: &Substep, state: &mut ParticleState) {
        let mut held = std::mem::take(&mut self.held);
        let this = &*self;
        state
            .positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(held.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(state.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(state.previous.par_chunks(PARTICLES_PER_TASK))
            .zip(state.inv_mass.par_chunks(PARTICLES_PER_TASK))
            .zip(this.margins.par_chunks(PARTICLES_PER_TASK))
            .zip(this.previous_bounds.par_iter())
            .for_each(
                |((((((positions, held), corrections), previous), inv_mass), margins), before)| {
                    let (lo, hi) = bounds(positions);
                    if !this.reaches(lo.min(before.0), hi.max(before.1), this.largest_margin) {
                        return;
                    }
                    for (i, p) in positions.iter_mut().enumerate() {
                        if inv_mass[i] == 0.0 {
                            continue;
                        }
                        let (resolved, held_back) =
                            this.resolve_holding_back(*p, previous[i], margins[i]);
                        held[i] |= held_back;
                        corrections[i] += resolved - *p;
                        *p = resolved;
                    }
                },
            );
        self.held = held;
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
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    fn ground(friction: f32) -> Colliders {
        Colliders::new(
            Some(GroundPlane {
                height: 0.0,
                friction,
            }),
            vec![],
        )
    }

    #[test]
    fn ground_and_boxes_push_out() {
        let block = PosedCollider::fixed(
            ColliderShape::Box {
                half_extents: Vec3::splat(0.5),
            },
            0.0,
            Pose::at(Vec3::splat(1.5)),
        );
        let colliders = Colliders::new(ground(0.0).ground, vec![block]);
        let p = colliders.resolve(Vec3A::new(0.0, -0.5, 0.0), Vec3A::ZERO, 0.0);
        assert_eq!(p.y, 0.0);
        let p = colliders.resolve(Vec3A::new(1.5, 1.9, 1.5), Vec3A::new(1.5, 2.5, 1.5), 0.0);
        assert!((p - Vec3A::new(1.5, 2.0, 1.5)).length() < 1e-6, "{p}");
    }

    #[test]
    fn friction_stops_small_slides() {
        let colliders = ground(1.0);
        // slid 0.05 sideways while sinking 0.1: the friction cone holds it
        let p = colliders.resolve(Vec3A::new(0.05, -0.1, 0.0), Vec3A::ZERO, 0.0);
        assert_eq!(p, Vec3A::ZERO);
        // slid 0.5 sideways while sinking 0.1: kinetic friction removes 0.1 of it
        let p = colliders.resolve(Vec3A::new(0.5, -0.1, 0.0), Vec3A::ZERO, 0.0);
        assert!((p.x - 0.4).abs() < 1e-6 && p.y == 0.0, "{p}");
    }

    /// A 0.6 m box turned about Y (0.5 rad), without friction.
    fn turned_block() -> PosedCollider {
        PosedCollider::fixed(
            ColliderShape::Box {
                half_extents: Vec3::splat(0.3),
            },
            0.0,
            Pose {
                position: Vec3::ZERO,
                rotation: Quat::from_rotation_y(0.5),
            },
        )
    }

    #[test]
    fn a_fast_particle_stops_at_the_face_it_came_through() {
        // a particle crossing the turned box in one substep, ending beyond it or just
        // inside its far face
        let block = turned_block();
        let colliders = Colliders::new(None, vec![block.clone()]);
        for end_x in [2.0, 0.25] {
            let (from, to) = (Vec3A::new(-2.0, 0.05, 0.0), Vec3A::new(end_x, 0.05, 0.0));
            let p = colliders.resolve(to, from, 0.0);
            assert!(p.x < -0.29, "ended at {p} (end {end_x})");
            assert!(
                block
                    .shape
                    .signed_distance(block.end_inverse.transform_point3a(p))
                    > -1e-5
            );
        }
    }

    #[test]
    fn a_particle_sliding_on_a_face_is_not_taken_for_one_passing_through() {
        // resting on the top face of a box, it slides 0.1 sideways and lifts off
        // slightly: outside at both ends, a graze along the face
        let block = PosedCollider::fixed(
            ColliderShape::Box {
                half_extents: Vec3::splat(0.5),
            },
            0.3,
            Pose::at(Vec3::ZERO),
        );
        let from = Vec3A::new(0.0, 0.5, 0.0);
        for to in [Vec3A::new(0.1, 0.5, 0.0), Vec3A::new(0.1, 0.5001, 0.0)] {
            assert_eq!(block.resolve(to, from, 0.0), None, "{to}");
        }
        // sinking a little while it slides: kinetic friction, not a stop
        let (p, depth_before) = block
            .resolve(Vec3A::new(0.1, 0.49, 0.0), from, 0.0)
            .expect("a contact");
        assert_eq!(depth_before, 0.0);
        assert!((p.y - 0.5).abs() < 1e-6 && p.x > 0.09, "{p}");
    }

    #[test]
    fn a_moving_collider_carries_particles_in_front_of_it() {
        // a plate moving +X by 0.5 in one substep past a particle at rest at x = 0.2
        let plate = ColliderShape::Box {
            half_extents: Vec3::new(0.05, 1.0, 1.0),
        };
        let moving = PosedCollider::new(
            plate,
            0.0,
            Pose::at(Vec3::new(0.0, 0.0, 0.0)),
            Pose::at(Vec3::new(0.5, 0.0, 0.0)),
        );
        let at = Vec3A::new(0.2, 0.3, 0.0);
        let (p, depth_before) = moving
            .resolve(at, at, 0.0)
            .expect("the plate reaches the particle");
        assert_eq!(depth_before, 0.0, "the plate came to it");
        assert!(
            (p.x - 0.55).abs() < 1e-5,
            "pushed to the plate's front face: {p}"
        );
        // a particle behind the plate is left alone
        let behind = Vec3A::new(-0.2, 0.3, 0.0);
        assert_eq!(moving.resolve(behind, behind, 0.0), None);
    }

    #[test]
    fn a_particle_that_began_the_substep_deep_in_a_collider_comes_out_a_step_at_a_time() {
        // a particle that starts and ends 0.3 deep in a box (or below the ground) comes
        // out by `depenetration_step` per substep
        let mut colliders = Colliders::new(
            ground(0.0).ground,
            vec![PosedCollider::fixed(
                ColliderShape::Box {
                    half_extents: Vec3::splat(0.5),
                },
                0.0,
                Pose::at(Vec3::new(0.0, 0.0, 3.0)),
            )],
        );
        colliders.depenetration_step = 0.01;
        for (inside, out) in [
            (Vec3A::new(0.0, 0.2, 3.0), Vec3A::new(0.0, 0.21, 3.0)),
            (Vec3A::new(0.0, -0.3, 0.0), Vec3A::new(0.0, -0.29, 0.0)),
        ] {
            let p = colliders.resolve(inside, inside, 0.0);
            assert!(p.distance(out) < 1e-6, "{p}");
            // one that came in during the substep goes out at once, from either
            let entered = colliders.resolve(inside, inside + Vec3A::new(0.0, 0.8, 0.0), 0.0);
            assert!((entered.y - (out.y + 0.29)).abs() < 1e-6, "{entered}");
        }
    }

    #[test]
    fn blocks_far_from_every_collider_are_skipped_and_near_ones_are_not() {
        let colliders = Colliders::new(
            ground(0.5).ground,
            vec![PosedCollider::fixed(
                ColliderShape::Sphere { radius: 0.5 },
                0.5,
                Pose::at(Vec3::new(2.0, 1.0, 0.0)),
            )],
        );
        assert!(!colliders.reaches(Vec3A::new(-1.0, 0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.0));
        assert!(colliders.reaches(Vec3A::new(-1.0, -0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.0));
        assert!(colliders.reaches(Vec3A::new(1.0, 0.1, -1.0), Vec3A::new(1.6, 2.0, 1.0), 0.0));
        // a ball of radius 0.2 reaches the ground from 0.1 above it
        assert!(colliders.reaches(Vec3A::new(-1.0, 0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.2));
        let (lo, hi) = bounds(&[Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 0.0)]);
        assert!(
            colliders.reaches(lo, hi, 0.0),
            "a NaN point is never skipped over"
        );
    }

    #[test]
    fn balls_rest_with_their_radius_on_the_ground_and_on_colliders() {
        let r = 0.05;
        let p = ground(0.0).resolve(Vec3A::new(0.0, 0.01, 0.0), Vec3A::new(0.0, 0.2, 0.0), r);
        assert_eq!(p.y, r);
        // a fast ball crossing the turned box stops a radius short of the face it came
        // through
        let block = turned_block();
        let colliders = Colliders::new(None, vec![block.clone()]);
        for end_x in [2.0, 0.25, -0.3] {
            let (from, to) = (Vec3A::new(-2.0, 0.05, 0.0), Vec3A::new(end_x, 0.05, 0.0));
            let p = colliders.resolve(to, from, r);
            let local = block.end_inverse.transform_point3a(p);
            let gap = block.shape.signed_distance(local);
            assert!(
                (gap - r).abs() < 1e-4,
                "ended {gap} from the box (end {end_x})"
            );
            assert!(p.x < -0.29, "{p}");
        }
        // resting on the top face a radius above it is a graze, not a contact
        let flat = PosedCollider::fixed(
            ColliderShape::Box {
                half_extents: Vec3::splat(0.5),
            },
            0.3,
            Pose::at(Vec3::ZERO),
        );
        let from = Vec3A::new(0.0, 0.5 + r, 0.0);
        assert_eq!(flat.resolve(Vec3A::new(0.1, 0.5 + r, 0.0), from, r), None);
    }
}
