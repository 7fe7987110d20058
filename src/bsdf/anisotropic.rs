//! The anisotropic factor model's importance sampler (2-D D tables).
//!
//! Per specular lobe m, a [`PiecewiseConstant2D`] over (t = sin^2 theta_h,
//! phi_h) with cell mass the integral of D^m(theta_h, phi_h) dt dphi (D
//! bilinear on its grid, 4-point Gauss-Legendre per cell axis), so the half
//! vector's density per solid angle is proportional to D^m cos theta_h
//! (d omega_h = dt dphi / (2 cos theta_h)); wi is wo reflected about h, with
//! density p_h / (4 wo.h). Mixed with cosine-weighted diffuse.
//!
//! The component probabilities do not depend on wo (so the pdf is exact and
//! cheap): diffuse in proportion to pi lum(d), lobe m to lum(s^m) lum(mean
//! F) times half its D mass (its hemispherical integral of D cos theta_h),
//! each component with mass floored at [`super::SELECTION_FLOOR`], then
//! renormalised. Cells: the D grid's theta intervals (15 degrees for the
//! UTIA layout) split into [`THETA_SUB`] parts over [0, 90] degrees, its phi
//! intervals into [`PHI_SUB`].

use super::hemisphere::{cosine_hemisphere, reflect};
use super::interface::{BsdfSample, Component};
use super::quadrature::{GL4_W, GL4_X};
use super::selection::SELECTION_FLOOR;
use crate::model::Model;
use crate::sampling::PiecewiseConstant2D;
use npf_data_loaders::geometry::{dot, Vec3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Sub-cells per theta interval of the D grid.
pub const THETA_SUB: usize = 4;
/// Sub-cells per phi interval of the D grid.
pub const PHI_SUB: usize = 4;
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

fn lum(v: [f64; 3]) -> f64 {
    v[0] * LUMINANCE[0] + v[1] * LUMINANCE[1] + v[2] * LUMINANCE[2]
}

/// Sampling tables of an anisotropic model.
#[derive(Clone, Debug)]
pub struct AnisoSampler {
    /// Per lobe; `None` for a lobe without mass (never chosen).
    lobes: Vec<Option<PiecewiseConstant2D>>,
    /// Component probabilities, diffuse first.
    select: Vec<f64>,
}

impl AnisoSampler {
    /// Builds the tables of a (validated) model with a 2-D D grid.
    pub fn new(model: &Model) -> Self {
        let grid = model.layout.d;
        let axis = grid.theta;
        // Theta cells: the D axis's intervals split THETA_SUB ways, up to 90 degrees.
        let end = axis.coord(FRAC_PI_2);
        let n_t = (end.ceil() as usize).max(1) * THETA_SUB;
        let mut t_edges: Vec<f64> = (0..=n_t)
            .map(|j| {
                axis.angle_at((j as f64 / THETA_SUB as f64).min(end))
                    .sin()
                    .powi(2)
            })
            .collect();
        t_edges[0] = 0.0;
        t_edges[n_t] = 1.0;
        t_edges.dedup_by(|b, a| *b <= *a);
        let n_p = grid.n_phi() * PHI_SUB;
        let p_edges: Vec<f64> = (0..=n_p).map(|k| k as f64 / n_p as f64 * TAU).collect();
        let fmean: [f64; 3] = std::array::from_fn(|c| {
            let f = &model.fresnel[c];
            f.iter().map(|&v| v as f64).sum::<f64>() / f.len().max(1) as f64
        });
        let mut weights = vec![PI * lum(model.diffuse.map(f64::from))];
        let lobes = model
            .lobes
            .iter()
            .map(|lobe| {
                let mut mass = Vec::with_capacity((t_edges.len() - 1) * n_p);
                for tw in t_edges.windows(2) {
                    for pw in p_edges.windows(2) {
                        let mut m = 0.0;
                        for (xa, wa) in GL4_X.iter().zip(GL4_W) {
                            let t = 0.5 * (tw[0] + tw[1]) + 0.5 * (tw[1] - tw[0]) * xa;
                            let theta = t.sqrt().min(1.0).asin();
                            for (xb, wb) in GL4_X.iter().zip(GL4_W) {
                                let phi = 0.5 * (pw[0] + pw[1]) + 0.5 * (pw[1] - pw[0]) * xb;
                                let d = grid.stencil(theta, phi).apply_f32(&lobe.d).max(0.0);
                                m += 0.25 * wa * wb * d;
                            }
                        }
                        mass.push(m * (tw[1] - tw[0]) * (pw[1] - pw[0]));
                    }
                }
                let total: f64 = mass.iter().sum();
                let s = lum(lobe.s.map(f64::from));
                let dist = if s > 0.0 {
                    PiecewiseConstant2D::new(t_edges.clone(), n_p, TAU, &mass)
                } else {
                    None
                };
                weights.push(if dist.is_some() {
                    s * lum(fmean) * 0.5 * total
                } else {
                    0.0
                });
                dist
            })
            .collect();
        let sum: f64 = weights.iter().filter(|w| w.is_finite()).sum();
        let mut select: Vec<f64> = weights
            .iter()
            .map(|&w| {
                if !(w > 0.0 && w.is_finite()) {
                    0.0
                } else {
                    (w / sum).max(SELECTION_FLOOR)
                }
            })
            .collect();
        let total: f64 = select.iter().sum();
        if total > 0.0 {
            select.iter_mut().for_each(|p| *p /= total);
        }
        AnisoSampler { lobes, select }
    }

    /// Component probabilities, diffuse first (the same for every wo).
    pub fn selection(&self) -> &[f64] {
        &self.select
    }

    /// The mixture density of wi given wo (per solid angle).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        let mut pdf = self.select[0] * wi[2] / PI;
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = dot(s, s).sqrt();
        if !(n > 0.0) {
            return pdf;
        }
        let h = [s[0] / n, s[1] / n, s[2] / n];
        let wo_h = dot(wo, h);
        if !(wo_h > 0.0 && h[2] > 0.0) {
            return pdf;
        }
        let t = (h[0] * h[0] + h[1] * h[1]).min(1.0);
        let phi = h[1].atan2(h[0]).rem_euclid(TAU);
        for (m, dist) in self.lobes.iter().enumerate() {
            if let Some(d) = dist {
                // p(t, phi) dt dphi = p_h d omega_h with d omega_h = dt dphi / (2 cos theta_h).
                pdf += self.select[m + 1] * d.pdf(t, phi) * 2.0 * h[2] / (4.0 * wo_h);
            }
        }
        pdf
    }

    /// The direction component `c` draws from `u`, possibly below the horizon.
    fn draw(&self, c: usize, wo: Vec3, u: [f64; 2]) -> Vec3 {
        match c.checked_sub(1).and_then(|m| self.lobes[m].as_ref()) {
            None => cosine_hemisphere(u),
            Some(d) => {
                let (t, phi) = d.sample(u);
                let (sh, ch) = (t.sqrt(), (1.0 - t).max(0.0).sqrt());
                let h = [sh * phi.cos(), sh * phi.sin(), ch];
                if dot(wo, h) > 0.0 {
                    reflect(wo, h)
                } else {
                    [0.0, 0.0, -1.0]
                }
            }
        }
    }

    fn component(&self, u_lobe: f64) -> Option<usize> {
        let mut acc = 0.0;
        let mut last = None;
        for (c, &p) in self.select.iter().enumerate() {
            if p <= 0.0 {
                continue;
            }
            last = Some(c);
            acc += p;
            if u_lobe < acc {
                return Some(c);
            }
        }
        last
    }

    /// Draws wi for wo; a draw below the horizon is reported lost.
    pub fn sample(&self, model: &Model, wo: Vec3, u_lobe: f64, u: [f64; 2]) -> BsdfSample {
        let Some(c) = self.component(u_lobe).filter(|_| wo[2] > 0.0) else {
            return BsdfSample::lost([0.0, 0.0, 1.0], Component::Diffuse);
        };
        let component = if c == 0 {
            Component::Diffuse
        } else {
            Component::Lobe(c - 1)
        };
        let wi = self.draw(c, wo, u);
        if !(wi[2] > 0.0) {
            return BsdfSample::lost(wi, component);
        }
        BsdfSample::new(wi, model.eval(wo, wi), self.pdf(wo, wi), component)
    }

    /// Probability that a draw for wo leaves the upper hemisphere: per lobe,
    /// the fraction of a `cells` x `cells` midpoint grid of the random
    /// numbers (equal-probability strata of its table) whose half vector
    /// reflects wo below the horizon, weighed by the lobe's probability.
    pub fn lost_mass(&self, wo: Vec3, cells: usize) -> f64 {
        if !(wo[2] > 0.0) {
            return 1.0;
        }
        let mut lost = 0.0;
        for (m, dist) in self.lobes.iter().enumerate() {
            let Some(d) = dist else { continue };
            let n = cells.max(1);
            let mut l = 0.0;
            for a in 0..n {
                for b in 0..n {
                    let (t, phi) =
                        d.sample([(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64]);
                    let (sh, ch) = (t.sqrt(), (1.0 - t).max(0.0).sqrt());
                    let h = [sh * phi.cos(), sh * phi.sin(), ch];
                    if !(dot(wo, h) > 0.0 && reflect(wo, h)[2] > 0.0) {
                        l += 1.0;
                    }
                }
            }
            lost += self.select[m + 1] * l / (n * n) as f64;
        }
        lost
    }
}
