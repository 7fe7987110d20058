//! Working factors (f64) and the per-sample caches the updates share.

use super::{chunked_sum, chunked_sum_mut, MAX_LOBES};
use crate::model::{DiffuseForm, Layout, Lobe, Masking, Model};
use crate::samples::FitSet;
use rayon::prelude::*;

/// The model's parameters in working precision.
#[derive(Clone, Debug, PartialEq)]
pub struct Factors {
    /// The tables' layout.
    pub layout: Layout,
    /// d_C.
    pub diffuse: [f64; 3],
    /// s_C^m per lobe.
    pub s: Vec<[f64; 3]>,
    /// D^m per lobe.
    pub d: Vec<Vec<f64>>,
    /// G^m per lobe.
    pub g: Vec<Vec<f64>>,
    /// F_C per channel.
    pub f: [Vec<f64>; 3],
    /// How each lobe combines G at the two directions (a structural choice
    /// of the model, like the layout; no update changes it).
    pub masking: Masking,
}

impl Factors {
    /// Number of lobes.
    pub fn lobes(&self) -> usize {
        self.s.len()
    }

    /// The model (parameters rounded to f32).
    pub fn to_model(&self) -> Model {
        let v = |t: &Vec<f64>| t.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        Model {
            layout: self.layout,
            diffuse: self.diffuse.map(|x| x as f32),
            diffuse_form: Default::default(),
            masking: self.masking,
            compensation: None,
            fresnel: [v(&self.f[0]), v(&self.f[1]), v(&self.f[2])],
            lobes: (0..self.lobes())
                .map(|m| Lobe {
                    s: self.s[m].map(|x| x as f32),
                    d: v(&self.d[m]),
                    g: v(&self.g[m]),
                })
                .collect(),
        }
    }

    /// Working factors of a model.
    pub fn from_model(model: &Model) -> Self {
        let v = |t: &Vec<f32>| t.iter().map(|&x| x as f64).collect::<Vec<f64>>();
        Factors {
            layout: model.layout,
            diffuse: model.diffuse.map(f64::from),
            s: model.lobes.iter().map(|l| l.s.map(f64::from)).collect(),
            d: model.lobes.iter().map(|l| v(&l.d)).collect(),
            g: model.lobes.iter().map(|l| v(&l.g)).collect(),
            f: [
                v(&model.fresnel[0]),
                v(&model.fresnel[1]),
                v(&model.fresnel[2]),
            ],
            masking: model.masking,
        }
    }
}

/// Per-sample factor values and residual (model - data), kept in step with
/// the factors by every update.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cache {
    /// D^m at the sample.
    pub dv: [f64; MAX_LOBES],
    /// G^m at the incoming direction.
    pub gi: [f64; MAX_LOBES],
    /// G^m at the outgoing direction.
    pub go: [f64; MAX_LOBES],
    /// F_C at the sample.
    pub fv: [f64; 3],
    /// Residual model - data per channel.
    pub r: [f64; 3],
}

impl Cache {
    /// s_C^m-free specular product of lobe m: D G G / (cos cos) (G2 in
    /// place of G G for height-correlated masking).
    #[inline]
    pub fn lobe_product(&self, m: usize, inv_cc: f64, masking: Masking) -> f64 {
        self.dv[m] * masking.product(self.gi[m], self.go[m]) * inv_cc
    }
}

/// Factors plus their per-sample caches.
pub struct State {
    /// The working factors.
    pub factors: Factors,
    /// One cache per sample.
    pub cache: Vec<Cache>,
    /// The diffuse form the residuals use.
    pub diffuse_form: DiffuseForm,
    /// Its factor b_C per sample (`None`: Lambertian, b = 1).
    pub basis: Option<Vec<[f64; 3]>>,
}

/// b_C of sample j (1 without a basis).
#[inline]
pub(crate) fn basis_at(basis: &Option<Vec<[f64; 3]>>, j: usize, ch: usize) -> f64 {
    basis.as_ref().map_or(1.0, |b| b[j][ch])
}

/// Sample j's residuals r = model - data from the factors and its cached
/// factor values.
#[inline]
pub(crate) fn set_residual(
    set: &FitSet,
    f: &Factors,
    basis: &Option<Vec<[f64; 3]>>,
    j: usize,
    c: &mut Cache,
) {
    // Each lobe's product once, not once per channel (the same values).
    let lobes = f.lobes();
    let mut p = [0.0; MAX_LOBES];
    for (m, p) in p.iter_mut().enumerate().take(lobes) {
        *p = c.lobe_product(m, set.inv_cc[j], f.masking);
    }
    for ch in 0..3 {
        let mut v = f.diffuse[ch] * basis_at(basis, j, ch);
        for (s, p) in f.s.iter().zip(&p) {
            v += s[ch] * c.fv[ch] * p;
        }
        c.r[ch] = v - set.y[j][ch];
    }
}

/// Fills sample j's cache from the factors (factor values, then residuals);
/// generic, so each use is monomorphised and inlined.
trait Fill: Fn(&FitSet, &Factors, &Option<Vec<[f64; 3]>>, usize, &mut Cache) + Sync {}
impl<T: Fn(&FitSet, &Factors, &Option<Vec<[f64; 3]>>, usize, &mut Cache) + Sync> Fill for T {}

/// The stencil widths the refresh dispatches on.
fn widths(set: &FitSet) -> (usize, usize, usize) {
    (set.d_st.width, set.f_st.width, set.gi_st.width)
}

/// [`Fill`] for stencil widths known at compile time (unrolled loops).
#[inline(always)]
fn fill_n<const WD: usize, const WF: usize, const WG: usize>(
    set: &FitSet,
    f: &Factors,
    basis: &Option<Vec<[f64; 3]>>,
    j: usize,
    c: &mut Cache,
) {
    use crate::grid::StencilTable as T;
    let (d, gi, go) = (
        set.d_st.row::<WD>(j),
        set.gi_st.row::<WG>(j),
        set.go_st.row::<WG>(j),
    );
    for m in 0..f.lobes() {
        c.dv[m] = T::apply_row(d, &f.d[m]);
        c.gi[m] = T::apply_row(gi, &f.g[m]);
        c.go[m] = T::apply_row(go, &f.g[m]);
    }
    let fr = set.f_st.row::<WF>(j);
    for ch in 0..3 {
        c.fv[ch] = T::apply_row(fr, &f.f[ch]);
    }
    set_residual(set, f, basis, j, c);
}

/// [`Fill`] for any stencil widths.
#[inline(always)]
fn fill_any(set: &FitSet, f: &Factors, basis: &Option<Vec<[f64; 3]>>, j: usize, c: &mut Cache) {
    for m in 0..f.lobes() {
        c.dv[m] = set.d_st.apply(j, &f.d[m]);
        c.gi[m] = set.gi_st.apply(j, &f.g[m]);
        c.go[m] = set.go_st.apply(j, &f.g[m]);
    }
    for ch in 0..3 {
        c.fv[ch] = set.f_st.apply(j, &f.f[ch]);
    }
    set_residual(set, f, basis, j, c);
}

/// One sample's term of the objective: sum_C w_C r_C^2.
#[inline]
pub(crate) fn squared_error(c: &Cache, w: &[f64; 3]) -> f64 {
    w[0] * c.r[0] * c.r[0] + w[1] * c.r[1] * c.r[1] + w[2] * c.r[2] * c.r[2]
}

impl State {
    /// State with fresh caches.
    pub fn new(set: &FitSet, factors: Factors) -> Self {
        let mut s = State {
            factors,
            cache: vec![Cache::default(); set.len()],
            diffuse_form: DiffuseForm::Lambert,
            basis: None,
        };
        s.refresh(set);
        s
    }

    /// Recompute every cache from the factors (removes incremental drift).
    pub fn refresh(&mut self, set: &FitSet) {
        self.refresh_with::<false>(set);
    }

    /// [`State::refresh`] and then [`State::objective`], in one pass over
    /// the samples (bit-identical to the two calls).
    pub(crate) fn refresh_objective(&mut self, set: &FitSet) -> f64 {
        self.refresh_with::<true>(set) + set.objective_offset
    }

    /// The refresh; with `OBJ`, also the weighted squared residuals' sum
    /// (without the offset), else 0.
    fn refresh_with<const OBJ: bool>(&mut self, set: &FitSet) -> f64 {
        // Dispatch on the stencil widths once, so the per-sample loops are
        // unrolled for the built-in layouts (same arithmetic either way).
        match widths(set) {
            (2, 2, 4) => self.refresh_by::<OBJ>(set, fill_n::<2, 2, 4>),
            (4, 2, 8) => self.refresh_by::<OBJ>(set, fill_n::<4, 2, 8>),
            _ => self.refresh_by::<OBJ>(set, fill_any),
        }
    }

    fn refresh_by<const OBJ: bool>(&mut self, set: &FitSet, fill: impl Fill) -> f64 {
        let f = &self.factors;
        let basis = &self.basis;
        let [e] = chunked_sum_mut(&mut self.cache, |start, chunk| {
            let mut e = 0.0;
            for (i, c) in chunk.iter_mut().enumerate() {
                let j = start + i;
                fill(set, f, basis, j, c);
                if OBJ {
                    e += squared_error(c, &set.w[j]);
                }
            }
            [e]
        });
        e
    }

    /// The model with the state's diffuse form.
    pub fn to_model(&self) -> Model {
        let mut m = self.factors.to_model();
        m.diffuse_form = self.diffuse_form.clone();
        m
    }

    /// Use `form` for the diffuse term: fills the per-sample basis (the
    /// caller recomputes the residuals).
    pub fn set_diffuse_form(&mut self, set: &FitSet, form: DiffuseForm) {
        self.basis = match form {
            DiffuseForm::Lambert => None,
            _ => Some(
                set.dirs
                    .par_iter()
                    .map(|d| form.factor(d[0] as f64, d[1] as f64, d[2] as f64))
                    .collect(),
            ),
        };
        self.diffuse_form = form;
    }

    /// The objective sum_j sum_C w (model - data)^2, including the constant
    /// of merged reciprocal pairs.
    pub fn objective(&self, set: &FitSet) -> f64 {
        let [e] = chunked_sum(set.len(), |range| {
            let mut e = 0.0;
            for j in range {
                e += squared_error(&self.cache[j], &set.w[j]);
            }
            [e]
        });
        e + set.objective_offset
    }
}
