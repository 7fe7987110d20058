//! The factor model as a [`Bsdf`]: the model's own value
//! ([`Model::eval`], the one evaluator) with a tabulated importance
//! sampler.
//!
//! [`NpfBxdf`] wraps a [`Model`] with tables built once: per specular lobe
//! a piecewise-constant distribution of the half vector in
//! `t = sin^2 theta_h` proportional to `D^m(theta_h)` (so the half-vector
//! density per solid angle is proportional to `D^m cos theta_h`), and the
//! lobe-selection probabilities at 16 view angles.

// `!(x > 0.0)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::{cosine_hemisphere, reflect, unit, Bsdf, BsdfError, BsdfSample, Component};
use crate::model::Model;
use crate::sampling::PiecewiseConstant;
use npf_data_loaders::geometry::{Angles, Vec3};
use std::f64::consts::{FRAC_PI_2, PI};

/// Sub-cells per D-axis interval in the half-vector tables: 4 x 90 = 360
/// cells per lobe for the default layout.
pub const SUBCELLS: usize = 4;
/// View angles at which the lobe-selection probabilities are tabulated,
/// theta_o = k / (VIEW_NODES - 1) * VIEW_MAX_DEG, linear in between.
pub const VIEW_NODES: usize = 16;
const VIEW_MAX_DEG: f64 = 89.0;
/// Every component with mass is chosen with at least this probability
/// (before renormalisation), so the mixture pdf covers all of f.
pub const SELECTION_FLOOR: f64 = 0.01;
/// Strata in u of the albedo quadrature behind the selection (twice as many
/// in phi_h): 48 puts five nodes inside a lobe of GGX roughness 0.02.
const ALBEDO_GRID: usize = 48;
/// Rec. 709 luminance, which weighs the three channels into one selection.
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// 4-point Gauss-Legendre nodes on [-1, 1] (the tests' quadratures use them too).
pub const GL4_X: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];
/// 4-point Gauss-Legendre weights.
pub const GL4_W: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];

/// A model with its sampling tables (built once by [`NpfBxdf::new`]).
#[derive(Clone, Debug)]
pub struct NpfBxdf {
    model: Model,
    /// Half-vector distribution in t = sin^2 theta_h per lobe; `None` for a
    /// lobe without mass (D or s all zero), which is never chosen.
    lobes: Vec<Option<PiecewiseConstant>>,
    /// Selection probabilities, VIEW_NODES rows of (1 + lobes): diffuse first.
    selection: Vec<f64>,
    /// The 2-D sampler of an anisotropic model (which then has no 1-D tables).
    aniso: Option<super::anisotropic::AnisoSampler>,
}

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn luminance(v: [f64; 3]) -> f64 {
    v[0] * LUMINANCE[0] + v[1] * LUMINANCE[1] + v[2] * LUMINANCE[2]
}

fn view_angle(k: usize) -> f64 {
    (k as f64 / (VIEW_NODES - 1) as f64 * VIEW_MAX_DEG).to_radians()
}

/// Half vector of (wi, wo) and sin^2 of its polar angle; None when wi = -wo.
#[inline]
fn half_vector(wi: Vec3, wo: Vec3) -> Option<(Vec3, f64)> {
    let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let n2 = dot(s, s);
    if !(n2 > 0.0) {
        return None;
    }
    let inv = 1.0 / n2.sqrt();
    let h = [s[0] * inv, s[1] * inv, s[2] * inv];
    let t = ((s[0] * s[0] + s[1] * s[1]) / n2).min(1.0);
    Some((h, t))
}

impl NpfBxdf {
    /// Builds the tables. The model is validated first (a model read from a
    /// file already is), so a bad model is an error, never a panic.
    pub fn new(model: Model) -> Result<Self, BsdfError> {
        model.validate().map_err(BsdfError::InvalidModel)?;
        if !model.layout.is_isotropic() {
            let aniso = Some(super::anisotropic::AnisoSampler::new(&model));
            let lobes = vec![None; model.lobes.len()];
            return Ok(NpfBxdf { model, lobes, selection: Vec::new(), aniso });
        }
        let lobes = model
            .lobes
            .iter()
            .map(|lobe| {
                if lobe.s.iter().all(|&s| s <= 0.0) {
                    return None;
                }
                half_vector_distribution(&model, &lobe.d, &lobe.g)
            })
            .collect();
        let mut bxdf = NpfBxdf {
            model,
            lobes,
            selection: Vec::new(),
            aniso: None,
        };
        bxdf.selection = bxdf.selection_table();
        Ok(bxdf)
    }

    /// The model the tables were built for.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Number of mixture components: diffuse plus one per lobe.
    pub fn components(&self) -> usize {
        1 + self.model.lobes.len()
    }

    /// Bytes of the sampling tables (half-vector distributions as f64 edges,
    /// cdf and densities, plus the selection table).
    pub fn table_bytes(&self) -> usize {
        self.lobes
            .iter()
            .flatten()
            .map(PiecewiseConstant::table_bytes)
            .sum::<usize>()
            + 8 * self.selection.len()
    }

    /// The half-vector distribution of lobe m in t = sin^2 theta_h.
    pub fn lobe_distribution(&self, m: usize) -> Option<&PiecewiseConstant> {
        self.lobes.get(m).and_then(Option::as_ref)
    }

    fn has_diffuse(&self) -> bool {
        self.model.diffuse.iter().any(|&d| d > 0.0)
    }

    /// Component estimates of the directional albedo (luminance) at
    /// theta_o: exact for the diffuse term, by the one albedo quadrature
    /// ([`super::half_vector_quadrature`], coarse: ALBEDO_GRID strata in u)
    /// for the lobes, all lobes in one pass through [`Model::lobe_terms`].
    fn albedo_estimates(&self, theta_o: f64) -> Vec<f64> {
        let lobes = self.model.lobes.len();
        let a = super::half_vector_quadrature(
            theta_o,
            ALBEDO_GRID,
            2 * ALBEDO_GRID,
            lobes,
            |wo, wi, w, acc| {
                self.model
                    .lobe_terms(&Angles::from_directions(wi, wo), |m, t| {
                        acc[m] += luminance(t).max(0.0) * w;
                    });
            },
        );
        std::iter::once(luminance(self.model.diffuse.map(f64::from)) * PI)
            .chain(a)
            .collect()
    }

    fn selection_table(&self) -> Vec<f64> {
        let nc = self.components();
        let present: Vec<bool> = (0..nc)
            .map(|c| {
                if c == 0 {
                    self.has_diffuse()
                } else {
                    self.lobes[c - 1].is_some()
                }
            })
            .collect();
        let count = present.iter().filter(|&&p| p).count();
        let mut table = Vec::with_capacity(VIEW_NODES * nc);
        for k in 0..VIEW_NODES {
            let a = self.albedo_estimates(view_angle(k));
            let a: Vec<f64> = a
                .iter()
                .zip(&present)
                .map(|(&a, &p)| if p && a.is_finite() { a.max(0.0) } else { 0.0 })
                .collect();
            let total: f64 = a.iter().sum();
            let mut p: Vec<f64> = (0..nc)
                .map(|c| {
                    if !present[c] {
                        0.0
                    } else if total > 0.0 {
                        (a[c] / total).max(SELECTION_FLOOR)
                    } else {
                        1.0 / count as f64
                    }
                })
                .collect();
            let sum: f64 = p.iter().sum();
            if sum > 0.0 {
                p.iter_mut().for_each(|v| *v /= sum);
            }
            table.extend(p);
        }
        table
    }

    /// Where a view with cos(theta_o) = cos_o falls in the selection table:
    /// the row below and the weight of the row above.
    #[inline]
    fn selection_row(&self, cos_o: f64) -> (usize, f64) {
        let theta = cos_o.clamp(-1.0, 1.0).acos();
        let x = theta.to_degrees() / VIEW_MAX_DEG * (VIEW_NODES - 1) as f64;
        let x = x.clamp(0.0, (VIEW_NODES - 1) as f64);
        let k = (x.floor() as usize).min(VIEW_NODES - 2);
        (k, x - k as f64)
    }

    /// Probability that `sample` uses component c (0 diffuse, 1 + m lobe m)
    /// at a view's table position (see `selection_row`).
    #[inline]
    fn selection_at(&self, (k, w): (usize, f64), c: usize) -> f64 {
        let nc = self.components();
        (1.0 - w) * self.selection[k * nc + c] + w * self.selection[(k + 1) * nc + c]
    }

    /// Selection probabilities at wo: diffuse first, then one per lobe.
    pub fn selection_probabilities(&self, wo: Vec3) -> Vec<f64> {
        if let Some(a) = self.aniso.as_ref().filter(|_| wo[2] > 0.0) {
            return a.selection().to_vec();
        }
        if !(wo[2] > 0.0) {
            return vec![0.0; self.components()];
        }
        let row = self.selection_row(wo[2]);
        (0..self.components())
            .map(|c| self.selection_at(row, c))
            .collect()
    }

    /// BRDF value f(wo, wi) per channel (1/sr): exactly [`Model::eval`]
    /// (zero when either direction is at or below the horizon, never
    /// negative).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        self.model.eval(wo, wi)
    }

    /// Mixture density (per solid angle of wi) with which [`NpfBxdf::sample`]
    /// draws wi given wo; zero when either direction is at or below the
    /// horizon. Usable as the BSDF pdf in multiple importance sampling.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if let Some(a) = &self.aniso {
            return a.pdf(wo, wi);
        }
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        let row = self.selection_row(wo[2]);
        let mut pdf = 0.0;
        let p_diffuse = self.selection_at(row, 0);
        if p_diffuse > 0.0 {
            pdf += p_diffuse * wi[2] / PI;
        }
        let Some((h, t)) = half_vector(wi, wo) else {
            return pdf;
        };
        let wo_h = dot(wo, h);
        for (m, dist) in self.lobes.iter().enumerate() {
            if let Some(dist) = dist {
                let p = self.selection_at(row, m + 1);
                if p > 0.0 {
                    pdf += p * lobe_pdf(dist, t, h[2], wo_h);
                }
            }
        }
        pdf
    }

    /// Draws wi for wo: `u_lobe` picks the component, `u` (two numbers in
    /// [0, 1)) the direction within it. See [`BxdfSample`] for draws that
    /// leave the hemisphere.
    pub fn sample(&self, wo: Vec3, u_lobe: f64, u: [f64; 2]) -> BsdfSample {
        if let Some(a) = &self.aniso {
            return a.sample(&self.model, wo, u_lobe, u);
        }
        if !(wo[2] > 0.0) {
            return BsdfSample::lost([0.0, 0.0, 1.0], Component::Diffuse);
        }
        let nc = self.components();
        let row = self.selection_row(wo[2]);
        let mut component = None;
        let mut acc = 0.0;
        let mut last = None;
        for c in 0..nc {
            let p = self.selection_at(row, c);
            if p <= 0.0 {
                continue;
            }
            last = Some(c);
            acc += p;
            if u_lobe < acc {
                component = Some(c);
                break;
            }
        }
        let Some(c) = component.or(last) else {
            return BsdfSample::lost([0.0, 0.0, 1.0], Component::Diffuse);
        };
        let (wi, component) = if c == 0 {
            (cosine_hemisphere(u), Component::Diffuse)
        } else {
            let m = c - 1;
            let dist = self.lobes[m].as_ref().expect("selected lobes have tables");
            match sample_half_vector(dist, wo, u) {
                Some(wi) => (wi, Component::Lobe(m)),
                None => {
                    let wi = reflect_raw(dist, wo, u);
                    return BsdfSample::lost(wi, Component::Lobe(m));
                }
            }
        };
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0) || !(wi[2] > 0.0) {
            return BsdfSample::lost(wi, component);
        }
        BsdfSample::new(wi, self.eval(wo, wi), pdf, component)
    }

    /// Probability that [`NpfBxdf::sample`] returns a draw below the
    /// horizon for this wo (mass of the mixture outside the upper
    /// hemisphere), by Gauss-Legendre quadrature over each table cell of
    /// the closed-form azimuthal fraction.
    pub fn lost_mass(&self, wo: Vec3) -> f64 {
        if let Some(a) = &self.aniso {
            return a.lost_mass(wo, 512);
        }
        if !(wo[2] > 0.0) {
            return 1.0;
        }
        let cos_o = wo[2].min(1.0);
        let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let row = self.selection_row(cos_o);
        if (0..self.components()).all(|c| self.selection_at(row, c) <= 0.0) {
            // Nothing to draw from (no diffuse term, no lobe with mass).
            return 1.0;
        }
        let mut lost = 0.0;
        for (m, dist) in self.lobes.iter().enumerate() {
            let Some(dist) = dist else { continue };
            let p = self.selection_at(row, m + 1);
            if p <= 0.0 {
                continue;
            }
            let e = dist.edges();
            let mut lobe_lost = 0.0;
            for i in 0..dist.cells() {
                let prob = dist.cell_probability(i);
                if prob == 0.0 {
                    continue;
                }
                // Four Gauss points on each of eight slices of the cell.
                let mut frac = 0.0;
                let slices = 8;
                for s in 0..slices {
                    let a = e[i] + (e[i + 1] - e[i]) * s as f64 / slices as f64;
                    let b = e[i] + (e[i + 1] - e[i]) * (s + 1) as f64 / slices as f64;
                    for (x, w) in GL4_X.iter().zip(GL4_W) {
                        let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
                        frac += 0.5 * w / slices as f64 * azimuth_lost_fraction(t, cos_o, sin_o);
                    }
                }
                lobe_lost += prob * frac;
            }
            lost += p * lobe_lost;
        }
        lost
    }
}

/// Fraction of azimuths phi_h for which the reflection of wo (polar angle
/// theta_o) about a half vector with sin^2 theta_h = t falls at or below the
/// horizon: wi_z = 2 (wo.h) cos theta_h - cos theta_o <= 0.
fn azimuth_lost_fraction(t: f64, cos_o: f64, sin_o: f64) -> f64 {
    let sin_h = t.max(0.0).sqrt();
    let cos_h = (1.0 - t).max(0.0).sqrt();
    if cos_h <= 0.0 {
        return 1.0;
    }
    // wo.h = sin_o sin_h cos(phi) + cos_o cos_h; lost iff wo.h <= cos_o / (2 cos_h).
    let rhs = cos_o / (2.0 * cos_h) - cos_o * cos_h;
    let k = sin_o * sin_h;
    if k <= 0.0 {
        return if rhs >= 0.0 { 1.0 } else { 0.0 };
    }
    let c = rhs / k;
    if c >= 1.0 {
        1.0
    } else if c <= -1.0 {
        0.0
    } else {
        1.0 - c.acos() / PI
    }
}

/// Half-vector density of a lobe, converted to wi: p_t(t) cos(theta_h) / pi
/// per solid angle of h, times the reflection Jacobian 1 / (4 |wo.h|).
#[inline]
fn lobe_pdf(dist: &PiecewiseConstant, t: f64, cos_h: f64, wo_h: f64) -> f64 {
    if !(cos_h > 0.0 && wo_h > 0.0) {
        return 0.0;
    }
    dist.pdf(t) * cos_h / PI / (4.0 * wo_h)
}

/// The raw reflection of wo about the half vector drawn from u (possibly
/// below the horizon).
fn reflect_raw(dist: &PiecewiseConstant, wo: Vec3, u: [f64; 2]) -> Vec3 {
    let t = dist.sample(u[0]);
    let (sin_h, cos_h) = (t.sqrt(), (1.0 - t).max(0.0).sqrt());
    let (sp, cp) = (2.0 * PI * u[1]).sin_cos();
    reflect(wo, [sin_h * cp, sin_h * sp, cos_h])
}

/// wi from a half vector drawn from a lobe table; None when it leaves the
/// upper hemisphere (or wo.h <= 0).
#[inline]
fn sample_half_vector(dist: &PiecewiseConstant, wo: Vec3, u: [f64; 2]) -> Option<Vec3> {
    let t = dist.sample(u[0]);
    let (sin_h, cos_h) = (t.sqrt(), (1.0 - t).max(0.0).sqrt());
    let (sp, cp) = (2.0 * PI * u[1]).sin_cos();
    let h = [sin_h * cp, sin_h * sp, cos_h];
    let wo_h = dot(wo, h);
    if !(wo_h > 0.0) {
        return None;
    }
    let k = 2.0 * wo_h;
    let wi = [k * h[0] - wo[0], k * h[1] - wo[1], k * h[2] - wo[2]];
    if wi[2] > 0.0 {
        Some(wi)
    } else {
        None
    }
}

/// Cells whose mass is below this fraction of the lobe's total get none:
/// never drawn, and pdf is zero there (other components still cover them).
pub const NEGLIGIBLE_CELL: f64 = 1e-6;

/// The half-vector table of one lobe: cells of t = sin^2 theta_h whose
/// edges split every interval of the D axis into SUBCELLS parts. Cell i
/// holds
///
///   mass_i = integral over the cell of D(theta_h) B(theta_h) dt
///
/// (4-point Gauss-Legendre), where B in [0, 1] is the bound of
/// G(theta_i) G(theta_o) over the configurations with that half angle,
/// divided by its largest value (see [`g_product_bound`]). With B = 1 the
/// density in t is proportional to D, a half-vector density proportional to
/// D cos theta_h per solid angle (classic D sampling). B only matters where
/// G vanishes: a fitted D can be astronomically large in a far tail where G
/// is ~1e-16 (its product with G G is what the model shows), and sampling
/// D alone would spend the lobe's draws there. Cells below NEGLIGIBLE_CELL
/// of the total are dropped. The table is exactly normalised either way, and
/// pdf is exactly what sample draws.
fn half_vector_distribution(model: &Model, d: &[f32], g: &[f32]) -> Option<PiecewiseConstant> {
    let axis = model.layout.d.theta;
    let end = axis.coord(FRAC_PI_2);
    let cells = (end.ceil() as usize).max(1) * SUBCELLS;
    let mut edges: Vec<f64> = (0..=cells)
        .map(|j| {
            let p = (j as f64 / SUBCELLS as f64).min(end);
            axis.angle_at(p).sin().powi(2)
        })
        .collect();
    edges[0] = 0.0;
    edges[cells] = 1.0;
    edges.dedup_by(|b, a| *b <= *a);
    if edges.len() < 2 {
        return None;
    }
    let bound = g_product_bound(model, g);
    let b_max = bound(0.0);
    if !(b_max > 0.0 && b_max.is_finite()) {
        return None;
    }
    let mut mass = Vec::with_capacity(edges.len() - 1);
    for w in edges.windows(2) {
        let (a, b) = (w[0], w[1]);
        let mut m = 0.0;
        for (x, wt) in GL4_X.iter().zip(GL4_W) {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let theta = t.sqrt().min(1.0).asin();
            let weight = (bound(theta) / b_max).min(1.0);
            m += 0.5 * (b - a) * wt * axis.stencil(theta).apply_f32(d).max(0.0) * weight;
        }
        mass.push(m);
    }
    let total: f64 = mass.iter().sum();
    if total.is_finite() && total > 0.0 {
        for m in mass.iter_mut() {
            if *m < NEGLIGIBLE_CELL * total {
                *m = 0.0;
            }
        }
    }
    PiecewiseConstant::new(edges, &mass)
}

/// The largest |G(theta_i) G(theta_o)| over the configurations with half
/// angle theta_h, on a 1/8-degree grid: the half vector is the geodesic
/// midpoint of wi and wo, so theta_i + theta_o >= 2 theta_h, each at most
/// pi/2. (On the grid, not a strict bound between grid points; it only
/// weights the table, so the sampler stays exact whatever its accuracy.)
fn g_product_bound(model: &Model, g: &[f32]) -> impl Fn(f64) -> f64 {
    const STEPS: usize = 720;
    let step = FRAC_PI_2 / STEPS as f64;
    let gv: Vec<f64> = (0..=STEPS)
        .map(|k| {
            model
                .layout
                .g
                .theta
                .stencil(k as f64 * step)
                .apply_f32(g)
                .abs()
        })
        .collect();
    // suffix[k] = max of gv over [k, STEPS].
    let mut suffix = gv.clone();
    for k in (0..STEPS).rev() {
        suffix[k] = suffix[k].max(suffix[k + 1]);
    }
    // table[s]: the bound when theta_i + theta_o >= s steps.
    let table: Vec<f64> = (0..=2 * STEPS)
        .map(|s| {
            let lo = s.saturating_sub(STEPS);
            (lo..=STEPS)
                .map(|a| gv[a] * suffix[s.saturating_sub(a).min(STEPS)])
                .fold(0.0, f64::max)
        })
        .collect();
    move |theta_h: f64| {
        // Round the sum limit down (a smaller limit gives a larger bound).
        let s = ((2.0 * theta_h / step).floor().max(0.0) as usize).min(2 * STEPS);
        table[s]
    }
}

impl Bsdf for NpfBxdf {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        NpfBxdf::eval(self, wo, wi)
    }

    fn sample(&self, wo: Vec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        Some(NpfBxdf::sample(self, wo, unit(uc), u)).filter(|s| !s.is_lost())
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        NpfBxdf::pdf(self, wo, wi)
    }

    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        self.model.eval_angles(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;

    #[test]
    fn eval_matches_the_model() {
        let b = NpfBxdf::new(known_factor_model(Layout::default(), &[0.1, 0.3])).unwrap();
        for k in 0..50 {
            let wo = npf_data_loaders::geometry::spherical(0.03 * k as f64, 0.1 * k as f64);
            let wi =
                npf_data_loaders::geometry::spherical(0.5 + 0.01 * k as f64, 2.0 + 0.07 * k as f64);
            let (a, m) = (b.eval(wo, wi), b.model().eval(wo, wi));
            for c in 0..3 {
                assert!(
                    (a[c] - m[c]).abs() <= 1e-9 * m[c].abs() + 1e-12,
                    "{a:?} {m:?}"
                );
            }
        }
    }

    #[test]
    fn a_black_model_loses_every_draw() {
        let mut m = known_factor_model(Layout::default(), &[0.1]);
        m.diffuse = [0.0; 3];
        m.lobes[0].s = [0.0; 3];
        let b = NpfBxdf::new(m).unwrap();
        let wo = [0.0, 0.0, 1.0];
        assert!(b.sample(wo, 0.3, [0.3, 0.3]).is_lost());
        assert_eq!(b.pdf(wo, [0.0, 0.6, 0.8]), 0.0);
        assert_eq!(b.lost_mass(wo), 1.0);
        assert_eq!(b.table_bytes(), 8 * VIEW_NODES * 2);
    }

    #[test]
    fn lost_fraction_limits() {
        // Normal view: lost iff theta_h >= 45 degrees.
        assert_eq!(azimuth_lost_fraction(0.4, 1.0, 0.0), 0.0);
        assert_eq!(azimuth_lost_fraction(0.6, 1.0, 0.0), 1.0);
        // Grazing view and a half vector at the normal: wi is the mirror, above.
        let (s, c) = 1.5f64.sin_cos();
        assert_eq!(azimuth_lost_fraction(0.0, c, s), 0.0);
    }
}
