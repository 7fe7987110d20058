//! Analytic BRDFs with known factors, tabulated as MERL tables: what the
//! tests, the demo and the benchmarks' sanity checks fit, so nothing needs
//! measured data.

use crate::microfacet::{ggx_d, ggx_g1, schlick, tabulate, GgxParams};
use crate::model::{Layout, Lobe, Model};
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::MerlTable;

/// A physically based GGX + Lambert BRDF: kd / pi + ks D F G1 G1 / (4 cos cos),
/// with Schlick's Fresnel (f0 per channel) and uncorrelated Smith G1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxLambert {
    /// Diffuse albedo per channel.
    pub kd: [f64; 3],
    /// Fresnel reflectance at normal incidence per channel.
    pub f0: [f64; 3],
    /// GGX roughness.
    pub alpha: f64,
}

impl GgxLambert {
    /// The same BRDF as GGX + Lambert parameters (ks = 1).
    pub fn params(&self) -> GgxParams {
        GgxParams {
            kd: self.kd,
            ks: [1.0; 3],
            f0: self.f0,
            alpha: self.alpha,
        }
    }

    /// BRDF value (1/sr) per channel; `None` below the horizon (a missing
    /// MERL cell).
    pub fn eval_angles(&self, a: &Angles) -> Option<[f64; 3]> {
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| self.params().eval_angles(a))
    }

    /// The BRDF tabulated as a MERL table.
    pub fn table(&self) -> MerlTable {
        crate::bsdf::to_merl(&self.params())
    }
}

/// A model with known, smooth factors: GGX-shaped D of roughness
/// `alphas[m]`, Smith-like G, a Schlick-like F per channel, and distinct
/// per-channel scales. Not in canonical form; fitting it back tests the
/// solver, comparing values (the factors themselves are only defined up to
/// the gauge).
pub fn known_factor_model(layout: Layout, alphas: &[f64]) -> Model {
    let f0 = [0.9, 0.6, 0.3];
    let fresnel = f0.map(|f0: f64| tabulate(layout.f, &|t| schlick(f0, t.cos())));
    let lobes = alphas
        .iter()
        .enumerate()
        .map(|(m, &a)| Lobe {
            s: [[0.8, 0.5, 0.3], [0.2, 0.3, 0.5], [0.1, 0.1, 0.1]][m % 3],
            d: tabulate(layout.d, &|t| ggx_d(t, a)),
            g: tabulate(layout.g, &|t| ggx_g1(t, a * 1.5)),
        })
        .collect();
    Model {
        layout,
        diffuse: [0.05, 0.08, 0.03],
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel,
        lobes,
    }
}

/// Ashikhmin-Shirley's coupled diffuse factor at one direction, 1 - (1 -
/// cos theta / 2)^5, on `n` uniform theta nodes spanning [0, pi/2] (a
/// separable diffuse form's P, [`crate::model::DiffuseForm::Separable`],
/// not rescaled to its gauge).
pub fn ashikhmin_shirley_p(n: usize) -> Vec<f32> {
    (0..n)
        .map(|k| {
            let theta = k as f64 / (n - 1) as f64 * std::f64::consts::FRAC_PI_2;
            (1.0 - (1.0 - 0.5 * theta.cos()).powi(5)) as f32
        })
        .collect()
}
