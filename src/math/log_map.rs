//! The turn between two orientations as a rotation vector (axis × angle): the
//! logarithm of the relative unit quaternion, the inverse of the exponential map the
//! rotation extraction turns by. Angular velocities are read off it.
//!
//! Two forms:
//! - [`turn_x8`], eight turns at once, generic over [`Lane`], with its own arctangent:
//!   for the spins of particles in clusters, which every frame's end reads off their
//!   blended orientations. A libm `atan2f` call per particle is dearer than the rest of
//!   the velocity update and cannot be vectorised.
//! - [`turn`], one turn through glam and libm: for the spins the dynamics integrate
//!   (particles in no cluster, the oriented model's, rigid colliders'). Their rounding
//!   compounds over frames, through contacts and joints, so they keep libm's bits and
//!   the results they had.

use crate::math::lanes::{Quatx8, Vec3x8};
use crate::math::simd::Lane;
use glam::{Quat, Vec3};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};

/// `tan(π/8)`: above it the arctangent's argument is moved next to 0 by
/// `atan t = π/4 + atan((t − 1)/(t + 1))`.
const TAN_PI_8: f32 = 0.414_213_57;

/// `atan(u)/u − 1 = z · P(z)` with `z = u²` for `|u| ≤ tan(π/8)`: `P`'s coefficients,
/// lowest first, fitted to the relative error of the arctangent (below 7·10⁻¹⁰ in
/// exact arithmetic, so the `f32` evaluation's rounding is what remains).
const ATAN_SERIES: [f32; 5] = [
    -0.333_333_16,
    0.199_984_92,
    -0.142_438_83,
    0.105_961_99,
    -0.060_838_44,
];

/// `atan(u)/u − 1` for `|u| ≤ tan(π/8)`, from `z = u²` (see [`ATAN_SERIES`]).
#[inline(always)]
fn atan_over_arg_minus_one<L: Lane>(z: L) -> L {
    let [c0, c1, c2, c3, c4] = ATAN_SERIES.map(L::splat);
    let p = c4
        .mul_add(z, c3)
        .mul_add(z, c2)
        .mul_add(z, c1)
        .mul_add(z, c0);
    z * p
}

/// The rotation vector of the unit quaternion `r` per lane, the shorter way round
/// (`r` and `−r` give the same); zero in a lane that is not finite.
///
/// With `v = (x, y, z)`, `l = |v|` and `w ≥ 0`, the angle is `θ = 2 atan2(l, w)` and the
/// vector `v θ / l`. For `t = l / w ≤ tan(π/8)` (turns up to 45°: every substep's in
/// practice) `θ / l = 2 (atan t / t) / w` is a polynomial in `t²`, within a few ulps
/// down to a zero turn, with no division by `l`. Larger turns reduce the arctangent's
/// argument to that range (`angle_over_length`).
#[inline(always)]
pub fn log_map_x8<L: Lane>(r: Quatx8<L>) -> Vec3x8<L> {
    let sign = r.w.simd_lt(L::ZERO).select(L::splat(-1.0), L::ONE);
    let (v, w) = (
        Vec3x8 {
            x: r.x * sign,
            y: r.y * sign,
            z: r.z * sign,
        },
        r.w * sign,
    );
    let l = v.dot(v).sqrt();
    let inv_w = L::ONE / w;
    let t = l * inv_w;
    let mut scale = L::splat(2.0) * (L::ONE + atan_over_arg_minus_one(t * t)) * inv_w;
    let beyond = t.simd_gt(L::splat(TAN_PI_8));
    if beyond.any() {
        scale = beyond.select(angle_over_length(l, w), scale);
    }
    let turned = v.scale(scale);
    let finite = turned.x.is_finite() & turned.y.is_finite() & turned.z.is_finite();
    Vec3x8::select(finite, turned, Vec3x8::ZERO)
}

/// `2 atan2(l, w) / l` for `l, w ≥ 0` with `l² + w² = 1`: the arctangent's argument is
/// the smaller over the larger (`atan2(l, w) = π/2 − atan(w / l)` past a right angle),
/// and above `tan(π/8)` it is moved next to 0 by `atan t = π/4 + atan((t − 1)/(t + 1))`.
#[inline(always)]
fn angle_over_length<L: Lane>(l: L, w: L) -> L {
    let past_right_angle = l.simd_gt(w);
    let t = past_right_angle.select(w / l, l / w);
    let reduced = t.simd_gt(L::splat(TAN_PI_8));
    let u = reduced.select((t - L::ONE) / (t + L::ONE), t);
    let atan_t =
        reduced.select(L::splat(FRAC_PI_4), L::ZERO) + u.mul_add(atan_over_arg_minus_one(u * u), u);
    let half_angle = past_right_angle.select(L::splat(FRAC_PI_2) - atan_t, atan_t);
    L::splat(2.0) * half_angle / l
}

/// The turn from `from` to `to` per lane as a rotation vector (see [`log_map_x8`]).
#[inline(always)]
pub fn turn_x8<L: Lane>(from: Quatx8<L>, to: Quatx8<L>) -> Vec3x8<L> {
    log_map_x8(to * from.conjugate())
}

/// The turn from `from` to `to` as a rotation vector (axis × angle, the shorter way
/// round); zero when either is not finite.
pub fn turn(from: Quat, to: Quat) -> Vec3 {
    let r = to * from.conjugate();
    let r = if r.w < 0.0 { -r } else { r };
    let v = r.to_scaled_axis();
    if v.is_finite() { v } else { Vec3::ZERO }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::simd::{WithLanes, on_every_backend};
    use glam::{DQuat, DVec3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The rotation vector of `q` in double precision, the shorter way round: the
    /// reference the lanes are held to.
    fn exact_log(q: DQuat) -> DVec3 {
        let q = if q.w < 0.0 { -q } else { q };
        let v = DVec3::new(q.x, q.y, q.z);
        let l = v.length();
        if l == 0.0 {
            DVec3::ZERO
        } else {
            v * (2.0 * l.atan2(q.w) / l)
        }
    }

    /// Pairs of orientations whose turns span a zero turn to a half turn, either way
    /// round, each turn's quaternion given with both signs.
    fn pairs(rng: &mut ChaCha8Rng) -> Vec<(Quat, Quat)> {
        let mut pairs = Vec::new();
        for exponent in -8..=0 {
            for _ in 0..40 {
                let axis = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let angle =
                    std::f32::consts::PI * 10f32.powi(exponent) * rng.random_range(0.1..1.0);
                let from = Quat::from_scaled_axis(Vec3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ));
                let to = Quat::from_axis_angle(axis.normalize(), angle) * from;
                pairs.push((from, to));
                pairs.push((from, -to));
            }
        }
        pairs
    }

    /// [`log_map_x8`] against [`exact_log`] of the same `f32` quaternions, with lanes
    /// `L`: the worst error over the angle.
    #[derive(Clone)]
    struct AgainstDouble;

    impl WithLanes for AgainstDouble {
        type Output = f64;
        fn run<L: Lane>(self) -> f64 {
            let mut rng = ChaCha8Rng::seed_from_u64(11);
            let turns: Vec<Quat> = pairs(&mut rng)
                .iter()
                .map(|(from, to)| *to * from.conjugate())
                .collect();
            let mut worst = 0.0f64;
            for chunk in turns.chunks(8) {
                let lanes =
                    Quatx8::<L>::from_lanes(std::array::from_fn(|l| chunk[l % chunk.len()]));
                let got = log_map_x8(lanes).to_lanes();
                for (l, r) in chunk.iter().enumerate() {
                    let exact = exact_log(r.as_dquat());
                    let error = (got[l].as_dvec3() - exact).length();
                    worst = worst.max(error / exact.length());
                }
            }
            worst
        }
    }

    #[test]
    fn turns_of_every_size_match_a_double_precision_logarithm() {
        for worst in on_every_backend(AgainstDouble) {
            // within 2.5 ulps (3·10⁻⁷), from turns of 10⁻⁹ rad to a half turn
            assert!(worst < 3e-7, "relative error {worst}");
        }
    }

    /// [`turn_x8`] of fixed pairs, lane 0, with lanes `L`.
    #[derive(Clone)]
    struct Cases(Vec<(Quat, Quat)>);

    impl WithLanes for Cases {
        type Output = Vec<Vec3>;
        fn run<L: Lane>(self) -> Vec<Vec3> {
            (self.0.iter())
                .map(|&(from, to)| {
                    let (from, to) = (
                        Quatx8::<L>::from_lanes([from; 8]),
                        Quatx8::<L>::from_lanes([to; 8]),
                    );
                    turn_x8(from, to).lane(0).into()
                })
                .collect()
        }
    }

    #[test]
    fn a_turn_is_the_shorter_way_round_and_zero_where_it_is_not_finite() {
        let q = Quat::from_rotation_y(0.4);
        let three_quarters = Quat::from_rotation_z(1.5 * std::f32::consts::PI);
        let cases = vec![
            (q, q),
            (q, -q),
            (Quat::IDENTITY, three_quarters),
            (Quat::IDENTITY, Quat::from_rotation_x(std::f32::consts::PI)),
            (Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0), q),
            (q, Quat::from_xyzw(0.0, f32::INFINITY, 0.0, 1.0)),
        ];
        for got in on_every_backend(Cases(cases)) {
            // (q q⁻¹ is the identity but for the product's rounding)
            assert!(got[0].length() < 1e-6, "{}", got[0]);
            assert!(got[1].length() < 1e-6, "{}", got[1]);
            // three quarters of a turn one way is a quarter the other
            let quarter = Vec3::new(0.0, 0.0, -0.5 * std::f32::consts::PI);
            assert!(got[2].abs_diff_eq(quarter, 1e-6), "{}", got[2]);
            assert!(
                (got[3].length() - std::f32::consts::PI).abs() < 1e-6,
                "{}",
                got[3]
            );
            assert_eq!(&got[4..], &[Vec3::ZERO; 2]);
        }
    }

    #[test]
    fn the_lanes_and_the_single_turn_agree() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let pairs = pairs(&mut rng);
        for got in on_every_backend(Cases(pairs.clone())) {
            for (lanes, &(from, to)) in got.iter().zip(&pairs) {
                let one = turn(from, to);
                // (beside the turns' rounding in the quaternion product, ~1e-7 rad)
                let tolerance = 1e-6 * one.length() + 2e-7;
                assert!((*lanes - one).length() <= tolerance, "{lanes} vs {one}");
            }
        }
    }
}
