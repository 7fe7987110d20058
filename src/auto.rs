//! `--model auto`: fit several candidate forms on one table and keep the
//! one whose renders are closest to the table's own ([`crate::judge`]).
//!
//! No form is best everywhere (issue 43: Independent-G renders closer on a
//! steel, cosine-L2 weights on colour-changing paints, the separable
//! diffuse form on foams), and a table-space error can prefer the form
//! that renders worse, so the choice is made by rendering. The default form
//! is kept unless another beats its mean render PSNR by more than
//! [`MARGIN_DB`]: a richer form that only ties (the separable form contains
//! Lambert) is not worth its parameters. The model file records the choice
//! and every candidate's render and table errors (`selection.auto`).

use crate::bsdf::{Bsdf, EvaluatedModel};
use crate::coarse::{CoarseError, LevelsEnd};
use crate::fit::{
    fit as fit_one, AutoPlan, CandidateRun, FitConfig, FitError, Fitted, ModelKind, Screened,
};
use crate::judge::{Judge, RenderScore};
use crate::render::RenderOptions;
use crate::samples::{FitSet, SampleData, Weighting};
use crate::solver::{DiffuseKind, Factors, SweepReport};
use npf_data_loaders::MeasuredSamples;

/// A candidate must beat the default's mean render PSNR by more than this
/// (dB) to be chosen.
pub const MARGIN_DB: f64 = 0.1;

/// Sweeps a candidate that starts from the default's own factors (the
/// separable form, cosine-L2 weights) runs on the decimated level before
/// it is judged (the default runs the level to its own limits). Measured
/// on the 26 shared tables (BENCHMARKS.md, issue 43): against 25 sweeps,
/// the same choice on 24, the other two near-ties (within 0.13 dB of the
/// default at 25 sweeps), 0.4 s less median auto time.
pub const SCREEN_SWEEPS: usize = 10;

/// Sweeps Independent-G runs before it is judged: it starts from the
/// default's lobes regrouped per channel ([`independent_start`]), further
/// from its optimum; at 15 sweeps it lost chm_mint's choice, which its
/// 25-sweep screen wins (BENCHMARKS.md, issue 43).
pub const SCREEN_SWEEPS_INDEPENDENT: usize = 25;

/// The chosen candidate's sweeps on the decimated level after its screen,
/// at most (and within the level's sweep limit). Measured on the 12 shared
/// tables where auto takes the separable form: against running on to the
/// level's limit, -0.16 to +1.3 dB under score.py (median -0.08) and a
/// maximum auto time of 2.5 s instead of 3.1 (BENCHMARKS.md, issue 43).
pub const RUN_ON_SWEEPS: usize = 40;

/// The screen's sweeps for a candidate's configuration.
fn screen_sweeps(config: &FitConfig) -> usize {
    match config.model {
        ModelKind::IndependentG => SCREEN_SWEEPS_INDEPENDENT,
        _ => SCREEN_SWEEPS,
    }
}

/// The candidate forms for a configuration, the default first: the
/// configuration's factor model with Lambertian diffuse, the same with the
/// separable diffuse form, Independent-G, and the factor model with
/// cosine-weighted L2 weights.
pub fn candidates(base: &FitConfig) -> Vec<(&'static str, FitConfig)> {
    let factor = FitConfig {
        model: ModelKind::Factor,
        diffuse: DiffuseKind::Lambert,
        ..base.clone()
    };
    vec![
        ("factor", factor.clone()),
        (
            "factor, separable diffuse",
            FitConfig {
                diffuse: DiffuseKind::Separable,
                ..factor.clone()
            },
        ),
        (
            "independent-g",
            FitConfig {
                model: ModelKind::IndependentG,
                ..factor.clone()
            },
        ),
        (
            "factor, cosine-l2 weights",
            FitConfig {
                weighting: Weighting::CosineL2,
                ..factor
            },
        ),
    ]
}

/// One candidate's outcome, as recorded.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CandidateRecord {
    /// The candidate's name ([`candidates`]).
    pub name: &'static str,
    /// Its render scores against the table.
    pub render: RenderScore,
    /// Its log RMSE against the samples it was judged on (the screen's
    /// decimated samples, or all of them without a screen).
    pub log_rmse: f64,
    /// Its relative cosine-weighted RMSE, likewise.
    pub rel_cos_rmse: f64,
    /// Its fit's seconds.
    pub seconds: f64,
    /// Its fit's sweeps (on the screen's decimated set, or all samples).
    pub sweeps: usize,
}

/// Fit `config`'s candidates to `samples`, judge each against `reference`
/// (the same table as a BSDF) rendered with `opts`, and return the chosen
/// fit, its provenance extended by the record of all of them. Where the
/// fit runs a decimated level ([`crate::coarse`]), the candidates are
/// screened there ([`screen`]) and only the chosen one is fitted on all
/// samples; otherwise each is fitted in full.
pub fn fit(
    samples: &MeasuredSamples,
    reference: &(dyn Bsdf + Sync),
    config: &FitConfig,
    opts: RenderOptions,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    let judge = Judge::new(reference, opts);
    let data = SampleData::Records(std::borrow::Cow::Borrowed(samples));
    judged(
        data,
        &judge,
        config,
        observer,
        |_, config, plan, observer| crate::fit::fit_with(samples, config, Some(plan), observer),
    )
}

/// [`fit`] owning the samples, judged by `judge`: a MERL table's grid
/// need not be made into records, and `reread` gives the table again for
/// the error measures (as [`crate::fit::fit_owned`]).
pub fn fit_owned(
    samples: SampleData<'static>,
    reread: impl FnOnce() -> Result<npf_data_loaders::Table, FitError> + Send,
    judge: &Judge,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    judged(
        samples,
        judge,
        config,
        observer,
        |samples, config, plan, observer| {
            crate::fit::fit_owned_with(samples, reread, config, Some(plan), observer)
        },
    )
}

/// The plan's fit (`fit_planned`) where a decimated level runs, every
/// candidate fitted in full otherwise.
fn judged<'a>(
    samples: SampleData<'a>,
    judge: &Judge,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
    fit_planned: impl FnOnce(
        SampleData<'a>,
        &FitConfig,
        &AutoPlan,
        &mut (dyn FnMut(usize, &SweepReport) + Send),
    ) -> Result<Fitted, FitError>,
) -> Result<Fitted, FitError> {
    if !crate::fit::auto_screens(config, &samples) {
        return match &samples {
            SampleData::Records(s) => fit_each(s, judge, config, observer),
            SampleData::Merl(m) => {
                fit_each(&m.table().samples(m.source()), judge, config, observer)
            }
        };
    }
    let screen = |end: &LevelsEnd<'_>, runs: &[CandidateRun]| screen(judge, end, runs);
    let plan = AutoPlan {
        candidates: candidates(config),
        screen: &screen,
    };
    let config = FitConfig {
        model: ModelKind::Auto,
        ..config.clone()
    };
    fit_planned(samples, &config, &plan, observer)
}

/// Auto's screen: every candidate fitted on the last decimated level from
/// where the default's levels ended (the separable form and cosine-L2
/// weights from its factors, Independent-G from its lobes summed per
/// channel, [`independent_start`]), each judged by its renders; the
/// chosen one's decimated fit is where the full set starts.
pub fn screen(
    judge: &Judge,
    end: &LevelsEnd<'_>,
    runs: &[CandidateRun],
) -> Result<Screened, CoarseError> {
    let mut results = Vec::with_capacity(runs.len());
    let mut records = Vec::with_capacity(runs.len());
    // Candidates with their own weights get their own decimated set, kept
    // for the chosen one's run on.
    let mut own_sets = Vec::with_capacity(runs.len());
    for (i, run) in runs.iter().enumerate() {
        let t = std::time::Instant::now();
        let result = if i == 0 {
            // The default: the levels' own run.
            end.result.clone()
        } else {
            let start = match run.config.model {
                ModelKind::IndependentG => independent_start(&end.result.factors),
                _ => end.result.factors.clone(),
            };
            own_sets.push(own_set(end, run)?);
            let set = own_sets[i - 1].as_ref().unwrap_or(end.set);
            end.run(set, (run.opts, screen_sweeps(&run.config)), start, None)?
        };
        let seconds = t.elapsed().as_secs_f64();
        let model = &result.model;
        let render = match EvaluatedModel::new(model.clone()) {
            Ok(bsdf) => judge.score(&bsdf),
            // Not renderable: never chosen.
            Err(_) => RenderScore {
                psnr_db: Vec::new(),
                mean_db: f64::NEG_INFINITY,
                linear_psnr_db: Vec::new(),
                linear_mean_db: f64::NEG_INFINITY,
            },
        };
        let m = crate::metrics::compare_model(end.kept, run.config.max_theta, model);
        records.push(CandidateRecord {
            name: run.name,
            render,
            log_rmse: m.log_rmse,
            rel_cos_rmse: m.rel_cos_rmse,
            seconds,
            sweeps: result.history.len(),
        });
        results.push(result);
        crate::phases::mark(&format!("screen: {}", run.name));
    }
    let chosen = choose(&records);
    let mut result = results.swap_remove(chosen);
    // The chosen one's level runs on, within the level's sweep limit.
    let mut continued = 0;
    let left = end
        .schedule
        .max_sweeps
        .saturating_sub(result.history.len())
        .min(RUN_ON_SWEEPS);
    if chosen != 0 && !result.converged && left > 0 {
        let run = &runs[chosen];
        let start = result.factors.clone();
        let form = result.model.diffuse_form.clone();
        let set = own_sets[chosen - 1].as_ref().unwrap_or(end.set);
        result = end.run(set, (run.opts, left), start, Some(form))?;
        continued = result.history.len();
        crate::phases::mark("screen: the chosen one's level run on");
    }
    let mut record = auto_record(judge, &records, chosen);
    record["screened_on"] = serde_json::json!({
        "factor": end.schedule.factors.last(),
        "samples": end.set.len(),
        "sweeps": SCREEN_SWEEPS,
        "sweeps_independent_g": SCREEN_SWEEPS_INDEPENDENT,
        "run_on_at_most": RUN_ON_SWEEPS,
        "chosen_ran_on": continued,
    });
    Ok(Screened {
        chosen,
        result,
        record,
    })
}

/// The decimated set of a candidate with its own sample options
/// (weights), built from the level's samples; `None`: the level's set.
fn own_set(end: &LevelsEnd<'_>, run: &CandidateRun) -> Result<Option<FitSet>, CoarseError> {
    Ok(if run.so == end.so {
        None
    } else {
        Some(FitSet::build(end.kept, end.layout, run.so)?)
    })
}

/// Independent-G's start from a factor fit: channel C's lobe is the sum
/// of the fit's lobes in that channel (s_C^m D^m, one non-parametric D
/// holds it), its G their mean weighted by each lobe's peak in that
/// channel, F and d as fitted. Its render is the factor fit's but for G.
pub fn independent_start(f: &Factors) -> Factors {
    let lobes = f.lobes();
    let (nd, ng) = (f.d[0].len(), f.g[0].len());
    let mut s = vec![[0.0; 3]; 3];
    let mut d = vec![vec![0.0; nd]; 3];
    let mut g = vec![vec![0.0; ng]; 3];
    for c in 0..3 {
        s[c][c] = 1.0;
        for m in 0..lobes {
            for (k, v) in d[c].iter_mut().enumerate() {
                *v += f.s[m][c] * f.d[m][k];
            }
        }
        let w: Vec<f64> = (0..lobes)
            .map(|m| (f.s[m][c] * f.d[m][0]).max(0.0))
            .collect();
        let total: f64 = w.iter().sum();
        for (k, v) in g[c].iter_mut().enumerate() {
            *v = if total > 0.0 {
                (0..lobes).map(|m| w[m] * f.g[m][k]).sum::<f64>() / total
            } else {
                f.g[0][k]
            };
        }
        if d[c].iter().all(|&v| v <= 0.0) {
            // No specular in this channel: a lobe's shape, no scale.
            d[c] = f.d[0].clone();
            s[c][c] = 0.0;
        }
    }
    Factors {
        layout: f.layout,
        diffuse: f.diffuse,
        s,
        d,
        g,
        f: f.f.clone(),
        masking: f.masking,
    }
}

/// Without a decimated level: every candidate fitted on all samples.
fn fit_each(
    samples: &MeasuredSamples,
    judge: &Judge,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    let mut fits = Vec::new();
    let mut records = Vec::new();
    for (name, c) in candidates(config) {
        let t = std::time::Instant::now();
        let fitted = fit_one(samples, &c, observer)?;
        let seconds = t.elapsed().as_secs_f64();
        let bsdf = EvaluatedModel::new(fitted.result.model.clone()).map_err(|e| {
            FitError::Unrepresentable {
                source_name: samples.source.clone(),
                problem: format!("the {name} candidate cannot be rendered: {e}"),
            }
        })?;
        records.push(CandidateRecord {
            name,
            render: judge.score(&bsdf),
            log_rmse: fitted.metrics.log_rmse,
            rel_cos_rmse: fitted.metrics.rel_cos_rmse,
            seconds,
            sweeps: fitted.result.history.len(),
        });
        fits.push(fitted);
    }
    let chosen = choose(&records);
    let mut fitted = fits.swap_remove(chosen);
    if let Some(sel) = fitted.info.selection.as_mut() {
        sel["auto"] = auto_record(judge, &records, chosen);
    }
    Ok(fitted)
}

/// `fit.selection.auto`: the choice, the judge's settings and every
/// candidate's record.
fn auto_record(judge: &Judge, records: &[CandidateRecord], chosen: usize) -> serde_json::Value {
    serde_json::json!({
        "chosen": records[chosen].name,
        "margin_db": MARGIN_DB,
        "scenes": judge.scene_names(),
        "render": judge.options_record(),
        "candidates": records,
    })
}

/// The index of the chosen candidate: the best mean render PSNR, unless
/// the default (index 0) is within [`MARGIN_DB`] of it.
pub fn choose(records: &[CandidateRecord]) -> usize {
    let score = |r: &CandidateRecord| r.render.mean_db;
    let best = (0..records.len())
        .max_by(|&a, &b| score(&records[a]).total_cmp(&score(&records[b])))
        .unwrap_or(0);
    if score(&records[best]) - score(&records[0]) > MARGIN_DB {
        best
    } else {
        0
    }
}
