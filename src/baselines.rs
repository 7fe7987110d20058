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

use crate::model::{Layout, Lobe, Model};
use crate::samples::SampleOptions;
use crate::solver::init::{ggx_d, ggx_g1};
use npf_data_loaders::{MeasuredSamples, MerlTable};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
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
        fresnel,
        lobes,
    }
}

/// The analytic GGX + Lambert parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GgxParams {
    pub kd: [f64; 3],
    pub ks: [f64; 3],
    pub f0: [f64; 3],
    pub alpha: f64,
}

impl GgxParams {
    /// BRDF value (1/sr) per channel; zero below the horizon.
    pub fn eval_angles(&self, a: &npf_data_loaders::geometry::Angles) -> [f64; 3] {
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if ci <= 0.0 || co <= 0.0 {
            return [0.0; 3];
        }
        let spec = ggx_d(a.theta_h, self.alpha)
            * ggx_g1(a.theta_i, self.alpha)
            * ggx_g1(a.theta_o, self.alpha)
            / (4.0 * ci * co);
        let s5 = (1.0 - a.theta_d.cos()).powi(5);
        std::array::from_fn(|c| {
            self.kd[c] / PI + self.ks[c] * (self.f0[c] + (1.0 - self.f0[c]) * s5) * spec
        })
    }

    /// The same BRDF as a one-lobe factor model: d = kd / pi, s = ks / 4,
    /// D = GGX D, G = Smith G1, F_C = Schlick, tabulated on `layout`.
    pub fn to_model(&self, layout: Layout) -> Model {
        let table = |grid: crate::grid::Grid, f: &dyn Fn(f64) -> f64| -> Vec<f32> {
            crate::solver::init::theta_table(grid, f)
                .into_iter()
                .map(|v| v as f32)
                .collect()
        };
        let alpha = self.alpha;
        Model {
            layout,
            diffuse: self.kd.map(|k| (k / PI) as f32),
            fresnel: self
                .f0
                .map(|f0| table(layout.f, &|t| f0 + (1.0 - f0) * (1.0 - t.cos()).powi(5))),
            lobes: vec![Lobe {
                s: self.ks.map(|k| (k / 4.0) as f32),
                d: table(layout.d, &|t| ggx_d(t, alpha)),
                g: table(layout.g, &|t| ggx_g1(t, alpha)),
            }],
        }
    }
}

/// A finished GGX + Lambert fit.
#[derive(Clone, Debug)]
pub struct GgxFit {
    pub params: GgxParams,
    /// Weighted least-squares objective (same weights as the factor fits).
    pub objective: f64,
    /// Objective evaluations (alpha trials).
    pub trials: usize,
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

/// Best non-negative x for min x'Ax - 2 b'x + c over 3 unknowns, by trying
/// every active set; returns (x, objective).
fn nnls3(a: &[[f64; 3]; 3], b: &[f64; 3], c: f64) -> ([f64; 3], f64) {
    let mut best = ([0.0; 3], c);
    for mask in 1u32..8 {
        let idx: Vec<usize> = (0..3).filter(|k| mask & (1 << k) != 0).collect();
        let n = idx.len();
        let m = nalgebra::DMatrix::from_fn(n, n, |r, s| a[idx[r]][idx[s]]);
        let v = nalgebra::DVector::from_fn(n, |r, _| b[idx[r]]);
        let Some(sol) = m.clone().cholesky().map(|ch| ch.solve(&v)) else {
            continue;
        };
        if sol.iter().any(|&x| !(x >= 0.0) || !x.is_finite()) {
            continue;
        }
        let mut x = [0.0; 3];
        for (r, &k) in idx.iter().enumerate() {
            x[k] = sol[r];
        }
        let mut obj = c;
        for i in 0..3 {
            obj -= 2.0 * b[i] * x[i];
            for j in 0..3 {
                obj += x[i] * a[i][j] * x[j];
            }
        }
        if obj < best.1 {
            best = (x, obj);
        }
    }
    best
}

fn ggx_solve(samples: &[GgxSample], alpha: f64) -> (GgxParams, f64) {
    // Per channel: A (3x3), b (3), c.
    type Acc = [[f64; 13]; 3];
    let a2 = alpha * alpha;
    let acc: Acc = samples
        .par_chunks(8192)
        .map(|chunk| {
            let mut acc = [[0.0; 13]; 3];
            for s in chunk {
                // The GGX D and Smith G1 of `solver::init`, from cached cosines.
                let t2h = (1.0 - s.c2h) / s.c2h.max(1e-300);
                let d = 1.0 / (PI * a2 * s.c2h * s.c2h * (1.0 + t2h / a2).powi(2));
                let g1 = |t2: f64| 2.0 / (1.0 + (1.0 + a2 * t2).sqrt());
                let spec = d * g1(s.t2i) * g1(s.t2o) * s.inv4cc;
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
        let m = [[a[0], a[1], a[2]], [a[3], a[4], a[5]], [a[6], a[7], a[8]]];
        let (x, obj) = nnls3(&m, &[a[9], a[10], a[11]], a[12]);
        p.kd[c] = x[0];
        p.ks[c] = x[1] + x[2];
        p.f0[c] = if p.ks[c] > 0.0 { x[1] / p.ks[c] } else { 1.0 };
        total += obj.max(0.0);
    }
    (p, total)
}

/// Fit GGX + Lambert to the samples with the factor fit's weighting and
/// cut-off. Errors only on an empty or invalid sample set.
pub fn fit_ggx(samples: &MeasuredSamples, options: SampleOptions) -> Result<GgxFit, String> {
    let t0 = Instant::now();
    let cut = options.max_theta_deg.to_radians();
    let mut set = Vec::with_capacity(samples.samples.len());
    for s in &samples.samples {
        let a = &s.angles;
        if s.rgb.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(format!(
                "{}: a sample has a non-finite or negative value",
                samples.source
            ));
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
            s5: (1.0 - a.theta_d.cos()).powi(5),
            y: s.rgb,
            w: s.rgb.map(|v| options.weight(v, ci)),
        });
    }
    if set.is_empty() {
        return Err(format!(
            "{}: no valid samples within the {} degree cut-off",
            samples.source, options.max_theta_deg
        ));
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
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(n)]);
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = b - r * (b - a);
    let mut x2 = a + r * (b - a);
    let (mut f1, mut f2) = (eval(x1), eval(x2));
    for _ in 0..40 {
        if (b - a).abs() < 1e-5 {
            break;
        }
        if f1 <= f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - r * (b - a);
            f1 = eval(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + r * (b - a);
            f2 = eval(x2);
        }
    }
    let mut la = if f1 <= f2 { x1 } else { x2 };
    if vals[best] < f1.min(f2) {
        la = grid[best];
    }
    drop(eval);
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
    MerlTable::from_fn(|th, td, pd| {
        let a = npf_data_loaders::geometry::Angles::from_half_diff(th, 0.0, td, pd);
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| p.eval_angles(&a))
    })
}
