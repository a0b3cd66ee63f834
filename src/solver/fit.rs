//! One cluster fit (SPEC §2.2): moments of the current positions against the rest
//! offsets, the warm-started rotation (Müller 2016), and the frame that gives every
//! member's pull, premultiplied by the stiffness.

use super::{ROTATION_ITERATIONS, SolverLayout};
use crate::rotation::extract_rotation;
use glam::{Mat3A, Quat, Vec3A, Vec4};

/// The result of one cluster fit, premultiplied by the stiffness `s`: the pull on the
/// member with rest offset `q` at `p` is `s (R q + c − p)` =
/// `scaled_rotation · q + scaled_translation − s·p`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ClusterFrame {
    scaled_rotation: Mat3A,
    scaled_translation: Vec3A,
}

impl ClusterFrame {
    /// `S q + T`; the caller subtracts `s·p`.
    #[inline(always)]
    pub(super) fn scaled_goal(&self, q: Vec3A) -> Vec3A {
        madd(
            self.scaled_rotation.z_axis,
            Vec3A::splat(q.z),
            madd(
                self.scaled_rotation.y_axis,
                Vec3A::splat(q.y),
                madd(
                    self.scaled_rotation.x_axis,
                    Vec3A::splat(q.x),
                    self.scaled_translation,
                ),
            ),
        )
    }
}

/// `a·b + c`, fused where the target has FMA.
#[inline(always)]
fn madd(a: Vec3A, b: Vec3A, c: Vec3A) -> Vec3A {
    #[cfg(target_feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(target_feature = "fma"))]
    {
        a * b + c
    }
}

/// Fits one cluster to the current positions (read through `position`): accumulates
/// the weighted centroid and the moment matrix `A = Σ w (p − o) qᵀ` relative to
/// the first member `o`, updates the warm-started rotation, and returns the frame that
/// gives every member's pull.
#[inline(always)]
pub(super) fn fit_cluster(
    members: &[u32],
    moments: &[Vec4],
    position: impl Fn(usize) -> Vec3A,
    constants: ClusterConstants,
    rotation: &mut Quat,
) -> ClusterFrame {
    let Some(&first) = members.first() else {
        return ClusterFrame::default();
    };
    let origin = position(first as usize);
    let mut sum = Vec3A::ZERO;
    let mut a = Mat3A::ZERO;
    for (&m, moment) in members.iter().zip(moments) {
        let wd = (position(m as usize) - origin) * moment.w;
        sum += wd;
        a.x_axis = madd(wd, Vec3A::splat(moment.x), a.x_axis);
        a.y_axis = madd(wd, Vec3A::splat(moment.y), a.y_axis);
        a.z_axis = madd(wd, Vec3A::splat(moment.z), a.z_axis);
    }
    *rotation = extract_rotation(a, *rotation, ROTATION_ITERATIONS);
    let r = Mat3A::from_quat(*rotation);
    // Σ w (R q + c − d) = R·bias + c·W − Σ w d = 0 exactly when c = (Σ w d − R·bias)/W.
    let centroid = (sum - r * constants.offset_bias) * constants.inv_weight_sum + origin;
    let s = constants.stiffness;
    ClusterFrame {
        scaled_rotation: r * s,
        scaled_translation: centroid * s,
    }
}

/// Per-cluster constants of a fit.
#[derive(Clone, Copy)]
pub(super) struct ClusterConstants {
    offset_bias: Vec3A,
    inv_weight_sum: f32,
    pub(super) stiffness: f32,
}

impl SolverLayout {
    /// The fit constants of cluster `k`.
    #[inline(always)]
    pub(super) fn constants(&self, k: usize) -> ClusterConstants {
        ClusterConstants {
            offset_bias: self.offset_bias[k],
            inv_weight_sum: self.inv_weight_sum[k],
            stiffness: self.stiffness[k],
        }
    }
}
