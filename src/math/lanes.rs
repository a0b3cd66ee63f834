//! Eight-wide structure-of-arrays vectors, matrices and quaternions (one lane per
//! cluster), so that the solver fits eight clusters with one stream of SIMD
//! instructions instead of eight scalar streams.
//!
//! Plain maths, generic over the eight-lane float [`Lane`] (see [`crate::math::simd`]); lane
//! `l` of every value belongs to the same cluster. Stored values use the default lane
//! type, [`wide::f32x8`]; kernels load them into theirs with [`Vec3x8::load`].

use crate::math::simd::Lane;
use glam::{Mat3A, Quat, Vec3A};
use wide::f32x8;

/// Number of lanes.
pub const LANES: usize = 8;

/// Eight 3-vectors, one per lane.
#[derive(Clone, Copy, Debug, Default)]
pub struct Vec3x8<L = f32x8> {
    /// x of every lane.
    pub x: L,
    /// y of every lane.
    pub y: L,
    /// z of every lane.
    pub z: L,
}

impl<L: Lane> Vec3x8<L> {
    /// All lanes zero.
    pub const ZERO: Self = Self {
        x: L::ZERO,
        y: L::ZERO,
        z: L::ZERO,
    };

    /// The same vector in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3A) -> Self {
        Self {
            x: L::splat(v.x),
            y: L::splat(v.y),
            z: L::splat(v.z),
        }
    }

    /// A stored value in lanes `L`.
    #[inline(always)]
    pub fn load(v: &Vec3x8) -> Self {
        Self {
            x: L::from_stored(v.x),
            y: L::from_stored(v.y),
            z: L::from_stored(v.z),
        }
    }

    /// The stored form of `self`.
    #[inline(always)]
    pub fn store(self) -> Vec3x8 {
        Vec3x8 {
            x: self.x.to_stored(),
            y: self.y.to_stored(),
            z: self.z.to_stored(),
        }
    }

    /// Gathers one vector per lane (a 4×8 transpose in registers on AVX).
    #[inline(always)]
    pub fn from_lanes(v: [Vec3A; LANES]) -> Self {
        let [x, y, z] = L::transpose_in(v);
        Self { x, y, z }
    }

    /// One vector per lane: the inverse of [`Vec3x8::from_lanes`].
    #[inline(always)]
    pub fn to_lanes(self) -> [Vec3A; LANES] {
        L::transpose_out([self.x, self.y, self.z])
    }

    /// The vector of lane `l`.
    #[inline(always)]
    pub fn lane(&self, l: usize) -> Vec3A {
        Vec3A::new(
            self.x.to_array()[l],
            self.y.to_array()[l],
            self.z.to_array()[l],
        )
    }

    /// Every lane scaled by its own factor.
    #[inline(always)]
    pub fn scale(self, s: L) -> Self {
        Self {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    /// `self · s + c`, fused.
    #[inline(always)]
    pub fn mul_add(self, s: L, c: Self) -> Self {
        Self {
            x: self.x.mul_add(s, c.x),
            y: self.y.mul_add(s, c.y),
            z: self.z.mul_add(s, c.z),
        }
    }

    /// Lane-wise dot product.
    #[inline(always)]
    pub fn dot(self, o: Self) -> L {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z))
    }

    /// Lane-wise cross product.
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self {
            x: self.y.mul_sub(o.z, self.z * o.y),
            y: self.z.mul_sub(o.x, self.x * o.z),
            z: self.x.mul_sub(o.y, self.y * o.x),
        }
    }

    /// Largest absolute component per lane.
    #[inline(always)]
    pub fn abs_max(self) -> L {
        self.x.abs().max(self.y.abs()).max(self.z.abs())
    }

    /// Lane-wise choice: `mask` lanes (all bits set) from `if_true`, the others from
    /// `if_false`.
    #[inline(always)]
    pub fn select(mask: L, if_true: Self, if_false: Self) -> Self {
        Self {
            x: mask.select(if_true.x, if_false.x),
            y: mask.select(if_true.y, if_false.y),
            z: mask.select(if_true.z, if_false.z),
        }
    }
}

impl<L: Lane> std::ops::Add for Vec3x8<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}

impl<L: Lane> std::ops::Sub for Vec3x8<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}

/// Eight 3×3 matrices, stored by columns.
#[derive(Clone, Copy, Debug, Default)]
pub struct Mat3x8<L = f32x8> {
    /// First column.
    pub x_axis: Vec3x8<L>,
    /// Second column.
    pub y_axis: Vec3x8<L>,
    /// Third column.
    pub z_axis: Vec3x8<L>,
}

impl<L: Lane> Mat3x8<L> {
    /// All lanes zero.
    pub const ZERO: Self = Self {
        x_axis: Vec3x8::ZERO,
        y_axis: Vec3x8::ZERO,
        z_axis: Vec3x8::ZERO,
    };

    /// `self · v` per lane.
    #[inline(always)]
    pub fn mul_vec(&self, v: Vec3x8<L>) -> Vec3x8<L> {
        self.z_axis
            .mul_add(v.z, self.y_axis.mul_add(v.y, self.x_axis.scale(v.x)))
    }

    /// Lane-wise `self · v + t`, as three fused multiply-adds per component.
    #[inline(always)]
    pub fn mul_vec_add(&self, v: Vec3x8<L>, t: Vec3x8<L>) -> Vec3x8<L> {
        self.z_axis
            .mul_add(v.z, self.y_axis.mul_add(v.y, self.x_axis.mul_add(v.x, t)))
    }

    /// The rotation matrix of each lane's unit quaternion.
    #[inline(always)]
    pub fn from_quat(q: Quatx8<L>) -> Self {
        let (x2, y2, z2) = (q.x + q.x, q.y + q.y, q.z + q.z);
        let (xx, xy, xz) = (q.x * x2, q.x * y2, q.x * z2);
        let (yy, yz, zz) = (q.y * y2, q.y * z2, q.z * z2);
        let (wx, wy, wz) = (q.w * x2, q.w * y2, q.w * z2);
        let one = L::ONE;
        Self {
            x_axis: Vec3x8 {
                x: one - (yy + zz),
                y: xy + wz,
                z: xz - wy,
            },
            y_axis: Vec3x8 {
                x: xy - wz,
                y: one - (xx + zz),
                z: yz + wx,
            },
            z_axis: Vec3x8 {
                x: xz + wy,
                y: yz - wx,
                z: one - (xx + yy),
            },
        }
    }

    /// The matrix of lane `l`.
    pub fn lane(&self, l: usize) -> Mat3A {
        Mat3A::from_cols(
            self.x_axis.lane(l),
            self.y_axis.lane(l),
            self.z_axis.lane(l),
        )
    }

    /// Every lane's matrix at once (three transposes, where [`Mat3x8::lane`] in a loop
    /// would take each component out of its register eight times).
    #[inline(always)]
    pub fn to_lanes(self) -> [Mat3A; LANES] {
        let (x, y, z) = (
            self.x_axis.to_lanes(),
            self.y_axis.to_lanes(),
            self.z_axis.to_lanes(),
        );
        std::array::from_fn(|l| Mat3A::from_cols(x[l], y[l], z[l]))
    }
}

/// Eight quaternions.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quatx8<L = f32x8> {
    /// Vector part x.
    pub x: L,
    /// Vector part y.
    pub y: L,
    /// Vector part z.
    pub z: L,
    /// Scalar part.
    pub w: L,
}

impl<L: Lane> Quatx8<L> {
    /// Gathers one quaternion per lane.
    #[inline(always)]
    pub fn from_lanes(q: [Quat; LANES]) -> Self {
        Self {
            x: L::from_array(q.map(|q| q.x)),
            y: L::from_array(q.map(|q| q.y)),
            z: L::from_array(q.map(|q| q.z)),
            w: L::from_array(q.map(|q| q.w)),
        }
    }

    /// Every lane's quaternion at once.
    #[inline(always)]
    pub fn to_lanes(self) -> [Quat; LANES] {
        let (x, y, z, w) = (
            self.x.to_array(),
            self.y.to_array(),
            self.z.to_array(),
            self.w.to_array(),
        );
        std::array::from_fn(|l| Quat::from_xyzw(x[l], y[l], z[l], w[l]))
    }

    /// The quaternion of lane `l`.
    #[inline(always)]
    pub fn lane(&self, l: usize) -> Quat {
        Quat::from_xyzw(
            self.x.to_array()[l],
            self.y.to_array()[l],
            self.z.to_array()[l],
            self.w.to_array()[l],
        )
    }

    /// Each lane divided by its length.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        let len2 = self.x.mul_add(
            self.x,
            self.y
                .mul_add(self.y, self.z.mul_add(self.z, self.w * self.w)),
        );
        let inv = L::ONE / len2.sqrt();
        Self {
            x: self.x * inv,
            y: self.y * inv,
            z: self.z * inv,
            w: self.w * inv,
        }
    }

    /// Lane-wise choice: `mask` lanes (all bits set) from `if_true`, the others from
    /// `if_false`.
    #[inline(always)]
    pub fn select(mask: L, if_true: Self, if_false: Self) -> Self {
        Self {
            x: mask.select(if_true.x, if_false.x),
            y: mask.select(if_true.y, if_false.y),
            z: mask.select(if_true.z, if_false.z),
            w: mask.select(if_true.w, if_false.w),
        }
    }

    /// Each lane's conjugate (its inverse, for a unit quaternion).
    #[inline(always)]
    pub fn conjugate(self) -> Self {
        Self {
            x: L::ZERO - self.x,
            y: L::ZERO - self.y,
            z: L::ZERO - self.z,
            w: self.w,
        }
    }
}

impl<L: Lane> std::ops::Mul for Quatx8<L> {
    type Output = Self;
    /// Hamilton product `self · o` per lane.
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let (a, b) = (self, o);
        Self {
            x: a.w
                .mul_add(b.x, a.x.mul_add(b.w, a.y.mul_sub(b.z, a.z * b.y))),
            y: a.w
                .mul_add(b.y, a.y.mul_add(b.w, a.z.mul_sub(b.x, a.x * b.z))),
            z: a.w
                .mul_add(b.z, a.z.mul_add(b.w, a.x.mul_sub(b.y, a.y * b.x))),
            w: a.w
                .mul_sub(b.w, a.x.mul_add(b.x, a.y.mul_add(b.y, a.z * b.z))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::simd::{WithLanes, on_every_backend};
    use glam::Vec3;

    /// The lanes against glam, lane by lane, with lanes `L`.
    #[derive(Clone)]
    struct MatchGlam;

    impl WithLanes for MatchGlam {
        type Output = ();
        fn run<L: Lane>(self) {
            let vs: [Vec3A; LANES] = std::array::from_fn(|l| {
                Vec3A::new(l as f32, 1.0 - l as f32 * 0.5, 0.25 * l as f32)
            });
            let ws: [Vec3A; LANES] = std::array::from_fn(|l| Vec3A::new(0.5, l as f32, -2.0));
            let qs: [Quat; LANES] = std::array::from_fn(|l| {
                Quat::from_axis_angle(Vec3::new(1.0, l as f32, 2.0).normalize(), 0.3 * l as f32)
            });
            let (v, w, q) = (
                Vec3x8::<L>::from_lanes(vs),
                Vec3x8::from_lanes(ws),
                Quatx8::from_lanes(qs),
            );
            let m = Mat3x8::from_quat(q);
            let product = q * Quatx8::from_lanes(qs.map(|q| q.inverse()));
            for l in 0..LANES {
                assert_eq!(v.to_lanes()[l], vs[l]);
                assert_eq!(v.lane(l), vs[l]);
                assert!(v.cross(w).lane(l).abs_diff_eq(vs[l].cross(ws[l]), 1e-5));
                assert!((v.dot(w).to_array()[l] - vs[l].dot(ws[l])).abs() < 1e-5);
                assert!(m.lane(l).abs_diff_eq(Mat3A::from_quat(qs[l]), 1e-6));
                assert_eq!(m.to_lanes()[l], m.lane(l));
                assert_eq!(q.to_lanes()[l], q.lane(l));
                assert!(m.mul_vec(v).lane(l).abs_diff_eq(qs[l] * vs[l], 1e-5));
                let t = Vec3A::new(0.5, -2.0, 3.0) * l as f32;
                let moved = m.mul_vec_add(v, Vec3x8::<L>::from_lanes([t; LANES]));
                assert!(moved.lane(l).abs_diff_eq(qs[l] * vs[l] + t, 1e-5));
                assert!(product.lane(l).abs_diff_eq(Quat::IDENTITY, 1e-6));
                assert!((v.abs_max().to_array()[l] - vs[l].abs().max_element()).abs() == 0.0);
            }
        }
    }

    #[test]
    fn lanes_match_glam() {
        on_every_backend(MatchGlam);
    }
}

/// Serde for `f32x8` as eight floats (`#[serde(with = "crate::math::lanes::f32x8_serde")]`).
pub mod f32x8_serde {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use wide::f32x8;

    /// Writes the eight lanes.
    pub fn serialize<S: Serializer>(v: &f32x8, s: S) -> Result<S::Ok, S::Error> {
        v.to_array().serialize(s)
    }

    /// Reads eight lanes.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f32x8, D::Error> {
        Ok(f32x8::from(<[f32; 8]>::deserialize(d)?))
    }
}

impl serde::Serialize for Vec3x8 {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        [self.x.to_array(), self.y.to_array(), self.z.to_array()].serialize(s)
    }
}

impl<'de> serde::Deserialize<'de> for Vec3x8 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let [x, y, z] = <[[f32; 8]; 3]>::deserialize(d)?;
        Ok(Self {
            x: f32x8::from(x),
            y: f32x8::from(y),
            z: f32x8::from(z),
        })
    }
}
