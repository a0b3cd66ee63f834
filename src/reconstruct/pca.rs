//! The tightest projection plane of a point set (for splitting a cluster): the eigenvector of the
//! largest eigenvalue of the covariance matrix is the plane's normal.

use crate::math::eigen::symmetric_eigen;
use glam::{Mat3, Vec3};

/// Normal of the tightest projection plane of `points`: the principal (long) axis.
pub fn split_normal(points: &[Vec3]) -> Vec3 {
    if points.len() < 2 {
        return Vec3::X;
    }
    let mean = points.iter().copied().sum::<Vec3>() / points.len() as f32;
    let mut cov = Mat3::ZERO;
    for p in points {
        let d = *p - mean;
        cov += Mat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    symmetric_eigen(cov * (1.0 / points.len() as f32)).1.z_axis
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_is_long_axis() {
        let pts: Vec<Vec3> = (0..10)
            .flat_map(|x| (0..3).map(move |y| Vec3::new(x as f32, y as f32, 0.0)))
            .collect();
        assert!(split_normal(&pts).abs().abs_diff_eq(Vec3::X, 1e-4));
    }
}
