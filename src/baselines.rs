//! Baseline models fitted by the same machinery and on the same weighted
//! samples as the shared-factor model, so the evaluation compares models and
//! not data handling:
//!
//! - **Independent-G** (Bagher et al. 2016): one lobe whose D, F and G are
//!   separate for each channel: rho_C = d_C + s_C D_C F_C G_C(theta_i)
//!   G_C(theta_o) / (cos theta_i cos theta_o), 3 x (1 + 1 + 3 x 90) = 816
//!   parameters. Fitted as one AWLS fit of three lobes with a channel
//!   mask (lobe C may light channel C only), which separates into the
//!   three per-channel problems. Stored as an ordinary
//!   three-lobe factor model whose lobe C has scale s_C in channel C and 0
//!   in the others (822 numbers, 6 of them structural zeros), so `npf
//!   reconstruct`, `eval` and `info` read it like any other model.
//! - **GGX + Lambert**: rho_C = kd_C / pi + ks_C D(alpha) F_C G1 G1 / (4 cos
//!   theta_i cos theta_o), Schlick F_C = f0_C + (1 - f0_C)(1 - cos theta_d)^5,
//!   uncorrelated Smith G1: 10 parameters (kd, ks, f0 per channel, alpha).
//!   For a given alpha the model is linear in (kd_C, ks_C f0_C, ks_C (1 -
//!   f0_C)) per channel: a 3-unknown non-negative weighted least-squares
//!   problem solved exactly (all active sets); alpha is found by a
//!   log-spaced scan followed by golden-section search on log alpha. Stored
//!   as a one-lobe factor model with these factors tabulated on the default
//!   layout (the analytic parameters are kept in the file's provenance).
//!
//! Both are fitted through [`crate::fit::fit`] (`ModelKind` picks the model).

use crate::microfacet::{ggx_d_cos2, ggx_g1_tan2};
use crate::model::{Lobe, Model};
use crate::nnls::nnls_enumerate;
use crate::samples::SampleOptions;
use npf_data_loaders::{MeasuredSamples, MerlTable};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// The Independent-G model of three one-lobe, single-channel models
/// (channel 0 of each is used).
pub fn independent_g_model(per_channel: &[Model; 3]) -> Model {
    let layout = per_channel[0].layout;
    let mut diffuse = [0f32; 3];
    let mut fresnel: [Vec<f32>; 3] = Default::default();
    let mut lobes = Vec::with_capacity(3);
    for (c, m) in per_channel.iter().enumerate() {
        diffuse[c] = m.diffuse[0];
        fresnel[c] = m.fresnel[0].clone();
        let mut s = [0f32; 3];
        s[c] = m.lobes[0].s[0];
        lobes.push(Lobe {
            s,
            d: m.lobes[0].d.clone(),
            g: m.lobes[0].g.clone(),
        });
    }
    Model {
        layout,
        diffuse,
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel,
        lobes,
    }
}

pub use crate::microfacet::GgxParams;

/// A finished GGX + Lambert fit.
#[derive(Clone, Debug)]
pub struct GgxFit {
    /// The fitted parameters.
    pub params: GgxParams,
    /// Weighted least-squares objective (same weights as the factor fits).
    pub objective: f64,
    /// Objective evaluations (alpha trials).
    pub trials: usize,
    /// Wall-clock time of the fit.
    pub seconds: f64,
}

/// The weighted samples the GGX fit sees: the factor fit's cut-off and weights.
struct GgxSample {
    /// cos^2 theta_h, tan^2 theta_i, tan^2 theta_o, 1 / (4 cos cos).
    c2h: f64,
    t2i: f64,
    t2o: f64,
    inv4cc: f64,
    s5: f64,
    y: [f64; 3],
    w: [f64; 3],
}

fn ggx_solve(samples: &[GgxSample], alpha: f64) -> (GgxParams, f64) {
    // Per channel: A (3x3), b (3), c.
    type Acc = [[f64; 13]; 3];
    let acc: Acc = samples
        .par_chunks(8192)
        .map(|chunk| {
            let mut acc = [[0.0; 13]; 3];
            for s in chunk {
                // The one GGX D and Smith G1, from cached cosines.
                let d = ggx_d_cos2(s.c2h, alpha);
                let spec = d * ggx_g1_tan2(s.t2i, alpha) * ggx_g1_tan2(s.t2o, alpha) * s.inv4cc;
                let phi = [1.0 / PI, spec, spec * s.s5];
                for c in 0..3 {
                    let w = s.w[c];
                    let a = &mut acc[c];
                    for i in 0..3 {
                        for j in 0..3 {
                            a[3 * i + j] += w * phi[i] * phi[j];
                        }
                        a[9 + i] += w * phi[i] * s.y[c];
                    }
                    a[12] += w * s.y[c] * s.y[c];
                }
            }
            acc
        })
        .collect::<Vec<Acc>>()
        .into_iter()
        .fold([[0.0; 13]; 3], |mut t, p| {
            for c in 0..3 {
                for k in 0..13 {
                    t[c][k] += p[c][k];
                }
            }
            t
        });
    let mut p = GgxParams {
        kd: [0.0; 3],
        ks: [0.0; 3],
        f0: [0.0; 3],
        alpha,
    };
    let mut total = 0.0;
    for c in 0..3 {
        let a = &acc[c];
        let gram = nalgebra::DMatrix::from_fn(3, 3, |r, k| a[3 * r + k]);
        let rhs = nalgebra::DVector::from_column_slice(&a[9..12]);
        let x = nnls_enumerate(&gram, &rhs, &[0.0; 3]);
        // y'Wy - 2 b'x + x'Ax, summed in this order (the value is a small
        // difference of large sums, so the order shows in the last digits).
        let mut obj = a[12];
        for i in 0..3 {
            obj -= 2.0 * a[9 + i] * x[i];
            for j in 0..3 {
                obj += x[i] * a[3 * i + j] * x[j];
            }
        }
        p.kd[c] = x[0];
        p.ks[c] = x[1] + x[2];
        p.f0[c] = if p.ks[c] > 0.0 { x[1] / p.ks[c] } else { 1.0 };
        total += obj.max(0.0);
    }
    (p, total)
}

/// Why a GGX + Lambert fit could not start.
#[derive(Debug, thiserror::Error)]
pub enum GgxFitError {
    /// A sample value is NaN, infinite or negative.
    #[error("{source_name}: a sample has a non-finite or negative value")]
    InvalidSample {
        /// The sample set's source.
        source_name: String,
    },
    /// No sample lies within the grazing cut-off.
    #[error("{source_name}: no valid samples within the {max_theta_deg} degree cut-off")]
    NoSamples {
        /// The sample set's source.
        source_name: String,
        /// The cut-off (degrees).
        max_theta_deg: f64,
    },
}

/// Fit GGX + Lambert to the samples with the factor fit's weighting and
/// cut-off. Errors only on an empty or invalid sample set.
pub fn fit_ggx(samples: &MeasuredSamples, options: SampleOptions) -> Result<GgxFit, GgxFitError> {
    let t0 = Instant::now();
    let cut = options.max_theta_deg.to_radians();
    let mut set = Vec::with_capacity(samples.samples.len());
    for s in &samples.samples {
        let a = &s.angles;
        if s.rgb.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(GgxFitError::InvalidSample {
                source_name: samples.source.clone(),
            });
        }
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if a.theta_i > cut || a.theta_o > cut || ci <= 0.0 || co <= 0.0 {
            continue;
        }
        set.push(GgxSample {
            c2h: a.theta_h.cos().powi(2),
            t2i: (1.0 - ci * ci) / (ci * ci),
            t2o: (1.0 - co * co) / (co * co),
            inv4cc: 1.0 / (4.0 * ci * co),
            s5: crate::microfacet::schlick_weight(a.theta_d.cos()),
            y: s.rgb,
            w: s.rgb.map(|v| options.weight(v, ci)),
        });
    }
    if set.is_empty() {
        return Err(GgxFitError::NoSamples {
            source_name: samples.source.clone(),
            max_theta_deg: options.max_theta_deg,
        });
    }
    let mut trials = 0;
    let mut eval = |la: f64| {
        trials += 1;
        ggx_solve(&set, la.exp()).1
    };
    // Scan log alpha over [1e-3, 1.5], then refine by golden-section search
    // around the best grid point.
    let (lo, hi) = (1e-3f64.ln(), 1.5f64.ln());
    let n = 30;
    let grid: Vec<f64> = (0..=n)
        .map(|k| lo + (hi - lo) * k as f64 / n as f64)
        .collect();
    let vals: Vec<f64> = grid.iter().map(|&x| eval(x)).collect();
    let best = (0..=n)
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(0);
    let br = crate::golden::golden_section(
        &mut eval,
        grid[best.saturating_sub(1)],
        grid[(best + 1).min(n)],
        40,
        1e-5,
        true,
    );
    let (mut la, f_best) = br.best();
    if vals[best] < f_best {
        la = grid[best];
    }
    let (params, objective) = ggx_solve(&set, la.exp());
    Ok(GgxFit {
        params,
        objective,
        trials: trials + 1,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// A MERL table of an analytic GGX + Lambert BRDF (for tests and demos).
pub fn ggx_table(p: &GgxParams) -> MerlTable {
    crate::bsdf::to_merl(p)
}
