//! Directional albedo of a fitted model's specular lobes, tabulated for
//! the energy-coupled diffuse form (Kelemen / Kulla-Conty, seed `001`).

use crate::bsdf::half_vector_quadrature;
use crate::model::{DiffuseForm, Model, ALBEDO_NODES};
use std::f64::consts::FRAC_PI_2;

/// Strata of the half-vector quadrature in u and phi_h. Coarser than the
/// comparison's 160 x 320: the table is refreshed every sweep, and the
/// coupling only needs E to about 1e-3.
const NU: usize = 64;
const NPHI: usize = 128;

/// E_C(theta) = integral of the specular lobes' f cos over the incident
/// hemisphere at [`ALBEDO_NODES`] uniform theta nodes (the last at 89.5
/// degrees: the horizon itself sees nothing), per channel, unclamped.
pub fn specular_albedo(model: &Model) -> [Vec<f64>; 3] {
    let mut spec = model.clone();
    spec.diffuse = [0.0; 3];
    spec.diffuse_form = DiffuseForm::Lambert;
    let mut out: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(ALBEDO_NODES));
    for k in 0..ALBEDO_NODES {
        let theta = (k as f64 / (ALBEDO_NODES - 1) as f64 * FRAC_PI_2).min(89.5f64.to_radians());
        let a = half_vector_quadrature(theta, NU, NPHI, 3, |wo, wi, w, acc| {
            let v = spec.eval(wo, wi);
            for c in 0..3 {
                acc[c] += v[c] * w;
            }
        });
        for c in 0..3 {
            out[c].push(a[c]);
        }
    }
    out
}

/// 2 * integral over [0, 1] of E(mu) mu dmu for a table on uniform theta
/// nodes (linear in theta), by 8-point midpoint sub-steps per cell.
pub fn average_of(table: &[f64]) -> f64 {
    let n = table.len();
    let h = FRAC_PI_2 / (n - 1) as f64;
    let mut sum = 0.0;
    for k in 0..n - 1 {
        for q in 0..8 {
            let u = (q as f64 + 0.5) / 8.0;
            let theta = (k as f64 + u) * h;
            let e = table[k] * (1.0 - u) + table[k + 1] * u;
            // mu dmu = cos sin dtheta.
            sum += e * theta.cos() * theta.sin() * h / 8.0;
        }
    }
    2.0 * sum
}

/// The energy-coupled diffuse form of a model: its specular albedo clamped
/// to [0, 1] (measured lobes may reflect more than they receive) and the
/// clamped table's average.
pub fn energy_coupled_form(model: &Model) -> DiffuseForm {
    let e = specular_albedo(model);
    let clamped: [Vec<f64>; 3] =
        std::array::from_fn(|c| e[c].iter().map(|v| v.clamp(0.0, 1.0)).collect());
    DiffuseForm::EnergyCoupled {
        average: std::array::from_fn(|c| average_of(&clamped[c]).clamp(0.0, 1.0) as f32),
        albedo: std::array::from_fn(|c| clamped[c].iter().map(|&v| v as f32).collect()),
    }
}
