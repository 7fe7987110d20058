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

use crate::bsdf::{Bsdf, NpfBxdf};
use crate::fit::{fit as fit_one, FitConfig, FitError, Fitted, ModelKind};
use crate::judge::{Judge, RenderScore};
use crate::render::RenderOptions;
use crate::samples::Weighting;
use crate::solver::{DiffuseKind, SweepReport};
use npf_data_loaders::MeasuredSamples;

/// A candidate must beat the default's mean render PSNR by more than this
/// (dB) to be chosen.
pub const MARGIN_DB: f64 = 0.1;

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
    /// Its log RMSE against the samples (the fit's own measure).
    pub log_rmse: f64,
    /// Its relative cosine-weighted RMSE.
    pub rel_cos_rmse: f64,
    /// Its fit's seconds.
    pub seconds: f64,
}

/// Fit every candidate of `config` to `samples`, judge each against
/// `reference` (the same table as a BSDF) rendered with `opts`, and return
/// the chosen fit, its provenance extended by the record of all of them.
pub fn fit(
    samples: &MeasuredSamples,
    reference: &(dyn Bsdf + Sync),
    config: &FitConfig,
    opts: RenderOptions,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    let judge = Judge::new(reference, opts);
    let mut fits = Vec::new();
    let mut records = Vec::new();
    for (name, c) in candidates(config) {
        let t = std::time::Instant::now();
        let fitted = fit_one(samples, &c, observer)?;
        let seconds = t.elapsed().as_secs_f64();
        let bsdf =
            NpfBxdf::new(fitted.result.model.clone()).map_err(|e| FitError::Unrepresentable {
                source_name: samples.source.clone(),
                problem: format!("the {name} candidate cannot be rendered: {e}"),
            })?;
        records.push(CandidateRecord {
            name,
            render: judge.score(&bsdf),
            log_rmse: fitted.metrics.log_rmse,
            rel_cos_rmse: fitted.metrics.rel_cos_rmse,
            seconds,
        });
        fits.push(fitted);
    }
    let chosen = choose(&records);
    let mut fitted = fits.swap_remove(chosen);
    let record = serde_json::json!({
        "chosen": records[chosen].name,
        "margin_db": MARGIN_DB,
        "scenes": judge.scene_names(),
        "render": { "res": opts.res, "n_theta": opts.n_theta, "env": format!("{:?}", opts.env) },
        "candidates": records,
    });
    if let Some(sel) = fitted.info.selection.as_mut() {
        sel["auto"] = record;
    }
    Ok(fitted)
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
