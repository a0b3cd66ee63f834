//! Dynamic colliders: rigid bodies the solve moves with the particles. Each substep the
//! body is predicted under gravity from its velocity; in each iteration every push
//! between it and a particle is shared by their inverse masses, as one contact
//! constraint between two bodies is in position-based dynamics, the body's share of all
//! its contacts applied after the iteration; and at the substep's end its velocity is
//! its motion over the substep. A body that touches `k` particles counts each contact's
//! share as if `k` pushed at once (mass splitting, with the last iteration's count), so
//! that a light body on many particles is not pushed `k` times too far — for contacts of
//! one depth and direction the shares are then the exact solution. The ground holds the
//! body up without friction; static boxes of the config do not touch it.

use crate::cut::tool::Pose;
use crate::geometry::collider::ColliderShape;
use crate::math::log_map::turn;
use glam::{Quat, Vec3, Vec3A};
use smallvec::{SmallVec, smallvec};

/// A rigid body's mass properties and motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidMotion {
    /// 1 / mass (1/kg).
    pub inv_mass: f32,
    /// 1 / principal moments of inertia about the local axes (1/(kg·m²)).
    pub inv_inertia: Vec3A,
    /// Linear velocity (m/s).
    pub velocity: Vec3A,
    /// Angular velocity, world frame (rad/s).
    pub angular_velocity: Vec3A,
}

/// A rigid body during one substep.
#[derive(Clone, Debug)]
pub(super) struct RigidStep {
    pub(super) motion: RigidMotion,
    /// Its pose at the substep's start.
    pub(super) start: Pose,
    /// Its pose now (predicted, then moved by each iteration's contacts).
    pub(super) now: Pose,
    /// Its contacts in the last iteration (each share is counted as one of this many).
    pub(super) contacts: u32,
    /// Gravity, and the substep's length.
    gravity: Vec3A,
    dt: f32,
}

impl RigidStep {
    /// The body at `pose` with `motion`, predicted over a substep of `dt` under `gravity`.
    pub(super) fn predicted(motion: RigidMotion, pose: Pose, gravity: Vec3, dt: f32) -> Self {
        let mut motion = motion;
        motion.velocity += Vec3A::from(gravity) * dt;
        let position = pose.position + Vec3::from(motion.velocity) * dt;
        let rotation = turned(pose.rotation, motion.angular_velocity * dt);
        Self {
            motion,
            start: pose,
            now: Pose { position, rotation },
            contacts: 0,
            gravity: gravity.into(),
            dt,
        }
    }

    /// The same body at the start of the next substep: its velocity its motion over this
    /// one, predicted again.
    pub(super) fn next(&self) -> Self {
        let motion = self.finished();
        Self {
            contacts: self.contacts,
            ..Self::predicted(motion, self.now, self.gravity.into(), self.dt)
        }
    }

    /// Its motion at the substep's end (velocities from the substep's displacement).
    pub(super) fn finished(&self) -> RigidMotion {
        RigidMotion {
            velocity: Vec3A::from(self.now.position - self.start.position) / self.dt,
            angular_velocity: Vec3A::from(turn(self.start.rotation, self.now.rotation)) / self.dt,
            ..self.motion
        }
    }

    /// The inverse mass the body shows to a push along unit `n` at `r` from its centre.
    fn inverse_mass_along(&self, r: Vec3A, n: Vec3A) -> f32 {
        let local = self.now.rotation.conjugate() * Vec3::from(r.cross(n));
        self.motion.inv_mass + (Vec3A::from(local * local) * self.motion.inv_inertia).element_sum()
    }

    /// Of a `push` a particle of inverse mass `w` at `at` needs out of the body, the part
    /// the particle takes; adds the body's part, as a shift and a turn, to `share`.
    pub(super) fn split(
        &self,
        push: Vec3A,
        at: Vec3A,
        w: f32,
        share: &mut (Vec3A, Vec3A),
    ) -> Vec3A {
        let length = push.length();
        if length == 0.0 {
            return push;
        }
        let r = at - Vec3A::from(self.now.position);
        let body = self.inverse_mass_along(r, push / length) * self.contacts.max(1) as f32;
        // the push as a position-level impulse (kg·m) both sides take, oppositely
        let impulse = push / (w + body);
        share.0 -= impulse * self.motion.inv_mass;
        share.1 -= self.world_inverse_inertia(r.cross(impulse));
        impulse * w
    }

    /// Moves the body by an iteration's `shift` and `turn`, then out of the ground at
    /// `ground` (a height): each support point of `shape` below it is pushed up as a
    /// contact against an immovable plane — the body shifted and turned by its inverse
    /// masses at that point — one after the other.
    pub(super) fn apply(
        &mut self,
        shift: Vec3A,
        spin: Vec3A,
        shape: &ColliderShape,
        ground: Option<f32>,
    ) {
        self.now.position += Vec3::from(shift);
        self.now.rotation = turned(self.now.rotation, spin);
        let Some(height) = ground else { return };
        let (points, radius) = support(shape);
        for local in points {
            let r = Vec3A::from(self.now.rotation * local);
            let depth = height + radius - (self.now.position.y + r.y);
            if depth <= 0.0 {
                continue;
            }
            let impulse = Vec3A::Y * (depth / self.inverse_mass_along(r, Vec3A::Y));
            self.now.position += Vec3::from(impulse * self.motion.inv_mass);
            let turn = self.world_inverse_inertia(r.cross(impulse));
            self.now.rotation = turned(self.now.rotation, turn);
        }
    }

    /// `I⁻¹ · torque` in the world frame.
    fn world_inverse_inertia(&self, torque: Vec3A) -> Vec3A {
        let local = self.now.rotation.conjugate() * Vec3::from(torque);
        Vec3A::from(self.now.rotation * Vec3::from(Vec3A::from(local) * self.motion.inv_inertia))
    }
}

/// `q` turned by the rotation vector `spin` (first order, normalised).
fn turned(q: Quat, spin: Vec3A) -> Quat {
    let dq = Quat::from_xyzw(spin.x, spin.y, spin.z, 0.0) * q * 0.5;
    (q + dq).normalize()
}

/// The points (local) and radius whose balls' hull is `shape` for the ground: a ball's
/// centre, a capsule's ends, a box's (or a mesh's bounding box's) corners.
fn support(shape: &ColliderShape) -> (SmallVec<[Vec3; 8]>, f32) {
    match *shape {
        ColliderShape::Sphere { radius } => (smallvec![Vec3::ZERO], radius),
        ColliderShape::Capsule {
            radius,
            half_length,
        } => (
            smallvec![Vec3::X * half_length, -Vec3::X * half_length],
            radius,
        ),
        ref other => {
            let h = other.local_half_extents();
            let corners = (0..8)
                .map(|i| h * Vec3::new(sign(i & 1), sign(i & 2), sign(i & 4)))
                .collect();
            (corners, 0.0)
        }
    }
}

fn sign(bit: usize) -> f32 {
    if bit == 0 { -1.0 } else { 1.0 }
}

/// The principal moments of inertia of a solid `shape` of `mass` (a capsule as its
/// cylinder and two half balls, a mesh as its bounding box).
pub fn solid_inertia(shape: &ColliderShape, mass: f32) -> Vec3 {
    match *shape {
        ColliderShape::Sphere { radius } => Vec3::splat(0.4 * mass * radius * radius),
        ColliderShape::Capsule {
            radius,
            half_length,
        } => {
            let (r, l) = (radius, 2.0 * half_length);
            let (cylinder, ball) = (
                std::f32::consts::PI * r * r * l,
                4.0 / 3.0 * std::f32::consts::PI * r * r * r,
            );
            let density = mass / (cylinder + ball);
            let (mc, mb) = (density * cylinder, density * ball);
            let axial = mc * r * r / 2.0 + mb * 0.4 * r * r;
            let across = mc * (r * r / 4.0 + l * l / 12.0)
                + mb * (0.4 * r * r + l * l / 4.0 + 3.0 * l * r / 8.0);
            Vec3::new(axial, across, across)
        }
        ref other => {
            let s = 2.0 * other.local_half_extents();
            let s2 = s * s;
            Vec3::new(s2.y + s2.z, s2.x + s2.z, s2.x + s2.y) * (mass / 12.0)
        }
    }
}
