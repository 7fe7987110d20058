//! The GGX + Lambert baseline as a [`Bsdf`]: the analytic value, the GGX
//! visible-normal distribution for the specular part mixed with cosine
//! sampling for the diffuse part, and the exact mixture pdf.

use super::{cosine_hemisphere, cosine_hemisphere_pdf, reflect, unit, Bsdf, BsdfSample, Component};
use crate::microfacet::{ggx_visible_normal, ggx_visible_normal_pdf, GgxParams};
use npf_data_loaders::geometry::{Angles, Vec3};

/// Rec. 709 luminance of a per-channel weight.
fn luminance(v: [f64; 3]) -> f64 {
    0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]
}

impl GgxParams {
    /// Probability of the diffuse component in [`Bsdf::sample`]: the share
    /// of kd in kd + ks (luminance), 0 or 1 where one side is absent or the
    /// roughness cannot be sampled. `None` when nothing can be drawn.
    fn diffuse_probability(&self) -> Option<f64> {
        let d = luminance(self.kd).max(0.0);
        let s = if self.alpha > 0.0 && self.alpha.is_finite() {
            luminance(self.ks).max(0.0)
        } else {
            0.0
        };
        let total = d + s;
        (total > 0.0 && total.is_finite()).then(|| d / total)
    }
}

impl Bsdf for GgxParams {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return [0.0; 3];
        }
        self.eval_angles(&Angles::from_directions(wi, wo))
    }

    fn sample(&self, wo: Vec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if !(wo[2] > 0.0) {
            return None;
        }
        let p_diffuse = self.diffuse_probability()?;
        let (wi, component) = if unit(uc) < p_diffuse {
            (cosine_hemisphere(u), Component::Diffuse)
        } else {
            let h = ggx_visible_normal(self.alpha, wo, [unit(u[0]), unit(u[1])]);
            (reflect(wo, h), Component::Lobe(0))
        };
        if !(wi[2] > 0.0) {
            return None;
        }
        let s = BsdfSample::new(wi, self.eval(wo, wi), self.pdf(wo, wi), component);
        (!s.is_lost()).then_some(s)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        let Some(p_diffuse) = self.diffuse_probability() else {
            return 0.0;
        };
        let mut pdf = p_diffuse * cosine_hemisphere_pdf(wi);
        let s = [wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]];
        let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        if p_diffuse < 1.0 && n > 0.0 {
            let h = [s[0] / n, s[1] / n, s[2] / n];
            let wo_h = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
            if wo_h > 0.0 {
                // Reflection Jacobian: dOmega_h / dOmega_i = 1 / (4 wo.h).
                pdf += (1.0 - p_diffuse) * ggx_visible_normal_pdf(self.alpha, wo, h) / (4.0 * wo_h);
            }
        }
        pdf
    }

    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        GgxParams::eval_angles(self, a)
    }
}
