//! A measured MERL table as a [`Bsdf`]: its own (truncating) lookup, zero
//! for missing cells and below the horizon, drawn by cosine-weighted
//! hemisphere sampling (the table has no sampler of its own).

use super::{cosine_draw, cosine_pdf_for, Bsdf, BsdfSample};
use npf_data_loaders::geometry::{half_diff_from_directions, Angles, Vec3};
use npf_data_loaders::MerlTable;

impl Bsdf for MerlTable {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let (th, _ph, td, pd) = half_diff_from_directions(wi, wo);
        self.lookup(th, td, pd).unwrap_or([0.0; 3])
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        cosine_draw(self, wo, u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        cosine_pdf_for(wo, wi)
    }

    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        self.lookup(a.theta_h, a.theta_d, a.phi_d)
            .unwrap_or([0.0; 3])
    }
}

/// A MERL table read by interpolation between its nodes
/// ([`MerlTable::lookup_interpolated`]): the reading under which a model
/// that reproduces every node reproduces the table (the truncating
/// [`MerlTable::lookup`] holds each node's value across its bin, which no
/// interpolating model follows near a sharp peak).
pub struct InterpolatedMerl<'a>(pub &'a MerlTable);

impl Bsdf for InterpolatedMerl<'_> {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let (th, _ph, td, pd) = half_diff_from_directions(wi, wo);
        self.0.lookup_interpolated(th, td, pd).unwrap_or([0.0; 3])
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        cosine_draw(self, wo, u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        cosine_pdf_for(wo, wi)
    }

    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        self.0
            .lookup_interpolated(a.theta_h, a.theta_d, a.phi_d)
            .unwrap_or([0.0; 3])
    }
}
