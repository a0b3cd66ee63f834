//! The rigid motion that best carries one set of paired points onto another (a polar
//! decomposition of their cross-covariance), and how far the points are from it: the
//! shape error every relaxation, static solve and statistic reports.

use super::rotation::extract_rotation;
use glam::{Mat3, Quat, Vec3};

/// The best rigid transform from `rest` to `current` (paired points): its rotation and
/// the two centroids.
pub fn rigid_fit(rest: &[Vec3], current: &[Vec3]) -> (Quat, Vec3, Vec3) {
    let n = rest.len().max(1) as f32;
    let (rc, cc) = (
        rest.iter().sum::<Vec3>() / n,
        current.iter().sum::<Vec3>() / n,
    );
    let mut a = Mat3::ZERO;
    for (r, c) in rest.iter().zip(current) {
        let (q, p) = (*r - rc, *c - cc);
        a += Mat3::from_cols(p * q.x, p * q.y, p * q.z);
    }
    let rot = extract_rotation(glam::Mat3A::from(a), Quat::IDENTITY, 200);
    (rot, rc, cc)
}

/// RMS distance between `current` and the best rigid transform of `rest`.
pub fn rigid_fit_error(rest: &[Vec3], current: &[Vec3]) -> f32 {
    if rest.is_empty() {
        return 0.0;
    }
    let n = rest.len() as f32;
    let (rot, rc, cc) = rigid_fit(rest, current);
    let sum: f32 = rest
        .iter()
        .zip(current)
        .map(|(r, c)| (rot * (*r - rc) + cc - *c).length_squared())
        .sum();
    (sum / n).sqrt()
}
