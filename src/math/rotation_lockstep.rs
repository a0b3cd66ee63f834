//! Eight scalar rotation extractions in lockstep: [`extract_rotations_lockstep`] gives
//! lane `l` exactly the bits of [`extract_rotation`]`(a[l], warm[l], n)`.
//!
//! [`extract_rotation`]: super::rotation::extract_rotation
//!
//! The scalar extraction is a long dependency chain: every iteration waits on two
//! square roots and two divisions. Run one lane per matrix, eight chains overlap in
//! one register. [`extract_rotation_x8`](super::rotation::extract_rotation_x8), the
//! batched fits' kernel, does the same sums with fused products and a reciprocal, so
//! its lanes agree with the scalar extraction only to rounding. Here every operation is
//! the one glam's scalar code performs, in its order, fused exactly where glam's is.
//! That is for the fits whose results must not depend on whether they were batched:
//! a cluster's turn fitted afresh after a cut gives the rotation the one-at-a-time fit
//! gave.

use super::lanes::{Mat3x8, Quatx8, Vec3x8};
use super::rotation::{exp_map, extraction_epsilon, warm_start};
use super::simd::Lane;
use glam::{Mat3A, Quat};

/// [`extract_rotation`](super::rotation::extract_rotation) of eight matrices at once, bit
/// for bit (see the module docs).
#[inline(always)]
pub fn extract_rotations_lockstep<L: Lane>(
    a: &[Mat3A; 8],
    warm: [Quat; 8],
    max_iterations: u32,
) -> [Quat; 8] {
    let starts = warm.map(warm_start);
    let epsilon = a.map(extraction_epsilon);
    let mut active = L::from_array(epsilon.map(|e| f32::from_bits(e.map_or(0, |_| !0))));
    let eps = L::from_array(epsilon.map(|e| e.unwrap_or(0.0)));
    let column = |c: usize| Vec3x8::<L>::from_lanes(a.map(|a| a.col(c)));
    let a = Mat3x8 {
        x_axis: column(0),
        y_axis: column(1),
        z_axis: column(2),
    };
    let mut q = Quatx8::<L>::from_lanes(starts);
    for _ in 0..max_iterations {
        if !active.any() {
            break;
        }
        let r = Mat3x8::from_quat(q);
        let omega =
            cross(r.x_axis, a.x_axis) + cross(r.y_axis, a.y_axis) + cross(r.z_axis, a.z_axis);
        let dot = (dot3(r.x_axis, a.x_axis) + dot3(r.y_axis, a.y_axis)) + dot3(r.z_axis, a.z_axis);
        let divisor = dot.abs() + eps;
        let omega = Vec3x8 {
            x: omega.x / divisor,
            y: omega.y / divisor,
            z: omega.z / divisor,
        };
        let w2 = dot3(omega, omega);
        active = active & w2.simd_gt(L::splat(1e-18)) & w2.is_finite();
        let turned = normalize(mul(exp_map_lockstep(omega, w2, active), q));
        q = Quatx8::select(active, turned, q);
    }
    std::array::from_fn(|l| q.lane(l))
}

/// glam's `Vec3A::dot`: `(x x' + y y') + z z'`.
#[inline(always)]
fn dot3<L: Lane>(a: Vec3x8<L>, b: Vec3x8<L>) -> L {
    (a.x * b.x + a.y * b.y) + a.z * b.z
}

/// glam's `Vec3A::cross`: each component `p − q` of two products, the second fused
/// where glam's build has FMA.
#[inline(always)]
fn cross<L: Lane>(a: Vec3x8<L>, b: Vec3x8<L>) -> Vec3x8<L> {
    #[cfg(not(target_feature = "fma"))]
    let minus = |p: L, s: L, t: L| p - s * t;
    #[cfg(target_feature = "fma")]
    let minus = |p: L, s: L, t: L| L::ZERO - s.mul_sub(t, p);
    Vec3x8 {
        x: minus(a.y * b.z, b.y, a.z),
        y: minus(a.z * b.x, b.z, a.x),
        z: minus(a.x * b.y, b.x, a.y),
    }
}

/// glam's `Quat * Quat` (its SSE order of sums; the products by ±1 it fuses are exact,
/// so fused or not it rounds alike).
#[inline(always)]
fn mul<L: Lane>(a: Quatx8<L>, b: Quatx8<L>) -> Quatx8<L> {
    Quatx8 {
        x: (a.x * b.w + a.w * b.x) + (a.y * b.z - a.z * b.y),
        y: (a.w * b.y - a.x * b.z) + (a.z * b.x + a.y * b.w),
        z: (a.x * b.y + a.w * b.z) + (a.z * b.w - a.y * b.x),
        w: (a.w * b.w - a.x * b.x) - (a.z * b.z + a.y * b.y),
    }
}

/// glam's `Quat::normalize`: each component over `√((x² + z²) + (y² + w²))`.
#[inline(always)]
fn normalize<L: Lane>(q: Quatx8<L>) -> Quatx8<L> {
    let length = ((q.x * q.x + q.z * q.z) + (q.y * q.y + q.w * q.w)).sqrt();
    Quatx8 {
        x: q.x / length,
        y: q.y / length,
        z: q.z / length,
        w: q.w / length,
    }
}

/// [`exp_map`] per lane: its series in lanes for the lanes under 1 rad, the scalar map
/// itself for the `active` lanes beyond (its sine and cosine are the standard
/// library's, which lanes do not reproduce).
#[inline(always)]
fn exp_map_lockstep<L: Lane>(omega: Vec3x8<L>, w2: L, active: L) -> Quatx8<L> {
    let x2 = w2 * L::splat(0.25);
    let sin_over_w = L::splat(0.5) * (L::ONE - x2 / L::splat(6.0) * (L::ONE - x2 / L::splat(20.0)));
    let cos = L::ONE - x2 * L::splat(0.5) * (L::ONE - x2 / L::splat(12.0));
    let series = Quatx8 {
        x: omega.x * sin_over_w,
        y: omega.y * sin_over_w,
        z: omega.z * sin_over_w,
        w: cos,
    };
    // (`w2 ≥ 1`, the scalar map's test, as `w2 >` the float below 1)
    let beyond = active & w2.simd_gt(L::splat(1.0f32.next_down()));
    if !beyond.any() {
        return series;
    }
    let (mask, w2, omega, series) = (
        beyond.to_array(),
        w2.to_array(),
        omega.to_lanes(),
        series.to_lanes(),
    );
    Quatx8::from_lanes(std::array::from_fn(|l| {
        if mask[l].to_bits() == 0 {
            series[l]
        } else {
            exp_map(omega[l], w2[l])
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rotation::extract_rotation;
    use crate::math::simd::{WithLanes, on_every_backend};
    use glam::{Mat3, Vec3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random matrix: a rotation times a stretch, scaled, or a degenerate one.
    fn matrix(rng: &mut impl Rng, kind: u32) -> Mat3A {
        let mut v = || Vec3::from_array(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
        let r = Mat3::from_quat(Quat::from_scaled_axis(v() * 3.0));
        let m = match kind % 10 {
            0 => Mat3::ZERO,
            1 => Mat3::from_cols(Vec3::NAN, Vec3::X, Vec3::Y),
            2 => Mat3::from_cols(Vec3::INFINITY, Vec3::X, Vec3::Y),
            3 => r * 1e-30,
            4 => r * 1e30,
            5 => r * Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0)),
            6 => r * Mat3::from_diagonal(Vec3::new(2.0, 1.0, 0.0)),
            _ => r * Mat3::from_cols(v(), v(), v()) + Mat3::from_diagonal(Vec3::splat(2.0)),
        };
        Mat3A::from(m)
    }

    /// The lockstep extraction against eight scalar ones, bit for bit, with lanes `L`.
    #[derive(Clone)]
    struct Lockstep;

    impl WithLanes for Lockstep {
        type Output = ();
        fn run<L: Lane>(self) {
            let mut rng = ChaCha8Rng::seed_from_u64(64);
            for round in 0..400 {
                let a: [Mat3A; 8] = std::array::from_fn(|l| matrix(&mut rng, round + l as u32));
                // warm starts near and far (beyond 1 rad a step takes the exact map),
                // unnormalised, zero and NaN
                let warm: [Quat; 8] = std::array::from_fn(|l| match (round + 3 * l as u32) % 9 {
                    0 => Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
                    1 => Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0),
                    2 => Quat::from_xyzw(0.1, 0.2, 0.3, 2.0),
                    _ => Quat::from_scaled_axis(Vec3::from_array(std::array::from_fn(|_| {
                        rng.random_range(-2.0..2.0)
                    }))),
                });
                for iterations in [0, 1, 3, 16] {
                    let lanes = extract_rotations_lockstep::<L>(&a, warm, iterations);
                    for l in 0..8 {
                        let scalar = extract_rotation(a[l], warm[l], iterations);
                        assert_eq!(
                            lanes[l].to_array().map(f32::to_bits),
                            scalar.to_array().map(f32::to_bits),
                            "{}, {iterations} iterations: {:?} from {:?}: {} vs {scalar}",
                            L::NAME,
                            a[l],
                            warm[l],
                            lanes[l]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn lockstep_lanes_are_the_scalar_extraction_bit_for_bit() {
        on_every_backend(Lockstep);
    }
}
