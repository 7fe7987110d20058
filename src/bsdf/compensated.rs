//! An energy-compensated fitted model: the model plus Kulla-Conty's
//! multiple-scattering term from its own lobes
//! ([`crate::energy::coupled::multiple_scattering`]).

use super::{
    cosine_hemisphere, cosine_hemisphere_pdf, unit, Bsdf, BsdfError, BsdfSample, Component, NpfBxdf,
};
use crate::energy::coupled::multiple_scattering;
use crate::model::{DiffuseForm, Model};
use npf_data_loaders::geometry::Vec3;

/// A model with its multiple-scattering term added: eval is Model::eval
/// plus f_ms; sampling draws f_ms's share cosine-weighted and the rest with
/// the model's own sampler (pdf the exact mixture).
pub struct Compensated {
    inner: NpfBxdf,
    form: DiffuseForm,
    scale: [f64; 3],
    /// Probability of the cosine draw for the f_ms term.
    p_ms: f64,
}

impl Compensated {
    /// Compensates `model` (validated first).
    pub fn new(model: Model) -> Result<Self, BsdfError> {
        let (form, scale) = multiple_scattering(&model);
        // f_ms's albedo at normal incidence against the model's, in luminance.
        let lum = |v: [f64; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
        let ms = lum(std::array::from_fn(|c| {
            std::f64::consts::PI * scale[c] * form.factor(0.0, 0.0, 1.0)[c]
        }));
        let inner = NpfBxdf::new(model)?;
        let total = ms + lum(super::albedo(0.0, &inner));
        let p_ms = if total > 0.0 {
            (ms / total).clamp(0.05, 0.95)
        } else {
            0.5
        };
        Ok(Compensated {
            inner,
            form,
            scale,
            p_ms,
        })
    }

    /// f_ms per channel.
    pub fn multiple_scattering(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let acos = |c: f64| c.clamp(-1.0, 1.0).acos();
        let b = self.form.factor(acos(wi[2]), acos(wo[2]), 1.0);
        std::array::from_fn(|c| self.scale[c] * b[c])
    }
}

impl Bsdf for Compensated {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        let (a, b) = (self.inner.eval(wo, wi), self.multiple_scattering(wo, wi));
        std::array::from_fn(|c| a[c] + b[c])
    }

    fn sample(&self, wo: Vec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if !(wo[2] > 0.0) {
            return None;
        }
        let uc = unit(uc);
        let (wi, component) = if uc < self.p_ms {
            (cosine_hemisphere(u), Component::Diffuse)
        } else {
            let s = Bsdf::sample(&self.inner, wo, (uc - self.p_ms) / (1.0 - self.p_ms), u)?;
            (s.wi, s.component)
        };
        let s = BsdfSample::new(wi, self.eval(wo, wi), self.pdf(wo, wi), component);
        (!s.is_lost()).then_some(s)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        self.p_ms * cosine_hemisphere_pdf(wi) + (1.0 - self.p_ms) * Bsdf::pdf(&self.inner, wo, wi)
    }
}
