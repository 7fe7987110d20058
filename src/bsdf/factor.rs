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

use super::anisotropic::AnisoSampler;
use super::azimuth::{azimuth_cell, azimuth_centre, PHI_CELLS};
use super::draw_geometry::*;
use super::f64x2::floor_index;
use super::flat::{acos_lanes, FlatEval};
use super::hemisphere::{cosine_hemisphere, unit};
use super::interface::{Bsdf, BsdfError, BsdfSample, Component};
use super::lobe_tables::*;
use super::quadrature::{half_vector_quadrature, GL4_W, GL4_X};
use super::selection::SELECTION_FLOOR;
use crate::model::Model;
use crate::sampling::{PiecewiseConstant, PiecewiseConstant2D};
use npf_data_loaders::geometry::{Angles, Vec3};
use std::f64::consts::PI;

/// Strata in u of the albedo quadrature behind the selection (twice as many
/// in phi_h): 48 puts five nodes inside a lobe of GGX roughness 0.02.
pub(super) const ALBEDO_GRID: usize = 48;
/// Candidate shares of the cosine draw blended into a view row's
/// albedo-proportional selection (see `NpfBxdf::defensive_blend`).
pub(super) const DEFENSIVE_SHARES: [f64; 10] = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 0.9, 0.95, 1.0];
/// Relative gain in the estimated white-furnace variance a blend must
/// reach over the albedo selection to replace it.
pub(super) const DEFENSIVE_MARGIN: f64 = 0.05;
/// Strata per axis of each component's quadrature draws in that search.
pub(super) const DEFENSIVE_GRID: usize = 48;

/// Components whose interpolated selection probabilities a draw or pdf
/// computes at once ([`Sel`]): the diffuse term and FLAT_LOBES lobes;
/// further lobes are interpolated where used.
pub(super) const SEL_ROW: usize = 1 + super::flat::FLAT_LOBES;

/// A view's selection-table position (row below, weight of the row above)
/// with the first SEL_ROW components' probabilities there.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sel {
    pub(super) at: (usize, f64),
    pub(super) p: [f64; SEL_ROW],
}

/// A model with its sampling tables (built once by [`NpfBxdf::new`]).
#[derive(Clone, Debug)]
pub struct NpfBxdf {
    pub(super) model: Model,
    /// The t = sin^2 theta_h cell edges every lobe's tables share (the D
    /// axis's intervals, split into SUBCELLS).
    pub(super) edges: Vec<f64>,
    /// Per lobe, VIEW_NODES half-vector tables over (t, relative azimuth in
    /// [0, pi]); `None` for a lobe without mass (D or s all zero), which is
    /// never chosen.
    pub(super) lobes: Vec<Option<Vec<PiecewiseConstant2D>>>,
    /// Selection probabilities, VIEW_NODES rows of (1 + lobes): diffuse
    /// first, each row padded with zeros to `sel_stride` entries.
    pub(super) selection: Vec<f64>,
    /// Entries per selection row: max(1 + lobes, SEL_ROW), so a draw reads
    /// the first SEL_ROW of two rows at fixed offsets.
    pub(super) sel_stride: usize,
    /// The 2-D sampler of an anisotropic model (which then has no 1-D tables).
    pub(super) aniso: Option<AnisoSampler>,
    /// Every lobe's cell densities side by side, for `pdf`: entry
    /// `((view * cells + i) * PHI_CELLS + j) * lobes + m` is
    /// `lobe_table(m, view).cell_density(i, j)` (0 for a lobe without
    /// tables), so one cache line serves all lobes.
    pub(super) densities: Vec<f64>,
    /// Guide table over u = t^(1/4) (near-uniform in the edges' index):
    /// entry b is the last cell whose lower edge is at most (b / len)^4.
    pub(super) t_guide: Vec<u32>,
    /// The model flattened for fast evaluation (isotropic, at most
    /// FLAT_LOBES lobes; otherwise eval is `Model::eval`).
    pub(super) flat: Option<FlatEval>,
}

pub(super) fn luminance(v: [f64; 3]) -> f64 {
    v[0] * LUMINANCE[0] + v[1] * LUMINANCE[1] + v[2] * LUMINANCE[2]
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

    pub(super) fn fused_densities(&self) -> Vec<f64> {
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
    pub(super) fn t_cell(&self, t: f64) -> usize {
        let g = self.t_guide.len();
        self.t_cell_from(floor_index(t.sqrt().sqrt() * g as f64).min(g - 1), t)
    }

    /// [`NpfBxdf::t_cell`] from its guide entry b (the batch forms b in lanes).
    #[inline(always)]
    pub(super) fn t_cell_from(&self, b: usize, t: f64) -> usize {
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

    pub(super) fn has_diffuse(&self) -> bool {
        // The compensation term is cosine-sampled with the diffuse term.
        self.model.diffuse.iter().any(|&d| d > 0.0) || self.model.compensation.is_some()
    }

    /// Component estimates of the directional albedo (luminance) at
    /// theta_o: exact for the diffuse term, by the one albedo quadrature
    /// ([`super::half_vector_quadrature`], coarse: ALBEDO_GRID strata in u)
    /// for the lobes, all lobes in one pass through [`Model::lobe_terms`].
    pub(super) fn albedo_estimates(&self, theta_o: f64) -> Vec<f64> {
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

    pub(super) fn selection_table(&self) -> Vec<f64> {
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
    pub(super) fn defensive_blend(&self, k: usize, p: &[f64], present: &[bool]) -> Vec<f64> {
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
    pub(super) fn component_draw(&self, k: usize, wo: Vec3, c: usize, u: [f64; 2]) -> Option<Vec3> {
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
    pub(super) fn component_densities(&self, k: usize, wo: Vec3, wi: Vec3, out: &mut [f64]) {
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
    pub(super) fn selection_row(&self, cos_o: f64) -> (usize, f64) {
        // The branch-free arccosine (views at random angles would
        // mispredict fdlibm's branches); a cos_o below 0 lands on the last
        // node either way.
        row_at_angle(acos_lanes(cos_o.clamp(0.0, 1.0)))
    }

    /// Probability that `sample` uses component c (0 diffuse, 1 + m lobe m)
    /// at a view's table position (see `selection_row`).
    #[inline]
    pub(super) fn selection_at(&self, (k, w): (usize, f64), c: usize) -> f64 {
        let st = self.sel_stride;
        (1.0 - w) * self.selection[k * st + c] + w * self.selection[(k + 1) * st + c]
    }

    /// The interpolated selection probabilities of the first SEL_ROW
    /// components at a view's table position, computed once per draw or
    /// pdf (the choice, the diffuse pdf and every lobe's share read them);
    /// the values of `selection_at`, bit for bit.
    #[inline(always)]
    pub(super) fn selection_row_at(&self, at: (usize, f64)) -> Sel {
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
    pub(super) fn sel_p(&self, sel: &Sel, c: usize) -> f64 {
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
    pub(super) fn pdf_parts(
        &self,
        wo: Vec3,
        wi: Vec3,
    ) -> Option<(f64, Option<(Sel, Vec3, f64, f64)>)> {
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
    pub(super) fn pdf_parts_at(
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
    pub(super) fn pdf_at(&self, wo: Vec3, wi: Vec3, sel: &Sel) -> f64 {
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
    pub(super) fn diffuse_pdf(&self, wi: Vec3, sel: &Sel) -> f64 {
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
    pub(super) fn density_row(&self, sel: &Sel, (i, j): (usize, usize)) -> &[f64] {
        let nl = self.model.lobes.len();
        let cells = self.edges.len() - 1;
        let base = ((view_node(sel.at) * cells + i) * PHI_CELLS + j) * nl;
        &self.densities[base..base + nl]
    }

    /// `pdf` plus every lobe's part of the mixture density for a half
    /// vector in cell (i, j) (t cell, azimuth cell), added lobe by lobe.
    #[inline(always)]
    pub(super) fn add_lobe_densities(
        &self,
        mut pdf: f64,
        sel: &Sel,
        (i, j): (usize, usize),
        jac: f64,
    ) -> f64 {
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
    /// [0, 1)) the direction within it. See [`BxdfSample`](crate::bsdf::BxdfSample) for draws that
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

    /// A diffuse draw whole (the cosine direction and its mixture pdf), as
    /// `draw` makes it.
    #[inline(always)]
    pub(super) fn diffuse_draw(&self, wo: Vec3, sel: &Sel, u: [f64; 2]) -> Drawn {
        let wi = cosine_hemisphere(u);
        if !(wi[2] > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Diffuse));
        }
        self.finish_diffuse(wo, sel, wi)
    }

    /// Lobe m's table draw at a view: the (t, azimuth) cells, t, the
    /// azimuth's position in its cell and its sign.
    #[inline(always)]
    pub(super) fn lobe_cells(
        &self,
        sel: &Sel,
        m: usize,
        u: [f64; 2],
    ) -> ((usize, usize), f64, f64, f64) {
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
    pub(super) fn choose(&self, sel: &Sel, u_lobe: f64) -> Option<usize> {
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
    pub(super) fn finish_diffuse(&self, wo: Vec3, sel: &Sel, wi: Vec3) -> Drawn {
        let pdf = self.pdf_at(wo, wi, sel);
        if !(pdf > 0.0) {
            return Err(BsdfSample::lost(wi, Component::Diffuse));
        }
        Ok((wi, pdf, Component::Diffuse))
    }

    /// A lobe draw's result from its reflection: lost below the horizon,
    /// else its mixture pdf.
    #[inline(always)]
    pub(super) fn finish_lobe(
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

/// The selection-table position (row below, weight of the row above) of
/// a view at angle theta (radians).
#[inline(always)]
pub(super) fn row_at_angle(theta: f64) -> (usize, f64) {
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
pub(super) fn view_node((k, w): (usize, f64)) -> usize {
    if w >= 0.5 {
        k + 1
    } else {
        k
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
