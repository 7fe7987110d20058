//! The one analytic GGX: normal distribution, uncorrelated Smith G1,
//! Schlick's Fresnel, visible-normal sampling, and the GGX + Lambert BRDF
//! built from them.
//!
//! Shared by the solver's initial lobes, the synthetic tables, the GGX
//! baseline (its fit, its tabulated model and its [`crate::bsdf::Bsdf`]),
//! and the energy toolkit, so every part of npf means the same GGX.

use crate::grid::Grid;
use crate::model::{Layout, Lobe, Model};
use npf_data_loaders::geometry::{Angles, Vec3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// GGX normal distribution at half angle `theta_h` (normalised: the
/// integral of D cos theta_h over the hemisphere is 1).
pub fn ggx_d(theta_h: f64, alpha: f64) -> f64 {
    ggx_d_cos2(theta_h.cos().powi(2), alpha)
}

/// [`ggx_d`] from cos^2 theta_h (what the GGX fit caches per sample).
#[inline]
pub fn ggx_d_cos2(c2: f64, alpha: f64) -> f64 {
    let t2 = (1.0 - c2) / c2.max(1e-300);
    let a2 = alpha * alpha;
    1.0 / (PI * a2 * c2 * c2 * (1.0 + t2 / a2).powi(2))
}

/// Uncorrelated Smith G1 for GGX at polar angle `theta`; zero at and below
/// the horizon.
pub fn ggx_g1(theta: f64, alpha: f64) -> f64 {
    let c = theta.cos();
    if c <= 0.0 {
        return 0.0;
    }
    ggx_g1_tan2((1.0 - c * c) / (c * c), alpha)
}

/// [`ggx_g1`] from tan^2 theta (what the GGX fit caches per sample).
#[inline]
pub fn ggx_g1_tan2(t2: f64, alpha: f64) -> f64 {
    2.0 / (1.0 + (1.0 + alpha * alpha * t2).sqrt())
}

/// Schlick's Fresnel factor (1 - cos theta_d)^5, the weight of 1 - f0.
#[inline]
pub fn schlick_weight(cos_d: f64) -> f64 {
    (1.0 - cos_d).powi(5)
}

/// Schlick's Fresnel f0 + (1 - f0)(1 - cos theta_d)^5.
#[inline]
pub fn schlick(f0: f64, cos_d: f64) -> f64 {
    f0 + (1.0 - f0) * schlick_weight(cos_d)
}

/// A GGX normal from the distribution of normals visible from `w`,
/// proportional to max(0, w.m) D(m), for any unit `w` on the sphere (a `w`
/// below the horizon sees the surface from underneath); `u` two numbers in
/// [0, 1). Dupuy and Benyoub 2023: stretch to alpha = 1, draw on a
/// spherical cap of height 1 + w_z offset by w, stretch back.
pub fn ggx_visible_normal(alpha: f64, w: Vec3, u: [f64; 2]) -> Vec3 {
    let ws = normalize([alpha * w[0], alpha * w[1], w[2]]);
    let phi = 2.0 * PI * u[0];
    let z = (1.0 - u[1]) * (1.0 + ws[2]) - ws[2];
    let s = (1.0 - z * z).max(0.0).sqrt();
    let m = [s * phi.cos() + ws[0], s * phi.sin() + ws[1], z + ws[2]];
    let m = [alpha * m[0], alpha * m[1], m[2]];
    let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
    if !(l > 0.0) || !l.is_finite() {
        return [0.0, 0.0, 1.0];
    }
    [m[0] / l, m[1] / l, m[2] / l]
}

/// Density (per solid angle of m) with which [`ggx_visible_normal`] draws
/// m for a `w` above the horizon: G1(w) max(0, w.m) D(m) / w_z.
pub fn ggx_visible_normal_pdf(alpha: f64, w: Vec3, m: Vec3) -> f64 {
    let wm = w[0] * m[0] + w[1] * m[1] + w[2] * m[2];
    if !(w[2] > 0.0 && m[2] > 0.0 && wm > 0.0) {
        return 0.0;
    }
    let g1 = ggx_g1_tan2((1.0 - w[2] * w[2]).max(0.0) / (w[2] * w[2]), alpha);
    g1 * wm * ggx_d_cos2(m[2] * m[2], alpha) / w[2]
}

fn normalize(v: Vec3) -> Vec3 {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// The analytic GGX + Lambert BRDF: rho_C = kd_C / pi + ks_C D F_C G1 G1 /
/// (4 cos theta_i cos theta_o), Schlick F_C with f0_C, uncorrelated Smith
/// G1: 10 parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GgxParams {
    /// Diffuse albedo per channel (the Lambert term is kd / pi).
    pub kd: [f64; 3],
    /// Specular scale per channel.
    pub ks: [f64; 3],
    /// Fresnel reflectance at normal incidence per channel.
    pub f0: [f64; 3],
    /// GGX roughness.
    pub alpha: f64,
}

impl GgxParams {
    /// BRDF value (1/sr) per channel; zero below the horizon.
    pub fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if ci <= 0.0 || co <= 0.0 {
            return [0.0; 3];
        }
        let d = ggx_d(a.theta_h, self.alpha);
        let g = ggx_g1(a.theta_i, self.alpha) * ggx_g1(a.theta_o, self.alpha);
        let s5 = schlick_weight(a.theta_d.cos());
        std::array::from_fn(|c| {
            let f = self.f0[c] + (1.0 - self.f0[c]) * s5;
            self.kd[c] / PI + self.ks[c] * (d * f * g / (4.0 * ci * co))
        })
    }

    /// The same BRDF as a one-lobe factor model: d = kd / pi, s = ks / 4,
    /// D = GGX D, G = Smith G1, F_C = Schlick, tabulated on `layout`.
    pub fn to_model(&self, layout: Layout) -> Model {
        let alpha = self.alpha;
        Model {
            layout,
            diffuse: self.kd.map(|k| (k / PI) as f32),
            diffuse_form: Default::default(),
            masking: Default::default(),
            compensation: None,
            fresnel: self
                .f0
                .map(|f0| tabulate(layout.f, &|t| schlick(f0, t.cos()))),
            lobes: vec![Lobe {
                s: self.ks.map(|k| (k / 4.0) as f32),
                d: tabulate(layout.d, &|t| ggx_d(t, alpha)),
                g: tabulate(layout.g, &|t| ggx_g1(t, alpha)),
            }],
        }
    }
}

/// The values of `f(theta)` at a grid's nodes (the same profile in every
/// phi column), as a model stores them.
pub fn tabulate(grid: Grid, f: &dyn Fn(f64) -> f64) -> Vec<f32> {
    crate::grid::theta_table(grid, f)
        .into_iter()
        .map(|v| v as f32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visible_normal_pdf_integrates_to_one() {
        let alpha = 0.3;
        let w = [0.6f64.sin(), 0.0, 0.6f64.cos()];
        let (n, m) = (400, 400);
        let mut sum = 0.0;
        for a in 0..n {
            let t = (a as f64 + 0.5) / n as f64 * PI / 2.0;
            for b in 0..m {
                let p = (b as f64 + 0.5) / m as f64 * 2.0 * PI;
                let h = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
                sum += ggx_visible_normal_pdf(alpha, w, h)
                    * t.sin()
                    * (PI / 2.0 / n as f64)
                    * (2.0 * PI / m as f64);
            }
        }
        assert!((sum - 1.0).abs() < 2e-3, "{sum}");
    }
}
