//! Update of the G control points, one at a time (Gauss-Seidel).
//!
//! G^m(theta) is a Catmull-Rom spline, linear in each control value, so for
//! one control point changed by t a sample's G(theta_i) G(theta_o) becomes
//! alpha beta + P1 t + P2 t^2 with P1 = alpha v + beta u, P2 = u v (u, v: the
//! point's weights at theta_i and theta_o). With B_C = s_C D F / (cos cos),
//! S_r = sum_C w r B and S_a = sum_C w B^2, the change of the objective is
//! exactly the quartic
//!   dE(t) = c1 t + c2 t^2 + c3 t^3 + c4 t^4,
//!   c1 = sum 2 S_r P1, c2 = sum S_a P1^2 + 2 S_r P2, c3 = sum 2 S_a P1 P2, c4 = sum S_a P2^2.
//! Its derivative is a cubic; the update evaluates dE at every real root
//! (found by the `roots` crate) and at the bound (control value 0), keeps the
//! smallest, and applies it only if dE < 0. The quartic is not convex when a
//! sample reads the point through both angles, which is why all roots count.
//! Control points cannot be updated in parallel (any two can share a sample
//! through a (theta_i, theta_o) pair); the sums inside one are parallel.

use super::duo::Duo;
use super::g_work::{apply_entry, apply_work, cubic_sums, fill_work, GPassStats, GWork};
use super::state::State;
use super::{chunked_sum, GMethod, CHUNK};
use crate::samples::FitSet;
use rayon::prelude::*;

/// A point list at least this long is split with the partner of a
/// decimated level ([`Duo`]); shorter ones cost less than the hand-off
/// (both halves then run on the caller, with the same sums).
const HAND_OFF_ENTRIES: usize = 512;

#[inline]
fn quartic(c: &[f64; 4], t: f64) -> f64 {
    (((c[3] * t + c[2]) * t + c[1]) * t + c[0]) * t
}

/// The best step for a control value `x` under the cubic rule.
pub fn best_cubic_step(c: &[f64; 4], x: f64) -> f64 {
    let mut cands: Vec<f64> = Vec::with_capacity(4);
    cands.push(-x);
    match roots::find_roots_cubic(4.0 * c[3], 3.0 * c[2], 2.0 * c[1], c[0]) {
        roots::Roots::No(_) => {}
        r => cands.extend(r.as_ref().iter().copied()),
    }
    let mut best = (0.0, 0.0);
    for t in cands {
        let t = if t.is_finite() { t.max(-x) } else { continue };
        let de = quartic(c, t);
        if de < best.1 {
            best = (t, de);
        }
    }
    best.0
}

/// Golden-section search of the control value over [0, hi].
pub fn best_golden_step(c: &[f64; 4], x: f64, hi: f64) -> f64 {
    let br = crate::golden::golden_section(|v| quartic(c, v - x), 0.0, hi.max(x), 60, 0.0, false);
    let (a, b) = (br.a, br.b);
    let v = 0.5 * (a + b);
    if quartic(c, v - x) < 0.0 {
        v - x
    } else {
        0.0
    }
}

/// Shared mutable access to distinct elements from parallel tasks.
struct Disjoint<'a, T>(&'a [std::cell::UnsafeCell<T>]);
// SAFETY: callers only touch distinct indices from different tasks.
unsafe impl<T: Send> Sync for Disjoint<'_, T> {}
impl<'a, T> Disjoint<'a, T> {
    fn new(v: &'a mut [T]) -> Self {
        // SAFETY: UnsafeCell<T> has the same layout as T, and the exclusive borrow is held for 'a.
        Disjoint(unsafe { &*(v as *mut [T] as *const [std::cell::UnsafeCell<T>]) })
    }
    /// SAFETY: no two concurrent calls may pass the same index.
    #[allow(clippy::mut_from_ref)]
    unsafe fn get(&self, i: usize) -> &mut T {
        &mut *self.0[i].get()
    }
    /// The first element and the length, for the vector kernels.
    #[cfg(target_arch = "x86_64")]
    fn raw(&self) -> (*mut T, usize) {
        (self.0.as_ptr() as *mut T, self.0.len())
    }
}

pub(crate) fn update_g(
    set: &FitSet,
    st: &mut State,
    m: usize,
    method: GMethod,
    work: &mut Vec<GWork>,
    duo: Option<&Duo>,
) -> GPassStats {
    let mut stats = GPassStats {
        worst_accepted: f64::NEG_INFINITY,
        ..Default::default()
    };
    if method == GMethod::Fixed {
        return stats;
    }
    fill_work(set, st, m, work);
    if !st.factors.masking.is_separable() {
        return super::g2_update::g2_points(set, st, m, work, stats);
    }
    let inc = &set.g_inc;
    let golden_hi = 2.0 * st.factors.g[m].iter().cloned().fold(1.0, f64::max);
    // The same sums and steps in AVX registers where available (bit-identical).
    #[cfg(target_arch = "x86_64")]
    let avx = super::avx::available();
    for k in 0..inc.has_data.len() {
        if !inc.has_data[k] {
            continue;
        }
        let range = inc.entries(k);
        let wv = &work[..];
        let sums = |lo: usize, hi: usize| {
            // Slices of the chunk (no per-entry bounds checks on the lists).
            let (sample, u, v) = (&inc.sample[lo..hi], &inc.u[lo..hi], &inc.v[lo..hi]);
            #[cfg(target_arch = "x86_64")]
            if avx {
                // SAFETY: AVX2 was detected.
                return unsafe { super::avx::cubic_sums(wv, sample, u, v) };
            }
            cubic_sums(wv, sample, u, v)
        };
        let c = match duo {
            // A decimated level: the list's two halves (split at its
            // midpoint whichever thread runs them), added first + second.
            Some(duo) => {
                let mid = range.start + range.len() / 2;
                let [a, b] = duo.halves(range.len() >= HAND_OFF_ENTRIES, |h| {
                    if h == 0 {
                        sums(range.start, mid)
                    } else {
                        sums(mid, range.end)
                    }
                });
                std::array::from_fn(|i| a[i] + b[i])
            }
            None => chunked_sum(range.len(), |r| {
                sums(range.start + r.start, range.start + r.end)
            }),
        };
        let x = st.factors.g[m][k];
        let t = match method {
            GMethod::Cubic => best_cubic_step(&c, x),
            GMethod::Golden => best_golden_step(&c, x, golden_hi),
            GMethod::Fixed => unreachable!(),
        };
        let de = quartic(&c, t);
        if t == 0.0 || !(de < 0.0) {
            stats.rejected += 1;
            continue;
        }
        stats.accepted += 1;
        stats.worst_accepted = stats.worst_accepted.max(de);
        st.factors.g[m][k] = x + t;
        // Each sample appears once in a point's list, so the entries touch
        // distinct samples and can be applied in parallel.
        let shared = Disjoint::new(&mut work[..]);
        let apply = |lo: usize, hi: usize| {
            let (sample, u, v) = (&inc.sample[lo..hi], &inc.u[lo..hi], &inc.v[lo..hi]);
            #[allow(unused_mut)]
            let mut k = 0;
            #[cfg(target_arch = "x86_64")]
            if avx {
                // SAFETY: AVX2 was detected; the rows are the work's, the
                // samples distinct (as below) and this task's alone.
                k = unsafe { super::avx::apply_step(shared.raw(), sample, u, v, t) };
            }
            let (sample, u, v) = (&sample[k..], &u[k..], &v[k..]);
            for ((&j, &u), &v) in sample.iter().zip(u).zip(v) {
                // SAFETY: distinct samples within one point's list (see GIncidence::build).
                apply_entry(unsafe { shared.get(j as usize) }, u, v, t);
            }
        };
        let chunks = range.len().div_ceil(CHUNK);
        if let Some(duo) = duo {
            let mid = range.start + range.len() / 2;
            duo.halves(range.len() >= HAND_OFF_ENTRIES, |h| {
                if h == 0 {
                    apply(range.start, mid)
                } else {
                    apply(mid, range.end)
                }
            });
        } else if chunks <= 1 {
            apply(range.start, range.end);
        } else {
            (0..chunks).into_par_iter().for_each(|ci| {
                let lo = range.start + ci * CHUNK;
                apply(lo, (lo + CHUNK).min(range.end));
            });
        }
    }
    apply_work(set, st, m, work, |a, b| a * b);
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_step_is_the_global_minimum_over_the_feasible_range() {
        // Non-convex quartics with two local minima.
        for c in [
            [-1.0, -2.0, 0.5, 1.0],
            [0.3, -3.0, -0.2, 0.9],
            [2.0, 1.0, 0.0, 0.0],
            [-4.0, 1.0, 0.0, 0.0],
        ] {
            for x in [0.0, 0.5, 2.0] {
                let t = best_cubic_step(&c, x);
                assert!(t >= -x);
                let mut grid_best = 0.0f64;
                for i in 0..=40000 {
                    let tt = -x + i as f64 * 1e-3;
                    grid_best = grid_best.min(quartic(&c, tt));
                }
                assert!(
                    quartic(&c, t) <= grid_best + 1e-9,
                    "c={c:?} x={x}: {} vs {grid_best}",
                    quartic(&c, t)
                );
                assert!(quartic(&c, t) <= 0.0);
            }
        }
    }
}
