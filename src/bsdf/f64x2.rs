//! Two f64 lanes ([`F64x2`]) for the flat evaluator's hot arithmetic: SSE2
//! on x86-64 (part of its baseline, so no runtime detection), plain arrays
//! elsewhere. Every operation is the IEEE one lane by lane (no
//! fused multiply-add), so results are bit-identical to scalar code doing
//! the same operations in the same order.

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod imp {
    // SAFETY (every `unsafe` block below): the blocks call SSE2 intrinsics
    // on values only (no pointers), and this module is compiled only when
    // the target has SSE2 (`cfg(target_feature = "sse2")`).
    use std::arch::x86_64::*;

    /// Two f64 lanes.
    #[derive(Clone, Copy, Debug)]
    pub struct F64x2(__m128d);

    /// x truncated towards zero (i32::MIN for NaN or out of range): one
    /// `cvttsd2si`, without the saturating checks of `as`.
    #[inline(always)]
    pub fn trunc_i32(x: f64) -> i32 {
        unsafe { _mm_cvttsd_si32(_mm_set_sd(x)) }
    }

    impl F64x2 {
        /// Lanes (a, b).
        #[inline(always)]
        pub fn new(a: f64, b: f64) -> Self {
            unsafe { F64x2(_mm_set_pd(b, a)) }
        }
        /// Both lanes x.
        #[inline(always)]
        pub fn splat(x: f64) -> Self {
            unsafe { F64x2(_mm_set1_pd(x)) }
        }
        /// Lanes (r[0], r[1]).
        #[inline(always)]
        pub fn load_lo(r: &[f64; 4]) -> Self {
            // SAFETY: reads r[0] and r[1], inside the array.
            unsafe { F64x2(_mm_loadu_pd(r.as_ptr())) }
        }
        /// Lanes (r[2], r[3]).
        #[inline(always)]
        pub fn load_hi(r: &[f64; 4]) -> Self {
            // SAFETY: reads r[2] and r[3], inside the array.
            unsafe { F64x2(_mm_loadu_pd(r.as_ptr().add(2))) }
        }
        /// The first lane.
        #[inline(always)]
        pub fn lo(self) -> f64 {
            unsafe { _mm_cvtsd_f64(self.0) }
        }
        /// The second lane.
        #[inline(always)]
        pub fn hi(self) -> f64 {
            unsafe { _mm_cvtsd_f64(_mm_unpackhi_pd(self.0, self.0)) }
        }
        /// Lane-wise square root.
        #[inline(always)]
        pub fn sqrt(self) -> Self {
            unsafe { F64x2(_mm_sqrt_pd(self.0)) }
        }
        /// Lane-wise minimum (`min` of SSE2: the second operand when
        /// either is NaN).
        #[inline(always)]
        pub fn min(self, o: Self) -> Self {
            unsafe { F64x2(_mm_min_pd(self.0, o.0)) }
        }
        /// Lane-wise maximum (the second operand when either is NaN).
        #[inline(always)]
        pub fn max(self, o: Self) -> Self {
            unsafe { F64x2(_mm_max_pd(self.0, o.0)) }
        }
        /// Per lane: `a` where self < o, else `b`.
        #[inline(always)]
        pub fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
            let m = unsafe { _mm_cmplt_pd(self.0, o.0) };
            unsafe { F64x2(_mm_or_pd(_mm_and_pd(m, a.0), _mm_andnot_pd(m, b.0))) }
        }
    }

    macro_rules! op {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl std::ops::$tr for F64x2 {
                type Output = F64x2;
                #[inline(always)]
                fn $f(self, o: F64x2) -> F64x2 {
                    unsafe { F64x2($intr(self.0, o.0)) }
                }
            }
        };
    }
    op!(Add, add, _mm_add_pd);
    op!(Sub, sub, _mm_sub_pd);
    op!(Mul, mul, _mm_mul_pd);
    op!(Div, div, _mm_div_pd);
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
mod imp {
    /// Two f64 lanes.
    #[derive(Clone, Copy, Debug)]
    pub struct F64x2([f64; 2]);

    /// x truncated towards zero (i32::MIN for NaN or out of range, as SSE2).
    #[inline(always)]
    pub fn trunc_i32(x: f64) -> i32 {
        if x > -2147483649.0 && x < 2147483648.0 {
            x as i32
        } else {
            i32::MIN
        }
    }

    impl F64x2 {
        /// Lanes (r[0], r[1]).
        #[inline(always)]
        pub fn load_lo(r: &[f64; 4]) -> Self {
            F64x2([r[0], r[1]])
        }
        /// Lanes (r[2], r[3]).
        #[inline(always)]
        pub fn load_hi(r: &[f64; 4]) -> Self {
            F64x2([r[2], r[3]])
        }
        /// Lanes (a, b).
        #[inline(always)]
        pub fn new(a: f64, b: f64) -> Self {
            F64x2([a, b])
        }
        /// Both lanes x.
        #[inline(always)]
        pub fn splat(x: f64) -> Self {
            F64x2([x, x])
        }
        /// The first lane.
        #[inline(always)]
        pub fn lo(self) -> f64 {
            self.0[0]
        }
        /// The second lane.
        #[inline(always)]
        pub fn hi(self) -> f64 {
            self.0[1]
        }
        /// Lane-wise square root.
        #[inline(always)]
        pub fn sqrt(self) -> Self {
            F64x2(self.0.map(f64::sqrt))
        }
        /// Lane-wise minimum (the second operand when either is NaN, as SSE2).
        #[inline(always)]
        pub fn min(self, o: Self) -> Self {
            let f = |a: f64, b: f64| if a < b { a } else { b };
            F64x2([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
        }
        /// Lane-wise maximum (the second operand when either is NaN, as SSE2).
        #[inline(always)]
        pub fn max(self, o: Self) -> Self {
            let f = |a: f64, b: f64| if a > b { a } else { b };
            F64x2([f(self.0[0], o.0[0]), f(self.0[1], o.0[1])])
        }
        /// Per lane: `a` where self < o, else `b`.
        #[inline(always)]
        pub fn lt_select(self, o: Self, a: Self, b: Self) -> Self {
            let f = |k: usize| if self.0[k] < o.0[k] { a.0[k] } else { b.0[k] };
            F64x2([f(0), f(1)])
        }
    }

    macro_rules! op {
        ($tr:ident, $f:ident, $o:tt) => {
            impl std::ops::$tr for F64x2 {
                type Output = F64x2;
                #[inline(always)]
                fn $f(self, o: F64x2) -> F64x2 {
                    F64x2([self.0[0] $o o.0[0], self.0[1] $o o.0[1]])
                }
            }
        };
    }
    op!(Add, add, +);
    op!(Sub, sub, -);
    op!(Mul, mul, *);
    op!(Div, div, /);
}

pub use imp::{trunc_i32, F64x2};

/// floor(x) as an index for x >= 0 (0 for negative x or NaN): one
/// truncation; x must be below 2^31 (grid and table coordinates are).
#[inline(always)]
pub fn floor_index(x: f64) -> usize {
    trunc_i32(x).max(0) as usize
}

#[cfg(test)]
mod tests {
    use super::F64x2;

    #[test]
    fn lanes_are_the_scalar_operations() {
        let (a, b) = (F64x2::new(1.5, -2.25), F64x2::new(0.3, 7.0));
        let lanes = |v: F64x2| [v.lo(), v.hi()];
        assert_eq!(lanes(a + b), [1.5 + 0.3, -2.25 + 7.0]);
        assert_eq!(lanes(a - b), [1.5 - 0.3, -2.25 - 7.0]);
        assert_eq!(lanes(a * b), [1.5 * 0.3, -2.25 * 7.0]);
        assert_eq!(lanes(a / b), [1.5 / 0.3, -2.25 / 7.0]);
        assert_eq!(lanes(b.sqrt()), [0.3f64.sqrt(), 7.0f64.sqrt()]);
        assert_eq!(lanes(a.min(b)), [0.3, -2.25]);
        assert_eq!(lanes(a.max(b)), [1.5, 7.0]);
        assert_eq!(lanes(a.lt_select(b, a, b)), [0.3, -2.25]);
        assert_eq!(lanes(F64x2::splat(4.0)), [4.0, 4.0]);
        let r = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(lanes(F64x2::load_lo(&r)), [1.0, 2.0]);
        assert_eq!(lanes(F64x2::load_hi(&r)), [3.0, 4.0]);
        for (x, i) in [
            (0.0, 0),
            (0.999, 0),
            (1.0, 1),
            (89.7, 89),
            (-0.5, 0),
            (-3.0, 0),
            (f64::NAN, 0),
        ] {
            assert_eq!(super::floor_index(x), i, "{x}");
        }
        assert_eq!(super::trunc_i32(-2.5), -2);
        assert_eq!(super::trunc_i32(1e300), i32::MIN);
        // NaN: min/max give the second operand (SSE2's rule, both builds).
        let n = F64x2::new(f64::NAN, 1.0);
        assert_eq!(n.max(F64x2::splat(0.0)).lo(), 0.0);
    }
}
