//! The factor model as a [`Bsdf`]: the model's own value
//! ([`Model::eval`], the one evaluator) with a tabulated importance
//! sampler.
//!
//! [`NpfBxdf`] wraps a [`Model`] with tables built once: per specular lobe
//! and per view angle (16 nodes in theta_o) a piecewise-constant 2-D
//! distribution of the half vector in (`t = sin^2 theta_h`, azimuth
//! relative to wo) proportional to the lobe's visible normals,
//! `D^m(theta_h) max(0, wo.h)`, weighted by the lobe's `G^m(theta_i)` and
//! `F(theta_d)` (plus a small share of plain `D` for coverage); and the
//! component-selection probabilities at the same 16 view angles from each
//! component's directional albedo. See docs/sampling.md.

// `!(x > 0.0)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::anisotropic::AnisoSampler;
use super::azimuth::{
    azimuth_cell, azimuth_centre, azimuth_sin_cos, turn_sin_cos_lanes, EDGE_COS, PHI_CELLS,
};
use super::f64x2::floor_index;
use super::flat::{acos_lanes, FlatEval};
use super::hemisphere::{cosine_direction, cosine_hemisphere, unit};
use super::interface::{Bsdf, BsdfError, BsdfSample, Component};
use super::lanes::{Lanes, Lanes4};
use super::quadrature::{half_vector_quadrature, GL4_W, GL4_X};
use super::selection::SELECTION_FLOOR;
use crate::model::Model;
use crate::sampling::{PiecewiseConstant, PiecewiseConstant2D};
use npf_data_loaders::geometry::{Angles, Vec3};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// Sub-cells per D-axis interval in the half-vector tables: 4 x 90 = 360
/// cells per lobe for the default layout.
pub const SUBCELLS: usize = 4;
/// View angles at which the lobe-selection probabilities are tabulated,
/// theta_o = k / (VIEW_NODES - 1) * VIEW_MAX_DEG, linear in between.
pub const VIEW_NODES: usize = 16;
const VIEW_MAX_DEG: f64 = 89.0;
/// Strata in u of the albedo quadrature behind the selection (twice as many
/// in phi_h): 48 puts five nodes inside a lobe of GGX roughness 0.02.
const ALBEDO_GRID: usize = 48;
/// Share of a view table's mass spread as plain D (times the G bound) over
/// every azimuth, whatever the view: the lobe then covers every half vector
/// where D has mass, and weights stay bounded between view nodes.
/// (2% rather than 10%: near-Lambertian fits sample better, 2x lower
/// variance on white-fabric, see docs/sampling.md.)
pub const COVERAGE_SHARE: f64 = 0.02;
/// Candidate shares of the cosine draw blended into a view row's
/// albedo-proportional selection (see `NpfBxdf::defensive_blend`).
const DEFENSIVE_SHARES: [f64; 10] = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 0.9, 0.95, 1.0];
/// Relative gain in the estimated white-furnace variance a blend must
/// reach over the albedo selection to replace it.
const DEFENSIVE_MARGIN: f64 = 0.05;
/// Strata per axis of each component's quadrature draws in that search.
const DEFENSIVE_GRID: usize = 48;
/// Rec. 709 luminance, which weighs the three channels into one selection.
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Components whose interpolated selection probabilities a draw or pdf
/// computes at once ([`Sel`]): the diffuse term and FLAT_LOBES lobes;
/// further lobes are interpolated where used.
const SEL_ROW: usize = 1 + super::flat::FLAT_LOBES;

/// A view's selection-table position (row below, weight of the row above)
/// with the first SEL_ROW components' probabilities there.
#[derive(Clone, Copy, Debug)]
struct Sel {
    at: (usize, f64),
    p: [f64; SEL_ROW],
}

/// A model with its sampling tables (built once by [`NpfBxdf::new`]).
#[derive(Clone, Debug)]
pub struct NpfBxdf {
    model: Model,
    /// The t = sin^2 theta_h cell edges every lobe's tables share (the D
    /// axis's intervals, split into SUBCELLS).
    edges: Vec<f64>,
    /// Per lobe, VIEW_NODES half-vector tables over (t, relative azimuth in
    /// [0, pi]); `None` for a lobe without mass (D or s all zero), which is
    /// never chosen.
    lobes: Vec<Option<Vec<PiecewiseConstant2D>>>,
    /// Selection probabilities, VIEW_NODES rows of (1 + lobes): diffuse
    /// first, each row padded with zeros to `sel_stride` entries.
    selection: Vec<f64>,
    /// Entries per selection row: max(1 + lobes, SEL_ROW), so a draw reads
    /// the first SEL_ROW of two rows at fixed offsets.
    sel_stride: usize,
    /// The 2-D sampler of an anisotropic model (which then has no 1-D tables).
    aniso: Option<AnisoSampler>,
    /// Every lobe's cell densities side by side, for `pdf`: entry
    /// `((view * cells + i) * PHI_CELLS + j) * lobes + m` is
    /// `lobe_table(m, view).cell_density(i, j)` (0 for a lobe without
    /// tables), so one cache line serves all lobes.
    densities: Vec<f64>,
    /// Guide table over u = t^(1/4) (near-uniform in the edges' index):
    /// entry b is the last cell whose lower edge is at most (b / len)^4.
    t_guide: Vec<u32>,
    /// The model flattened for fast evaluation (isotropic, at most
    /// FLAT_LOBES lobes; otherwise eval is `Model::eval`).
    flat: Option<FlatEval>,
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
            let aniso = Some(AnisoSampler::new(&model));
            let lobes = vec![None; model.lobes.len()];
            return Ok(NpfBxdf {
                model,
                edges: Vec::new(),
                lobes,
                selection: Vec::new(),
                sel_stride: 0,
                aniso,
                densities: Vec::new(),
                t_guide: Vec::new(),
                flat: None,
            });
        }
        let edges = t_edges(&model);
        let lobes = (0..model.lobes.len())
            .map(|m| {
                if model.lobes[m].s.iter().all(|&s| s <= 0.0) {
                    return None;
                }
                lobe_tables(&model, m, &edges)
            })
            .collect();
        let mut bxdf = NpfBxdf {
            model,
            edges,
            lobes,
            selection: Vec::new(),
            sel_stride: 0,
            aniso: None,
            densities: Vec::new(),
            t_guide: Vec::new(),
            flat: None,
        };
        bxdf.flat = FlatEval::new(&bxdf.model);
        bxdf.densities = bxdf.fused_densities();
        bxdf.t_guide = t_guide(&bxdf.edges);
        let nc = bxdf.components();
        bxdf.sel_stride = nc.max(SEL_ROW);
        bxdf.selection = bxdf
            .selection_table()
            .chunks(nc)
            .flat_map(|r| {
                r.iter()
                    .copied()
                    .chain(std::iter::repeat(0.0))
                    .take(nc.max(SEL_ROW))
            })
            .collect();
        Ok(bxdf)
    }

    /// The flat evaluator, when the model has one (isotropic, at most
    /// FLAT_LOBES lobes, the plain form); then the model has no
    /// anisotropic sampler either.
    pub(crate) fn flat(&self) -> Option<&FlatEval> {
        self.flat.as_ref()
    }

    /// The model the tables were built for.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Number of mixture components: diffuse plus one per lobe.
    pub fn components(&self) -> usize {
        1 + self.model.lobes.len()
    }

    /// Bytes of the sampling tables (half-vector tables as f64 edges, cdf
    /// and densities, plus the selection table).
    pub fn table_bytes(&self) -> usize {
        self.lobes
            .iter()
            .flatten()
            .flatten()
            .map(PiecewiseConstant2D::table_bytes)
            .sum::<usize>()
            + 8 * (VIEW_NODES * self.components() + self.edges.len() + self.densities.len())
            + 4 * self.t_guide.len()
            + self.flat.as_ref().map_or(0, FlatEval::table_bytes)
    }

    fn fused_densities(&self) -> Vec<f64> {
        let cells = self.edges.len().saturating_sub(1);
        let nl = self.model.lobes.len();
        if self.lobes.iter().all(Option::is_none) {
            return Vec::new();
        }
        let mut out = vec![0.0; VIEW_NODES * cells * PHI_CELLS * nl];
        for (m, tables) in self.lobes.iter().enumerate() {
            let Some(tables) = tables else { continue };
            for (view, table) in tables.iter().enumerate() {
                for i in 0..cells {
                    for j in 0..PHI_CELLS {
                        out[((view * cells + i) * PHI_CELLS + j) * nl + m] =
                            table.cell_density(i, j);
                    }
                }
            }
        }
        out
    }

    /// The t cell holding t in [0, 1): the last i with `edges[i] <= t`
    /// (what a binary search finds), from the guide table.
    #[inline]
    fn t_cell(&self, t: f64) -> usize {
        let g = self.t_guide.len();
        self.t_cell_from(floor_index(t.sqrt().sqrt() * g as f64).min(g - 1), t)
    }

    /// [`NpfBxdf::t_cell`] from its guide entry b (the batch forms b in lanes).
    #[inline(always)]
    fn t_cell_from(&self, b: usize, t: f64) -> usize {
        let n = self.edges.len() - 1;
        let mut i = self.t_guide[b] as usize;
        while i + 1 < n && self.edges[i + 1] <= t {
            i += 1;
        }
        while i > 0 && self.edges[i] > t {
            i -= 1;
        }
        i
    }

    /// The half-vector distribution of lobe m in t = sin^2 theta_h at
    /// normal view (the marginal of its first view table); its edges are
    /// those of every table of the model.
    pub fn lobe_distribution(&self, m: usize) -> Option<&PiecewiseConstant> {
        self.lobe_table(m, 0).map(PiecewiseConstant2D::marginal)
    }

    /// Lobe m's half-vector table at view node k (theta_o = k / 15 * 89
    /// degrees): x = t = sin^2 theta_h, y = |phi_h - phi_o| in [0, pi].
    pub fn lobe_table(&self, m: usize, k: usize) -> Option<&PiecewiseConstant2D> {
        self.lobes.get(m)?.as_ref()?.get(k)
    }

    fn has_diffuse(&self) -> bool {
        // The compensation term is cosine-sampled with the diffuse term.
        self.model.diffuse.iter().any(|&d| d > 0.0) || self.model.compensation.is_some()
    }

    /// Component estimates of the directional albedo (luminance) at
    /// theta_o: exact for the diffuse term, by the one albedo quadrature
    /// ([`super::half_vector_quadrature`], coarse: ALBEDO_GRID strata in u)
    /// for the lobes, all lobes in one pass through [`Model::lobe_terms`].
    fn albedo_estimates(&self, theta_o: f64) -> Vec<f64> {
        let lobes = self.model.lobes.len();
        let a = half_vector_quadrature(
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
        std::iter::once(luminance(self.model.diffuse_albedo(theta_o)))
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
            if present[0] && sum > 0.0 {
                p = self.defensive_blend(k, &p, &present);
            }
            table.extend(p);
        }
        table
    }

    /// The albedo-proportional selection `p` at view node k blended with
    /// the cosine draw, `(1 - a) p + a e_diffuse`, at the share `a` of
    /// DEFENSIVE_SHARES whose white-furnace variance
    /// `integral (lum(f) cos)^2 / pdf - albedo^2` is least by quadrature. Albedo
    /// shares are not variance-optimal when a lobe's own draw is poor (a
    /// broad lobe whose f is shaped by G, F and 1/(cos i cos o) rather
    /// than by D): its weights then blow up where the cosine draw would
    /// keep them bounded. A blend must beat the albedo selection by
    /// DEFENSIVE_MARGIN, so quadrature noise leaves good rows alone.
    fn defensive_blend(&self, k: usize, p: &[f64], present: &[bool]) -> Vec<f64> {
        let nc = self.components();
        let theta = view_angle(k);
        let wo = [theta.sin(), 0.0, theta.cos()];
        // Quadrature points: DEFENSIVE_GRID^2 stratified draws from each
        // present component (the cosine draw and each lobe's node-k
        // table), weighted by the equal-share mixture q of those draws.
        let drawn: Vec<usize> = (0..nc).filter(|&c| present[c]).collect();
        let n = DEFENSIVE_GRID;
        let mut points: Vec<(f64, Vec<f64>)> = Vec::with_capacity(drawn.len() * n * n);
        let mut albedo = 0.0;
        let mut dens = vec![0.0; nc];
        for &c in &drawn {
            for a in 0..n {
                for b in 0..n {
                    let u = [(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64];
                    let Some(wi) = self.component_draw(k, wo, c, u) else {
                        continue;
                    };
                    self.component_densities(k, wo, wi, &mut dens);
                    let q: f64 = drawn.iter().map(|&d| dens[d]).sum::<f64>() / drawn.len() as f64;
                    let f = luminance(self.eval(wo, wi)).max(0.0) * wi[2];
                    if q > 0.0 && f > 0.0 {
                        albedo += f / q;
                        points.push((f * f / q, dens.clone()));
                    }
                }
            }
        }
        // The variance, not the second moment: that is mostly albedo^2
        // on a near-Lambertian row, which no selection changes.
        let count = (drawn.len() * n * n) as f64;
        let albedo = albedo / count;
        let variance = |s: &[f64]| -> f64 {
            let moment: f64 = points
                .iter()
                .map(|(w, d)| {
                    let pdf: f64 = s.iter().zip(d).map(|(s, d)| s * d).sum();
                    if pdf > 0.0 {
                        w / pdf
                    } else {
                        f64::INFINITY
                    }
                })
                .sum();
            moment / count - albedo * albedo
        };
        // Each present lobe keeps SELECTION_FLOOR (renormalised), as in
        // the albedo rows.
        let blend = |a: f64| -> Vec<f64> {
            let mut s: Vec<f64> = (0..nc)
                .map(|c| match c {
                    0 => (1.0 - a) * p[0] + a,
                    _ if present[c] => ((1.0 - a) * p[c]).max(SELECTION_FLOOR),
                    _ => 0.0,
                })
                .collect();
            let sum: f64 = s.iter().sum();
            s.iter_mut().for_each(|v| *v /= sum);
            s
        };
        let base = variance(p);
        let mut best = (base * (1.0 - DEFENSIVE_MARGIN), p.to_vec());
        for &a in &DEFENSIVE_SHARES {
            let s = blend(a);
            let m = variance(&s);
            if m < best.0 {
                best = (m, s);
            }
        }
        best.1
    }

    /// Component c's draw (0 the cosine draw, 1 + m lobe m's node-k table)
    /// from u, None when it leaves the upper hemisphere.
    fn component_draw(&self, k: usize, wo: Vec3, c: usize, u: [f64; 2]) -> Option<Vec3> {
        let wi = if c == 0 {
            cosine_hemisphere(u)
        } else {
            let tables = self.lobes[c - 1].as_ref()?;
            let (sign, v) = if u[1] < 0.5 {
                (1.0, 2.0 * u[1])
            } else {
                (-1.0, (2.0 * u[1] - 1.0).min(1.0))
            };
            let (_, t, j, dv) = tables[k].sample_cells([u[0], v]);
            let r = reflection::<f64>(wo, t, sign, azimuth_centre(j), dv);
            if !(r.wo_h > 0.0) {
                return None;
            }
            r.wi
        };
        (wi[2] > 0.0).then_some(wi)
    }

    /// Each component's own density (per solid angle, before selection)
    /// of wi at view node k: the cosine draw's first, then each lobe's.
    fn component_densities(&self, k: usize, wo: Vec3, wi: Vec3, out: &mut [f64]) {
        out.iter_mut().for_each(|d| *d = 0.0);
        out[0] = wi[2] / PI;
        if self.densities.is_empty() {
            return;
        }
        let Some(jac) = lobe_jacobian(wo, wi) else {
            return;
        };
        let Some((h, t)) = half_vector(wi, wo) else {
            return;
        };
        let nl = self.model.lobes.len();
        let cells = self.edges.len() - 1;
        let (ex, ey) = azimuth_frame(wo);
        let base = ((k * cells + self.t_cell(t)) * PHI_CELLS + azimuth_cell(h, ex, ey)) * nl;
        for m in 0..nl {
            out[1 + m] = self.densities[base + m] * jac;
        }
    }

    /// Where a view with cos(theta_o) = cos_o falls in the selection table:
    /// the row below and the weight of the row above.
    #[inline(always)]
    fn selection_row(&self, cos_o: f64) -> (usize, f64) {
        // The branch-free arccosine (views at random angles would
        // mispredict fdlibm's branches); a cos_o below 0 lands on the last
        // node either way.
        row_at_angle(acos_lanes(cos_o.clamp(0.0, 1.0)))
    }

    /// Probability that `sample` uses component c (0 diffuse, 1 + m lobe m)
    /// at a view's table position (see `selection_row`).
    #[inline]
    fn selection_at(&self, (k, w): (usize, f64), c: usize) -> f64 {
        let st = self.sel_stride;
        (1.0 - w) * self.selection[k * st + c] + w * self.selection[(k + 1) * st + c]
    }

    /// The interpolated selection probabilities of the first SEL_ROW
    /// components at a view's table position, computed once per draw or
    /// pdf (the choice, the diffuse pdf and every lobe's share read them);
    /// the values of `selection_at`, bit for bit.
    #[inline(always)]
    fn selection_row_at(&self, at: (usize, f64)) -> Sel {
        let (k, w) = at;
        let st = self.sel_stride;
        let lo = &self.selection[k * st..k * st + SEL_ROW];
        let hi = &self.selection[(k + 1) * st..(k + 1) * st + SEL_ROW];
        let mut p = [0.0; SEL_ROW];
        for c in 0..SEL_ROW {
            p[c] = (1.0 - w) * lo[c] + w * hi[c];
        }
        Sel { at, p }
    }

    /// Probability of component c at the view of `sel`.
    #[inline(always)]
    fn sel_p(&self, sel: &Sel, c: usize) -> f64 {
        if c < SEL_ROW {
            sel.p[c]
        } else {
            self.selection_at(sel.at, c)
        }
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

    /// BRDF value f(wo, wi) per channel (1/sr): [`Model::eval`]'s value
    /// (zero when either direction is at or below the horizon, never
    /// negative), through the flat copy [`FlatEval`] when the model has
    /// one (the same arithmetic; 1e-9 relative, tested).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        match &self.flat {
            Some(f) => f.eval(wo, wi),
            None => self.model.eval(wo, wi),
        }
    }

    /// The diffuse part of the mixture density at (wo, wi) and, when a lobe
    /// could have drawn wi, what the lobe part needs: the selection-table
    /// position, the half vector h, t = sin^2 theta_h and the Jacobian
    /// `cos theta_h / (4 wo.h)` from the tables' density to solid angle.
    /// None for the whole when wo or wi is at or below the horizon.
    #[inline]
    #[allow(clippy::type_complexity)]
    fn pdf_parts(&self, wo: Vec3, wi: Vec3) -> Option<(f64, Option<(Sel, Vec3, f64, f64)>)> {
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return None;
        }
        let sel = self.selection_row_at(self.selection_row(wo[2]));
        self.pdf_parts_at(wo, wi, &sel)
    }

    /// [`NpfBxdf::pdf_parts`] at a known selection-table position of wo
    /// (wo and wi above the horizon).
    #[inline]
    #[allow(clippy::type_complexity)]
    fn pdf_parts_at(
        &self,
        wo: Vec3,
        wi: Vec3,
        sel: &Sel,
    ) -> Option<(f64, Option<(Sel, Vec3, f64, f64)>)> {
        let pdf = self.diffuse_pdf(wi, sel);
        let lobe = lobe_jacobian(wo, wi)
            .and_then(|jac| half_vector(wi, wo).map(|(h, t)| (*sel, h, t, jac)));
        Some((pdf, lobe))
    }

    /// Mixture density (per solid angle of wi) with which [`NpfBxdf::sample`]
    /// draws wi given wo; zero when either direction is at or below the
    /// horizon. Usable as the BSDF pdf in multiple importance sampling.
    /// (The fused form of [`NpfBxdf::pdf_reference`]: a guide table finds
    /// the t cell, comparisons the azimuth cell, and one row of the fused
    /// density table holds every lobe's density.)
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if let Some(a) = &self.aniso {
            return a.pdf(wo, wi);
        }
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        let sel = self.selection_row_at(self.selection_row(wo[2]));
        self.pdf_at(wo, wi, &sel)
    }

    /// [`NpfBxdf::pdf`] of an isotropic model at a known selection-table
    /// position of wo (wo and wi above the horizon), as `sample` calls it.
    #[inline]
    fn pdf_at(&self, wo: Vec3, wi: Vec3, sel: &Sel) -> f64 {
        let Some((pdf, lobe)) = self.pdf_parts_at(wo, wi, sel) else {
            return 0.0;
        };
        let Some((sel, h, t, jac)) = lobe.filter(|_| !self.densities.is_empty()) else {
            return pdf;
        };
        let i = self.t_cell(t);
        let (ex, ey) = azimuth_frame(wo);
        let j = azimuth_cell(h, ex, ey);
        self.add_lobe_densities(pdf, &sel, (i, j), jac)
    }

    /// The diffuse component's part of the mixture density.
    #[inline]
    fn diffuse_pdf(&self, wi: Vec3, sel: &Sel) -> f64 {
        let p_diffuse = sel.p[0];
        if p_diffuse > 0.0 {
            p_diffuse * wi[2] / PI
        } else {
            0.0
        }
    }

    /// Every lobe's density in cell (i, j) (t cell, azimuth cell) of the
    /// tables at the view node of `sel`.
    #[inline(always)]
    fn density_row(&self, sel: &Sel, (i, j): (usize, usize)) -> &[f64] {
        let nl = self.model.lobes.len();
        let cells = self.edges.len() - 1;
        let base = ((view_node(sel.at) * cells + i) * PHI_CELLS + j) * nl;
        &self.densities[base..base + nl]
    }

    /// `pdf` plus every lobe's part of the mixture density for a half
    /// vector in cell (i, j) (t cell, azimuth cell), added lobe by lobe.
    #[inline(always)]
    fn add_lobe_densities(&self, mut pdf: f64, sel: &Sel, (i, j): (usize, usize), jac: f64) -> f64 {
        let nl = self.model.lobes.len();
        let row = self.density_row(sel, (i, j));
        // The lobes in `sel` first, without branches (a zero density adds
        // an exact 0, as skipping it would), then any further lobes.
        let head = nl.min(SEL_ROW - 1);
        for (m, &d) in row[..head].iter().enumerate() {
            let add = sel.p[m + 1] * d * jac;
            pdf += if d > 0.0 { add } else { 0.0 };
        }
        for (m, &d) in row.iter().enumerate().skip(head) {
            if d > 0.0 {
                pdf += self.selection_at(sel.at, m + 1) * d * jac;
            }
        }
        pdf
    }

    /// [`NpfBxdf::pdf`] computed from the per-lobe tables themselves (a
    /// binary search for the t cell, atan2 for the azimuth cell): the
    /// reference the fused fast path is tested against (same value; only
    /// cells at their exact edges could differ).
    pub fn pdf_reference(&self, wo: Vec3, wi: Vec3) -> f64 {
        if let Some(a) = &self.aniso {
            return a.pdf(wo, wi);
        }
        let Some((mut pdf, lobe)) = self.pdf_parts(wo, wi) else {
            return 0.0;
        };
        let Some((sel, h, t, jac)) = lobe else {
            return pdf;
        };
        // One cell lookup serves every lobe: they share the edges.
        let n = self.edges.len() - 1;
        let i = (self.edges.partition_point(|&e| e <= t) - 1).min(n - 1);
        let (ex, ey) = azimuth_frame(wo);
        let phi = relative_azimuth(h, ex, ey);
        let j = ((phi / PI * PHI_CELLS as f64) as usize).min(PHI_CELLS - 1);
        let view = view_node(sel.at);
        for (m, tables) in self.lobes.iter().enumerate() {
            if let Some(tables) = tables {
                // Interpolated here, not read from `sel`: the reference for
                // the per-draw row too.
                let p = self.selection_at(sel.at, m + 1);
                if p > 0.0 {
                    pdf += p * tables[view].cell_density(i, j) * jac;
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
        match self.draw(wo, u_lobe, u) {
            Ok((wi, pdf, component)) => BsdfSample::new(wi, self.eval(wo, wi), pdf, component),
            Err(lost) => lost,
        }
    }

    /// The draw of [`NpfBxdf::sample`] for an isotropic model without its
    /// value: (wi, pdf, component), or the lost sample.
    #[inline]
    pub(crate) fn draw(&self, wo: Vec3, u_lobe: f64, u: [f64; 2]) -> Drawn {
        if !(wo[2] > 0.0) {
            return Err(BsdfSample::lost([0.0, 0.0, 1.0], Component::Diffuse));
        }
        let sel = self.selection_row_at(self.selection_row(wo[2]));
        let Some(c) = self.choose(&sel, u_lobe) else {
            return Err(BsdfSample::lost([0.0, 0.0, 1.0], Component::Diffuse));
        };
        if c == 0 {
            return self.diffuse_draw(wo, &sel, u);
        }
        let (cell, t, dv, sign) = self.lobe_cells(&sel, c - 1, u);
        let r = reflection::<f64>(wo, t, sign, azimuth_centre(cell.1), dv);
        self.finish_lobe(wo, &sel, c - 1, cell, &r)
    }

    /// [`NpfBxdf::draw`] of four views at once, exactly its results (bit
    /// for bit, tested), lane k of each array for draw k, a lost draw with
    /// pdf 0 and the direction and component `draw` reports: the view
    /// arccosines, each lobe draw's reflection and Jacobian and each
    /// diffuse draw's cosine direction and half vector in four lanes `V`
    /// (the square roots, the azimuth polynomials, the frame's division),
    /// the four draws' component choices, table searches and density reads
    /// one by one (independent, so the core overlaps them), then every
    /// draw's mixture pdf in the same lanes. Every lane sees the operations
    /// of `draw` in its order. The results go straight to arrays (no
    /// `Drawn` per lane: moving those enums cost about 50 instructions a
    /// draw).
    // No closures around lane operations (see `FlatEval::eval4`).
    #[inline(always)]
    pub(crate) fn draw4<V: Lanes4>(
        &self,
        wo: [Vec3; 4],
        u_lobe: [f64; 4],
        u: [[f64; 2]; 4],
    ) -> Drawn4 {
        let mut cos = [0.0; 4];
        for k in 0..4 {
            cos[k] = wo[k][2].clamp(0.0, 1.0);
        }
        let theta = acos_lanes(V::load(&cos)).to_array();
        let mut out = Drawn4 {
            wi: [[0.0; 4], [0.0; 4], [1.0; 4]],
            pdf: [0.0; 4],
            component: [Component::Diffuse; 4],
            theta_o: theta,
        };
        // Lanes of other draws get a harmless lobe draw, then discarded.
        let (mut t, mut sign, mut dv) = ([0.0; 4], [1.0; 4], [0.5; 4]);
        let (mut sc, mut cc) = ([0.0; 4], [1.0; 4]);
        let mut sels = [Sel {
            at: (0, 0.0),
            p: [0.0; SEL_ROW],
        }; 4];
        // The t and azimuth cells of each lobe draw (None: no lobe draw).
        let mut cells = [None; 4];
        // The mixture pdf in lanes: per lane, the diffuse share, each
        // lobe's share times its density in the cell of the draw's half
        // vector, and that density (a zero adds nothing). Only up to
        // SEL_ROW - 1 lobes (every model with a flat evaluator); others
        // take the per-lane `finish_lobe` and `diffuse_draw`.
        let nl = self.model.lobes.len();
        let in_lanes = nl < SEL_ROW;
        let mut p_diffuse = [0.0; 4];
        // 1 in the lanes of lobe draws, of diffuse draws made in lanes.
        let (mut lobe, mut diffuse) = ([0.0; 4], [0.0; 4]);
        // The diffuse draws' random numbers, `unit` as `cosine_hemisphere`'s.
        let mut ud = [[0.0; 4]; 2];
        let mut dens = Dens4 {
            share_d: [[0.0; 4]; SEL_ROW - 1],
            d: [[0.0; 4]; SEL_ROW - 1],
        };
        for k in 0..4 {
            sels[k] = self.selection_row_at(row_at_angle(theta[k]));
            if !(wo[k][2] > 0.0) {
                continue;
            }
            let Some(c) = self.choose(&sels[k], u_lobe[k]) else {
                continue;
            };
            p_diffuse[k] = sels[k].p[0];
            if c == 0 {
                if in_lanes {
                    diffuse[k] = 1.0;
                    (ud[0][k], ud[1][k]) = (unit(u[k][0]), unit(u[k][1]));
                    continue;
                }
                let (wi, pdf) = match self.diffuse_draw(wo[k], &sels[k], u[k]) {
                    Ok((wi, pdf, _)) => (wi, pdf),
                    Err(lost) => (lost.wi, 0.0),
                };
                (out.wi[0][k], out.wi[1][k], out.wi[2][k]) = (wi[0], wi[1], wi[2]);
                out.pdf[k] = pdf;
                continue;
            }
            let (cell, tk, d, s) = self.lobe_cells(&sels[k], c - 1, u[k]);
            out.component[k] = Component::Lobe(c - 1);
            cells[k] = Some(cell);
            [sc[k], cc[k]] = azimuth_centre(cell.1);
            (t[k], sign[k], dv[k]) = (tk, s, d);
            lobe[k] = 1.0;
            if in_lanes {
                self.read_densities(&mut dens, k, &sels[k], cell);
            }
        }
        let column = |c: usize| [wo[0][c], wo[1][c], wo[2][c], wo[3][c]];
        let (o0, o1, o2) = (column(0), column(1), column(2));
        let wo_l = [V::load(&o0), V::load(&o1), V::load(&o2)];
        let ex = frame_lanes(wo_l);
        let r = reflection_in::<V>(
            wo_l,
            ex,
            V::load(&t),
            V::load(&sign),
            [V::load(&sc), V::load(&cc)],
            V::load(&dv),
        );
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        let (s_z, wo_s, r2) = (r.jac.s_z, r.jac.wo_s, r.jac.r2);
        let jac_ok = zero.lt_select(
            s_z,
            zero.lt_select(wo_s, r2.lt_select(r2 + s_z * s_z, one, zero), zero),
            zero,
        );
        let kept = zero.lt_select(r.wo_h, zero.lt_select(r.wi[2], one, zero), zero);
        // Per lane: the draw's wi and Jacobian, 1 where it stands (a lobe
        // draw kept with a valid Jacobian, a diffuse draw above the
        // horizon), 1 where there is a draw in lanes at all.
        let (mut wi, mut jac, mut ok) = (r.wi, r.jac.jac, kept * jac_ok);
        let mut drawn = V::load(&lobe);
        if diffuse != [0.0; 4] {
            let is_diffuse = V::load(&diffuse);
            let (wd, jd) = self.diffuse_lanes::<V>(wo_l, ex, &diffuse, ud, &sels, &mut dens);
            for c in 0..3 {
                wi[c] = zero.lt_select(is_diffuse, wd[c], wi[c]);
            }
            jac = zero.lt_select(is_diffuse, jd, jac);
            ok = zero.lt_select(is_diffuse, zero.lt_select(wd[2], one, zero), ok);
            drawn = drawn + is_diffuse;
        }
        // `finish_lobe`'s and `pdf_at`'s operations in their order: the
        // diffuse part, each lobe's (share x density) x Jacobian where the
        // density is above 0, then 0 for a lost draw (see `ok`) or a pdf
        // not above 0.
        let p0 = V::load(&p_diffuse);
        let mut pdf = zero.lt_select(p0, p0 * wi[2] / V::splat(PI), zero);
        for m in 0..nl.min(SEL_ROW - 1) {
            let d = V::load(&dens.d[m]);
            pdf = pdf + zero.lt_select(d, V::load(&dens.share_d[m]) * jac, zero);
        }
        let pdf = zero.lt_select(pdf, pdf, zero);
        let pdf = zero.lt_select(ok, pdf, zero);
        let [w0, w1, w2] = wi;
        out.wi = [
            zero.lt_select(drawn, w0, V::load(&out.wi[0])).to_array(),
            zero.lt_select(drawn, w1, V::load(&out.wi[1])).to_array(),
            zero.lt_select(drawn, w2, V::load(&out.wi[2])).to_array(),
        ];
        out.pdf = zero.lt_select(drawn, pdf, V::load(&out.pdf)).to_array();
        // Rare: a kept lobe draw whose Jacobian `finish_lobe` would not
        // take (it then calls `pdf_at`), or more lobes than the lanes hold.
        let is_lobe = V::load(&lobe);
        let odd = (is_lobe * kept * (one - jac_ok)).to_array();
        if in_lanes && odd == [0.0; 4] {
            return out;
        }
        for k in 0..4 {
            let (Some(cell), Component::Lobe(m)) = (cells[k], out.component[k]) else {
                continue;
            };
            if in_lanes && odd[k] == 0.0 {
                continue;
            }
            let r = Reflection {
                wi: [out.wi[0][k], out.wi[1][k], out.wi[2][k]],
                wo_h: r.wo_h.to_array()[k],
                jac: JacobianParts {
                    s_z: s_z.to_array()[k],
                    wo_s: wo_s.to_array()[k],
                    r2: r2.to_array()[k],
                    jac: r.jac.jac.to_array()[k],
                },
            };
            out.pdf[k] = match self.finish_lobe(wo[k], &sels[k], m, cell, &r) {
                Ok((_, pdf, _)) => pdf,
                Err(_) => 0.0,
            };
        }
        out
    }

    /// Lane k's share x density and density of each of the first SEL_ROW
    /// - 1 lobes in cell (i, j) of its view's tables, into `dens`.
    #[inline(always)]
    fn read_densities(&self, dens: &mut Dens4, k: usize, sel: &Sel, cell: (usize, usize)) {
        let row = self.density_row(sel, cell);
        for (m, &dm) in row.iter().enumerate().take(SEL_ROW - 1) {
            (dens.share_d[m][k], dens.d[m][k]) = (sel.p[m + 1] * dm, dm);
        }
    }

    /// The diffuse draws of `draw4` in lanes (the lanes where `diffuse` is
    /// 1; `ud` their random numbers in [0, 1]): `cosine_hemisphere`'s
    /// direction and `pdf_at`'s Jacobian, and, where a lobe could have
    /// drawn that direction (the Jacobian valid), the densities of the
    /// cell `pdf_at` finds for its half vector (the t cell from the guide
    /// table, the azimuth cell by `azimuth_cell`'s compares), into those
    /// lanes of `dens`. Returns (wi, Jacobian) lanes.
    #[inline(always)]
    fn diffuse_lanes<V: Lanes4>(
        &self,
        wo: [V; 3],
        [ex0, ex1]: [V; 2],
        diffuse: &[f64; 4],
        ud: [[f64; 4]; 2],
        sels: &[Sel; 4],
        dens: &mut Dens4,
    ) -> ([V; 3], V) {
        let (sp, cp) = turn_sin_cos_lanes(V::load(&ud[1]));
        let wi = cosine_direction(V::load(&ud[0]), sp, cp);
        let jp = jacobian_parts(wo, wi);
        if self.densities.is_empty() {
            return (wi, jp.jac);
        }
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        // `JacobianParts::valid`, and a diffuse lane.
        let (s_z, r2) = (jp.s_z, jp.r2);
        let n2 = r2 + s_z * s_z;
        let valid = zero.lt_select(
            s_z,
            zero.lt_select(jp.wo_s, r2.lt_select(n2, one, zero), zero),
            zero,
        );
        let valid = (valid * V::load(diffuse)).to_array();
        if valid == [0.0; 4] {
            return (wi, jp.jac);
        }
        // `half_vector`'s h (x and y) and t; |s|^2 = n2 as its dot forms it.
        let inv = one / n2.sqrt();
        let (h0, h1) = ((wi[0] + wo[0]) * inv, (wi[1] + wo[1]) * inv);
        let th = (r2 / n2).min(one);
        // `azimuth_cell`: x <= c r is "not c r < x" (all finite where the
        // Jacobian is valid); y only enters squared, so h1 ex.x - h0 ex.y
        // serves for h0 (-ex.y) + h1 ex.x (they differ at most in a zero's
        // sign).
        let x = h0 * ex0 + h1 * ex1;
        let y = h1 * ex0 - h0 * ex1;
        let r = (x * x + y * y).sqrt();
        let mut count = zero;
        for c in EDGE_COS {
            count = count + (V::splat(c) * r).lt_select(x, zero, one);
        }
        let j = zero.lt_select(r, count, zero).to_u32();
        // `t_cell`'s guide entry.
        let g = self.t_guide.len();
        let b = (th.sqrt().sqrt() * V::splat(g as f64))
            .floor_index()
            .min(V::splat((g - 1) as f64))
            .to_u32();
        let th = th.to_array();
        for k in 0..4 {
            if valid[k] == 0.0 {
                continue;
            }
            let i = self.t_cell_from(b[k] as usize, th[k]);
            self.read_densities(dens, k, &sels[k], (i, j[k] as usize));
        }
        (wi, jp.jac)
    }

    /// A diffuse draw whole (the cosine direction and its mixture pdf), as
    /// `draw` makes it.
    #[inline(always)]
    fn diffuse_draw(&self, wo: Vec3, sel: &Sel, u: [f64; 2]) -> Drawn {
        let wi = cosine_hemisphere(u);
        if !(wi[2] > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Diffuse));
        }
        self.finish_diffuse(wo, sel, wi)
    }

    /// Lobe m's table draw at a view: the (t, azimuth) cells, t, the
    /// azimuth's position in its cell and its sign.
    #[inline(always)]
    fn lobe_cells(&self, sel: &Sel, m: usize, u: [f64; 2]) -> ((usize, usize), f64, f64, f64) {
        let tables = self.lobes[m].as_ref().expect("selected lobes have tables");
        // u[1]: the sign of the relative azimuth (below or above 1/2) and,
        // rescaled, its magnitude.
        let v = unit(u[1]);
        let (sign, v) = if v < 0.5 {
            (1.0, 2.0 * v)
        } else {
            (-1.0, (2.0 * v - 1.0).min(1.0))
        };
        // v is in [0, 1] already (`unit`, then 2v or 2v - 1 at most 1).
        let (i, t, j, dv) = tables[view_node(sel.at)].sample_cells_unit_v(u[0], v);
        ((i, j), t, dv, sign)
    }

    /// The component `u_lobe` picks: the first with u_lobe below its
    /// cumulative share, else (u_lobe at or past the total, or NaN) the last
    /// with a share; None when none has one. Without branches: the first
    /// such component is the count of cumulative shares at most u_lobe
    /// (shares are never negative, so the sums do not decrease, and a
    /// component without a share adds an exact 0), which a random u_lobe
    /// would mispredict as a loop exit.
    #[inline(always)]
    fn choose(&self, sel: &Sel, u_lobe: f64) -> Option<usize> {
        let nc = self.components();
        // A negative u_lobe picks the first component with a share, as 0
        // does (leading components without one then count as at most u).
        // NaN stays NaN: it compares with nothing and picks the last.
        let u_lobe = if u_lobe < 0.0 { 0.0 } else { u_lobe };
        let mut acc = 0.0;
        let mut below = 0;
        // The row's padding (zeros past nc) adds nothing and counts only
        // when u_lobe is at or past the total, like the components past
        // the last with a share.
        for &p in &sel.p {
            acc += p;
            below += usize::from(!(u_lobe < acc));
        }
        for c in SEL_ROW..nc {
            acc += self.selection_at(sel.at, c);
            below += usize::from(!(u_lobe < acc));
        }
        if below < nc {
            return Some(below);
        }
        // Rare (u_lobe at the total or NaN): the last with a share.
        (0..nc).rev().find(|&c| self.sel_p(sel, c) > 0.0)
    }

    /// A diffuse draw's result: its mixture pdf.
    #[inline(always)]
    fn finish_diffuse(&self, wo: Vec3, sel: &Sel, wi: Vec3) -> Drawn {
        let pdf = self.pdf_at(wo, wi, sel);
        if !(pdf > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Diffuse));
        }
        Ok((wi, pdf, Component::Diffuse))
    }

    /// A lobe draw's result from its reflection: lost below the horizon,
    /// else its mixture pdf.
    #[inline(always)]
    fn finish_lobe(
        &self,
        wo: Vec3,
        sel: &Sel,
        m: usize,
        cell: (usize, usize),
        r: &Reflection<f64>,
    ) -> Drawn {
        let wi = r.wi;
        if !(r.wo_h > 0.0 && wi[2] > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Lobe(m)));
        }
        // The drawn cell is where pdf finds wi's half vector (up to
        // rounding at a cell edge): its density row serves directly. The
        // Jacobian is pdf's own, from wi (the drawn h's differs by rounding
        // that grazing views amplify past 1e-12 relative).
        let pdf = match r.jac.valid() {
            Some(jac) => self.add_lobe_densities(self.diffuse_pdf(wi, sel), sel, cell, jac),
            None => self.pdf_at(wo, wi, sel),
        };
        if !(pdf > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Lobe(m)));
        }
        Ok((wi, pdf, Component::Lobe(m)))
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
        let view = view_node(row);
        let mut lost = 0.0;
        for (m, tables) in self.lobes.iter().enumerate() {
            let Some(tables) = tables else { continue };
            let p = self.selection_at(row, m + 1);
            if p <= 0.0 {
                continue;
            }
            let table = &tables[view];
            let e = &self.edges;
            let dphi = PI / PHI_CELLS as f64;
            let mut lobe_lost = 0.0;
            for i in 0..e.len() - 1 {
                let prob = table.marginal().cell_probability(i);
                if prob == 0.0 {
                    continue;
                }
                // Four Gauss points on each of eight slices of the cell; at
                // each, the lost azimuths are [phi*, pi] (closed form).
                let slices = 8;
                let mut frac = [0.0; PHI_CELLS];
                for s in 0..slices {
                    let a = e[i] + (e[i + 1] - e[i]) * s as f64 / slices as f64;
                    let b = e[i] + (e[i + 1] - e[i]) * (s + 1) as f64 / slices as f64;
                    for (x, w) in GL4_X.iter().zip(GL4_W) {
                        let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
                        let phi_star = PI * (1.0 - azimuth_lost_fraction(t, cos_o, sin_o));
                        for (j, f) in frac.iter_mut().enumerate() {
                            let (lo, hi) = (j as f64 * dphi, (j + 1) as f64 * dphi);
                            let over = (hi - phi_star.max(lo)).clamp(0.0, dphi) / dphi;
                            *f += 0.5 * w / slices as f64 * over;
                        }
                    }
                }
                let cell: f64 = frac
                    .iter()
                    .enumerate()
                    .map(|(j, f)| table.conditional_probability(i, j) * f)
                    .sum();
                lobe_lost += prob * cell;
            }
            lost += p * lobe_lost;
        }
        lost
    }
}

/// A draw of [`NpfBxdf::draw`]: (wi, pdf, component), or the lost sample.
pub(crate) type Drawn = Result<(Vec3, f64, Component), BsdfSample>;

/// Four draws of [`NpfBxdf::draw4`]: lane k of each array is draw k (wi
/// per coordinate, pdf 0 when lost).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Drawn4 {
    pub wi: [[f64; 4]; 3],
    pub pdf: [f64; 4],
    pub component: [Component; 4],
    /// The views' angles, `acos_lanes` of wo.z clamped to [0, 1] (what
    /// `FlatEval::eval4_view` takes).
    pub theta_o: [f64; 4],
}

/// The lobe densities of four draws' cells (lane k of each row for draw
/// k): per lobe m < SEL_ROW - 1, its share x density and its density (0
/// in lanes without a lobe part).
#[derive(Clone, Copy, Debug)]
struct Dens4 {
    share_d: [[f64; 4]; SEL_ROW - 1],
    d: [[f64; 4]; SEL_ROW - 1],
}

/// What the lobe Jacobian is made of, from s = wi + wo (h's direction,
/// whose length cancels): `jac = s.z / (4 wo.s)`, the tables' density to
/// solid angle of wi (`cos theta_h / (4 wo.h)`: one division and no square
/// root, `sample` computes it for every draw); valid when s.z > 0, wo.s > 0
/// and t = r2 / |s|^2 < 1, with r2 = s.x^2 + s.y^2.
#[derive(Clone, Copy, Debug)]
struct JacobianParts<V> {
    s_z: V,
    wo_s: V,
    r2: V,
    jac: V,
}

#[inline(always)]
fn jacobian_parts<V: Lanes>(wo: [V; 3], wi: [V; 3]) -> JacobianParts<V> {
    let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let wo_s = wo[0] * s[0] + wo[1] * s[1] + wo[2] * s[2];
    JacobianParts {
        s_z: s[2],
        wo_s,
        r2: s[0] * s[0] + s[1] * s[1],
        // Density per solid angle of h: (table density / 2) over signed
        // azimuths, times dt dphi / dOmega_h = 2 cos theta_h.
        jac: s[2] / (V::splat(4.0) * wo_s),
    }
}

impl JacobianParts<f64> {
    /// The Jacobian when a lobe could have drawn wi (its half vector above
    /// the surface, facing wo, t < 1 as `half_vector` forms t).
    #[inline(always)]
    fn valid(&self) -> Option<f64> {
        let ok = self.s_z > 0.0 && self.wo_s > 0.0 && self.r2 < self.r2 + self.s_z * self.s_z;
        ok.then_some(self.jac)
    }
}

/// The Jacobian `cos theta_h / (4 wo.h)` from the tables' density to
/// solid angle of wi, when a lobe could have drawn wi (see
/// [`JacobianParts`]).
#[inline]
fn lobe_jacobian(wo: Vec3, wi: Vec3) -> Option<f64> {
    jacobian_parts::<f64>(wo, wi).valid()
}

/// A lobe draw's reflected direction, wo.h and its Jacobian's parts.
#[derive(Clone, Copy, Debug)]
struct Reflection<V> {
    wi: [V; 3],
    wo_h: V,
    jac: JacobianParts<V>,
}

/// The half vector of a lobe draw (t = sin^2 theta_h, the azimuth at dv
/// in the cell with centre (sin, cos) `centre`, of sign `sign`, relative
/// to wo's azimuth) and its reflection of wo, lane by lane.
#[inline(always)]
fn reflection<V: Lanes>(wo: [V; 3], t: V, sign: V, centre: [V; 2], dv: V) -> Reflection<V> {
    reflection_in(wo, frame_lanes(wo), t, sign, centre, dv)
}

/// `azimuth_frame`'s ex lane by lane (the same values): the unit vector
/// along wo's azimuth (ey = (-ex.y, ex.x)), x for a wo at the normal.
#[inline(always)]
fn frame_lanes<V: Lanes>(wo: [V; 3]) -> [V; 2] {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let r2 = wo[0] * wo[0] + wo[1] * wo[1];
    let inv = one / r2.sqrt();
    let tiny = V::splat(1e-30);
    [
        tiny.lt_select(r2, wo[0] * inv, one),
        tiny.lt_select(r2, wo[1] * inv, zero),
    ]
}

/// [`reflection`] given wo's frame ex (`frame_lanes`).
#[inline(always)]
fn reflection_in<V: Lanes>(
    wo: [V; 3],
    [ex0, ex1]: [V; 2],
    t: V,
    sign: V,
    centre: [V; 2],
    dv: V,
) -> Reflection<V> {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (sin_h, cos_h) = (t.sqrt(), (one - t).max(zero).sqrt());
    let (sp, cp) = azimuth_sin_cos(centre, dv);
    let (hx, hy) = (sin_h * cp, sign * sin_h * sp);
    // hx ex + hy ey (hy (-ex.y) added is hy ex.y subtracted, exactly).
    let h = [hx * ex0 - hy * ex1, hx * ex1 + hy * ex0, cos_h];
    let wo_h = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    let k = V::splat(2.0) * wo_h;
    let wi = [k * h[0] - wo[0], k * h[1] - wo[1], k * h[2] - wo[2]];
    Reflection {
        wi,
        wo_h,
        jac: jacobian_parts(wo, wi),
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

/// The selection-table position (row below, weight of the row above) of
/// a view at angle theta (radians).
#[inline(always)]
fn row_at_angle(theta: f64) -> (usize, f64) {
    // Nodes per radian of theta_o.
    const PER_RAD: f64 = (VIEW_NODES - 1) as f64 * 180.0 / (VIEW_MAX_DEG * PI);
    let x = (theta * PER_RAD).clamp(0.0, (VIEW_NODES - 1) as f64);
    // x >= 0 (or NaN, 0 either way): truncation is floor, without libm.
    let k = floor_index(x).min(VIEW_NODES - 2);
    (k, x - k as f64)
}

/// The nearest view node of a view at selection-table position (k, w)
/// (see `selection_row`): each lobe draws from that node's table, so its
/// density is exactly that table's.
#[inline]
fn view_node((k, w): (usize, f64)) -> usize {
    if w >= 0.5 {
        k + 1
    } else {
        k
    }
}

/// Unit vectors along wo's azimuth and perpendicular to it in the tangent
/// plane (x and y for a wo at the normal).
#[inline]
fn azimuth_frame(wo: Vec3) -> ([f64; 2], [f64; 2]) {
    let r2 = wo[0] * wo[0] + wo[1] * wo[1];
    if !(r2 > 1e-30) {
        return ([1.0, 0.0], [0.0, 1.0]);
    }
    let inv = 1.0 / r2.sqrt();
    let ex = [wo[0] * inv, wo[1] * inv];
    (ex, [-ex[1], ex[0]])
}

/// |phi_h - phi_o| in [0, pi] of a half vector.
#[inline]
fn relative_azimuth(h: Vec3, ex: [f64; 2], ey: [f64; 2]) -> f64 {
    let x = h[0] * ex[0] + h[1] * ex[1];
    let y = h[0] * ey[0] + h[1] * ey[1];
    y.abs().atan2(x)
}

/// Cells whose mass is below this fraction of the lobe's total get none:
/// never drawn, and pdf is zero there (other components still cover them).
pub const NEGLIGIBLE_CELL: f64 = 1e-6;

/// The t = sin^2 theta_h edges of the half-vector tables: every interval
/// of the D axis split into SUBCELLS parts, from t = 0 to exactly 1.
fn t_edges(model: &Model) -> Vec<f64> {
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
    edges
}

/// The guide table of [`NpfBxdf::t_cell`]: 2 entries per cell, over
/// u = t^(1/4) in [0, 1).
fn t_guide(edges: &[f64]) -> Vec<u32> {
    let n = edges.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let g = 2 * n;
    (0..g)
        .map(|b| {
            let t = (b as f64 / g as f64).powi(4);
            (edges.partition_point(|&e| e <= t).saturating_sub(1)).min(n - 1) as u32
        })
        .collect()
}

/// Gauss-Legendre points per azimuth cell in the table masses.
const PHI_GAUSS: usize = 2;

/// The VIEW_NODES half-vector tables of lobe m: for view node k (wo_k at
/// theta_k, azimuth 0), cell (i, j) of (t, |phi|) holds
///
///   mass = integral over the cell of D(theta_h) [ max(0, wo_k.h) / cos theta_h
///          * G+(theta_i) F(theta_d) [wi_k above the horizon] ] dt dphi
///
/// (the visible normals of D, per solid angle D max(0, wo.h), times the
/// lobe's shadowing of wi and its Fresnel luminance, both normalised by
/// their largest values; 4 x 2 Gauss-Legendre points per cell), renormalised
/// and mixed with a COVERAGE_SHARE of the view-independent D B table (B the
/// G-product bound of [`g_product_bound`]), which keeps every half vector
/// where D has mass covered at every view. Cells below NEGLIGIBLE_CELL of
/// the total get none. The tables are exactly normalised, and pdf is
/// exactly what sample draws, whatever the quadrature's accuracy.
fn lobe_tables(model: &Model, m: usize, edges: &[f64]) -> Option<Vec<PiecewiseConstant2D>> {
    let lobe = &model.lobes[m];
    let (d_axis, g_axis, f_axis) = (
        model.layout.d.theta,
        model.layout.g.theta,
        model.layout.f.theta,
    );
    if edges.len() < 2 {
        return None;
    }
    let bound = g_product_bound(model, &lobe.g);
    let b_max = bound(0.0);
    if !(b_max > 0.0 && b_max.is_finite()) {
        return None;
    }
    // G+ and the lobe's Fresnel luminance (with its scales), normalised.
    let g_plus = |theta: f64| g_axis.stencil(theta).apply_f32(&lobe.g).max(0.0);
    let f_lum: Vec<f32> = (0..model.fresnel[0].len())
        .map(|k| {
            (0..3)
                .map(|c| LUMINANCE[c] * lobe.s[c] as f64 * model.fresnel[c][k] as f64)
                .sum::<f64>() as f32
        })
        .collect();
    let g_max = (0..=360)
        .map(|k| g_plus(k as f64 / 360.0 * FRAC_PI_2))
        .fold(0.0, f64::max);
    let f_max = f_lum.iter().copied().fold(0.0f32, f32::max) as f64;
    let nx = edges.len() - 1;
    let dphi = PI / PHI_CELLS as f64;
    // Gauss points in t per cell: (t, weight, D, D B, sin_h, cos_h).
    let mut points = Vec::with_capacity(nx * 4);
    for w in edges.windows(2) {
        let (a, b) = (w[0], w[1]);
        for (x, wt) in GL4_X.iter().zip(GL4_W) {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let theta = t.sqrt().min(1.0).asin();
            let d = d_axis.stencil(theta).apply_f32(&lobe.d).max(0.0);
            let db = d * (bound(theta) / b_max).min(1.0);
            points.push((
                0.5 * (b - a) * wt,
                d,
                db,
                t.sqrt(),
                (1.0 - t).max(0.0).sqrt(),
            ));
        }
    }
    // The view-independent coverage part (per cell; uniform in phi).
    let cover: Vec<f64> = points
        .chunks(4)
        .map(|p| p.iter().map(|q| q.0 * q.2).sum())
        .collect();
    let cover_total: f64 = cover.iter().sum();
    if !(cover_total > 0.0 && cover_total.is_finite()) {
        return None;
    }
    let shaped = g_max > 0.0 && f_max > 0.0;
    // Views are independent: build them in parallel (each table is the
    // same whatever the thread count).
    let view_table = |k: usize| -> Option<PiecewiseConstant2D> {
        let (sin_o, cos_o) = view_angle(k).sin_cos();
        let mut mass = vec![0.0; nx * PHI_CELLS];
        if shaped {
            for (i, cell) in points.chunks(4).enumerate() {
                for &(wt, d, _, sin_h, cos_h) in cell {
                    if !(d > 0.0 && cos_h > 0.0) {
                        continue;
                    }
                    for j in 0..PHI_CELLS {
                        let mut acc = 0.0;
                        for g in 0..PHI_GAUSS {
                            let x = if PHI_GAUSS == 2 {
                                [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8][g]
                            } else {
                                0.0
                            };
                            let phi = (j as f64 + 0.5 + 0.5 * x) * dphi;
                            let h = [sin_h * phi.cos(), sin_h * phi.sin(), cos_h];
                            let wo_h = sin_o * h[0] + cos_o * h[2];
                            let wi_z = 2.0 * wo_h * cos_h - cos_o;
                            if !(wo_h > 0.0 && wi_z > 0.0) {
                                continue;
                            }
                            let theta_i = wi_z.min(1.0).acos();
                            let theta_d = wo_h.min(1.0).acos();
                            let gi = g_plus(theta_i) / g_max;
                            let fd = f_axis.stencil(theta_d).apply_f32(&f_lum).max(0.0) / f_max;
                            acc += wo_h / cos_h * gi * fd / PHI_GAUSS as f64;
                        }
                        mass[i * PHI_CELLS + j] += wt * d * acc * dphi;
                    }
                }
            }
        }
        let total: f64 = mass.iter().sum();
        let (main, share) = if total > 0.0 && total.is_finite() {
            (1.0 / total, COVERAGE_SHARE)
        } else {
            (0.0, 1.0)
        };
        for (i, &c) in cover.iter().enumerate() {
            for j in 0..PHI_CELLS {
                let v = &mut mass[i * PHI_CELLS + j];
                *v = *v * main * (1.0 - share) + share * c / cover_total / PHI_CELLS as f64;
            }
        }
        for v in mass.iter_mut() {
            if *v < NEGLIGIBLE_CELL / PHI_CELLS as f64 {
                *v = 0.0;
            }
        }
        PiecewiseConstant2D::new(edges.to_vec(), PHI_CELLS, PI, &mass)
    };
    (0..VIEW_NODES).into_par_iter().map(view_table).collect()
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
        let cells = t_edges(b.model()).len() - 1;
        assert_eq!(
            b.table_bytes(),
            8 * (VIEW_NODES * 2 + cells + 1)
                + 4 * 2 * cells
                + FlatEval::new(b.model()).unwrap().table_bytes()
        );
    }

    /// draw4 in lane type V against draw, bit for bit, on views that
    /// include the normal, grazing and invalid ones and random numbers
    /// at and outside [0, 1].
    fn check_draw4<V: Lanes4>(b: &NpfBxdf) -> usize {
        let mut next = crate::bsdf::test_uniforms(0x9e37_79b9_7f4a_7c15u64);
        let odd = [0.0, 1.0, 1.0 - 1e-17, 0.5, f64::NAN, -0.25, 2.0];
        let (mut drawn, mut n) = (0, 0);
        while n < 20_000 {
            let mut wo = [[0.0; 3]; 4];
            let (mut ul, mut u) = ([0.0; 4], [[0.0; 2]; 4]);
            for k in 0..4 {
                let z = match n % 97 {
                    0 => 1.0,
                    1 => 1e-9,
                    2 => -0.3,
                    3 => f64::NAN,
                    _ => next(),
                };
                let r = (1.0 - z * z).max(0.0).sqrt();
                let p = next() * std::f64::consts::TAU;
                wo[k] = [r * p.cos(), r * p.sin(), z];
                ul[k] = next();
                u[k] = [next(), next()];
                if n % 89 < 3 {
                    u[k][n % 2] = odd[n % odd.len()];
                    ul[k] = odd[(n / 2) % odd.len()];
                }
                n += 1;
            }
            let got = b.draw4::<V>(wo, ul, u);
            for k in 0..4 {
                let one = b.draw(wo[k], ul[k], u[k]);
                let (wi, pdf, c) = match one {
                    Ok(d) => d,
                    Err(l) => (l.wi, l.pdf, l.component),
                };
                let four = (
                    [got.wi[0][k], got.wi[1][k], got.wi[2][k]].map(f64::to_bits),
                    got.pdf[k].to_bits(),
                    got.component[k],
                );
                let one_bits = (wi.map(f64::to_bits), pdf.to_bits(), c);
                assert_eq!(four, one_bits, "{wo:?} {ul:?} {u:?} lane {k}");
                drawn += usize::from(one.is_ok());
            }
        }
        drawn
    }

    #[test]
    fn four_draws_at_once_equal_one_at_a_time_bit_for_bit() {
        let mut with_diffuse = known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]);
        with_diffuse.diffuse = [0.2, 0.1, 0.05];
        // Mostly diffuse (a matte fabric): most groups of four hold
        // several diffuse draws, many all four.
        let mut matte = known_factor_model(Layout::default(), &[0.5]);
        matte.diffuse = [0.8, 0.7, 0.6];
        let mut max_diffuse = 0.0f64;
        for model in [
            with_diffuse,
            known_factor_model(Layout::isotropic(30), &[0.3]),
            matte,
        ] {
            let b = NpfBxdf::new(model).unwrap();
            max_diffuse = max_diffuse.max(b.selection_probabilities([0.0, 0.0, 1.0])[0]);
            // Not vacuous: most draws carry light.
            assert!(check_draw4::<super::super::lanes::F64x2x2>(&b) > 10_000);
            #[cfg(target_arch = "x86_64")]
            if is_x86_feature_detected!("avx2") {
                #[target_feature(enable = "avx2")]
                fn avx(b: &NpfBxdf) -> usize {
                    check_draw4::<super::super::lanes::avx::F64x4>(b)
                }
                // SAFETY: AVX2 was detected.
                assert!(unsafe { avx(&b) } > 10_000);
            }
        }
        // The matte model draws mostly diffuse.
        assert!(max_diffuse > 0.5, "{max_diffuse}");
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
