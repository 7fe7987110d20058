//! The library's fit entry point: one [`FitConfig`] (whose `Default` is the
//! only place fit defaults are chosen), one [`fit`] for every [`ModelKind`],
//! and the [`Fitted`] result with its provenance.
//!
//! The `npf` program's flags, the benchmark report and library users all go
//! through here, so a model fitted by any of them is the same model.

mod config;
mod rules;

pub use config::*;
pub use rules::*;
use rules::{scalable, scale_energy};

use crate::baselines::{fit_ggx, GgxParams};
use crate::coarse::CoarseError;
use crate::metrics::{compare_model, compare_model_table, MerlReference, Metrics};
use crate::model::Layout;
use crate::modelfile::FitInfo;
use crate::samples::{SampleData, SampleOptions, SampleSource, Weighting};
use crate::solver::{
    init, DiffuseKind, Factors, FitOptions, FitResult, SweepReport, INDEPENDENT_CHANNELS,
};
use npf_data_loaders::MeasuredSamples;
use std::borrow::Cow;

/// A finished fit with its provenance and errors against the input.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// The solver's result (model, objective, history).
    pub result: FitResult,
    /// The provenance written into model files.
    pub info: FitInfo,
    /// Errors against the input samples within the grazing cut-off.
    pub metrics: Metrics,
}

/// What [`fit_model`] produced besides the solver result.
struct Produced {
    result: FitResult,
    ggx: Option<GgxParams>,
    /// Size of the fit set, where one was built for the whole fit.
    set_len: Option<usize>,
    /// What the data-dependent floor read and chose (read once, before the
    /// samples are freed).
    floor: FloorRule,
    /// The coarse-to-fine schedule as run (absent: no decimated level ran),
    /// for the record: whether G was fitted on the full set or kept.
    coarse: Option<serde_json::Value>,
    /// The error measures' model-independent part, where it was prepared
    /// during the fit.
    reference: Option<MerlReference>,
    /// Auto's screen: the chosen candidate (an index of the plan's) and
    /// the record of every candidate.
    auto: Option<(usize, serde_json::Value)>,
}

/// `--model auto`'s plan ([`crate::auto`]): the candidate forms, the
/// default first, and the screen that fits each from where the default's
/// decimated levels end and judges them. The full set then fits the
/// chosen one only.
pub struct AutoPlan<'a> {
    /// (name, configuration) of each candidate; the first is the default.
    pub candidates: Vec<(&'static str, FitConfig)>,
    /// The screen: given the levels' end and the candidates' runs, the
    /// chosen one's decimated fit and the record.
    #[allow(clippy::type_complexity)]
    pub screen: &'a (dyn Fn(&crate::coarse::LevelsEnd<'_>, &[CandidateRun]) -> Result<Screened, CoarseError>
             + Sync),
}

/// A candidate as the fit runs it.
pub struct CandidateRun {
    /// Its name.
    pub name: &'static str,
    /// Its configuration.
    pub config: FitConfig,
    /// Its solver options.
    pub opts: FitOptions,
    /// Its sample options (on this data).
    pub so: SampleOptions,
}

/// What auto's screen chose.
pub struct Screened {
    /// The chosen candidate's index.
    pub chosen: usize,
    /// Its fit on the decimated set (where the full set starts).
    pub result: FitResult,
    /// Every candidate's record.
    pub record: serde_json::Value,
}

/// The solver options a factor kind runs with on `layout`.
fn options_for(config: &FitConfig, layout: Layout) -> FitOptions {
    let base = FitOptions {
        gauss_newton: config.gauss_newton.unwrap_or(!layout.is_isotropic()),
        ..config.fit_options()
    };
    match config.model {
        ModelKind::IndependentG => FitOptions {
            lobes: 3,
            channel_mask: INDEPENDENT_CHANNELS,
            ..base
        },
        _ => base,
    }
}

/// Whether auto's plan can screen on `samples`: a decimated level runs.
pub fn auto_screens<S: SampleSource + ?Sized>(config: &FitConfig, samples: &S) -> bool {
    let layout = config.layout_for(samples);
    crate::coarse::levels_run_on(samples, layout, &config.coarse, config.lobes)
}

/// Refuse data beyond [`MAX_SAMPLE_VALUE`] before fitting it.
fn check_representable<S: SampleSource + ?Sized>(samples: &S) -> Result<(), FitError> {
    // Serial: a parallel scan measured 4 times the CPU time on the shared
    // machine for this one comparison a value.
    let big = (0..samples.sample_count())
        .flat_map(|i| samples.rgb(i))
        .find(|v| v.abs() > MAX_SAMPLE_VALUE);
    match big {
        Some(v) => Err(FitError::Unrepresentable {
            source_name: samples.source_name().to_string(),
            problem: format!(
                "a measured value of {v:e} 1/sr is beyond what a model can represent (at most {MAX_SAMPLE_VALUE:e}; models store f32)"
            ),
        }),
        None => Ok(()),
    }
}

/// Refuse a result whose model or measures are not finite in f32 (such a
/// model file could not be read back).
fn check_result(source: &str, result: &FitResult, metrics: &Metrics) -> Result<(), FitError> {
    let bad = |problem: String| FitError::Unrepresentable {
        source_name: source.to_string(),
        problem,
    };
    if let Err(e) = result.model.validate() {
        return Err(bad(format!("the fitted model cannot be stored: {e}")));
    }
    if !result.objective.is_finite()
        || !metrics.cos_rmse.is_finite()
        || !metrics.log_rmse.is_finite()
    {
        return Err(bad(format!(
            "the fit's objective ({:e}) or errors (RMSE {:e}, log RMSE {:e}) are not finite",
            result.objective, metrics.cos_rmse, metrics.log_rmse
        )));
    }
    Ok(())
}

/// Owned samples are freed during the fit, once its sample sets are built.
fn run_kind(
    samples: SampleData<'_>,
    config: &FitConfig,
    observer: &mut dyn FnMut(usize, &SweepReport),
    plan: Option<&AutoPlan>,
) -> Result<Produced, FitError> {
    config.validate()?;
    // The value check and the floor rule on the samples' own type, not
    // through `SampleData`'s match a sample: their passes then inline the
    // reads.
    crate::samples::on_data!(&samples, s => check_representable(s))?;
    crate::phases::mark("check values");
    let layout = config.layout_for(&samples);
    let floor = crate::samples::on_data!(&samples, s => config.floor_rule(s));
    let isotropic = samples.is_isotropic();
    let so = config.sample_options_with(&floor, isotropic);
    // The rule's parallel passes left their freed buffers in the worker
    // threads' heaps, which the set build would not reuse (up to 13 MB
    // more peak memory measured).
    crate::memory::release_free();
    crate::phases::mark("floor rule");
    // Both factor kinds are one run of the shared solver; Independent-G is
    // three lobes with lobe C lighting channel C only, so the objective
    // separates per channel and this solves the three per-channel problems
    // together, with one history.
    let factor_fit = |samples: SampleData<'_>,
                      opts: FitOptions,
                      start: Factors,
                      observer: &mut dyn FnMut(usize, &SweepReport),
                      screen: Option<crate::coarse::Screen>| {
        let mut obs = |r: &SweepReport| observer(0, r);
        let schedule = crate::coarse::Schedule {
            factors: &config.coarse,
            tol: config.coarse_tol,
            max_sweeps: config.coarse_max_sweeps,
            keep_g: config.keep_coarse_g.unwrap_or(layout.is_isotropic()),
            kept_g_tol: config.kept_g_tol.unwrap_or(2.0 * config.tol),
            gauss_newton: config.coarse_gauss_newton,
        };
        // The error measures' model-independent part (on a MERL grid whose
        // model the fast path can measure) beside the coarse level: it then
        // leaves the critical path after the fit.
        let prepare = layout.is_isotropic() && !matches!(config.diffuse, DiffuseKind::OrenNayar);
        let max_theta = config.max_theta;
        let beside = move |samples: &SampleData| match samples {
            SampleData::Merl(m) if prepare => {
                let t = std::time::Instant::now();
                let r = MerlReference::prepare(m, max_theta);
                Some((r, t.elapsed().as_secs_f64()))
            }
            _ => None,
        };
        let run = (schedule, opts, start);
        let (fitted, reference) =
            crate::coarse::fit_beside(samples, (layout, so), run, &mut obs, beside, screen)
                .map_err(|e| match e {
                    CoarseError::Samples(e) => FitError::Samples(e),
                    CoarseError::Solver(e) => FitError::Solver(e),
                })?;
        crate::phases::note("full set built after", fitted.set_seconds);
        let reference = reference.map(|(r, seconds)| {
            crate::phases::note("measures' reference, beside the coarse level", seconds);
            r
        });
        for l in &fitted.levels {
            crate::phases::note(
                &format!("coarse 1/{} ({} sweeps)", l.factor, l.sweeps),
                l.seconds,
            );
        }
        crate::phases::mark("fit (set, coarse, sweeps)");
        // `levels` is empty exactly when no decimated level ran, and G is
        // kept only when one did (`coarse::fit`).
        let coarse = (!fitted.levels.is_empty()).then(|| {
            let kept = schedule.keep_g;
            serde_json::json!({
                "levels": fitted.levels.iter().map(|l| {
                    let mut v = serde_json::json!({
                        "factor": l.factor,
                        "samples": l.samples,
                        "sweeps": l.sweeps,
                        "converged": l.converged,
                    });
                    if let Some(held) = l.separable_held {
                        v["separable_p_held"] = held.into();
                    }
                    v
                }).collect::<Vec<_>>(),
                "g_on_full_set": if kept { "kept" } else { "updated" },
                "full_set_tol": if kept { schedule.kept_g_tol } else { opts.tol },
            })
        });
        Ok::<_, FitError>(Produced {
            result: fitted.result,
            ggx: None,
            set_len: Some(fitted.set_len),
            floor,
            coarse,
            reference,
            auto: None,
        })
    };
    let mut produced = match config.model {
        ModelKind::Factor => {
            let opts = options_for(config, layout);
            let start = init::initial_factors(layout, opts.lobes);
            factor_fit(samples, opts, start, observer, None)
        }
        ModelKind::IndependentG => {
            let opts = options_for(config, layout);
            let alpha = init::start_alphas(1)[0];
            let start = init::initial_factors_with(layout, &[alpha; 3]);
            factor_fit(samples, opts, start, observer, None)
        }
        ModelKind::Auto => {
            let Some(plan) = plan else {
                return Err(FitError::AutoNeedsTable);
            };
            let runs: Vec<CandidateRun> = plan
                .candidates
                .iter()
                .map(|(name, c)| CandidateRun {
                    name,
                    config: c.clone(),
                    opts: options_for(c, layout),
                    so: c.sample_options_with(&floor, isotropic),
                })
                .collect();
            let chosen = std::sync::Mutex::new(None);
            let screen: crate::coarse::Screen = Box::new(|end| {
                let Screened {
                    chosen: i,
                    result,
                    record,
                } = (plan.screen)(&end, &runs)?;
                let c = &runs[i];
                let finish = crate::coarse::Finish {
                    start: result.factors,
                    form: Some(result.model.diffuse_form),
                    opts: c.opts,
                    so: (c.so != end.so).then_some(c.so),
                };
                *chosen.lock().unwrap_or_else(|e| e.into_inner()) = Some((i, record));
                Ok(finish)
            });
            let opts = runs[0].opts;
            let start = init::initial_factors(layout, opts.lobes);
            let mut produced = factor_fit(samples, opts, start, observer, Some(screen))?;
            produced.auto = chosen.into_inner().unwrap_or_else(|e| e.into_inner());
            Ok(produced)
        }
        ModelKind::Ggx => {
            let fit = match &samples {
                SampleData::Records(s) => fit_ggx(s, so)?,
                SampleData::Merl(m) => fit_ggx(&m.table().samples(m.source()), so)?,
            };
            let model = fit.params.to_model(layout);
            Ok(Produced {
                result: FitResult {
                    factors: Factors::from_model(&model),
                    model,
                    initial_objective: fit.objective,
                    objective: fit.objective,
                    history: Vec::new(),
                    converged: true,
                    seconds: fit.seconds,
                },
                ggx: Some(fit.params),
                set_len: None,
                floor,
                coarse: None,
                reference: None,
                auto: None,
            })
        }
    }?;
    if config.compensate {
        // After the fit: the measured data already hold multiple
        // scattering, so the term is the fitted lobes' own, not refitted.
        let model = &mut produced.result.model;
        model.compensation = Some(crate::energy::coupled::compensation(model));
    }
    Ok(produced)
}

/// Fit `config.model` in the calling thread pool, without provenance or
/// error measures (the benchmark report's inner loop). The observer sees
/// every sweep with the part it belongs to (the channel for Independent-G,
/// 0 otherwise; GGX has no sweeps). Also returns the analytic parameters of
/// a GGX fit.
pub fn fit_model(
    samples: &MeasuredSamples,
    config: &FitConfig,
    observer: &mut dyn FnMut(usize, &SweepReport),
) -> Result<(FitResult, Option<GgxParams>), FitError> {
    run_kind(
        SampleData::Records(Cow::Borrowed(samples)),
        config,
        observer,
        None,
    )
    .map(|p| (p.result, p.ggx))
}

/// Fit `config.model` to measured samples in a pool of `config.threads`
/// threads, and record the provenance (including [`selection`]) and the
/// errors against the input. The observer is as for [`fit_model`] (it runs
/// inside the pool, hence `Send`).
pub fn fit(
    samples: &MeasuredSamples,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    fit_with(samples, config, None, observer)
}

/// [`fit`], with `--model auto`'s plan ([`crate::auto`]) where
/// `config.model` is [`ModelKind::Auto`].
pub fn fit_with(
    samples: &MeasuredSamples,
    config: &FitConfig,
    plan: Option<&AutoPlan>,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    fit_measured(
        SampleData::Records(Cow::Borrowed(samples)),
        || Ok(Measured::Samples(samples)),
        config,
        observer,
        plan,
    )
}

/// As [`fit`], but owning the samples: they are freed once the fit's sample
/// sets are built, before its sweeps, and `reread` gives their table again
/// for the error measures after the fit (e.g. a fresh read of the file, so
/// that not even the table is held during the sweeps; its error is the
/// fit's). The measures visit the table's samples piece by piece
/// ([`npf_data_loaders::Table::map_sample_chunks`]), so the measured samples
/// (128 MB for a MERL table) are made once, and never in memory together
/// with the solver's caches. `reread` must give the table `samples` came
/// from (`table.samples(..)` is `samples`). A MERL table's
/// [`npf_data_loaders::MerlSamples`] are fitted without their records
/// ([`crate::samples::FitSet::build_merl`]): the same fit.
pub fn fit_owned(
    samples: impl Into<SampleData<'static>>,
    reread: impl FnOnce() -> Result<npf_data_loaders::Table, FitError> + Send,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    fit_owned_with(samples, reread, config, None, observer)
}

/// [`fit_owned`], with `--model auto`'s plan as for [`fit_with`].
pub fn fit_owned_with(
    samples: impl Into<SampleData<'static>>,
    reread: impl FnOnce() -> Result<npf_data_loaders::Table, FitError> + Send,
    config: &FitConfig,
    plan: Option<&AutoPlan>,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
) -> Result<Fitted, FitError> {
    fit_measured(
        samples.into(),
        || reread().map(Measured::Table),
        config,
        observer,
        plan,
    )
}

/// What a fit's error measures are computed against.
enum Measured<'a> {
    /// The samples themselves.
    Samples(&'a MeasuredSamples),
    /// Their table (its samples made piece by piece).
    Table(npf_data_loaders::Table),
}

/// [`fit`] and [`fit_owned`]: `samples` go into the fit, `remeasure` gives
/// the same samples (or their table) for the error measures.
fn fit_measured<'a>(
    samples: SampleData<'a>,
    remeasure: impl FnOnce() -> Result<Measured<'a>, FitError> + Send,
    config: &FitConfig,
    observer: &mut (dyn FnMut(usize, &SweepReport) + Send),
    plan: Option<&AutoPlan>,
) -> Result<Fitted, FitError> {
    config.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|source| FitError::Threads {
            threads: config.threads,
            source,
        })?;
    let threads = pool.current_num_threads();
    let (source, isotropic) = (samples.source_name().to_string(), samples.is_isotropic());
    pool.install(|| {
        let Produced {
            mut result,
            ggx,
            set_len,
            floor,
            coarse,
            reference,
            auto,
        } = run_kind(samples, config, observer, plan)?;
        // Auto's provenance is the chosen candidate's, with the record.
        let (config, auto) = match (auto, plan) {
            (Some((i, record)), Some(plan)) => (&plan.candidates[i].1, Some(record)),
            _ => (config, None),
        };
        // The sets and caches are freed; their pages go back before the
        // samples are made again.
        crate::memory::release_free();
        crate::phases::mark("release");
        let mut energy = None;
        let metrics = match remeasure()? {
            Measured::Samples(s) => compare_model(s, config.max_theta, &result.model),
            Measured::Table(t) => {
                crate::phases::mark("re-read");
                if let npf_data_loaders::Table::Merl(merl) = &t {
                    if config.energy_scale.unwrap_or(floor.untrusted) && scalable(config, &result) {
                        let table = (merl, reference.as_ref());
                        energy = Some(scale_energy(table, config.max_theta, &mut result));
                        crate::phases::mark("energy scale");
                    }
                }
                let prepared = match (&t, &reference) {
                    (npf_data_loaders::Table::Merl(merl), Some(r)) => {
                        r.compare(merl, config.max_theta, &result.model)
                    }
                    _ => None,
                };
                prepared.unwrap_or_else(|| compare_model_table(&t, config.max_theta, &result.model))
            }
        };
        crate::phases::mark("error measures");
        check_result(&source, &result, &metrics)?;
        let kind = config.model;
        let info = FitInfo {
            source,
            npf_version: env!("CARGO_PKG_VERSION").into(),
            lobes: if kind == ModelKind::Factor {
                config.lobes
            } else {
                result.model.lobe_count()
            },
            weighting: format!("{:?}", config.weighting).to_lowercase(),
            epsilon: floor.epsilon,
            max_theta_deg: config.max_theta,
            max_theta_h_deg: config.max_theta_h,
            d_monotone_from_deg: config.d_monotone_from,
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
            samples: set_len.unwrap_or(metrics.samples),
            // JSON has no NaN: a relative error against an all-black table is undefined.
            metrics: Some(metrics).filter(Metrics::is_finite),
            selection: Some({
                // The parameter count on the layout actually fitted (the
                // anisotropic one for anisotropic data).
                let mut v = selection(config, ggx.as_ref());
                v["effective_parameters"] = kind
                    .effective_params(&result.model.layout, config.lobes)
                    .into();
                // What the data-dependent floor read and chose.
                if config.weighting == Weighting::Compressive {
                    v["floor"] = serde_json::to_value(floor).unwrap_or_default();
                    // The pooling this table got (the untrusted rule may raise it).
                    match config.pool_scale_below_for(&floor, isotropic) {
                        Some(p) => v["pool_scale_below_deg"] = p.into(),
                        None => {
                            if let Some(m) = v.as_object_mut() {
                                m.remove("pool_scale_below_deg");
                            }
                        }
                    }
                }
                if config.grazing_trust > 0.0 {
                    let g = config.grazing_rule(&floor);
                    v["grazing"] = serde_json::to_value(g).unwrap_or_default();
                }
                if let Some(c) = coarse {
                    v["coarse"] = c;
                }
                if let Some(e) = energy {
                    v["energy_scale"] = e;
                }
                if let Some(a) = auto {
                    v["auto"] = a;
                }
                v
            }),
        };
        Ok(Fitted {
            result,
            info,
            metrics,
        })
    })
}

/// The provenance note naming the model kind and its true parameter count
/// (on the configuration's layout), with GGX's analytic parameters.
pub fn selection(config: &FitConfig, ggx: Option<&GgxParams>) -> serde_json::Value {
    let mut v = serde_json::json!({
        "model": config.model.name(),
        "effective_parameters": config.effective_params(),
    });
    if let Some(t) = config.taper_from {
        v["taper_from_deg"] = t.into();
    }
    if !config.masking.is_separable() {
        v["masking"] = config.masking.name().into();
    }
    if config.compensate {
        v["compensated"] = true.into();
    }
    if let Some(p) = config.pool_scale_below {
        v["pool_scale_below_deg"] = p.into();
    }
    if config.epsilon_median > 0.0 {
        v["epsilon_median"] = config.epsilon_median.into();
    }
    if let Some(p) = ggx {
        v["ggx"] = serde_json::to_value(p).unwrap_or_default();
    }
    v
}

/// The model kind recorded in a model file's provenance (factor if none).
pub fn kind_of(info: Option<&FitInfo>) -> ModelKind {
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
