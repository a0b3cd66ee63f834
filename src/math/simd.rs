//! The eight-lane float the batched kernels compute with, and the run-time choice of
//! its instruction set.
//!
//! The kernels (`lanes.rs`, `rotation.rs`, the batched fits) are written once, generic
//! over [`Lane`], and read as the maths. Two backends implement it:
//! - [`wide::f32x8`], compiled for whatever the build targets (two SSE halves in a
//!   default x86-64 build);
//! - `Avx2` on x86-64: one 256-bit register, fused multiply-adds.
//!
//! Cargo builds for the x86-64 baseline unless whoever builds the program sets a target
//! CPU, so the backend is picked at run time: [`dispatch`] runs a [`WithLanes`] task
//! inside a function compiled for AVX2 and FMA when the CPU has them, and with `f32x8`
//! otherwise. Every `Lane` method is `#[inline(always)]`, so a task's whole kernel is
//! compiled into that function with the 256-bit instructions. A build that already
//! targets AVX2 and FMA picks `Avx2` at compile time.
//!
//! A closure is compiled as a function of its own, without the caller's target
//! features: code that computes with lanes inside a kernel goes in `#[inline(always)]`
//! functions, not closures, or every lane operation in it becomes a call.

use glam::Vec3A;
use std::ops::{Add, BitAnd, Div, Mul, Sub};
use wide::f32x8;

/// Eight `f32` lanes. A comparison gives a mask of the same type: all bits set in the
/// lanes where it holds, zero elsewhere.
pub trait Lane:
    Copy
    + Default
    + std::fmt::Debug
    + Send
    + Sync
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + BitAnd<Output = Self>
    + sealed::Sealed
{
    /// The backend's name, as [`backend`] reports it.
    const NAME: &'static str;
    /// All lanes 0.
    const ZERO: Self;
    /// All lanes 1.
    const ONE: Self;
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// The lanes of `a`.
    fn from_array(a: [f32; 8]) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> [f32; 8];
    /// The stored form's lanes (see [`crate::math::lanes`]: stored data is `f32x8`).
    fn from_stored(v: f32x8) -> Self;
    /// The lanes in the stored form.
    fn to_stored(self) -> f32x8;
    /// `self · m + a`, fused where the backend has FMA.
    fn mul_add(self, m: Self, a: Self) -> Self;
    /// `self · m − s`, fused where the backend has FMA.
    fn mul_sub(self, m: Self, s: Self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Lane-wise maximum; where `rhs` is NaN, `self`.
    fn max(self, rhs: Self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Mask of `self > rhs`.
    fn simd_gt(self, rhs: Self) -> Self;
    /// Mask of `self < rhs`.
    fn simd_lt(self, rhs: Self) -> Self;
    /// Mask of the finite lanes.
    fn is_finite(self) -> Self;
    /// With `self` a mask: `if_true` in its set lanes, `if_false` in the others.
    fn select(self, if_true: Self, if_false: Self) -> Self;
    /// With `self` a mask: whether any lane is set.
    fn any(self) -> bool;
    /// With `self` a mask: whether every lane is set.
    fn all(self) -> bool;
    /// Sine and cosine.
    fn sin_cos(self) -> (Self, Self);
    /// The x, y and z lanes of eight vectors (lane `l` from `v[l]`).
    fn transpose_in(v: [Vec3A; 8]) -> [Self; 3];
    /// Eight vectors from x, y and z lanes: the inverse of [`Lane::transpose_in`].
    fn transpose_out(xyz: [Self; 3]) -> [Vec3A; 8];
}

mod sealed {
    /// Only this crate's backends are lanes (one of them may run AVX instructions).
    pub trait Sealed {}
    impl Sealed for wide::f32x8 {}
    #[cfg(target_arch = "x86_64")]
    impl Sealed for super::avx2::Avx2 {}
}

impl Lane for f32x8 {
    const NAME: &'static str = "portable";
    const ZERO: Self = f32x8::ZERO;
    const ONE: Self = f32x8::ONE;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn from_array(a: [f32; 8]) -> Self {
        f32x8::new(a)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        f32x8::to_array(self)
    }
    #[inline(always)]
    fn from_stored(v: f32x8) -> Self {
        v
    }
    #[inline(always)]
    fn to_stored(self) -> f32x8 {
        self
    }
    #[inline(always)]
    fn mul_add(self, m: Self, a: Self) -> Self {
        f32x8::mul_add(self, m, a)
    }
    #[inline(always)]
    fn mul_sub(self, m: Self, s: Self) -> Self {
        f32x8::mul_sub(self, m, s)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        f32x8::max(self, rhs)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }
    #[inline(always)]
    fn simd_gt(self, rhs: Self) -> Self {
        f32x8::simd_gt(self, rhs)
    }
    #[inline(always)]
    fn simd_lt(self, rhs: Self) -> Self {
        f32x8::simd_lt(self, rhs)
    }
    #[inline(always)]
    fn is_finite(self) -> Self {
        f32x8::is_finite(self)
    }
    #[inline(always)]
    fn select(self, if_true: Self, if_false: Self) -> Self {
        f32x8::select(self, if_true, if_false)
    }
    #[inline(always)]
    fn any(self) -> bool {
        f32x8::any(self)
    }
    #[inline(always)]
    fn all(self) -> bool {
        f32x8::all(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f32x8::sin_cos(self)
    }
    #[inline(always)]
    fn transpose_in(v: [Vec3A; 8]) -> [Self; 3] {
        [v.map(|v| v.x), v.map(|v| v.y), v.map(|v| v.z)].map(f32x8::new)
    }
    #[inline(always)]
    fn transpose_out(xyz: [Self; 3]) -> [Vec3A; 8] {
        let [x, y, z] = xyz.map(f32x8::to_array);
        std::array::from_fn(|l| Vec3A::new(x[l], y[l], z[l]))
    }
}

/// A task that runs with whichever [`Lane`] backend [`dispatch`] picks.
pub trait WithLanes {
    /// What the task returns.
    type Output;
    /// Runs the task with lanes `L`. Implementations should be `#[inline(always)]`, and
    /// so should everything they call that computes with `L` (no closures: see the
    /// module docs), so that the whole kernel is compiled for the backend's
    /// instruction set.
    fn run<L: Lane>(self) -> Self::Output;
}

/// Runs `task` with the fastest backend this CPU has (see the module docs).
#[inline]
pub fn dispatch<T: WithLanes>(task: T) -> T::Output {
    #[cfg(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    ))]
    {
        task.run::<avx2::Avx2>()
    }
    #[cfg(not(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    )))]
    {
        #[cfg(target_arch = "x86_64")]
        if avx2::available() {
            // SAFETY: the CPU has AVX2 and FMA (just checked).
            return unsafe { avx2::run(task) };
        }
        task.run::<f32x8>()
    }
}

/// The backend [`dispatch`] runs on this CPU: `"avx2+fma"` or `"portable"`.
pub fn backend() -> &'static str {
    struct Name;
    impl WithLanes for Name {
        type Output = &'static str;
        fn run<L: Lane>(self) -> &'static str {
            L::NAME
        }
    }
    dispatch(Name)
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Lane;
    use glam::Vec3A;
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, Div, Mul, Sub};
    use wide::f32x8;

    /// Eight lanes in one AVX register.
    ///
    /// Its methods execute AVX2 and FMA instructions, so a value of this type is only
    /// ever made inside [`run`] (or in a build that targets AVX2 and FMA): [`dispatch`]
    /// is the only caller that instantiates kernels with it.
    ///
    /// [`dispatch`]: super::dispatch
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct Avx2(__m256);

    /// Whether this CPU runs [`Avx2`]'s instructions.
    #[cfg_attr(all(target_feature = "avx2", target_feature = "fma"), allow(dead_code))]
    pub(super) fn available() -> bool {
        is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    }

    /// Runs `task` with [`Avx2`] lanes, compiled for AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA ([`available`]).
    #[cfg_attr(all(target_feature = "avx2", target_feature = "fma"), allow(dead_code))]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn run<T: super::WithLanes>(task: T) -> T::Output {
        task.run::<Avx2>()
    }

    /// `[f32; 8]` as a register, for constants.
    const fn from_floats(a: [f32; 8]) -> Avx2 {
        // SAFETY: `__m256` is eight `f32`s, any bits are valid.
        Avx2(unsafe { std::mem::transmute::<[f32; 8], __m256>(a) })
    }

    impl Default for Avx2 {
        fn default() -> Self {
            Self::ZERO
        }
    }

    // SAFETY (every `unsafe` block below): a value of `Avx2` exists only where the CPU
    // has AVX2 and FMA (see the type's docs).
    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Avx2 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, o: Self) -> Self {
                    Self(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_ps);
    binary!(Sub, sub, _mm256_sub_ps);
    binary!(Mul, mul, _mm256_mul_ps);
    binary!(Div, div, _mm256_div_ps);
    binary!(BitAnd, bitand, _mm256_and_ps);

    impl Lane for Avx2 {
        const NAME: &'static str = "avx2+fma";
        const ZERO: Self = from_floats([0.0; 8]);
        const ONE: Self = from_floats([1.0; 8]);
        #[inline(always)]
        fn splat(x: f32) -> Self {
            Self(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn from_array(a: [f32; 8]) -> Self {
            Self(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn from_stored(v: f32x8) -> Self {
            // (`f32x8` is eight contiguous `f32`s aligned to 32 bytes in every build)
            Self(unsafe { _mm256_load_ps((&v as *const f32x8).cast()) })
        }
        #[inline(always)]
        fn to_stored(self) -> f32x8 {
            let mut v = f32x8::ZERO;
            unsafe { _mm256_store_ps((&mut v as *mut f32x8).cast(), self.0) };
            v
        }
        #[inline(always)]
        fn mul_add(self, m: Self, a: Self) -> Self {
            Self(unsafe { _mm256_fmadd_ps(self.0, m.0, a.0) })
        }
        #[inline(always)]
        fn mul_sub(self, m: Self, s: Self) -> Self {
            Self(unsafe { _mm256_fmsub_ps(self.0, m.0, s.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            self & Self(unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)) })
        }
        #[inline(always)]
        fn max(self, rhs: Self) -> Self {
            // `vmaxps` gives its second operand when either is NaN
            let rhs_nan = Self(unsafe { _mm256_cmp_ps::<_CMP_UNORD_Q>(rhs.0, rhs.0) });
            rhs_nan.select(self, Self(unsafe { _mm256_max_ps(self.0, rhs.0) }))
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Self(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn simd_gt(self, rhs: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn simd_lt(self, rhs: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, rhs.0) })
        }
        #[inline(always)]
        fn is_finite(self) -> Self {
            // finite: the exponent is not all ones
            unsafe {
                let exponent = _mm256_set1_epi32(0x7F80_0000);
                let bits = _mm256_and_si256(_mm256_castps_si256(self.0), exponent);
                let infinite_or_nan = _mm256_cmpeq_epi32(bits, exponent);
                Self(_mm256_castsi256_ps(_mm256_xor_si256(
                    infinite_or_nan,
                    _mm256_set1_epi32(-1),
                )))
            }
        }
        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            Self(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, self.0) })
        }
        #[inline(always)]
        fn any(self) -> bool {
            unsafe { _mm256_movemask_ps(self.0) != 0 }
        }
        #[inline(always)]
        fn all(self) -> bool {
            unsafe { _mm256_movemask_ps(self.0) == 0xFF }
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            // (rare: large rotation steps only) the portable backend's polynomial
            let (sin, cos) = f32x8::new(self.to_array()).sin_cos();
            (
                Self::from_array(sin.to_array()),
                Self::from_array(cos.to_array()),
            )
        }
        #[inline(always)]
        fn transpose_in(v: [Vec3A; 8]) -> [Self; 3] {
            #[inline(always)]
            fn pair(lo: Vec3A, hi: Vec3A) -> __m256 {
                unsafe { _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(lo.into()), hi.into()) }
            }
            unsafe {
                // [a_l | a_{l+4}] for l = 0..4, then a 4×4 transpose in each 128-bit half
                let (v0, v1, v2, v3) = (
                    pair(v[0], v[4]),
                    pair(v[1], v[5]),
                    pair(v[2], v[6]),
                    pair(v[3], v[7]),
                );
                let (xy01, zw01) = (_mm256_unpacklo_ps(v0, v1), _mm256_unpackhi_ps(v0, v1));
                let (xy23, zw23) = (_mm256_unpacklo_ps(v2, v3), _mm256_unpackhi_ps(v2, v3));
                [
                    Self(_mm256_shuffle_ps::<0x44>(xy01, xy23)),
                    Self(_mm256_shuffle_ps::<0xEE>(xy01, xy23)),
                    Self(_mm256_shuffle_ps::<0x44>(zw01, zw23)),
                ]
            }
        }
        #[inline(always)]
        fn transpose_out(xyz: [Self; 3]) -> [Vec3A; 8] {
            let [Self(x), Self(y), Self(z)] = xyz;
            #[inline(always)]
            fn lo(v: __m256) -> Vec3A {
                Vec3A::from(unsafe { _mm256_castps256_ps128(v) })
            }
            #[inline(always)]
            fn hi(v: __m256) -> Vec3A {
                Vec3A::from(unsafe { _mm256_extractf128_ps::<1>(v) })
            }
            unsafe {
                let zero = _mm256_setzero_ps();
                // [x y x y] and [z 0 z 0] pairs, then [x y z 0] per lane in each half
                let (xy01, xy23) = (_mm256_unpacklo_ps(x, y), _mm256_unpackhi_ps(x, y));
                let (z01, z23) = (_mm256_unpacklo_ps(z, zero), _mm256_unpackhi_ps(z, zero));
                let v0 = _mm256_shuffle_ps::<0x44>(xy01, z01);
                let v1 = _mm256_shuffle_ps::<0xEE>(xy01, z01);
                let v2 = _mm256_shuffle_ps::<0x44>(xy23, z23);
                let v3 = _mm256_shuffle_ps::<0xEE>(xy23, z23);
                [
                    lo(v0),
                    lo(v1),
                    lo(v2),
                    lo(v3),
                    hi(v0),
                    hi(v1),
                    hi(v2),
                    hi(v3),
                ]
            }
        }
    }
}

/// Runs `task` with every backend this CPU has, portable first (for tests).
#[cfg(test)]
pub(crate) fn on_every_backend<T: WithLanes + Clone>(task: T) -> Vec<T::Output> {
    let mut outputs = vec![task.clone().run::<f32x8>()];
    #[cfg(target_arch = "x86_64")]
    if avx2::available() {
        // SAFETY: the CPU has AVX2 and FMA (just checked).
        outputs.push(unsafe { avx2::run(task) });
    }
    outputs
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Every operation of [`Lane`] on three inputs, as bit patterns.
    #[derive(Clone)]
    struct EveryOperation([[f32; 8]; 3]);

    impl WithLanes for EveryOperation {
        type Output = Vec<[f32; 8]>;
        fn run<L: Lane>(self) -> Self::Output {
            let [a, b, c] = self.0.map(L::from_array);
            let mask = a.simd_gt(b);
            let (sin, cos) = (a / L::splat(1e3)).sin_cos();
            let vectors: [Vec3A; 8] =
                std::array::from_fn(|l| Vec3A::new(self.0[0][l], self.0[1][l], self.0[2][l]));
            let transposed = L::transpose_out(L::transpose_in(vectors));
            let mut out = vec![
                (a + b).to_array(),
                (a - b).to_array(),
                (a * b).to_array(),
                (a / b).to_array(),
                a.abs().to_array(),
                a.max(b).to_array(),
                a.sqrt().to_array(),
                (mask & L::ONE).to_array(),
                (a.simd_lt(b) & L::ONE).to_array(),
                (a.is_finite() & L::ONE).to_array(),
                mask.select(a, c).to_array(),
                [
                    f32::from(u8::from(mask.any())),
                    f32::from(u8::from(mask.all())),
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ],
                sin.to_array(),
                cos.to_array(),
                L::from_stored(f32x8::from(self.0[2]))
                    .to_stored()
                    .to_array(),
                L::transpose_in(vectors)[1].to_array(),
                transposed.map(|v| v.z),
                (L::ZERO + L::splat(2.5)).to_array(),
            ];
            // fused or not, within one rounding of the exact result
            out.push(a.mul_add(b, c).to_array());
            out.push(a.mul_sub(b, c).to_array());
            out
        }
    }

    #[test]
    fn the_backends_agree_operation_by_operation() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let special = [
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
            1e-40,
            1e38,
            -3.5,
        ];
        for round in 0..200 {
            let inputs: [[f32; 8]; 3] = std::array::from_fn(|i| {
                std::array::from_fn(|l| {
                    if (round + i + l) % 5 == 0 {
                        special[(round + 3 * i + l) % special.len()]
                    } else {
                        rng.random_range(-100.0..100.0)
                    }
                })
            });
            let outputs = on_every_backend(EveryOperation(inputs));
            let portable = &outputs[0];
            for other in &outputs[1..] {
                let last = portable.len() - 2;
                for (op, (p, o)) in portable.iter().zip(other).enumerate() {
                    for l in 0..8 {
                        let same =
                            p[l].to_bits() == o[l].to_bits() || (p[l].is_nan() && o[l].is_nan());
                        let close = op >= last && (p[l] - o[l]).abs() <= 1e-6 * p[l].abs().max(1.0);
                        assert!(
                            same || close,
                            "operation {op}, lane {l}: {} vs {} ({inputs:?})",
                            p[l],
                            o[l]
                        );
                    }
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn a_cpu_with_avx2_and_fma_runs_the_avx2_backend() {
        let avx2 = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        let expected = if avx2 { "avx2+fma" } else { "portable" };
        assert_eq!(backend(), expected);
        let outputs = on_every_backend(EveryOperation([[1.0; 8]; 3]));
        assert_eq!(outputs.len(), 1 + usize::from(avx2), "every backend tested");
    }
}
