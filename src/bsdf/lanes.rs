//! The lane types the flat evaluator's arithmetic is written over
//! ([`Lanes`]): [`F64x2`] (two lanes), [`F64x2x2`] (four lanes as two SSE2
//! pairs, the portable four-lane form) and, on x86-64 with AVX2 detected at
//! run time, [`avx::F64x4`]. Every operation is the IEEE one lane by lane
//! (no fused multiply-add), so one generic routine gives bit-identical
//! values whichever lane type runs it: the batch evaluator (lanes across
//! directions, or across lobes) equals the per-call one exactly.

use super::f64x2::{floor_index, trunc_i32, F64x2};
use std::ops::{Add, Div, Mul, Sub};

/// Lanes of f64 with lane-wise IEEE arithmetic.
pub(crate) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// Every lane x.
    fn splat(x: f64) -> Self;
    /// Lane-wise square root.
    fn sqrt(self) -> Self;
    /// Lane-wise minimum (the second operand when either is NaN, as SSE2).
    fn min(self, o: Self) -> Self;
    /// Lane-wise maximum (the second operand when either is NaN, as SSE2).
    fn max(self, o: Self) -> Self;
    /// Per lane: `a` where self < o, else `b`.
    fn lt_select(self, o: Self, a: Self, b: Self) -> Self;
}

/// Four lanes: loads from and stores to `[f64; 4]`.
pub(crate) trait Lanes4: Lanes {
    /// Lanes (r[0], r[1], r[2], r[3]).
    fn load(r: &[f64; 4]) -> Self;
    /// The four lanes.
    fn to_array(self) -> [f64; 4];
    /// `f64x2::floor_index` of each lane, as f64 (exact).
    fn floor_index(self) -> Self;
    /// Lanes holding whole numbers in [0, 2^31) as integers.
    fn to_u32(self) -> [u32; 4];
}

impl Lanes for F64x2 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        F64x2::splat(x)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F64x2::sqrt(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        F64x2::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        F64x2::max(self, o)
    }
    #[inline(always)]
    fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
        F64x2::lt_select(self, o, a, b)
    }
}

/// One lane: the per-call form of code written over lanes (min, max and
/// the select with SSE2's semantics, so every lane type gives the same
/// values, NaN included).
impl Lanes for f64 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if self < o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if self > o {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
        if self < o {
            a
        } else {
            b
        }
    }
}

/// Four lanes as two [`F64x2`] pairs (lanes 0-1, 2-3): the portable form,
/// and what the per-call evaluator uses for its four lobes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct F64x2x2(pub [F64x2; 2]);

macro_rules! pair_op {
    ($tr:ident, $f:ident) => {
        impl std::ops::$tr for F64x2x2 {
            type Output = F64x2x2;
            #[inline(always)]
            fn $f(self, o: F64x2x2) -> F64x2x2 {
                F64x2x2([self.0[0].$f(o.0[0]), self.0[1].$f(o.0[1])])
            }
        }
    };
}
pair_op!(Add, add);
pair_op!(Sub, sub);
pair_op!(Mul, mul);
pair_op!(Div, div);

impl Lanes for F64x2x2 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        F64x2x2([F64x2::splat(x); 2])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F64x2x2(self.0.map(F64x2::sqrt))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        F64x2x2([self.0[0].min(o.0[0]), self.0[1].min(o.0[1])])
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        F64x2x2([self.0[0].max(o.0[0]), self.0[1].max(o.0[1])])
    }
    #[inline(always)]
    fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
        F64x2x2([
            self.0[0].lt_select(o.0[0], a.0[0], b.0[0]),
            self.0[1].lt_select(o.0[1], a.0[1], b.0[1]),
        ])
    }
}

impl Lanes4 for F64x2x2 {
    #[inline(always)]
    fn load(r: &[f64; 4]) -> Self {
        F64x2x2([F64x2::load_lo(r), F64x2::load_hi(r)])
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 4] {
        [
            self.0[0].lo(),
            self.0[0].hi(),
            self.0[1].lo(),
            self.0[1].hi(),
        ]
    }
    #[inline(always)]
    fn floor_index(self) -> Self {
        Self::load(&self.to_array().map(|x| floor_index(x) as u32 as f64))
    }
    #[inline(always)]
    fn to_u32(self) -> [u32; 4] {
        self.to_array().map(|x| trunc_i32(x) as u32)
    }
}

/// AVX lanes, for code compiled inside a `#[target_feature(enable =
/// "avx2")]` function only (see [`avx::F64x4`]).
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx {
    use super::{Lanes, Lanes4};
    use std::arch::x86_64::*;

    /// Four f64 lanes in one AVX register. Its methods use AVX
    /// instructions unconditionally: they may only run where AVX2 was
    /// detected (`is_x86_feature_detected!`), and are only instantiated in
    /// functions compiled with `target_feature(enable = "avx2")`.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct F64x4(__m256d);

    // SAFETY (every `unsafe` block below): AVX intrinsics on values (and on
    // one `[f64; 4]`, in bounds), run only where AVX2 was detected (the
    // type's contract).
    macro_rules! op {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl std::ops::$tr for F64x4 {
                type Output = F64x4;
                #[inline(always)]
                fn $f(self, o: F64x4) -> F64x4 {
                    unsafe { F64x4($intr(self.0, o.0)) }
                }
            }
        };
    }
    op!(Add, add, _mm256_add_pd);
    op!(Sub, sub, _mm256_sub_pd);
    op!(Mul, mul, _mm256_mul_pd);
    op!(Div, div, _mm256_div_pd);

    impl Lanes for F64x4 {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            unsafe { F64x4(_mm256_set1_pd(x)) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            unsafe { F64x4(_mm256_sqrt_pd(self.0)) }
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            unsafe { F64x4(_mm256_min_pd(self.0, o.0)) }
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            unsafe { F64x4(_mm256_max_pd(self.0, o.0)) }
        }
        #[inline(always)]
        fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
            // SSE2's cmplt is the ordered, signalling less-than.
            unsafe {
                let m = _mm256_cmp_pd::<_CMP_LT_OS>(self.0, o.0);
                F64x4(_mm256_blendv_pd(b.0, a.0, m))
            }
        }
    }

    impl Lanes4 for F64x4 {
        #[inline(always)]
        fn load(r: &[f64; 4]) -> Self {
            unsafe { F64x4(_mm256_loadu_pd(r.as_ptr())) }
        }
        #[inline(always)]
        fn to_array(self) -> [f64; 4] {
            let mut r = [0.0; 4];
            unsafe { _mm256_storeu_pd(r.as_mut_ptr(), self.0) };
            r
        }
        #[inline(always)]
        fn floor_index(self) -> Self {
            // Truncation (i32::MIN for NaN or out of range, as
            // `trunc_i32`), at least 0, back to f64.
            unsafe {
                let i = _mm_max_epi32(_mm256_cvttpd_epi32(self.0), _mm_setzero_si128());
                F64x4(_mm256_cvtepi32_pd(i))
            }
        }
        #[inline(always)]
        fn to_u32(self) -> [u32; 4] {
            let mut r = [0u32; 4];
            unsafe {
                _mm_storeu_si128(r.as_mut_ptr().cast(), _mm256_cvttpd_epi32(self.0));
            }
            r
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<V: Lanes4>() {
        let a = V::load(&[1.5, -2.25, f64::NAN, 4.0]);
        let b = V::load(&[0.3, 7.0, 1.0, 4.0]);
        assert_eq!((a + b).to_array()[..2], [1.5 + 0.3, -2.25 + 7.0]);
        assert_eq!((a - b).to_array()[..2], [1.5 - 0.3, -2.25 - 7.0]);
        assert_eq!((a * b).to_array()[..2], [1.5 * 0.3, -2.25 * 7.0]);
        assert_eq!((a / b).to_array()[..2], [1.5 / 0.3, -2.25 / 7.0]);
        assert_eq!(b.sqrt().to_array()[..2], [0.3f64.sqrt(), 7.0f64.sqrt()]);
        // NaN: min/max give the second operand; lt is false.
        assert_eq!(a.min(b).to_array(), [0.3, -2.25, 1.0, 4.0]);
        assert_eq!(a.max(b).to_array(), [1.5, 7.0, 1.0, 4.0]);
        assert_eq!(a.lt_select(b, a, b).to_array()[..3], [0.3, -2.25, 1.0]);
        assert_eq!(V::splat(2.0).to_array(), [2.0; 4]);
        let x = V::load(&[-3.5, 2.999_999_999, f64::NAN, 1e300]);
        let fi = x.floor_index().to_array();
        let want = [-3.5, 2.999_999_999, f64::NAN, 1e300].map(|v| floor_index(v) as f64);
        assert_eq!(fi, want);
        assert_eq!(fi, [0.0, 2.0, 0.0, 0.0]);
        assert_eq!(V::load(&[0.0, 7.0, 89.0, 3.0]).to_u32(), [0, 7, 89, 3]);
    }

    #[test]
    fn one_lane_has_the_sse2_semantics() {
        let (nan, v) = (f64::NAN, F64x2x2::load(&[1.5, f64::NAN, 1.0, -0.0]));
        let o = F64x2x2::load(&[0.3, 1.0, f64::NAN, 0.0]);
        let (a, b) = (v.to_array(), o.to_array());
        let lanes = |f: &dyn Fn(f64, f64) -> f64| [0, 1, 2, 3].map(|k| f(a[k], b[k]).to_bits());
        let bits = |x: F64x2x2| x.to_array().map(f64::to_bits);
        assert_eq!(lanes(&|x, y| Lanes::min(x, y)), bits(v.min(o)));
        assert_eq!(lanes(&|x, y| Lanes::max(x, y)), bits(v.max(o)));
        assert_eq!(
            lanes(&|x, y| x.lt_select(y, 2.0, nan)),
            bits(v.lt_select(o, F64x2x2::splat(2.0), F64x2x2::splat(nan)))
        );
    }

    #[test]
    fn four_lanes_are_the_scalar_operations() {
        check::<F64x2x2>();
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            fn avx() {
                check::<avx::F64x4>();
            }
            // SAFETY: AVX2 was detected.
            unsafe { avx() };
        }
    }
}
