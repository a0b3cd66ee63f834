//! Generalised shape matching of one group (Müller & Chentanez 2011, eq. 7): the
//! group's mass-weighted centroid `c` and the rotation `R` of its moment matrix
//!
//! `A = Σⱼ mⱼ (xⱼ − c)(x̄ⱼ − c̄)ᵀ + Σⱼ mⱼ Rⱼ Dⱼ`,
//!
//! where `x̄ⱼ` is member `j`'s rest position (`c̄` their weighted centroid), `Rⱼ` its
//! orientation and `Dⱼ` its ellipsoid's moment matrix per unit mass in its own frame
//! (`diag(a², b², c²)/5`). The second sum is what makes the matching generalised: a
//! lone particle's `A` is its own `Rⱼ Dⱼ`, whose rotation is its own orientation; a
//! chain's positions span one axis and its members' ellipsoids decide the turn about it.
//!
//! A particle the solver holds still (inverse mass 0) weighs [`KINEMATIC_WEIGHT`] times
//! the group's heaviest moving member: it cannot move, so the fit follows it, and the
//! others' goals continue its place and turn (a clamped root then holds a rod out in
//! one sweep instead of a sixth of the way per sweep).

use crate::math::rotation::extract_rotation;
use glam::{DVec3, Mat3A, Quat, Vec3, Vec3A};

/// Iterations of the rotation extraction per fit, warm-started from the orientation the
/// group gave last.
pub const ROTATION_ITERATIONS: u32 = 4;

/// Weight of a member held still, relative to the group's heaviest moving member.
pub const KINEMATIC_WEIGHT: f32 = 1e3;

/// A group's fit: its rotation and its members' weighted centroids, now and at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// The optimal rotation (from rest to now).
    pub rotation: Quat,
    /// The weighted centroid of the members' positions.
    pub centroid: Vec3A,
    /// The weighted centroid of their rest positions.
    pub rest_centroid: Vec3A,
}

impl Fit {
    /// The goal of the member at rest position `rest`: its rest offset turned and
    /// placed at the centroid.
    #[inline]
    pub fn goal(&self, rest: Vec3A) -> Vec3A {
        self.centroid + self.rotation * (rest - self.rest_centroid)
    }
}

/// The fit's weight of a member of inverse mass `inv_mass`: its mass, or
/// `kinematic` for one held still.
#[inline]
pub(super) fn weight(inv_mass: f32, kinematic: f32) -> f32 {
    if inv_mass > 0.0 {
        1.0 / inv_mass
    } else {
        kinematic
    }
}

/// The weight of a member held still in a group of dense `members`:
/// [`KINEMATIC_WEIGHT`] times the heaviest moving member's mass.
#[inline]
pub(super) fn kinematic_weight(members: &[u32], inv_mass: impl Fn(usize) -> f32) -> f32 {
    let lightest_inverse = members
        .iter()
        .map(|&m| inv_mass(m as usize))
        .filter(|w| *w > 0.0)
        .fold(f32::INFINITY, f32::min);
    KINEMATIC_WEIGHT
        / if lightest_inverse.is_finite() {
            lightest_inverse
        } else {
            1.0
        }
}

/// The fit's weights of the members `members` of a group, their inverse masses
/// `inv_mass(d)` (see [`KINEMATIC_WEIGHT`]).
fn fit_weights<'a>(
    members: &'a [u32],
    inv_mass: impl Fn(usize) -> f32 + Copy + 'a,
) -> impl Iterator<Item = f32> + 'a {
    let kinematic = kinematic_weight(members, inv_mass);
    members
        .iter()
        .map(move |&m| weight(inv_mass(m as usize), kinematic))
}

/// Groups with more members than this accumulate their fit in double precision.
///
/// The moment matrix of a large group sums many large terms whose rounding in single
/// precision leaves a small skew part: a rotation error of about 1e-6 rad for a rigid
/// part of a few thousand particles. The same error recurs every substep while the part
/// rests, and the goals it turns count as velocity, so it accumulates into a steady
/// angular acceleration (a resting chassis would start to spin). Implicit groups are a
/// particle and its six neighbours: their rounding is far smaller and cancels between
/// neighbours.
pub const PRECISE_GROUP: usize = 32;

/// Fits the group of dense `members` with rest positions `rest` (in the body's rest
/// frame) and moment diagonals `moment` to `position(d)` and `orientation(d)`, each
/// weighted by its mass from `inv_mass(d)` (see [`KINEMATIC_WEIGHT`]), starting the
/// rotation from `warm`. Sums run relative to the first member, so that goals keep full
/// precision far from the origin, and in double precision for groups larger than
/// [`PRECISE_GROUP`].
#[inline]
pub fn fit(
    members: &[u32],
    rest: &[Vec3A],
    moment: &[Vec3A],
    inv_mass: impl Fn(usize) -> f32 + Copy,
    position: impl Fn(usize) -> Vec3A + Copy,
    orientation: impl Fn(usize) -> Quat + Copy,
    warm: Quat,
) -> Fit {
    if members.len() > PRECISE_GROUP {
        fit_in::<DVec3>(members, rest, moment, inv_mass, position, orientation, warm)
    } else {
        fit_in::<Vec3A>(members, rest, moment, inv_mass, position, orientation, warm)
    }
}

/// A vector to accumulate a fit's sums in: single or double precision.
trait Accumulator: Copy + std::ops::Sub<Output = Self> + std::ops::AddAssign {
    const ZERO: Self;
    fn of(v: Vec3A) -> Self;
    fn scale(self, s: f64) -> Self;
    fn to(self) -> Vec3A;
    fn component(self, axis: usize) -> f64;
}

impl Accumulator for Vec3A {
    const ZERO: Self = Vec3A::ZERO;
    fn of(v: Vec3A) -> Self {
        v
    }
    fn scale(self, s: f64) -> Self {
        self * s as f32
    }
    fn to(self) -> Vec3A {
        self
    }
    fn component(self, axis: usize) -> f64 {
        self[axis] as f64
    }
}

impl Accumulator for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    fn of(v: Vec3A) -> Self {
        Vec3::from(v).as_dvec3()
    }
    fn scale(self, s: f64) -> Self {
        self * s
    }
    fn to(self) -> Vec3A {
        self.as_vec3().into()
    }
    fn component(self, axis: usize) -> f64 {
        self[axis]
    }
}

/// [`fit`] with its sums in `V`.
#[inline]
fn fit_in<V: Accumulator>(
    members: &[u32],
    rest: &[Vec3A],
    moment: &[Vec3A],
    inv_mass: impl Fn(usize) -> f32 + Copy,
    position: impl Fn(usize) -> Vec3A,
    orientation: impl Fn(usize) -> Quat,
    warm: Quat,
) -> Fit {
    let origin = position(members[0] as usize);
    let rest_origin = rest[0];
    let (mut sum, mut rest_sum, mut total) = (V::ZERO, V::ZERO, 0.0f64);
    for ((&m, r), w) in members.iter().zip(rest).zip(fit_weights(members, inv_mass)) {
        sum += V::of(position(m as usize) - origin).scale(w as f64);
        rest_sum += V::of(*r - rest_origin).scale(w as f64);
        total += w as f64;
    }
    let (centre, rest_centre) = (sum.scale(1.0 / total), rest_sum.scale(1.0 / total));
    let weights = fit_weights(members, inv_mass);
    let mut a = [V::ZERO; 3];
    for (((&m, r), d), w) in members.iter().zip(rest).zip(moment).zip(weights) {
        let x = (V::of(position(m as usize) - origin) - centre).scale(w as f64);
        let r = V::of(*r - rest_origin) - rest_centre;
        for (axis, column) in a.iter_mut().enumerate() {
            *column += x.scale(r.component(axis));
        }
        if *d != Vec3A::ZERO {
            let turn = Mat3A::from_quat(orientation(m as usize));
            let d = *d * w;
            for (axis, column) in a.iter_mut().enumerate() {
                *column += V::of(turn.col(axis) * d[axis]);
            }
        }
    }
    let a = Mat3A::from_cols(a[0].to(), a[1].to(), a[2].to());
    Fit {
        rotation: extract_rotation(a, warm, ROTATION_ITERATIONS),
        centroid: origin + centre.to(),
        rest_centroid: rest_origin + rest_centre.to(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    const SPHERE: Vec3A = Vec3A::splat(0.25 * 0.25 / 5.0);

    /// The fit after `n` solver iterations, each warm-started from the last (as the
    /// sweeps do: a group's centre keeps the rotation it was given).
    fn settled(n: usize, one: impl Fn(Quat) -> Fit) -> Fit {
        let mut f = one(Quat::IDENTITY);
        for _ in 1..n {
            f = one(f.rotation);
        }
        f
    }

    #[test]
    fn a_lone_particle_keeps_its_orientation() {
        let q = Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0);
        let f = settled(60, |warm| {
            fit(
                &[0],
                &[Vec3A::ZERO],
                &[Vec3A::new(0.01, 0.02, 0.03)],
                |_| 1.0,
                |_| Vec3A::new(4.0, 5.0, 6.0),
                |_| q,
                warm,
            )
        });
        assert!(
            f.rotation.dot(q).abs() > 1.0 - 1e-6,
            "{:?} vs {q:?}",
            f.rotation
        );
    }

    #[test]
    fn a_rigidly_moved_block_gives_its_rotation() {
        let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 0.7);
        let rest: Vec<Vec3A> = [Vec3A::ZERO, Vec3A::X, Vec3A::Y, Vec3A::Z, Vec3A::NEG_X]
            .into_iter()
            .collect();
        let at = Vec3A::new(100.0, -20.0, 3.0);
        let members = [0, 1, 2, 3, 4];
        let f = settled(60, |warm| {
            fit(
                &members,
                &rest,
                &[SPHERE; 5],
                |_| 1.0,
                |d| at + turn * rest[d],
                |_| turn,
                warm,
            )
        });
        assert!(f.rotation.dot(turn).abs() > 1.0 - 1e-6);
        for (d, r) in rest.iter().enumerate() {
            assert!((f.goal(*r) - (at + turn * rest[d])).length() < 1e-4);
        }
    }

    #[test]
    fn a_member_held_still_leads_the_fit() {
        // a rod's root (0, 1) pinned on the axis, its third member sagging: the goal puts
        // the third back on the axis, not a sixth of the way
        let rest = [Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0];
        let at = [Vec3A::ZERO, Vec3A::X, Vec3A::new(2.0, -0.3, 0.0)];
        let f = fit(
            &[0, 1, 2],
            &rest,
            &[SPHERE; 3],
            |d| if d < 2 { 0.0 } else { 1.0 },
            |d| at[d],
            |_| Quat::IDENTITY,
            Quat::IDENTITY,
        );
        // (the held pair weighs a thousand times the third: 0.1 % of the sag is left)
        let left = (f.goal(rest[2]) - rest[2]).length() / 0.3;
        assert!(left < 0.01, "{left}");
    }

    #[test]
    fn a_chain_leaves_the_turn_about_its_axis_to_its_members() {
        // a straight chain along x whose members are all turned about x: positions say
        // nothing about that turn, the ellipsoids do
        let twist = Quat::from_rotation_x(0.9);
        let offsets = [Vec3A::NEG_X, Vec3A::ZERO, Vec3A::X];
        // (the positions barely weigh on the turn about the axis, so the warm-started
        // extraction takes it in small steps: the solver's iterations and substeps)
        let f = settled(300, |warm| {
            fit(
                &[0, 1, 2],
                &offsets,
                &[SPHERE; 3],
                |_| 1.0,
                |d| offsets[d],
                |_| twist,
                warm,
            )
        });
        assert!(f.rotation.dot(twist).abs() > 1.0 - 1e-5, "{:?}", f.rotation);
        // and a bent chain turns the fit about the bend, whatever the members say
        let bend = Quat::from_rotation_z(0.4);
        let f = fit(
            &[0, 1, 2],
            &offsets,
            &[SPHERE; 3],
            |_| 1.0,
            |d| bend * offsets[d],
            |_| Quat::IDENTITY,
            Quat::IDENTITY,
        );
        let (axis, angle) = f.rotation.to_axis_angle();
        assert!(axis.z > 0.99 && angle > 0.3, "{axis} {angle}");
    }
}
