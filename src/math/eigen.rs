//! Eigen-decomposition of symmetric 3×3 matrices: the principal axes of a point set
//! (a cluster's split plane), the dominant directions of a quadric (a cut face's
//! vertex).

use glam::{Mat3, Vec3};

/// Eigen-decomposition of a symmetric 3×3 matrix by cyclic Jacobi rotations.
/// Returns eigenvalues (ascending) and the matching unit eigenvectors as columns.
pub fn symmetric_eigen(m: Mat3) -> (Vec3, Mat3) {
    let mut a = [[0.0f64; 3]; 3];
    for (c, col) in [m.x_axis, m.y_axis, m.z_axis].iter().enumerate() {
        for r in 0..3 {
            a[r][c] = col[r] as f64;
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0f64]];
    for _ in 0..50 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off < 1e-14 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let values = Vec3::new(
        a[order[0]][order[0]] as f32,
        a[order[1]][order[1]] as f32,
        a[order[2]][order[2]] as f32,
    );
    let col =
        |i: usize| Vec3::new(v[0][i] as f32, v[1][i] as f32, v[2][i] as f32).normalize_or(Vec3::X);
    (
        values,
        Mat3::from_cols(col(order[0]), col(order[1]), col(order[2])),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_reconstructs_matrix() {
        let m = Mat3::from_cols(
            Vec3::new(4.0, 1.0, 0.5),
            Vec3::new(1.0, 3.0, 0.2),
            Vec3::new(0.5, 0.2, 1.0),
        );
        let (vals, vecs) = symmetric_eigen(m);
        assert!(vals.x <= vals.y && vals.y <= vals.z);
        let back = vecs * Mat3::from_diagonal(vals) * vecs.transpose();
        assert!(back.abs_diff_eq(m, 1e-4), "{back:?}");
    }
}
