//! Directional albedo of a fitted model's specular lobes, tabulated for
//! the energy-coupled diffuse form (Kelemen / Kulla-Conty, seed `001`).

use crate::bsdf::half_vector_quadrature;
use crate::model::{Compensation, DiffuseForm, Model, ALBEDO_NODES};
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
    specular_albedo_with(model, ALBEDO_NODES, NU, NPHI)
}

/// [`specular_albedo`] on `nodes` theta nodes with `nu` x `nphi`
/// quadrature strata (160 x 320 is [`crate::bsdf::albedo`]'s).
pub fn specular_albedo_with(model: &Model, nodes: usize, nu: usize, nphi: usize) -> [Vec<f64>; 3] {
    let mut spec = model.clone();
    spec.diffuse = [0.0; 3];
    spec.diffuse_form = DiffuseForm::Lambert;
    let mut out: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(nodes));
    for k in 0..nodes {
        let theta = (k as f64 / (nodes - 1) as f64 * FRAC_PI_2).min(89.5f64.to_radians());
        let a = half_vector_quadrature(theta, nu, nphi, 3, |wo, wi, w, acc| {
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
    coupled_form_of(specular_albedo(model))
}

fn coupled_form_of(e: [Vec<f64>; 3]) -> DiffuseForm {
    let clamped: [Vec<f64>; 3] =
        std::array::from_fn(|c| e[c].iter().map(|v| v.clamp(0.0, 1.0)).collect());
    DiffuseForm::EnergyCoupled {
        average: std::array::from_fn(|c| average_of(&clamped[c]).clamp(0.0, 1.0) as f32),
        albedo: std::array::from_fn(|c| clamped[c].iter().map(|&v| v as f32).collect()),
    }
}

/// Kulla-Conty's multiple-scattering term of a fitted model, from the
/// model's own lobes with F set to 1: f_ms,C = (1 - E1_C(theta_i)) (1 -
/// E1_C(theta_o)) / (pi (1 - E1avg_C)) times Kulla-Conty's colour factor
/// Favg_C E1avg_C / (1 - Favg_C (1 - E1avg_C)) (Favg_C = 2 int F_C mu dmu of
/// the model's Fresnel table; the factor is 1 when F = 1). E1 is the
/// directional albedo (integral of f cos) of sum_m s_C^m D^m G^m G^m / (cos
/// cos), clamped to [0, 1]. Returned as the form (the albedo tables and
/// averages) and the per-channel scale 1/pi times the colour factor.
pub fn multiple_scattering(model: &Model) -> (DiffuseForm, [f64; 3]) {
    let mut white = model.clone();
    white.compensation = None;
    for f in white.fresnel.iter_mut() {
        f.iter_mut().for_each(|v| *v = 1.0);
    }
    // A one-off, so the comparison's quadrature on half-degree nodes: a
    // fit's E bends sharply near its grazing cut-off.
    let form = coupled_form_of(specular_albedo_with(&white, 181, 160, 320));
    let DiffuseForm::EnergyCoupled { average, .. } = &form else {
        unreachable!("energy_coupled_form returns the coupled form")
    };
    let nf = model.layout.f.len();
    let scale = std::array::from_fn(|c| {
        // Favg on the F table's uniform theta_d nodes (midpoint rule).
        let f = &model.fresnel[c];
        let favg = (0..nf)
            .map(|k| {
                let t = (k as f64 + 0.5) / nf as f64 * FRAC_PI_2;
                2.0 * f[k] as f64 * t.cos() * t.sin() * FRAC_PI_2 / nf as f64
            })
            .sum::<f64>()
            // A Fresnel average cannot exceed 1; a fitted F (gauge F(0) = 1,
            // rising at grazing) can, and would make the denominator
            // below vanish.
            .min(1.0);
        let e = average[c] as f64;
        let colour = if e > 0.0 {
            favg * e / (1.0 - favg * (1.0 - e)).max(1e-6)
        } else {
            1.0
        };
        colour / std::f64::consts::PI
    });
    (form, scale)
}

/// [`multiple_scattering`] as the model's own [`Compensation`] term (what
/// `npf fit --compensate` stores).
pub fn compensation(model: &Model) -> Compensation {
    let (form, scale) = multiple_scattering(model);
    let DiffuseForm::EnergyCoupled { albedo, average } = form else {
        unreachable!("multiple_scattering returns the coupled form")
    };
    Compensation {
        albedo,
        average,
        scale: scale.map(|v| v as f32),
    }
}
