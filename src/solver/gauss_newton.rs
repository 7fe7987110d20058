//! A joint Gauss-Newton (Levenberg-Marquardt) step over every factor at once.
//!
//! AWLS moves one block of factors at a time, so where lobes are blended
//! (several lobes explaining one feature of the data) it crawls along the
//! valley: each block's optimum barely moves the others'. A Gauss-Newton
//! step sees the coupling: it solves (J^T W J + lambda diag) dx = -J^T W r
//! over all parameters (d, s, D, G, F) together, matrix-free by
//! preconditioned conjugate gradients, where one product with J^T W J is
//! one pass over the samples (J v at a sample, then J^T back into the
//! entries its stencils touch). The step is projected back onto the
//! constraints (factors >= 0, masked scales 0, the D cap and monotone tail
//! of the extrapolation) and kept only if it lowers the objective, so the
//! objective stays monotone; a refused step raises lambda.
//!
//! Determinism: every pass sums per-chunk vectors in chunk order (the
//! chunks of [`super::CHUNK`]), so the step does not depend on the thread
//! count.

use super::state::{basis_at, Cache, Factors, State};
use super::{FitOptions, GMethod, CHUNK, MAX_LOBES};
use crate::grid::Weight;
use crate::samples::FitSet;
use rayon::prelude::*;

/// Offsets of each block in the packed parameter vector.
#[derive(Clone, Copy, Debug)]
struct Packing {
    lobes: usize,
    nd: usize,
    ng: usize,
    nf: usize,
}

impl Packing {
    fn of(f: &Factors) -> Self {
        Packing {
            lobes: f.lobes(),
            nd: f.layout.d.len(),
            ng: f.layout.g.len(),
            nf: f.layout.f.len(),
        }
    }
    fn s(&self, m: usize) -> usize {
        3 + 3 * m
    }
    fn d(&self, m: usize) -> usize {
        3 + 3 * self.lobes + m * self.nd
    }
    fn g(&self, m: usize) -> usize {
        self.d(self.lobes) + m * self.ng
    }
    fn f(&self, c: usize) -> usize {
        self.g(self.lobes) + c * self.nf
    }
    fn len(&self) -> usize {
        self.f(3)
    }
    fn pack(&self, f: &Factors) -> Vec<f64> {
        let mut v = Vec::with_capacity(self.len());
        v.extend_from_slice(&f.diffuse);
        for s in &f.s {
            v.extend_from_slice(s);
        }
        for t in f.d.iter().chain(&f.g).chain(&f.f) {
            v.extend_from_slice(t);
        }
        v
    }
    fn unpack(&self, v: &[f64], like: &Factors) -> Factors {
        let mut f = like.clone();
        f.diffuse.copy_from_slice(&v[0..3]);
        for m in 0..self.lobes {
            f.s[m].copy_from_slice(&v[self.s(m)..self.s(m) + 3]);
            f.d[m].copy_from_slice(&v[self.d(m)..self.d(m) + self.nd]);
            f.g[m].copy_from_slice(&v[self.g(m)..self.g(m) + self.ng]);
        }
        for c in 0..3 {
            f.f[c].copy_from_slice(&v[self.f(c)..self.f(c) + self.nf]);
        }
        f
    }
}

/// A sample's partial derivatives of the model value per channel with
/// respect to each factor's interpolated value there.
#[derive(Clone, Copy)]
struct Partials {
    /// d v_C / d s_C^m (= F_C P_m).
    s: [[f64; 3]; MAX_LOBES],
    /// d v_C / d D^m(h).
    d: [[f64; 3]; MAX_LOBES],
    /// d v_C / d G^m(wi).
    gi: [[f64; 3]; MAX_LOBES],
    /// d v_C / d G^m(wo).
    go: [[f64; 3]; MAX_LOBES],
    /// d v_C / d F_C(theta_d).
    f: [f64; 3],
    /// d v_C / d d_C (the diffuse basis).
    b: [f64; 3],
}

#[inline(always)]
fn partials(set: &FitSet, st: &State, j: usize, c: &Cache) -> Partials {
    let f = &st.factors;
    let icc = set.inv_cc[j];
    let mut p = Partials {
        s: [[0.0; 3]; MAX_LOBES],
        d: [[0.0; 3]; MAX_LOBES],
        gi: [[0.0; 3]; MAX_LOBES],
        go: [[0.0; 3]; MAX_LOBES],
        f: [0.0; 3],
        b: [0.0; 3],
    };
    for ch in 0..3 {
        p.b[ch] = basis_at(&st.basis, j, ch);
        for m in 0..f.lobes() {
            let sf = f.s[m][ch] * c.fv[ch] * icc;
            p.s[m][ch] = c.fv[ch] * c.lobe_product(m, icc, crate::model::Masking::Separable);
            p.d[m][ch] = sf * c.gi[m] * c.go[m];
            p.gi[m][ch] = sf * c.dv[m] * c.go[m];
            p.go[m][ch] = sf * c.dv[m] * c.gi[m];
            p.f[ch] += f.s[m][ch] * c.lobe_product(m, icc, crate::model::Masking::Separable);
        }
    }
    p
}

/// Slots of sample j in a stencil table of width `N`.
#[inline(always)]
fn slots<const N: usize>(t: &crate::grid::StencilTable, j: usize) -> (&[u32; N], &[Weight; N]) {
    t.row::<N>(j)
}

/// sum_k w_k v[off + idx_k].
#[inline(always)]
fn dot<const N: usize>(idx: &[u32; N], w: &[Weight; N], v: &[f64], off: usize) -> f64 {
    let mut a = 0.0;
    for k in 0..N {
        a += f64::from(w[k]) * v[off + idx[k] as usize];
    }
    a
}

/// out[off + idx_k] += w_k a.
#[inline(always)]
fn scatter<const N: usize>(idx: &[u32; N], w: &[Weight; N], out: &mut [f64], off: usize, a: f64) {
    for k in 0..N {
        out[off + idx[k] as usize] += f64::from(w[k]) * a;
    }
}

/// out[off + idx_k] += w_k^2 a.
#[inline(always)]
fn scatter_sq<const N: usize>(
    idx: &[u32; N],
    w: &[Weight; N],
    out: &mut [f64],
    off: usize,
    a: f64,
) {
    for k in 0..N {
        let w = f64::from(w[k]);
        out[off + idx[k] as usize] += w * w * a;
    }
}

/// What one pass over the samples accumulates.
#[derive(Clone, Copy)]
enum Pass<'a> {
    /// J^T W r and diag(J^T W J) (two vectors, concatenated).
    GradientDiag,
    /// J^T W J v.
    Product(&'a [f64]),
}

/// One pass over the samples, summed per chunk in chunk order; dispatched
/// once on the stencil widths (the built-in layouts' loops unrolled).
fn pass(set: &FitSet, st: &State, pk: Packing, what: Pass, pre: &[Partials]) -> Vec<f64> {
    match (set.d_st.width, set.f_st.width, set.gi_st.width) {
        (4, 2, 8) => pass_n::<4, 2, 8>(set, st, pk, what, pre),
        (2, 2, 4) => pass_n::<2, 2, 4>(set, st, pk, what, pre),
        _ => unreachable!("step() checks the widths"),
    }
}

/// Whether [`step`] has a pass for this set's stencil widths (the built-in
/// layouts'); on others it makes no step.
fn supported(set: &FitSet) -> bool {
    matches!(
        (set.d_st.width, set.f_st.width, set.gi_st.width),
        (4, 2, 8) | (2, 2, 4)
    )
}

fn pass_n<const WD: usize, const WF: usize, const WG: usize>(
    set: &FitSet,
    st: &State,
    pk: Packing,
    what: Pass,
    pre: &[Partials],
) -> Vec<f64> {
    let n = pk.len();
    let width = match what {
        Pass::GradientDiag => 2 * n,
        Pass::Product(_) => n,
    };
    let chunks = set.len().div_ceil(CHUNK);
    let partial: Vec<Vec<f64>> = (0..chunks)
        .into_par_iter()
        .map(|ck| {
            let mut out = vec![0.0; width];
            for j in ck * CHUNK..((ck + 1) * CHUNK).min(set.len()) {
                sample_terms::<WD, WF, WG>(set, st, pk, what, j, pre, &mut out);
            }
            out
        })
        .collect();
    let mut total = vec![0.0; width];
    for p in partial {
        for (t, v) in total.iter_mut().zip(p) {
            *t += v;
        }
    }
    total
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sample_terms<const WD: usize, const WF: usize, const WG: usize>(
    set: &FitSet,
    st: &State,
    pk: Packing,
    what: Pass,
    j: usize,
    pre: &[Partials],
    out: &mut [f64],
) {
    let c = &st.cache[j];
    let computed;
    let p = match pre.get(j) {
        Some(p) => p,
        None => {
            computed = partials(set, st, j, c);
            &computed
        }
    };
    let w = set.w[j];
    let lobes = pk.lobes;
    let (di, dw) = slots::<WD>(&set.d_st, j);
    let (ii, iw) = slots::<WG>(&set.gi_st, j);
    let (oi, ow) = slots::<WG>(&set.go_st, j);
    let (fi, fw) = slots::<WF>(&set.f_st, j);
    // u_C: W r (gradient) or W J v (product).
    let u: [f64; 3] = match what {
        Pass::GradientDiag => std::array::from_fn(|ch| w[ch] * c.r[ch]),
        Pass::Product(v) => {
            let mut dv = [0.0; 3];
            for ch in 0..3 {
                dv[ch] = p.b[ch] * v[ch];
            }
            for m in 0..lobes {
                let (dd, dgi, dgo) = (
                    dot(di, dw, v, pk.d(m)),
                    dot(ii, iw, v, pk.g(m)),
                    dot(oi, ow, v, pk.g(m)),
                );
                for ch in 0..3 {
                    dv[ch] += p.s[m][ch] * v[pk.s(m) + ch]
                        + p.d[m][ch] * dd
                        + p.gi[m][ch] * dgi
                        + p.go[m][ch] * dgo;
                }
            }
            for ch in 0..3 {
                dv[ch] += p.f[ch] * dot(fi, fw, v, pk.f(ch));
            }
            std::array::from_fn(|ch| w[ch] * dv[ch])
        }
    };
    let (g, diag) = out.split_at_mut(pk.len());
    let with_diag = matches!(what, Pass::GradientDiag);
    for ch in 0..3 {
        g[ch] += p.b[ch] * u[ch];
        if with_diag {
            diag[ch] += w[ch] * p.b[ch] * p.b[ch];
        }
    }
    for m in 0..lobes {
        let (mut td, mut ti, mut to) = (0.0, 0.0, 0.0);
        let (mut qd, mut qi, mut qo) = (0.0, 0.0, 0.0);
        for ch in 0..3 {
            g[pk.s(m) + ch] += p.s[m][ch] * u[ch];
            td += p.d[m][ch] * u[ch];
            ti += p.gi[m][ch] * u[ch];
            to += p.go[m][ch] * u[ch];
            if with_diag {
                diag[pk.s(m) + ch] += w[ch] * p.s[m][ch] * p.s[m][ch];
                qd += w[ch] * p.d[m][ch] * p.d[m][ch];
                qi += w[ch] * p.gi[m][ch] * p.gi[m][ch];
                qo += w[ch] * p.go[m][ch] * p.go[m][ch];
            }
        }
        scatter(di, dw, g, pk.d(m), td);
        scatter(ii, iw, g, pk.g(m), ti);
        scatter(oi, ow, g, pk.g(m), to);
        if with_diag {
            scatter_sq(di, dw, diag, pk.d(m), qd);
            scatter_sq(ii, iw, diag, pk.g(m), qi);
            scatter_sq(oi, ow, diag, pk.g(m), qo);
        }
    }
    for ch in 0..3 {
        scatter(fi, fw, g, pk.f(ch), p.f[ch] * u[ch]);
        if with_diag {
            scatter_sq(fi, fw, diag, pk.f(ch), w[ch] * p.f[ch] * p.f[ch]);
        }
    }
}

/// Parameters the step may move (masked scales, and G under
/// [`GMethod::Fixed`], stay).
fn free_mask(pk: Packing, opts: &FitOptions) -> Vec<bool> {
    let mut free = vec![true; pk.len()];
    for m in 0..pk.lobes {
        for ch in 0..3 {
            free[pk.s(m) + ch] = opts.channel_mask[m][ch];
        }
        if opts.g_method == GMethod::Fixed {
            free[pk.g(m)..pk.g(m) + pk.ng].fill(false);
        }
    }
    free
}

/// The Levenberg-Marquardt damping state carried between sweeps.
#[derive(Clone, Copy, Debug)]
pub struct Damping {
    /// lambda: the step solves (H + lambda diag(H)) dx = -g.
    pub lambda: f64,
}

impl Default for Damping {
    fn default() -> Self {
        Damping { lambda: 1e-3 }
    }
}

/// Sets of at most this many samples keep every sample's partials for the
/// step's passes (336 bytes a sample: 34 MB at the limit; a 1/32 MERL
/// level holds ~35 k samples).
const PRECOMPUTE_LIMIT: usize = 100_000;
/// Fractions of the step tried in turn.
const STEP_LENGTHS: [f64; 3] = [1.0, 0.5, 0.25];

/// What a step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Whether a step was kept.
    pub accepted: bool,
    /// The damping it was kept (or last refused) with.
    pub lambda: f64,
    /// Passes over the samples it took.
    pub passes: usize,
}

/// One damped Gauss-Newton step from the current factors (whose caches
/// must be fresh), kept only if the objective `e` falls; returns the new
/// objective. `project` maps a trial onto the constraints. On refusal the
/// factors and caches are as before.
pub(crate) fn step(
    set: &FitSet,
    st: &mut State,
    opts: &FitOptions,
    e: f64,
    damping: &mut Damping,
    project: &dyn Fn(&mut Factors, &Factors),
) -> (f64, StepStats) {
    let mut stats = StepStats::default();
    if !supported(set) {
        return (e, stats);
    }
    let pk = Packing::of(&st.factors);
    let n = pk.len();
    // The partials depend on the current factors only, so on a set small
    // enough (a coarse level) they are computed once for every pass.
    let pre: Vec<Partials> = if set.len() <= PRECOMPUTE_LIMIT {
        (0..set.len())
            .into_par_iter()
            .map(|j| partials(set, st, j, &st.cache[j]))
            .collect()
    } else {
        Vec::new()
    };
    let gd = pass(set, st, pk, Pass::GradientDiag, &pre);
    let (grad, diag) = gd.split_at(n);
    let x0 = pk.pack(&st.factors);
    // Active set: a parameter at its bound 0 that the gradient pushes
    // further down stays there (a projected Newton step), so the step is
    // not spoilt by clamping.
    let mut free = free_mask(pk, opts);
    for k in 0..n {
        if x0[k] <= 0.0 && grad[k] > 0.0 {
            free[k] = false;
        }
    }
    let top = diag.iter().cloned().fold(0.0, f64::max);
    let current = st.factors.clone();
    stats.passes = 1;
    let lambda = damping.lambda;
    stats.lambda = lambda;
    // (H + lambda diag + mu) dx = -g on the free parameters, Jacobi-
    // preconditioned CG; mu keeps entries without data at dx = 0.
    let mu = 1e-12 * top;
    let m_inv: Vec<f64> = (0..n)
        .map(|k| {
            if free[k] {
                1.0 / (diag[k] * (1.0 + lambda) + mu)
            } else {
                0.0
            }
        })
        .collect();
    let mut x = vec![0.0; n];
    let mut r: Vec<f64> = (0..n)
        .map(|k| if free[k] { -grad[k] } else { 0.0 })
        .collect();
    let mut z: Vec<f64> = r.iter().zip(&m_inv).map(|(a, b)| a * b).collect();
    let mut p = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let rz0 = rz;
    for _ in 0..opts.gauss_newton_cg {
        if !(rz > 1e-10 * rz0) {
            break;
        }
        let mut hp = pass(set, st, pk, Pass::Product(&p), &pre);
        stats.passes += 1;
        for k in 0..n {
            hp[k] = if free[k] {
                hp[k] + (lambda * diag[k] + mu) * p[k]
            } else {
                0.0
            };
        }
        let php: f64 = p.iter().zip(&hp).map(|(a, b)| a * b).sum();
        if !(php > 0.0) {
            break;
        }
        let a = rz / php;
        for k in 0..n {
            x[k] += a * p[k];
            r[k] -= a * hp[k];
            z[k] = r[k] * m_inv[k];
        }
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let b = rz_new / rz;
        rz = rz_new;
        for k in 0..n {
            p[k] = z[k] + b * p[k];
        }
    }
    // The full step, then shorter ones (one pass each): kept at the first
    // that lowers the objective.
    for (t, &len) in STEP_LENGTHS.iter().enumerate() {
        let trial: Vec<f64> = x0
            .iter()
            .zip(&x)
            .map(|(a, d)| (a + len * d).max(0.0))
            .collect();
        st.factors = pk.unpack(&trial, &current);
        project(&mut st.factors, &current);
        let e_trial = st.refresh_objective(set);
        stats.passes += 1;
        if e_trial < e {
            damping.lambda = if t == 0 {
                (lambda * 0.3).max(1e-6)
            } else {
                (lambda * 2.0).min(1e4)
            };
            stats.accepted = true;
            return (e_trial, stats);
        }
    }
    damping.lambda = (lambda * 8.0).min(1e4);
    st.factors = current;
    st.refresh(set);
    (e, stats)
}
