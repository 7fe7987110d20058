//! The per-sample work of one lobe's G pass and the kernels on it: the
//! quartic's terms and sums, a step applied to an entry, and the new G
//! values written back into the caches.

use super::state::{Cache, State};
use crate::samples::FitSet;
use rayon::prelude::*;

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
