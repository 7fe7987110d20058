//! Analytic BRDFs with known factors, tabulated as MERL tables: what the
//! tests, the demo and the benchmarks' sanity checks fit, so nothing needs
//! measured data.

use crate::model::{Layout, Lobe, Model};
use crate::solver::init::{ggx_d, ggx_g1};
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::MerlTable;

/// A physically based GGX + Lambert BRDF: kd / pi + ks D F G1 G1 / (4 cos cos),
/// with Schlick's Fresnel (f0 per channel) and uncorrelated Smith G1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxLambert {
    pub kd: [f64; 3],
    pub f0: [f64; 3],
    pub alpha: f64,
}

impl GgxLambert {
    pub fn eval_angles(&self, a: &Angles) -> Option<[f64; 3]> {
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if ci <= 0.0 || co <= 0.0 {
            return None;
        }
        let d = ggx_d(a.theta_h, self.alpha);
        let g = ggx_g1(a.theta_i, self.alpha) * ggx_g1(a.theta_o, self.alpha);
        let schlick = (1.0 - a.theta_d.cos()).powi(5);
        Some(std::array::from_fn(|c| {
            let f = self.f0[c] + (1.0 - self.f0[c]) * schlick;
            self.kd[c] / std::f64::consts::PI + d * f * g / (4.0 * ci * co)
        }))
    }

    pub fn table(&self) -> MerlTable {
        MerlTable::from_fn(|th, td, pd| self.eval_angles(&Angles::from_half_diff(th, 0.0, td, pd)))
    }
}

/// A model with known, smooth factors: GGX-shaped D of roughness
/// `alphas[m]`, Smith-like G, a Schlick-like F per channel, and distinct
/// per-channel scales. Not in canonical form; fitting it back tests the
/// solver, comparing values (the factors themselves are only defined up to
/// the gauge).
pub fn known_factor_model(layout: Layout, alphas: &[f64]) -> Model {
    let table = |grid: crate::grid::Grid, f: &dyn Fn(f64) -> f64| {
        crate::solver::init::theta_table(grid, f)
            .into_iter()
            .map(|v| v as f32)
            .collect::<Vec<f32>>()
    };
    let f0 = [0.9, 0.6, 0.3];
    let fresnel = f0.map(|f0: f64| table(layout.f, &|t| f0 + (1.0 - f0) * (1.0 - t.cos()).powi(5)));
    let lobes = alphas
        .iter()
        .enumerate()
        .map(|(m, &a)| Lobe {
            s: [[0.8, 0.5, 0.3], [0.2, 0.3, 0.5], [0.1, 0.1, 0.1]][m % 3],
            d: table(layout.d, &|t| ggx_d(t, a)),
            g: table(layout.g, &|t| ggx_g1(t, a * 1.5)),
        })
        .collect();
    Model {
        layout,
        diffuse: [0.05, 0.08, 0.03],
        fresnel,
        lobes,
    }
}
