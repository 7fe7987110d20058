//! Baseline models fitted by the same machinery and on the same weighted
//! samples as the shared-factor model, so the evaluation compares models and
//! not data handling:
//!
//! - **Independent-G** (Bagher et al. 2016): one lobe whose D, F and G are
//!   separate for each channel: rho_C = d_C + s_C D_C F_C G_C(theta_i)
//!   G_C(theta_o) / (cos theta_i cos theta_o), 3 x (1 + 1 + 3 x 90) = 816
//!   parameters. Fitted as three independent one-lobe AWLS fits, each on
//!   one channel (its values copied into all three channels of the sample
//!   set, so every solver stage is unchanged). Stored as an ordinary
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

use crate::cli::fit::FitConfig;
use crate::microfacet::{ggx_d_cos2, ggx_g1_tan2};
use crate::model::{Layout, Lobe, Model};
use crate::nnls::nnls_enumerate;
use crate::samples::{FitSet, SampleOptions};
use crate::solver::{Executor, FitOptions, FitResult, SweepReport};
use npf_data_loaders::{MeasuredSamples, MerlTable};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::time::Instant;

/// Which model a fit produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// The shared-factor model (1 to 3 lobes, `--lobes`).
    Factor,
    /// Bagher et al.'s Independent-G model: one lobe, per-channel D, F, G (816 parameters).
    IndependentG,
    /// Analytic GGX + Lambert with Schlick Fresnel (10 parameters).
    Ggx,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Factor => "factor",
            ModelKind::IndependentG => "independent-g",
            ModelKind::Ggx => "ggx",
        }
    }

    /// The number of free parameters the model really has (the stored form
    /// may hold more: structural zeros or tabulated analytic factors).
    pub fn effective_params(self, layout: &Layout, lobes: usize) -> usize {
        match self {
            ModelKind::Factor => layout.param_count(lobes),
            ModelKind::IndependentG => 3 * (2 + layout.d.len() + layout.f.len() + layout.g.len()),
            ModelKind::Ggx => 10,
        }
    }
}

/// Samples whose three channels all hold channel `c` of the input.
pub fn channel_samples(samples: &MeasuredSamples, c: usize) -> MeasuredSamples {
    let mut out = samples.clone();
    for s in &mut out.samples {
        s.rgb = [s.rgb[c]; 3];
    }
    out.source = format!("{} (channel {c})", samples.source);
    out
}

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

/// Fit the Independent-G model: three one-lobe fits with `opts` (its
/// `lobes` is ignored), one per channel, on the same weighting and cut-off.
/// The history adds the channels' objectives (each divided by 3, since a
/// channel's fit counts its values three times) and seconds sweep by sweep.
pub fn fit_independent_g(
    samples: &MeasuredSamples,
    layout: Layout,
    sample_options: SampleOptions,
    opts: FitOptions,
    observer: &mut dyn FnMut(usize, &SweepReport),
) -> Result<FitResult, String> {
    let opts = FitOptions { lobes: 1, ..opts };
    let t0 = Instant::now();
    let mut results = Vec::with_capacity(3);
    for c in 0..3 {
        let one = channel_samples(samples, c);
        let set = FitSet::build(&one, layout, sample_options).map_err(|e| e.to_string())?;
        let mut obs = |r: &SweepReport| observer(c, r);
        results.push(Executor::new(&set, opts).observe(&mut obs).run()?);
    }
    let models = [
        results[0].model.clone(),
        results[1].model.clone(),
        results[2].model.clone(),
    ];
    let model = independent_g_model(&models);
    let sweeps = results.iter().map(|r| r.history.len()).max().unwrap_or(0);
    let mut history = Vec::with_capacity(sweeps);
    for k in 0..sweeps {
        let mut objective = 0.0;
        let mut elapsed = 0.0;
        let mut prev = 0.0;
        for r in &results {
            let last = r.history.len().saturating_sub(1);
            let h = &r.history[k.min(last)];
            objective += h.objective / 3.0;
            elapsed += h.elapsed;
            prev += if k == 0 {
                r.initial_objective
            } else {
                r.history[(k - 1).min(last)].objective
            } / 3.0;
        }
        // elapsed: the time all three channels need to reach sweep k.
        history.push(SweepReport {
            sweep: k + 1,
            objective,
            rel_decrease: if prev > 0.0 {
                (prev - objective) / prev
            } else {
                0.0
            },
            elapsed,
            stages: Vec::new(),
            g_passes: Vec::new(),
            smoothing_reverted: 0,
            extrapolated: false,
            revived: 0,
        });
    }
    Ok(FitResult {
        factors: crate::solver::Factors::from_model(&model),
        model,
        initial_objective: results.iter().map(|r| r.initial_objective / 3.0).sum(),
        objective: results.iter().map(|r| r.objective / 3.0).sum(),
        history,
        converged: results.iter().all(|r| r.converged),
        seconds: t0.elapsed().as_secs_f64(),
    })
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
    drop(eval);
    let (params, objective) = ggx_solve(&set, la.exp());
    Ok(GgxFit {
        params,
        objective,
        trials: trials + 1,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Fit any model kind with a fit configuration (`config.lobes` applies to
/// the factor model only). The observer sees every sweep (of every channel
/// for Independent-G; none for GGX).
pub fn fit_kind(
    samples: &MeasuredSamples,
    config: &FitConfig,
    kind: ModelKind,
    observer: &mut dyn FnMut(usize, &SweepReport),
) -> Result<(FitResult, Option<GgxParams>), String> {
    let layout = Layout::default();
    let so = config.sample_options();
    match kind {
        ModelKind::Factor => {
            let set = FitSet::build(samples, layout, so).map_err(|e| e.to_string())?;
            let mut obs = |r: &SweepReport| observer(0, r);
            Ok((
                Executor::new(&set, config.fit_options())
                    .observe(&mut obs)
                    .run()?,
                None,
            ))
        }
        ModelKind::IndependentG => Ok((
            fit_independent_g(samples, layout, so, config.fit_options(), observer)?,
            None,
        )),
        ModelKind::Ggx => {
            let fit = fit_ggx(samples, so).map_err(|e| e.to_string())?;
            let model = fit.params.to_model(layout);
            Ok((
                FitResult {
                    factors: crate::solver::Factors::from_model(&model),
                    model,
                    initial_objective: fit.objective,
                    objective: fit.objective,
                    history: Vec::new(),
                    converged: true,
                    seconds: fit.seconds,
                },
                Some(fit.params),
            ))
        }
    }
}

/// A MERL table of an analytic GGX + Lambert BRDF (for tests and demos).
pub fn ggx_table(p: &GgxParams) -> MerlTable {
    crate::bsdf::to_merl(p)
}

/// Fit any model kind as `npf fit` does: in a pool of `config.threads`
/// threads, with the provenance (the kind, its effective parameter count
/// and, for GGX, the analytic parameters go into `FitInfo::selection`) and
/// errors against the input.
pub fn fitted(
    samples: &MeasuredSamples,
    config: &FitConfig,
    kind: ModelKind,
    progress: bool,
) -> Result<crate::cli::fit::Fitted, crate::cli::CliError> {
    use crate::cli::CliError;
    if kind == ModelKind::Factor {
        let mut f = crate::cli::fit::fit_samples(samples, config, progress)?;
        f.info.selection = Some(selection(kind, config.lobes, None));
        return Ok(f);
    }
    let opts = config.fit_options();
    if kind == ModelKind::IndependentG {
        FitOptions { lobes: 1, ..opts }
            .validate()
            .map_err(CliError::Message)?;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|e| CliError::Message(format!("cannot start {} threads: {e}", config.threads)))?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let bar = if progress && kind == ModelKind::IndependentG {
            indicatif::ProgressBar::new(3 * opts.max_sweeps as u64)
        } else {
            indicatif::ProgressBar::hidden()
        };
        let max = opts.max_sweeps as u64;
        let mut obs = |c: usize, r: &SweepReport| {
            bar.set_position(c as u64 * max + r.sweep as u64);
            bar.set_message(format!("channel {c}, objective {:.6e}", r.objective));
        };
        let (result, ggx) = fit_kind(samples, config, kind, &mut obs).map_err(CliError::Message)?;
        bar.finish_and_clear();
        let metrics = crate::metrics::compare_model(samples, config.max_theta, &result.model);
        let info = crate::modelfile::FitInfo {
            source: samples.source.clone(),
            npf_version: env!("CARGO_PKG_VERSION").into(),
            lobes: result.model.lobe_count(),
            weighting: format!("{:?}", config.weighting).to_lowercase(),
            epsilon: config.epsilon,
            max_theta_deg: config.max_theta,
            max_theta_h_deg: config.max_theta_h,
            d_monotone_from_deg: opts.d_monotone_from_deg,
            g_method: if kind == ModelKind::Ggx {
                "analytic".into()
            } else {
                format!("{:?}", config.g_method).to_lowercase()
            },
            smooth_g: config.smooth_g,
            sweeps: result.history.len(),
            converged: result.converged,
            objective: result.objective,
            seconds: result.seconds,
            threads,
            samples: metrics.samples,
            metrics: Some(metrics).filter(crate::metrics::Metrics::is_finite),
            selection: Some(selection(kind, config.lobes, ggx.as_ref())),
        };
        Ok(crate::cli::fit::Fitted {
            result,
            info,
            metrics,
        })
    })
}

/// The provenance note naming the model kind.
pub fn selection(kind: ModelKind, lobes: usize, ggx: Option<&GgxParams>) -> serde_json::Value {
    let layout = Layout::default();
    let mut v = serde_json::json!({
        "model": kind.name(),
        "effective_parameters": kind.effective_params(&layout, lobes),
    });
    if let Some(p) = ggx {
        v["ggx"] = serde_json::to_value(p).unwrap_or_default();
    }
    v
}

/// The model kind recorded in a model file's provenance (factor if none).
pub fn kind_of(info: Option<&crate::modelfile::FitInfo>) -> ModelKind {
    info.and_then(|i| i.selection.as_ref())
        .and_then(|s| s.get("model"))
        .and_then(|m| m.as_str())
        .and_then(|m| match m {
            "independent-g" => Some(ModelKind::IndependentG),
            "ggx" => Some(ModelKind::Ggx),
            _ => None,
        })
        .unwrap_or(ModelKind::Factor)
}
