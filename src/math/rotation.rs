//! Rotation extraction by Müller, Bender, Chentanez & Macklin 2016, "A robust method to
//! extract the rotational part of deformations": iterate
//! `q ← exp(ω) q` with `ω = Σᵢ rᵢ × aᵢ / (|Σᵢ rᵢ · aᵢ| + ε)` (rᵢ, aᵢ the columns of R(q), A).
//! Always returns a unit quaternion (a proper rotation), never NaN, for any input.

use crate::math::lanes::{Mat3x8, Quatx8, Vec3x8};
use crate::math::simd::Lane;
use glam::{Mat3A, Quat, Vec3A};

/// The unit quaternion in the direction of `q`, whatever its length; `None` when `q` is
/// not finite or is zero. Scaling by the largest component first keeps the length from
/// overflowing (`(0, 0, 0, 1e30)` is the identity) or vanishing.
pub fn unit_quaternion(q: Quat) -> Option<Quat> {
    let largest = q
        .to_array()
        .into_iter()
        .map(f32::abs)
        .fold(0.0f32, f32::max);
    if !(q.is_finite() && largest > 0.0) {
        return None;
    }
    Some((q / largest).normalize())
}

/// Extracts the rotation of `a`, starting from `warm` (the previous result), with at
/// most `max_iterations` iterations. Zero, rank-deficient, inverted or non-finite
/// matrices give a proper rotation (for a zero or non-finite `a`, the warm start).
/// Works on SIMD columns (`Mat3A`); convert a `Mat3` with `Mat3A::from`.
#[inline]
pub fn extract_rotation(a: Mat3A, warm: Quat, max_iterations: u32) -> Quat {
    let mut q = warm_start(warm);
    let Some(epsilon) = extraction_epsilon(a) else {
        return q;
    };
    for _ in 0..max_iterations {
        let r = Mat3A::from_quat(q);
        let omega: Vec3A =
            r.x_axis.cross(a.x_axis) + r.y_axis.cross(a.y_axis) + r.z_axis.cross(a.z_axis);
        let dot = r.x_axis.dot(a.x_axis) + r.y_axis.dot(a.y_axis) + r.z_axis.dot(a.z_axis);
        let omega = omega / (dot.abs() + epsilon);
        let w2 = omega.length_squared();
        if !(w2 > 1e-18 && w2.is_finite()) {
            break;
        }
        q = (exp_map(omega, w2) * q).normalize();
    }
    q
}

/// The ε of `a`'s extraction, relative to its largest entry so that the iteration does
/// not depend on its scale; `None` when `a` is zero or not finite (the extraction keeps
/// its warm start).
#[inline]
pub fn extraction_epsilon(a: Mat3A) -> Option<f32> {
    let scale = a
        .x_axis
        .abs()
        .max(a.y_axis.abs())
        .max(a.z_axis.abs())
        .max_element();
    (scale.is_finite() && scale > 0.0).then_some(1e-9 * scale)
}

/// A usable warm start: `warm` if it is a unit quaternion, else `warm` normalised, else
/// the identity (for a zero or non-finite `warm`).
#[inline]
pub fn warm_start(warm: Quat) -> Quat {
    if warm.is_finite() && (warm.length_squared() - 1.0).abs() < 1e-3 {
        warm
    } else if warm.is_finite() && warm.length_squared() > 0.0 {
        warm.normalize()
    } else {
        Quat::IDENTITY
    }
}

/// [`extract_rotation`] for eight matrices at once, one per lane, with the same
/// iteration and the same guards (a lane whose matrix is zero or non-finite, or whose
/// update is negligible or non-finite, keeps its current rotation). The warm starts
/// must be unit quaternions (see [`warm_start`]).
#[inline(always)]
pub fn extract_rotation_x8<L: Lane>(
    a: &Mat3x8<L>,
    warm: Quatx8<L>,
    max_iterations: u32,
) -> Quatx8<L> {
    let scale = a
        .x_axis
        .abs_max()
        .max(a.y_axis.abs_max())
        .max(a.z_axis.abs_max());
    let mut active = scale.is_finite() & scale.simd_gt(L::ZERO);
    let epsilon = scale * L::splat(1e-9);
    let mut q = warm;
    for _ in 0..max_iterations {
        if !active.any() {
            break;
        }
        let r = Mat3x8::from_quat(q);
        let omega = r.x_axis.cross(a.x_axis) + r.y_axis.cross(a.y_axis) + r.z_axis.cross(a.z_axis);
        let dot = r.x_axis.dot(a.x_axis) + r.y_axis.dot(a.y_axis) + r.z_axis.dot(a.z_axis);
        let omega = omega.scale(L::ONE / (dot.abs() + epsilon));
        let w2 = omega.dot(omega);
        active = active & w2.simd_gt(L::splat(1e-18)) & w2.is_finite();
        let turned = (exp_map_x8(omega, w2) * q).normalize();
        q = Quatx8::select(active, turned, q);
    }
    q
}

/// [`exp_map`] per lane.
#[inline(always)]
fn exp_map_x8<L: Lane>(omega: Vec3x8<L>, w2: L) -> Quatx8<L> {
    let x2 = w2 * L::splat(0.25);
    let sin_over_w = L::splat(0.5) * (L::ONE - x2 / L::splat(6.0) * (L::ONE - x2 / L::splat(20.0)));
    let cos = L::ONE - x2 * L::splat(0.5) * (L::ONE - x2 / L::splat(12.0));
    let small = w2.simd_lt(L::ONE);
    let (sin_over_w, cos) = if small.all() {
        (sin_over_w, cos)
    } else {
        let w = w2.sqrt();
        let (sin, exact_cos) = (w * L::splat(0.5)).sin_cos();
        (
            small.select(sin_over_w, sin / w),
            small.select(cos, exact_cos),
        )
    };
    let v = omega.scale(sin_over_w);
    Quatx8 {
        x: v.x,
        y: v.y,
        z: v.z,
        w: cos,
    }
}

/// The unit quaternion of the rotation vector `omega` (`w2 = |omega|²`): a short
/// Taylor series for angles up to 1 rad (error below 2·10⁻⁶, then normalised), the
/// exact sine and cosine beyond.
#[inline]
pub(super) fn exp_map(omega: Vec3A, w2: f32) -> Quat {
    if w2 < 1.0 {
        // x = w/2: sin(x)/w = (1 − x²/6 + x⁴/120)/2, cos(x) = 1 − x²/2 + x⁴/24
        let x2 = w2 * 0.25;
        let sin_over_w = 0.5 * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0));
        let cos = 1.0 - x2 * 0.5 * (1.0 - x2 / 12.0);
        let v = omega * sin_over_w;
        Quat::from_xyzw(v.x, v.y, v.z, cos)
    } else {
        let w = w2.sqrt();
        Quat::from_axis_angle((omega / w).into(), w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::simd::{WithLanes, on_every_backend};
    use glam::{Mat3, Vec3};

    #[test]
    fn a_quaternion_of_any_finite_length_gives_its_direction() {
        let cases = [
            (Quat::from_xyzw(0.0, 0.0, 0.0, 1e30), Some(Quat::IDENTITY)),
            (
                Quat::from_xyzw(0.0, 3e-30, 0.0, 0.0),
                Some(Quat::from_xyzw(0.0, 1.0, 0.0, 0.0)),
            ),
            (
                Quat::from_xyzw(2.0, 0.0, 0.0, 2.0),
                Some(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2)),
            ),
            (Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), None),
            (Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0), None),
            (Quat::from_xyzw(f32::INFINITY, 0.0, 0.0, 1.0), None),
        ];
        for (q, expected) in cases {
            let got = unit_quaternion(q);
            match (got, expected) {
                (Some(g), Some(e)) => assert!(g.dot(e) > 1.0 - 1e-6, "{q}: {g} vs {e}"),
                (g, e) => assert_eq!(g, e, "{q}"),
            }
        }
    }

    #[test]
    fn exp_map_matches_the_exact_rotation() {
        for w in [1e-4f32, 0.1, 0.5, 0.99, 1.0, 2.0, 3.0] {
            let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
            let q = exp_map(Vec3A::from(axis * w), w * w).normalize();
            let exact = Quat::from_axis_angle(axis, w);
            assert!(q.dot(exact).abs() > 1.0 - 1e-6, "{w}: {q} vs {exact}");
        }
    }
    /// [`exp_map_x8`] against [`exp_map`], with lanes `L`.
    #[derive(Clone)]
    struct ExpMapLanes;

    impl WithLanes for ExpMapLanes {
        type Output = ();
        fn run<L: Lane>(self) {
            for w in [1e-4f32, 0.1, 0.5, 0.99, 1.0, 1.5, 2.0, 3.0, 10.0, 100.0] {
                let axis = Vec3A::new(0.3, -0.5, 0.8).normalize();
                let lanes = exp_map_x8(Vec3x8::<L>::from_lanes([axis * w; 8]), L::splat(w * w));
                let scalar = exp_map(axis * w, w * w);
                assert!(
                    lanes.lane(3).abs_diff_eq(scalar, 1e-6),
                    "{w}: {} vs {scalar}",
                    lanes.lane(3)
                );
            }
        }
    }

    #[test]
    fn exp_map_lanes_match_the_scalar_map() {
        on_every_backend(ExpMapLanes);
    }

    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_rotation(rng: &mut impl Rng) -> Quat {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let angle = rng.random_range(0.0..std::f32::consts::PI);
        Quat::from_axis_angle(v.try_normalize().unwrap_or(Vec3::X), angle)
    }

    fn is_proper(q: Quat) -> bool {
        let m = Mat3::from_quat(q);
        q.is_finite() && (q.length() - 1.0).abs() < 1e-4 && (m.determinant() - 1.0).abs() < 1e-3
    }

    #[test]
    fn recovers_rotation_from_rotation_times_stretch() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..500 {
            let r = random_rotation(&mut rng);
            let s = Mat3::from_diagonal(Vec3::new(
                rng.random_range(0.3..3.0),
                rng.random_range(0.3..3.0),
                rng.random_range(0.3..3.0),
            ));
            // symmetric positive stretch with random axes: U S Uᵀ
            let u = Mat3::from_quat(random_rotation(&mut rng));
            let a = Mat3::from_quat(r) * u * s * u.transpose();
            let q = extract_rotation(Mat3A::from(a), Quat::IDENTITY, 100);
            assert!(is_proper(q));
            assert!(q.dot(r).abs() > 0.9999, "expected {r:?} got {q:?}");
        }
    }

    /// [`extract_rotation_x8`] against [`extract_rotation`] on random and degenerate
    /// matrices, with lanes `L`.
    #[derive(Clone)]
    struct ExtractionLanes;

    impl WithLanes for ExtractionLanes {
        type Output = ();
        fn run<L: Lane>(self) {
            let mut rng = ChaCha8Rng::seed_from_u64(9);
            for round in 0..200 {
                // lanes 0–3 degenerate, the others rotations times a positive stretch, warm
                // started within 0.6 rad of their rotation (as a solver's warm starts are:
                // far from it, one iteration is ill-conditioned in any precision)
                let mut warm = [Quat::IDENTITY; 8];
                let mats: [Mat3; 8] = std::array::from_fn(|l| {
                    let r = random_rotation(&mut rng);
                    let near = Quat::from_axis_angle(
                        Vec3::from_array(std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
                            .try_normalize()
                            .unwrap_or(Vec3::X),
                        rng.random_range(0.0..0.6),
                    );
                    warm[l] = (near * r).normalize();
                    match (round + l) % 8 {
                        0 => Mat3::ZERO,
                        1 => Mat3::from_cols(Vec3::NAN, Vec3::X, Vec3::Y),
                        2 => Mat3::from_quat(r) * 1e-30,
                        3 => Mat3::from_quat(r) * 1e30,
                        _ => {
                            let u = Mat3::from_quat(random_rotation(&mut rng));
                            let s = Vec3::from_array(std::array::from_fn(|_| {
                                rng.random_range(0.3..3.0)
                            }));
                            Mat3::from_quat(r) * u * Mat3::from_diagonal(s) * u.transpose()
                        }
                    }
                });
                let a = Mat3x8 {
                    x_axis: Vec3x8::<L>::from_lanes(mats.map(|m| Vec3A::from(m.x_axis))),
                    y_axis: Vec3x8::from_lanes(mats.map(|m| Vec3A::from(m.y_axis))),
                    z_axis: Vec3x8::from_lanes(mats.map(|m| Vec3A::from(m.z_axis))),
                };
                for iterations in [1, 4] {
                    let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), iterations);
                    for l in 0..8 {
                        let scalar = extract_rotation(Mat3A::from(mats[l]), warm[l], iterations);
                        assert!(is_proper(q.lane(l)), "{:?}", mats[l]);
                        assert!(
                            q.lane(l).dot(scalar).abs() > 1.0 - 1e-5,
                            "{:?}: {} vs {scalar}",
                            mats[l],
                            q.lane(l)
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn eight_lanes_match_the_scalar_extraction() {
        on_every_backend(ExtractionLanes);
    }

    #[test]
    fn degenerate_inputs_give_proper_rotations() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let warm = random_rotation(&mut rng);
        assert!(extract_rotation(Mat3A::ZERO, warm, 20).dot(warm.normalize()) > 1.0 - 1e-6);
        let nan = Mat3::from_cols(Vec3::NAN, Vec3::X, Vec3::Y);
        assert!(is_proper(extract_rotation(Mat3A::from(nan), warm, 20)));
        let inf = Mat3::from_cols(Vec3::INFINITY, Vec3::X, Vec3::Y);
        assert!(is_proper(extract_rotation(
            Mat3A::from(inf),
            Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0),
            20
        )));
        for _ in 0..300 {
            let r = Mat3::from_quat(random_rotation(&mut rng));
            let inverted = r * Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0));
            let rank1 = Mat3::from_cols(Vec3::X, Vec3::X * 2.0, Vec3::ZERO) * r;
            let rank2 = r * Mat3::from_diagonal(Vec3::new(2.0, 1.0, 0.0));
            let tiny = r * 1e-30;
            let huge = r * 1e30;
            for a in [inverted, rank1, rank2, tiny, huge] {
                let q = extract_rotation(Mat3A::from(a), random_rotation(&mut rng), 50);
                assert!(is_proper(q), "{a:?} -> {q:?}");
            }
            // A scaled rotation is recovered exactly regardless of scale.
            let q = extract_rotation(Mat3A::from(huge), Quat::IDENTITY, 100);
            assert!(Mat3::from_quat(q).abs_diff_eq(r, 1e-3));
        }
    }
}
