//! One collider placed for a substep: its shape between its start and end poses, the
//! resolution of a ball against it (pushed out to the nearest surface point, or back to
//! where its relative motion entered), and Coulomb friction against the displacement.

use super::rigid::{RigidMotion, RigidStep};
use crate::config::StaticBox;
use crate::cut::tool::Pose;
use crate::geometry::collider::ColliderShape;
use crate::math::cone::surely_within;
use glam::{Affine3A, Vec3, Vec3A};

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
    pub(super) end_inverse: Affine3A,
    /// World bounds of the shape over the substep (both poses).
    lo: Vec3A,
    hi: Vec3A,
    /// The caller's name for the collider, if it wants the impulses the particles put
    /// on it summed ([`super::Colliders::frame_impulses`]).
    pub tag: Option<u64>,
    /// A dynamic collider's body, moved by the solve ([`PosedCollider::dynamic`]).
    pub(super) rigid: Option<RigidStep>,
}

impl PosedCollider {
    /// `shape` moving from pose `start` to pose `end` during the substep.
    pub fn new(shape: ColliderShape, friction: f32, start: Pose, end: Pose) -> Self {
        let start = affine(start);
        let mut posed = Self {
            shape,
            friction,
            start_inverse: start.inverse(),
            end: start,
            end_inverse: start.inverse(),
            lo: Vec3A::ZERO,
            hi: Vec3A::ZERO,
            tag: None,
            rigid: None,
        };
        posed.move_end(start, affine(end));
        posed
    }

    /// A dynamic collider: a rigid body of `motion` at `pose` when the substep (of
    /// `dt`, under `gravity`) starts, which the particles push and which pushes them
    /// (see [`super::rigid`]). Its pose and motion at the substep's end:
    /// [`super::Colliders::rigid_bodies`].
    pub fn dynamic(
        shape: ColliderShape,
        friction: f32,
        pose: Pose,
        motion: RigidMotion,
        gravity: Vec3,
        dt: f32,
    ) -> Self {
        Self::stepping(
            shape,
            friction,
            RigidStep::predicted(motion, pose, gravity, dt),
        )
    }

    pub(super) fn stepping(shape: ColliderShape, friction: f32, step: RigidStep) -> Self {
        let mut posed = Self::new(shape, friction, step.start, step.now);
        posed.rigid = Some(step);
        posed
    }

    /// Sets the end pose to `end` (the start's transform being `start`), and the swept
    /// bounds.
    fn move_end(&mut self, start: Affine3A, end: Affine3A) {
        let half = Vec3A::from(self.shape.local_half_extents());
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for pose in [start, end] {
            // the world box of the rotated local box: |R|·half about the centre
            let m = pose.matrix3;
            let extent =
                m.x_axis.abs() * half.x + m.y_axis.abs() * half.y + m.z_axis.abs() * half.z;
            lo = lo.min(pose.translation - extent);
            hi = hi.max(pose.translation + extent);
        }
        (self.end, self.end_inverse, self.lo, self.hi) = (end, end.inverse(), lo, hi);
    }

    /// The same collider, its impulses summed under `tag`.
    pub fn tagged(self, tag: u64) -> Self {
        Self {
            tag: Some(tag),
            ..self
        }
    }

    /// Where its centre is at the end of the substep.
    pub(super) fn centre(&self) -> Vec3A {
        self.end.translation
    }

    /// A dynamic collider's body moved by an iteration's shares of its contacts.
    pub(super) fn apply(&mut self, shares: &Pushes, ground: Option<f32>) {
        let Some(rigid) = &mut self.rigid else { return };
        rigid.apply(shares.shift, shares.spin, &self.shape, ground);
        rigid.contacts = shares.contacts;
        let (start, end) = (affine(rigid.start), affine(rigid.now));
        self.move_end(start, end);
    }

    /// A static collider at `pose`.
    pub fn fixed(shape: ColliderShape, friction: f32, pose: Pose) -> Self {
        Self::new(shape, friction, pose, pose)
    }

    /// Whether the collider's swept bounds, grown by `margin`, meet the box `[lo, hi]`.
    pub(super) fn reaches(&self, lo: Vec3A, hi: Vec3A, margin: f32) -> bool {
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

fn affine(p: Pose) -> Affine3A {
    Affine3A::from_rotation_translation(p.rotation.normalize(), p.position)
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
pub(super) fn with_friction(
    target: Vec3A,
    from: Vec3A,
    normal: Vec3A,
    depth: f32,
    friction: f32,
) -> Vec3A {
    let moved = target - from;
    let tangential = moved - normal * moved.dot(normal);
    let limit = friction * depth;
    let squared = tangential.length_squared();
    // (a particle well inside the cone sticks without a root taken)
    if surely_within(squared, limit) {
        return target - tangential;
    }
    let length = squared.sqrt();
    if length <= limit {
        target - tangential
    } else if length > 0.0 {
        target - tangential * (limit / length)
    } else {
        target
    }
}

/// What one iteration's pushes did with one collider: the momentum they gave the
/// particles (kg·m/s × substep, that is kg·m) and its moment about the collider's
/// centre; for a dynamic collider, its shares of them (a shift and a turn) and how
/// many particles it touched.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Pushes {
    pub(super) momentum: Vec3A,
    pub(super) angular: Vec3A,
    pub(super) shift: Vec3A,
    pub(super) spin: Vec3A,
    pub(super) contacts: u32,
}
