//! `npf fit IN.binary -o MODEL.{json,npfb}`.

use super::{check_output, CliError, CliResult};
use crate::metrics::{compare_model, Metrics};
use crate::model::Layout;
use crate::modelfile::{self, FitInfo, ModelFile};
use crate::samples::{FitSet, SampleOptions, Weighting};
use crate::selection::{self, Candidate, Scores, Target};
use crate::solver::{Executor, FitOptions, FitResult, GMethod, SweepReport};
use clap::Args;
use npf_data_loaders::{MeasuredSamples, MerlTable};
use std::path::{Path, PathBuf};

/// Options shared by every command that fits.
#[derive(Args, Clone, Debug)]
pub struct FitConfig {
    /// Specular lobes (1 to 3).
    #[arg(long, default_value_t = 3)]
    pub lobes: usize,
    /// Values per factor table (D, F, G): 90 is MERL's resolution; fewer
    /// (e.g. 45, 30) give smaller models on the same axes.
    #[arg(long, default_value_t = 90)]
    pub nodes: usize,
    /// Residual weighting (see docs/fitting.md).
    #[arg(long, value_enum, default_value_t = Weighting::Compressive)]
    pub weighting: Weighting,
    /// Floor of the compressive weight (cosine-weighted 1/sr).
    #[arg(long, default_value_t = 1e-3)]
    pub epsilon: f64,
    /// Grazing cut-off: leave out samples with theta_i or theta_o above this (degrees).
    #[arg(long, default_value_t = 85.0)]
    pub max_theta: f64,
    /// D cells above this half angle (degrees) hold the last free cell's value.
    #[arg(long, default_value_t = 75.0)]
    pub max_theta_h: f64,
    /// Stop after this many sweeps.
    #[arg(long, default_value_t = 50)]
    pub max_sweeps: usize,
    /// Stop when a sweep lowers the objective by less than this fraction.
    #[arg(long, default_value_t = 3e-3)]
    pub tol: f64,
    /// How G control points are updated.
    #[arg(long, value_enum, default_value_t = GMethod::Cubic)]
    pub g_method: GMethod,
    /// Gaussian smoothing of G after each update (sigma in control points), kept only if it does not raise the objective.
    #[arg(long)]
    pub smooth_g: Option<f64>,
    /// D may not rise with theta_h past this angle (degrees), which stops D
    /// and G trading scale at grazing angles.
    #[arg(long, default_value_t = 60.0, conflicts_with = "free_d_tail")]
    pub d_monotone_from: f64,
    /// Leave the D tail unconstrained.
    #[arg(long)]
    pub free_d_tail: bool,
    /// Disable the extrapolation step between sweeps (plain AWLS).
    #[arg(long)]
    pub no_accelerate: bool,
    /// Worker threads (0: all cores). Results are identical for any count.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

impl FitConfig {
    pub fn sample_options(&self) -> SampleOptions {
        SampleOptions {
            weighting: self.weighting,
            epsilon: self.epsilon,
            max_theta_deg: self.max_theta,
            max_theta_h_deg: self.max_theta_h,
        }
    }

    pub fn validate(&self) -> Result<(), CliError> {
        if !(4..=90).contains(&self.nodes) {
            return Err(CliError::Message(format!(
                "--nodes must be 4 to 90, got {}",
                self.nodes
            )));
        }
        self.fit_options().validate().map_err(CliError::Message)
    }

    pub fn fit_options(&self) -> FitOptions {
        FitOptions {
            lobes: self.lobes,
            max_sweeps: self.max_sweeps,
            tol: self.tol,
            g_method: self.g_method,
            smooth_g: self.smooth_g,
            accelerate: !self.no_accelerate,
            trace_stages: false,
            d_monotone_from_deg: (!self.free_d_tail).then_some(self.d_monotone_from),
        }
    }
}

#[derive(Args, Debug)]
pub struct FitArgs {
    /// Measured BRDF (MERL .binary).
    pub input: PathBuf,
    /// Output model; the extension picks the form (.json or .npfb).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub config: FitConfig,
    /// Which model to fit: the shared-factor model or a baseline (see docs/evaluation.md).
    #[arg(long, value_enum, default_value_t = crate::baselines::ModelKind::Factor)]
    pub model: crate::baselines::ModelKind,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Choose the smallest model (1-3 lobes, 30/45/90 values per table)
    /// that meets METRIC=VALUE: log-rmse=X, rel-rmse=X (at most) or psnr=DB (rendering PSNR, at least).
    #[arg(long, value_name = "METRIC=VALUE", conflicts_with_all = ["lobes", "nodes", "budget", "model"])]
    pub target: Option<Target>,
    /// Choose the model with the lowest error (see --budget-metric) among
    /// those with at most N parameters.
    #[arg(long, value_name = "N", conflicts_with_all = ["lobes", "nodes", "model"])]
    pub budget: Option<usize>,
    /// Metric --budget minimises.
    #[arg(long, value_enum, default_value_t = BudgetMetric::LogRmse, requires = "budget")]
    pub budget_metric: BudgetMetric,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BudgetMetric {
    LogRmse,
    RelRmse,
}

/// A finished fit with its provenance and errors against the input.
pub struct Fitted {
    pub result: FitResult,
    pub info: FitInfo,
    pub metrics: Metrics,
}

/// Fit measured samples with a configuration, with an optional progress bar.
pub fn fit_samples(
    samples: &MeasuredSamples,
    config: &FitConfig,
    progress: bool,
) -> Result<Fitted, CliError> {
    config.validate()?;
    let opts = config.fit_options();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|e| CliError::Message(format!("cannot start {} threads: {e}", config.threads)))?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let set = FitSet::build(
            samples,
            Layout::isotropic(config.nodes),
            config.sample_options(),
        )
        .map_err(|e| CliError::Message(e.to_string()))?;
        let bar = if progress {
            indicatif::ProgressBar::new(opts.max_sweeps as u64)
        } else {
            indicatif::ProgressBar::hidden()
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} fitting [{bar:30}] {pos}/{len} sweeps  {msg}  {elapsed}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        let mut observer = |r: &SweepReport| {
            bar.set_position(r.sweep as u64);
            bar.set_message(format!(
                "objective {:.6e} (-{:.1e})",
                r.objective, r.rel_decrease
            ));
        };
        let result = Executor::new(&set, opts)
            .observe(&mut observer)
            .run()
            .map_err(CliError::Message)?;
        bar.finish_and_clear();
        let metrics = compare_model(samples, config.max_theta, &result.model);
        let info = FitInfo {
            source: samples.source.clone(),
            npf_version: env!("CARGO_PKG_VERSION").into(),
            lobes: opts.lobes,
            weighting: format!("{:?}", config.weighting).to_lowercase(),
            epsilon: config.epsilon,
            max_theta_deg: config.max_theta,
            max_theta_h_deg: config.max_theta_h,
            d_monotone_from_deg: config.fit_options().d_monotone_from_deg,
            g_method: format!("{:?}", config.g_method).to_lowercase(),
            smooth_g: config.smooth_g,
            sweeps: result.history.len(),
            converged: result.converged,
            objective: result.objective,
            seconds: result.seconds,
            threads,
            samples: set.len(),
            // JSON has no NaN: a relative error against an all-black table is undefined.
            metrics: Some(metrics).filter(Metrics::is_finite),
            selection: None,
        };
        Ok(Fitted {
            result,
            info,
            metrics,
        })
    })
}

pub fn print_summary(f: &Fitted) {
    let m = &f.metrics;
    eprintln!(
        "fitted {} parameters ({} lobes) in {:.2} s, {} sweeps ({}), objective {:.6e}",
        f.result.model.param_count(),
        f.info.lobes,
        f.info.seconds,
        f.info.sweeps,
        if f.info.converged {
            "converged"
        } else {
            "sweep limit"
        },
        f.info.objective
    );
    eprintln!(
        "errors over {} samples (theta <= {} deg): cosine-weighted RMSE {:.4e} (relative {:.4e}), log RMSE {:.4e}",
        m.samples, m.max_theta_deg, m.cos_rmse, m.rel_cos_rmse, m.log_rmse
    );
}

pub fn load_table(path: &Path) -> Result<MeasuredSamples, CliError> {
    let table = MerlTable::read(path)?;
    let samples = table.samples(&path.display().to_string());
    if samples.samples.is_empty() {
        return Err(CliError::Message(format!(
            "{}: the table holds no valid samples (all cells missing)",
            path.display()
        )));
    }
    Ok(samples)
}

pub fn run(args: FitArgs) -> CliResult {
    modelfile::Form::of(&args.output)?;
    check_output(&args.output, args.force)?;
    args.config.validate()?;
    let samples = load_table(&args.input)?;
    let fitted = match (args.target, args.budget) {
        (Some(target), _) => {
            // A rendering-PSNR target renders the input table once as the reference.
            let table = if target.needs_render() {
                Some(MerlTable::read(&args.input)?)
            } else {
                None
            };
            let reference = table
                .as_ref()
                .map(|t| crate::evaluation::Reference::new(t, &samples, Default::default()));
            select(
                &samples,
                &args,
                Selection::Target(target),
                reference.as_ref(),
            )?
        }
        (None, Some(budget)) => {
            let metric = match args.budget_metric {
                BudgetMetric::LogRmse => Target::LogRmse(f64::INFINITY),
                BudgetMetric::RelRmse => Target::RelRmse(f64::INFINITY),
            };
            select(&samples, &args, Selection::Budget(budget, metric), None)?
        }
        (None, None) => crate::baselines::fitted(&samples, &args.config, args.model, !args.quiet)?,
    };
    modelfile::write(
        &args.output,
        &ModelFile {
            model: fitted.result.model.clone(),
            fit: Some(fitted.info.clone()),
        },
        args.force,
    )?;
    if !args.quiet {
        print_summary(&fitted);
        eprintln!("wrote {}", args.output.display());
    }
    Ok(())
}

enum Selection {
    Target(Target),
    Budget(usize, Target),
}

/// Model selection: fits candidates (see `selection`), keeps the chosen
/// fit, and records the choice and every trial in the fit record.
fn select(
    samples: &MeasuredSamples,
    args: &FitArgs,
    how: Selection,
    reference: Option<&crate::evaluation::Reference>,
) -> Result<Fitted, CliError> {
    let mut kept: Vec<Fitted> = Vec::new();
    let mut fit = |c: Candidate| -> Result<(Scores, f64), CliError> {
        let mut config = args.config.clone();
        config.lobes = c.lobes;
        config.nodes = c.nodes;
        let f = fit_samples(samples, &config, false)?;
        let render_psnr_db = match reference {
            Some(r) => Some(
                r.evaluate_model(config.max_theta, &f.result.model)
                    .map_err(|e| CliError::Message(e.to_string()))?
                    .0
                    .render_psnr_db,
            ),
            None => None,
        };
        if !args.quiet {
            eprintln!(
                "  {} lobes x {} values ({} parameters): log RMSE {:.4e}, relative RMSE {:.4e}{} ({:.1} s)",
                c.lobes,
                c.nodes,
                c.params(),
                f.metrics.log_rmse,
                f.metrics.rel_cos_rmse,
                render_psnr_db.map_or(String::new(), |p| format!(", rendering PSNR {p:.2} dB")),
                f.info.seconds
            );
        }
        let out = (
            Scores {
                metrics: f.metrics,
                render_psnr_db,
            },
            f.info.seconds,
        );
        kept.push(f);
        Ok(out)
    };
    let (chosen, record) = match how {
        Selection::Target(target) => {
            if !args.quiet {
                eprintln!(
                    "choosing the smallest model with {} {} {}",
                    target.name(),
                    target.relation(),
                    target.threshold()
                );
            }
            let (i, met, trials) = selection::smallest_meeting(target, &mut fit)?;
            if !met && !args.quiet {
                eprintln!(
                    "warning: no candidate meets {} {} {}; keeping the best ({} parameters, {:.4e})",
                    target.name(), target.relation(), target.threshold(), trials[i].params, trials[i].value
                );
            }
            let record = serde_json::json!({
                "model": "factor", "mode": "target", "target": target, "met": met,
                "chosen": trials[i], "trials": trials,
            });
            (i, record)
        }
        Selection::Budget(budget, metric) => {
            let Some((i, trials)) = selection::best_within(budget, metric, &mut fit)? else {
                return Err(CliError::Message(format!(
                    "--budget {budget}: no candidate model has that few parameters (the smallest has {})",
                    selection::candidates()[0].params()
                )));
            };
            let record = serde_json::json!({
                "model": "factor", "mode": "budget", "budget": budget, "metric": metric.name(),
                "chosen": trials[i], "trials": trials,
            });
            (i, record)
        }
    };
    let mut fitted = kept.swap_remove(chosen);
    if !args.quiet {
        eprintln!(
            "chose {} lobes x {} values: {} parameters",
            fitted.info.lobes,
            fitted.result.model.layout.d.len(),
            fitted.result.model.param_count()
        );
    }
    fitted.info.selection = Some(record);
    Ok(fitted)
}
