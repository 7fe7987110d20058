//! A fitted model as a [`Bsdf`] for work that only evaluates it (the
//! render judge scores every candidate of `--model auto` by rendering):
//! [`NpfBxdf::new`](super::NpfBxdf::new) builds the importance-sampling
//! tables, about as long as a judge's renders take, so this view skips
//! them and draws cosine-weighted directions with their exact density.

use super::{cosine_hemisphere, cosine_hemisphere_pdf, unit, Bsdf, BsdfError, BsdfSample};
use super::{Component, FlatEval};
use crate::model::Model;
use npf_data_loaders::geometry::{Angles, Vec3};

/// A validated model evaluated as [`NpfBxdf`](super::NpfBxdf) evaluates it
/// (the same flat evaluator where the model has one, so the same values),
/// sampled by the cosine-weighted hemisphere.
pub struct EvaluatedModel {
    model: Model,
    flat: Option<FlatEval>,
}

impl EvaluatedModel {
    /// The view of `model`, refused as [`NpfBxdf::new`](super::NpfBxdf::new)
    /// refuses it.
    pub fn new(model: Model) -> Result<Self, BsdfError> {
        model.validate().map_err(BsdfError::InvalidModel)?;
        let flat = FlatEval::new(&model);
        Ok(EvaluatedModel { model, flat })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }
}

impl Bsdf for EvaluatedModel {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        match &self.flat {
            Some(f) => f.eval(wo, wi),
            None => self.model.eval(wo, wi),
        }
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if !(wo[2] > 0.0) {
            return None;
        }
        let wi = cosine_hemisphere([unit(u[0]), unit(u[1])]);
        if !(wi[2] > 0.0) {
            return None;
        }
        let s = BsdfSample::new(wi, self.eval(wo, wi), self.pdf(wo, wi), Component::Diffuse);
        (!s.is_lost()).then_some(s)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi)
    }

    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        self.model.eval_angles(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::NpfBxdf;
    use crate::model::Layout;
    use crate::synth::known_factor_model;
    use npf_data_loaders::geometry::spherical;

    #[test]
    fn evaluates_bit_for_bit_as_the_sampled_bsdf() {
        let model = known_factor_model(Layout::default(), &[0.1, 0.3]);
        let (a, b) = (
            EvaluatedModel::new(model.clone()).unwrap(),
            NpfBxdf::new(model).unwrap(),
        );
        for k in 0..200 {
            let wo = spherical(0.007 * k as f64, 0.1 * k as f64);
            let wi = spherical(1.5 - 0.0071 * k as f64, 2.0 + 0.07 * k as f64);
            assert_eq!(Bsdf::eval(&a, wo, wi), Bsdf::eval(&b, wo, wi));
        }
    }

    #[test]
    fn its_draws_carry_their_exact_density() {
        let a = EvaluatedModel::new(known_factor_model(Layout::default(), &[0.2])).unwrap();
        let wo = spherical(0.6, 0.0);
        let n = 64;
        // Stratified draws: the mean of f cos / pdf is the albedo, and every
        // draw's pdf is what pdf() says.
        let mut albedo = [0.0; 3];
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                let s = a.sample(wo, 0.5, u).unwrap();
                assert_eq!(s.pdf, a.pdf(wo, s.wi));
                let f = a.eval(wo, s.wi);
                for c in 0..3 {
                    albedo[c] += f[c] * s.wi[2] / s.pdf / (n * n) as f64;
                }
            }
        }
        let want = crate::bsdf::albedo(0.6, &a);
        for c in 0..3 {
            assert!(
                (albedo[c] - want[c]).abs() < 0.02 * want[c],
                "{albedo:?} {want:?}"
            );
        }
    }
}
