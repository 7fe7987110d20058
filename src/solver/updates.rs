//! Closed-form element updates of D, F, d and s.
//!
//! D and F enter the model linearly. For one table entry x with samples j
//! that read it with interpolation weight omega_j, the model moves by
//! A_jC omega_j dx, so the objective is a parabola in dx with minimum at
//! dx = -sum_j omega_j S_r(j) / sum_j omega_j^2 S_a(j), where
//! S_r = sum_C w_C r_C A_C and S_a = sum_C w_C A_C^2 (summed over the
//! channels that share the entry). Clamping the new value at 0 is then the
//! exact constrained minimum.

use super::gram::{gram_sums, GramInput, MAXK, SIZE};
use super::state::{set_residual, Cache, State};
use super::{chunked_sum, MAX_LOBES};
use crate::nnls::nnls_enumerate;
use crate::samples::{FitSet, Incidence};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Per-sample (S_r, S_a) and accumulated change of the entry's interpolated value.
pub(crate) struct Scratch {
    pub s: Vec<(f64, f64)>,
    pub delta: Vec<f64>,
}

impl Scratch {
    pub fn new(n: usize) -> Self {
        Scratch {
            s: vec![(0.0, 0.0); n],
            delta: vec![0.0; n],
        }
    }
}

/// One Gauss-Seidel pass over the entries of `table`, colour by colour;
/// entries of one colour are solved in parallel. `scratch.s` must hold
/// (S_r, S_a) for every sample; on return `scratch.delta` holds each sample's
/// change of the interpolated value. Entries whose theta index (k / stride;
/// `stride` is the number of phi columns, 1 for a 1-D table) is at least
/// `monotone_from` are kept at most max(previous entry along theta, current
/// value): an interval holding the current value, so the clamped parabola
/// minimum still never raises the objective, and a non-increasing tail stays
/// non-increasing in every phi column.
pub(crate) fn linear_pass(
    inc: &Incidence,
    table: &mut [f64],
    scratch: &mut Scratch,
    monotone_from: usize,
    stride: usize,
) {
    scratch.delta.par_iter_mut().for_each(|d| *d = 0.0);
    for color in &inc.colors {
        let steps: Vec<f64> = color
            .par_iter()
            .map(|&k| {
                let (mut num, mut den) = (0.0, 0.0);
                let r = inc.entries(k);
                for (&j, &om) in inc.sample[r.clone()].iter().zip(&inc.weight[r]) {
                    let (sr, sa) = scratch.s[j as usize];
                    let om = f64::from(om);
                    num += om * sr;
                    den += om * om * sa;
                }
                if den > 0.0 {
                    let kt = k / stride;
                    let upper = if kt >= monotone_from && kt > 0 {
                        table[k - stride].max(table[k])
                    } else {
                        f64::INFINITY
                    };
                    (table[k] - num / den).clamp(0.0, upper) - table[k]
                } else {
                    0.0
                }
            })
            .collect();
        for (&k, &dx) in color.iter().zip(&steps) {
            if dx == 0.0 {
                continue;
            }
            table[k] += dx;
            let r = inc.entries(k);
            for (&j, &om) in inc.sample[r.clone()].iter().zip(&inc.weight[r]) {
                let j = j as usize;
                let om = f64::from(om);
                let sj = &mut scratch.s[j];
                sj.0 += sj.1 * om * dx;
                scratch.delta[j] += om * dx;
            }
        }
    }
}

/// Update D^m. A_jC = s_C^m F_C G^m(theta_i) G^m(theta_o) / (cos cos).
/// `mask` is the lobe's channel mask (masked channels have s = 0).
pub(crate) fn update_d(
    set: &FitSet,
    st: &mut State,
    m: usize,
    scratch: &mut Scratch,
    monotone_from: usize,
    mask: [bool; 3],
) -> bool {
    // A lobe whose scales are all 0 contributes nothing, so D, F and G get
    // no gradient through it and it would stay dead for good (the bilinear
    // trap: s = 0 makes D irrelevant and vice versa). Such a lobe's D is
    // instead fitted afresh to the residual as if s = 1, without changing
    // the model; the next d, s solve switches it on if that helps. Masked
    // channels are always 0, so a lobe is dead when its unmasked s are.
    let dead = st.factors.s[m] == [0.0; 3];
    if dead {
        // Start from D = 0 so the pass fits the residual itself.
        st.factors.d[m].iter_mut().for_each(|v| *v = 0.0);
        st.cache.par_iter_mut().for_each(|c| c.dv[m] = 0.0);
    }
    let s = if dead {
        mask.map(|on| if on { 1.0 } else { 0.0 })
    } else {
        st.factors.s[m]
    };
    let masking = st.factors.masking;
    let coef = |c: &Cache, j: usize| {
        let p = masking.product(c.gi[m], c.go[m]) * set.inv_cc[j];
        [s[0] * c.fv[0] * p, s[1] * c.fv[1] * p, s[2] * c.fv[2] * p]
    };
    fill_scratch(set, &st.cache, scratch, |c, j| coef(c, j), [true; 3]);
    linear_pass(
        &set.d_inc,
        &mut st.factors.d[m],
        scratch,
        monotone_from,
        set.layout.d.n_phi(),
    );
    let delta = &scratch.delta;
    st.cache.par_iter_mut().enumerate().for_each(|(j, c)| {
        let dx = delta[j];
        if dx != 0.0 {
            let a = coef(c, j);
            c.dv[m] += dx;
            if !dead {
                for ch in 0..3 {
                    c.r[ch] += a[ch] * dx;
                }
            }
        }
    });
    dead
}

/// Update F_C for every channel. A_jC = sum_m s_C^m D^m G^m G^m / (cos cos).
/// The channels are independent, so their scratch is filled and applied in
/// one pass each.
pub(crate) fn update_f(set: &FitSet, st: &mut State, scratch: &mut [Scratch; 3]) {
    let lobes = st.factors.lobes();
    let s = st.factors.s.clone();
    let masking = st.factors.masking;
    let coef = |c: &Cache, j: usize| {
        let mut a = [0.0; 3];
        for m in 0..lobes {
            let p = c.lobe_product(m, set.inv_cc[j], masking);
            for ch in 0..3 {
                a[ch] += s[m][ch] * p;
            }
        }
        a
    };
    {
        let [s0, s1, s2] = scratch;
        s0.s.par_iter_mut()
            .zip(s1.s.par_iter_mut())
            .zip(s2.s.par_iter_mut())
            .enumerate()
            .for_each(|(j, ((o0, o1), o2))| {
                let c = &st.cache[j];
                let w = &set.w[j];
                let a = coef(c, j);
                *o0 = (w[0] * c.r[0] * a[0], w[0] * a[0] * a[0]);
                *o1 = (w[1] * c.r[1] * a[1], w[1] * a[1] * a[1]);
                *o2 = (w[2] * c.r[2] * a[2], w[2] * a[2] * a[2]);
            });
    }
    for ch in 0..3 {
        linear_pass(
            &set.f_inc,
            &mut st.factors.f[ch],
            &mut scratch[ch],
            usize::MAX,
            1,
        );
    }
    let [d0, d1, d2] = [&scratch[0].delta, &scratch[1].delta, &scratch[2].delta];
    st.cache.par_iter_mut().enumerate().for_each(|(j, c)| {
        let dx = [d0[j], d1[j], d2[j]];
        if dx != [0.0; 3] {
            let a = coef(c, j);
            for ch in 0..3 {
                c.fv[ch] += dx[ch];
                c.r[ch] += a[ch] * dx[ch];
            }
        }
    });
}

/// S_r and S_a of every sample for coefficients `a` (channels in `mask`).
pub(crate) fn fill_scratch(
    set: &FitSet,
    cache: &[Cache],
    scratch: &mut Scratch,
    a: impl Fn(&Cache, usize) -> [f64; 3] + Sync,
    mask: [bool; 3],
) {
    scratch.s.par_iter_mut().enumerate().for_each(|(j, out)| {
        let c = &cache[j];
        let w = &set.w[j];
        let coef = a(c, j);
        let (mut sr, mut sa) = (0.0, 0.0);
        for ch in 0..3 {
            if mask[ch] {
                sr += w[ch] * c.r[ch] * coef[ch];
                sa += w[ch] * coef[ch] * coef[ch];
            }
        }
        *out = (sr, sa);
    });
}

/// Update (d_C, s_C^1..s_C^M) per channel: the exact non-negative
/// least-squares solution of a tiny system, by enumerating active sets
/// (clamping an unconstrained solution could raise the objective). Lobes
/// masked for a channel are left out of its system and keep s = 0.
pub(crate) fn update_diffuse_and_scales(
    set: &FitSet,
    st: &mut State,
    mask: &[[bool; 3]; MAX_LOBES],
) {
    solve_diffuse_and_scales(set, st, mask);
    recompute_residuals(set, st);
}

/// [`update_diffuse_and_scales`] without the residuals' recomputation: the
/// caller must recompute them (e.g. fused with the gauge's rescaling).
pub(crate) fn solve_diffuse_and_scales(
    set: &FitSet,
    st: &mut State,
    mask: &[[bool; 3]; MAX_LOBES],
) {
    let lobes = st.factors.lobes();
    let k = lobes + 1;
    // Gram matrix and right-hand side per channel: basis b_0 = the diffuse factor, b_m = F D G G/(cc).
    let g = GramInput {
        set,
        cache: &st.cache,
        basis: &st.basis,
        masking: st.factors.masking,
    };
    // The per-sample loop for a lobe count known at compile time (unrolled
    // loops over the Gram matrix; the same arithmetic in the same order).
    fn sums_for<const LOBES: usize>(g: GramInput) -> [f64; SIZE] {
        // The same sums in AVX registers where available (bit-identical).
        #[cfg(target_arch = "x86_64")]
        let avx = super::avx::available();
        chunked_sum(g.set.len(), |range| {
            #[cfg(target_arch = "x86_64")]
            if avx {
                // SAFETY: AVX2 was detected.
                return unsafe { super::avx::gram_sums::<LOBES>(g, range) };
            }
            gram_sums::<LOBES>(g, range)
        })
    }
    let sums: [f64; SIZE] = match lobes {
        1 => sums_for::<1>(g),
        2 => sums_for::<2>(g),
        _ => sums_for::<MAX_LOBES>(g),
    };
    for ch in 0..3 {
        let base = ch * (MAXK * MAXK + MAXK);
        // Basis functions in the system: 0 (diffuse) and each unmasked lobe.
        let active: Vec<usize> = (0..k).filter(|&a| a == 0 || mask[a - 1][ch]).collect();
        let ka = active.len();
        let gram = DMatrix::from_fn(ka, ka, |a, b| {
            let (a, b) = (active[a], active[b]);
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            sums[base + lo * MAXK + hi]
        });
        let rhs = DVector::from_fn(ka, |a, _| sums[base + MAXK * MAXK + active[a]]);
        let current: Vec<f64> = active
            .iter()
            .map(|&a| {
                if a == 0 {
                    st.factors.diffuse[ch]
                } else {
                    st.factors.s[a - 1][ch]
                }
            })
            .collect();
        let x = nnls_enumerate(&gram, &rhs, &current);
        for m in 0..lobes {
            st.factors.s[m][ch] = 0.0;
        }
        for (&a, &v) in active.iter().zip(&x) {
            if a == 0 {
                st.factors.diffuse[ch] = v;
            } else {
                st.factors.s[a - 1][ch] = v;
            }
        }
    }
}

/// r = model - data of every sample from the factors and the cached factor
/// values (after d, s or the diffuse basis changed).
pub(crate) fn recompute_residuals(set: &FitSet, st: &mut State) {
    let f = &st.factors;
    let basis = &st.basis;
    st.cache
        .par_iter_mut()
        .enumerate()
        .for_each(|(j, c)| set_residual(set, f, basis, j, c));
}
