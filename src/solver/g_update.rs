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
use super::state::{Cache, State};
use super::{chunked_sum, GMethod, CHUNK};
use crate::samples::FitSet;
use rayon::prelude::*;

/// A point list at least this long is split with the partner of a
/// decimated level ([`Duo`]); shorter ones cost less than the hand-off
/// (both halves then run on the caller, with the same sums).
const HAND_OFF_ENTRIES: usize = 512;

/// What one G pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GPassStats {
    /// Control points whose update was applied.
    pub accepted: usize,
    /// Control points left unchanged (no step lowered the objective).
    pub rejected: usize,
    /// The largest (least negative) accepted change of the objective; always < 0.
    pub worst_accepted: f64,
}

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

/// One entry's terms of the quartic's coefficients c1..c4 (see the module
/// notes), added to `acc`; a function, not a closure, so it is inlined
/// into the tight per-point loop.
#[inline(always)]
pub(crate) fn cubic_terms(
    x: &GWork,
    u: crate::grid::Weight,
    v: crate::grid::Weight,
    acc: &mut [f64; 4],
) {
    let (u, v) = (f64::from(u), f64::from(v));
    let p1 = x.gi * v + x.go * u;
    let p2 = u * v;
    acc[0] += 2.0 * x.sr * p1;
    acc[1] += x.sa * p1 * p1 + 2.0 * x.sr * p2;
    acc[2] += 2.0 * x.sa * p1 * p2;
    acc[3] += x.sa * p2 * p2;
}

/// The quartic's coefficient sums over one chunk's entries `(sample, u, v)`.
#[inline(always)]
pub(crate) fn cubic_sums(
    wv: &[GWork],
    sample: &[u32],
    u: &[crate::grid::Weight],
    v: &[crate::grid::Weight],
) -> [f64; 4] {
    // Even and odd entries in separate sums: each sum is a chain of
    // dependent additions, so one chain would wait on the adder's latency,
    // two overlap (a fixed order, so still the same result for any thread
    // count).
    let (mut even, mut odd) = ([0.0; 4], [0.0; 4]);
    let pairs = sample
        .chunks_exact(2)
        .zip(u.chunks_exact(2))
        .zip(v.chunks_exact(2));
    for ((s, u), v) in pairs {
        cubic_terms(&wv[s[0] as usize], u[0], v[0], &mut even);
        cubic_terms(&wv[s[1] as usize], u[1], v[1], &mut odd);
    }
    if sample.len() % 2 == 1 {
        let e = sample.len() - 1;
        cubic_terms(&wv[sample[e] as usize], u[e], v[e], &mut even);
    }
    std::array::from_fn(|i| even[i] + odd[i])
}

/// The step `t` of a control point applied to one of its entries: the
/// sample's G values and S_r move with it.
#[inline(always)]
pub(crate) fn apply_entry(x: &mut GWork, u: crate::grid::Weight, v: crate::grid::Weight, t: f64) {
    let (u, v) = (f64::from(u), f64::from(v));
    let p1 = x.gi * v + x.go * u;
    let p2 = u * v;
    x.sr += x.sa * (p1 * t + p2 * t * t);
    x.gi += u * t;
    x.go += v * t;
}

/// Per-sample state of one lobe's G pass, packed so the per-point loops
/// touch 32 bytes per sample: G(theta_i), G(theta_o), S_r, S_a.
#[derive(Clone, Copy, Default)]
#[repr(C)] // one 32-byte row for the vector kernels (solver::avx)
pub(crate) struct GWork {
    pub(crate) gi: f64,
    pub(crate) go: f64,
    pub(crate) sr: f64,
    pub(crate) sa: f64,
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

/// B_C = s_C D F / (cos cos) of lobe m at sample j: what one unit of the
/// lobe's masking product adds to the sample's value.
#[inline]
pub(crate) fn spec_coef(set: &FitSet, s: [f64; 3], m: usize, c: &Cache, j: usize) -> [f64; 3] {
    let p = c.dv[m] * set.inv_cc[j];
    [s[0] * c.fv[0] * p, s[1] * c.fv[1] * p, s[2] * c.fv[2] * p]
}

/// Fill each sample's G values of lobe m and its S_r, S_a.
pub(crate) fn fill_work(set: &FitSet, st: &State, m: usize, work: &mut Vec<GWork>) {
    let s = st.factors.s[m];
    work.resize(set.len(), GWork::default());
    work.par_iter_mut()
        .zip(&st.cache)
        .enumerate()
        .for_each(|(j, (wk, c))| {
            let b = spec_coef(set, s, m, c, j);
            let w = &set.w[j];
            let (mut sr, mut sa) = (0.0, 0.0);
            for ch in 0..3 {
                sr += w[ch] * c.r[ch] * b[ch];
                sa += w[ch] * b[ch] * b[ch];
            }
            *wk = GWork {
                gi: c.gi[m],
                go: c.go[m],
                sr,
                sa,
            };
        });
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

/// Write the G pass's new G values of lobe m back into the caches, moving
/// each residual by B_C times the change of `product` (the lobe's masking
/// product of the two G values).
pub(crate) fn apply_work(
    set: &FitSet,
    st: &mut State,
    m: usize,
    work: &[GWork],
    product: impl Fn(f64, f64) -> f64 + Sync,
) {
    let s = st.factors.s[m];
    st.cache
        .par_iter_mut()
        .zip(work)
        .enumerate()
        .for_each(|(j, (c, x))| {
            if x.gi != c.gi[m] || x.go != c.go[m] {
                let change = product(x.gi, x.go) - product(c.gi[m], c.go[m]);
                let b = spec_coef(set, s, m, c, j);
                for ch in 0..3 {
                    c.r[ch] += b[ch] * change;
                }
                c.gi[m] = x.gi;
                c.go[m] = x.go;
            }
        });
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
