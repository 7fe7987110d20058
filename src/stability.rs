//! The stability suite: synthetic inputs that break fitters, and what each
//! fitting method does on them.
//!
//! Every case is a BRDF npf tabulates itself (so the clean truth is known),
//! optionally degraded by multiplicative noise or missing cells. A run fits
//! one case with one configuration (G method, lobes, weighting), traces the
//! objective after every stage, and records whether it converged, whether
//! the objective ever rose, whether any factor became NaN/inf or negative,
//! whether lobes collapsed or duplicated, the error against the clean truth,
//! and the time. `tests/stability.rs` runs a reduced grid in CI;
//! `examples/stability_report.rs` runs the full grid.

use crate::fit::FitConfig;
use crate::metrics::compare_model;
use crate::model::Model;
use crate::samples::{FitSet, Weighting};
use crate::solver::{Executor, FitOptions, GMethod};
use crate::synth::GgxLambert;
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::{MeasuredSamples, MerlTable};
use rand::{Rng, SeedableRng};
use std::time::Instant;

type Brdf = Box<dyn Fn(&Angles) -> Option<[f64; 3]> + Sync + Send>;

/// How cells are lost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Missing {
    /// No cell is lost.
    None,
    /// Each cell independently with probability 1/2.
    RandomHalf,
    /// Every cell with theta_d in [lo, hi) degrees.
    ThetaDBand(f64, f64),
    /// Every cell with theta_i or theta_o above this many degrees.
    Beyond(f64),
}

/// One stability case: a known BRDF, perhaps noisy or with cells lost.
pub struct Case {
    /// Short name.
    pub name: &'static str,
    /// The true BRDF (None where it is not defined).
    pub truth: Brdf,
    /// Standard deviation of multiplicative log-normal noise (0: none).
    pub noise: f64,
    /// Which cells are lost.
    pub missing: Missing,
}

fn ggx(kd: [f64; 3], f0: [f64; 3], alpha: f64) -> GgxLambert {
    GgxLambert { kd, f0, alpha }
}

fn from(b: GgxLambert) -> Brdf {
    Box::new(move |a| b.eval_angles(a))
}

/// The hard cases of the suite.
pub fn cases() -> Vec<Case> {
    let glossy = ggx([0.1, 0.06, 0.03], [0.9, 0.6, 0.4], 0.1);
    let case = |name, truth, noise, missing| Case {
        name,
        truth,
        noise,
        missing,
    };
    vec![
        case(
            "near-mirror (GGX alpha 0.002)",
            from(ggx([0.004; 3], [0.05; 3], 0.002)),
            0.0,
            Missing::None,
        ),
        case(
            "very rough (GGX alpha 1)",
            from(ggx([0.3, 0.25, 0.2], [0.5; 3], 1.0)),
            0.0,
            Missing::None,
        ),
        case(
            "retro-reflective",
            Box::new(|a: &Angles| {
                (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| {
                    let retro = 2.0 * (-(a.theta_d / 0.12).powi(2)).exp();
                    [0.2, 0.15, 0.1].map(|kd| kd / std::f64::consts::PI + retro * kd)
                })
            }),
            0.0,
            Missing::None,
        ),
        case(
            "purely diffuse (Lambert)",
            Box::new(|a: &Angles| {
                (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0)
                    .then(|| [0.5, 0.3, 0.2].map(|kd| kd / std::f64::consts::PI))
            }),
            0.0,
            Missing::None,
        ),
        case(
            "two lobes, alpha 0.01 and 0.5",
            Box::new(|a: &Angles| {
                let narrow = ggx([0.0; 3], [0.2, 0.2, 0.3], 0.01).eval_angles(a)?;
                let wide = ggx([0.05; 3], [0.6, 0.4, 0.2], 0.5).eval_angles(a)?;
                Some(std::array::from_fn(|c| narrow[c] + wide[c]))
            }),
            0.0,
            Missing::None,
        ),
        case("noise 5%", from(glossy), 0.05, Missing::None),
        case("noise 20%", from(glossy), 0.20, Missing::None),
        case(
            "missing 50% of cells",
            from(glossy),
            0.0,
            Missing::RandomHalf,
        ),
        case(
            "missing theta_d band 30-45 deg",
            from(glossy),
            0.0,
            Missing::ThetaDBand(30.0, 45.0),
        ),
        case(
            "missing beyond 60 deg",
            from(glossy),
            0.0,
            Missing::Beyond(60.0),
        ),
        case(
            "dynamic range 1e6",
            from(ggx([0.01; 3], [1.0; 3], 0.005)),
            0.0,
            Missing::None,
        ),
        case(
            "tiny blue channel (1e-9)",
            from(ggx([0.1, 0.06, 1e-9], [0.9, 0.6, 1e-9], 0.1)),
            0.0,
            Missing::None,
        ),
        case(
            "zero blue channel",
            from(ggx([0.1, 0.06, 0.0], [0.9, 0.6, 0.0], 0.1)),
            0.0,
            Missing::None,
        ),
    ]
}

impl Case {
    /// The clean table, every valid sample.
    pub fn clean(&self) -> MeasuredSamples {
        MerlTable::from_fn(|th, td, pd| (self.truth)(&Angles::from_half_diff(th, 0.0, td, pd)))
            .samples(self.name)
    }

    /// The degraded data: every `thin`-th clean sample, with noise and cells
    /// lost as the case says (deterministic for a seed).
    pub fn data(&self, clean: &MeasuredSamples, thin: usize, seed: u64) -> MeasuredSamples {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut out = clean.clone();
        out.source = format!("{} (1/{thin} of the cells)", self.name);
        out.samples = clean
            .samples
            .iter()
            .step_by(thin.max(1))
            .filter_map(|s| {
                let a = &s.angles;
                let lost = match self.missing {
                    Missing::None => false,
                    Missing::RandomHalf => rng.gen::<bool>(),
                    Missing::ThetaDBand(lo, hi) => {
                        (lo.to_radians()..hi.to_radians()).contains(&a.theta_d)
                    }
                    Missing::Beyond(t) => a.theta_i.max(a.theta_o) > t.to_radians(),
                };
                if lost {
                    return None;
                }
                let mut s = *s;
                if self.noise > 0.0 {
                    for v in s.rgb.iter_mut() {
                        *v *= (self.noise * gaussian(&mut rng) - 0.5 * self.noise.powi(2)).exp();
                    }
                }
                Some(s)
            })
            .collect();
        out
    }
}

/// A standard normal variate (Box-Muller).
fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>();
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// One fit configuration of the stability suite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// How G is updated.
    pub g_method: GMethod,
    /// Specular lobes.
    pub lobes: usize,
    /// Residual weighting.
    pub weighting: Weighting,
}

/// What one fit did.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The case's name.
    pub case: String,
    /// The configuration.
    pub config: Config,
    /// Set when the fit could not start (e.g. no valid sample): the message.
    pub error: Option<String>,
    /// Whether the fit met its tolerance.
    pub converged: bool,
    /// Sweeps run.
    pub sweeps: usize,
    /// Largest relative rise of the objective from one stage to the next
    /// (0 when it never rose).
    pub max_rise: f64,
    /// The largest rise relative to the data's scale (the black model's
    /// objective): rounding of the incrementally updated residuals shows up
    /// here as ~1e-16..1e-14.
    pub max_rise_vs_data: f64,
    /// Largest accepted G change dE (must be < 0); None if none was accepted.
    pub worst_g_step: Option<f64>,
    /// Whether every parameter is finite.
    pub finite: bool,
    /// Whether every parameter is non-negative.
    pub non_negative: bool,
    /// "collapsed lobe m" or "lobes m and n duplicate", if any.
    pub degenerate: Option<String>,
    /// Error of the fitted model against the clean truth (theta <= 85 deg).
    pub rel_cos_rmse: f64,
    /// RMSE of log(1 + f cos theta_i) against the clean truth.
    pub log_rmse: f64,
    /// Fit seconds.
    pub seconds: f64,
}

impl Outcome {
    /// Monotone up to rounding: no stage raised the objective by more than
    /// 1e-12 of the data's scale, and every accepted G step lowered it.
    pub fn monotone(&self) -> bool {
        self.max_rise_vs_data <= 1e-12 && self.worst_g_step.map_or(true, |w| w < 0.0)
    }
}

/// Fit the degraded data with one configuration, tracing every stage.
pub fn run(
    case: &Case,
    clean: &MeasuredSamples,
    data: &MeasuredSamples,
    config: Config,
    max_sweeps: usize,
) -> Outcome {
    run_with(case, clean, data, config, max_sweeps, &FitConfig::default())
}

/// [`run`] on other settings than npf's defaults: `base` gives every
/// setting but the configuration's lobes, G method and weighting and the
/// sweep limit (to see, for example, what the data-decided grazing rule
/// does to a case).
pub fn run_with(
    case: &Case,
    clean: &MeasuredSamples,
    data: &MeasuredSamples,
    config: Config,
    max_sweeps: usize,
    base: &FitConfig,
) -> Outcome {
    let t0 = Instant::now();
    let mut out = Outcome {
        case: case.name.to_string(),
        config,
        error: None,
        converged: false,
        sweeps: 0,
        max_rise: 0.0,
        max_rise_vs_data: 0.0,
        worst_g_step: None,
        finite: true,
        non_negative: true,
        degenerate: None,
        rel_cos_rmse: f64::NAN,
        log_rmse: f64::NAN,
        seconds: 0.0,
    };
    let fc = FitConfig {
        lobes: config.lobes,
        g_method: config.g_method,
        weighting: config.weighting,
        max_sweeps,
        ..base.clone()
    };
    let set = match FitSet::build(data, fc.layout(), fc.sample_options_for(data)) {
        Ok(s) => s,
        Err(e) => {
            out.error = Some(e.to_string());
            return out;
        }
    };
    let opts = FitOptions {
        trace_stages: true,
        ..fc.fit_options()
    };
    let res = match Executor::new(&set, opts).run() {
        Ok(r) => r,
        Err(e) => {
            out.error = Some(e.to_string());
            return out;
        }
    };
    out.seconds = t0.elapsed().as_secs_f64();
    out.converged = res.converged;
    out.sweeps = res.history.len();
    let scale = set.data_energy();
    let mut prev = res.initial_objective;
    for r in &res.history {
        for s in &r.stages {
            let e = s.objective.unwrap_or(prev);
            if !e.is_finite() {
                out.finite = false;
            } else if prev > 0.0 {
                out.max_rise = out.max_rise.max((e - prev) / prev);
                out.max_rise_vs_data = out.max_rise_vs_data.max((e - prev) / scale);
            }
            prev = e;
        }
        for g in &r.g_passes {
            if g.accepted > 0 {
                let w = out
                    .worst_g_step
                    .map_or(g.worst_accepted, |w| w.max(g.worst_accepted));
                out.worst_g_step = Some(w);
            }
        }
    }
    let params = res.model.params();
    out.finite &= params.iter().all(|v| v.is_finite());
    out.non_negative = params.iter().all(|&v| v >= 0.0);
    out.degenerate = degenerate(&res.model);
    let m = compare_model(clean, 85.0, &res.model);
    out.rel_cos_rmse = m.rel_cos_rmse;
    out.log_rmse = m.log_rmse;
    out
}

/// A collapsed lobe carries (almost) nothing; two duplicate lobes have the
/// same D and G shapes.
pub fn degenerate(model: &Model) -> Option<String> {
    let peak = |m: usize| {
        let l = &model.lobes[m];
        let s = l.s.iter().cloned().fold(0.0f32, f32::max) as f64;
        let d = l.d.iter().cloned().fold(0.0f32, f32::max) as f64;
        let g = l.g.iter().cloned().fold(0.0f32, f32::max) as f64;
        s * d * g * g
    };
    let n = model.lobes.len();
    let biggest = (0..n).map(peak).fold(0.0, f64::max);
    for m in 0..n {
        if biggest > 0.0 && peak(m) < 1e-6 * biggest {
            return Some(format!("collapsed lobe {m}"));
        }
    }
    let cosine = |a: &[f32], b: &[f32]| {
        let dot: f64 = a.iter().zip(b).map(|(&x, &y)| x as f64 * y as f64).sum();
        let na: f64 = a.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
        let nb: f64 = b.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
        dot / (na * nb).max(f64::MIN_POSITIVE)
    };
    for m in 0..n {
        for k in m + 1..n {
            let (a, b) = (&model.lobes[m], &model.lobes[k]);
            if cosine(&a.d, &b.d) > 0.9999 && cosine(&a.g, &b.g) > 0.9999 {
                return Some(format!("lobes {m} and {k} duplicate"));
            }
        }
    }
    None
}
