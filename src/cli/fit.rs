//! `npf fit IN.binary -o MODEL.{json,npfb}`.

use super::{check_outputs, CliError, CliResult};
use crate::fit::{fit, FitConfig, FitError, Fitted, ModelKind};
use crate::modelfile::{self, ModelFile};
use crate::samples::Weighting;
use crate::selection::{self, Candidate, Scores, Target};
use crate::solver::{DiffuseKind, GMethod, SweepReport, MAX_LOBES};
use clap::Args;
use npf_data_loaders::MeasuredSamples;
use std::path::PathBuf;

/// The help heading of the tuning knobs: `npf fit -h` leaves them out,
/// `--help` lists them under it (docs/fitting.md gives their effects).
pub const ADVANCED: &str = "Advanced (tuning; defaults are measured, docs/fitting.md)";

/// The library's defaults, which every flag below shows and falls back to.
fn defaults() -> FitConfig {
    FitConfig::default()
}

/// Options shared by every command that fits: the flags of
/// [`FitConfig`], with its defaults.
#[derive(Args, Clone, Debug)]
pub struct FitFlags {
    /// Specular lobes (1 to 3).
    #[arg(long, default_value_t = defaults().lobes)]
    pub lobes: usize,
    /// Values per factor table (D, F, G): 90 is MERL's resolution; fewer
    /// (e.g. 45, 30) give smaller models on the same axes.
    #[arg(long, default_value_t = defaults().nodes)]
    pub nodes: usize,
    /// Residual weighting (see docs/fitting.md).
    #[arg(long, value_enum, default_value_t = defaults().weighting)]
    pub weighting: Weighting,
    /// Least floor of the compressive weight (cosine-weighted 1/sr).
    #[arg(long, default_value_t = defaults().epsilon)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub epsilon: f64,
    /// The compressive floor as a fraction of the data's median
    /// cosine-weighted value (the floor is the larger of this times the
    /// median and --epsilon; 0: --epsilon alone). 0.3 suits tables with
    /// exactly-black cells, such as RGL's (docs/fitting.md).
    #[arg(long, default_value_t = defaults().epsilon_median)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub epsilon_median: f64,
    /// The same fraction for untrusted tables: clamped (at least 1 in 2,000
    /// of a channel's cells exactly 0) or, with --grazing-trust, not
    /// reciprocal at grazing angles; the larger of the two applies (0:
    /// off; docs/fitting.md).
    #[arg(long, default_value_t = defaults().epsilon_median_untrusted)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub epsilon_median_untrusted: f64,
    /// Grazing trust from the data (0: off): a table without clamped cells whose
    /// grazing cells' reciprocity asymmetry (upper quartile) is below this is fitted
    /// to 89 degrees with weights tapering from 85, others keep --max-theta
    /// (docs/fitting.md).
    #[arg(long, default_value_t = defaults().grazing_trust)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub grazing_trust: f64,
    /// Below this half angle (degrees) compressive weights use the mean
    /// value over phi_d of each (theta_h, theta_d) row (0: off).
    #[arg(long, default_value_t = defaults().pool_scale_below.unwrap_or(0.0))]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub pool_scale_below: f64,
    /// The same for untrusted tables (see --epsilon-median-untrusted); the
    /// larger of the two applies (0: off; docs/fitting.md).
    #[arg(long, default_value_t = defaults().pool_scale_below_untrusted.unwrap_or(0.0))]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub pool_scale_below_untrusted: f64,
    /// Grazing cut-off: leave out samples with theta_i or theta_o above this (degrees).
    #[arg(long, default_value_t = defaults().max_theta)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub max_theta: f64,
    /// D cells above this half angle (degrees) hold the last free cell's value.
    #[arg(long, default_value_t = defaults().max_theta_h)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub max_theta_h: f64,
    /// Stop after this many sweeps.
    #[arg(long, default_value_t = defaults().max_sweeps)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub max_sweeps: usize,
    /// Stop when a sweep lowers the objective by less than this fraction.
    #[arg(long, default_value_t = defaults().tol)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub tol: f64,
    /// How G control points are updated.
    #[arg(long, value_enum, default_value_t = defaults().g_method)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub g_method: GMethod,
    /// Gaussian smoothing of G after each update (sigma in control points), kept only if it does not raise the objective.
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub smooth_g: Option<f64>,
    /// D may not rise with theta_h past this angle (degrees), which stops D
    /// and G trading scale at grazing angles [default: the library's, 60].
    #[arg(long, conflicts_with = "free_d_tail")]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub d_monotone_from: Option<f64>,
    /// Leave the D tail unconstrained.
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub free_d_tail: bool,
    /// Disable the extrapolation step between sweeps (plain AWLS).
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub no_accelerate: bool,
    /// Hold G on the full sample set where the coarse level fitted it: on,
    /// off (default: on for isotropic tables; G is smooth, so the coarse
    /// level's samples pin it down, and its pass is half a full sweep).
    #[arg(long, value_name = "on|off", value_parser = clap::builder::BoolishValueParser::new(), hide_possible_values = true)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub keep_coarse_g: Option<bool>,
    /// Tolerance of the full set's sweeps when G is kept from the coarse
    /// level (they move D, F, d and s only; --tol applies otherwise)
    /// [default: twice --tol]
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub kept_g_tol: Option<f64>,
    /// After the fit, scale d and every lobe's s per channel to the
    /// table's energy (cells past theta_h = 5 deg; only when a channel is
    /// off by more than 5 %): on, off (default: on for untrusted tables,
    /// whose compressive fit reflects too little light; docs/fitting.md).
    #[arg(long, value_name = "on|off", value_parser = clap::builder::BoolishValueParser::new(), hide_possible_values = true)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub energy_scale: Option<bool>,
    /// Joint Gauss-Newton steps between sweeps: on, off (default: on for
    /// anisotropic tables only).
    #[arg(long, value_name = "on|off", value_parser = clap::builder::BoolishValueParser::new(), hide_possible_values = true)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub gauss_newton: Option<bool>,
    /// Joint Gauss-Newton steps on the coarse levels once their sweeps
    /// crawl (8 CG iterations a step), whatever --gauss-newton says of the
    /// full set: on, off (default: off).
    #[arg(long, value_name = "on|off", value_parser = clap::builder::BoolishValueParser::new(), hide_possible_values = true)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub coarse_gauss_newton: Option<bool>,
    /// Worker threads (0: all cores). Results are identical for any count.
    #[arg(long, default_value_t = defaults().threads)]
    pub threads: usize,
    /// The diffuse term's form (factor model; see docs/fitting.md).
    #[arg(long, value_enum, default_value_t = defaults().diffuse)]
    pub diffuse: DiffuseKind,
    /// Coarse-to-fine: decimation factors of the sample sets fitted before
    /// the full one, coarsest first (e.g. 8 or 16,4; 1: no coarse level).
    #[arg(long, value_delimiter = ',', default_values_t = defaults().coarse)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub coarse: Vec<usize>,
    /// Tolerance of the coarse levels.
    #[arg(long, default_value_t = defaults().coarse_tol)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub coarse_tol: f64,
    /// Sweep limit of the coarse levels.
    #[arg(long, default_value_t = defaults().coarse_max_sweeps)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub coarse_max_sweeps: usize,
    /// Grazing taper: past this angle (degrees) a sample's weight falls
    /// linearly to 0 at the horizon; use with a cut-off near 90, e.g.
    /// `--max-theta 89 --taper-from 80` (see docs/fitting.md).
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub taper_from: Option<f64>,
    /// Masking-shadowing form: separable G(theta_i) G(theta_o) (the
    /// paper's) or height-correlated G2 = 1 / (1 + Lambda_i + Lambda_o).
    #[arg(long, value_enum, default_value_t = defaults().masking)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub masking: crate::model::Masking,
    /// Add Kulla-Conty's multiple-scattering term of the fitted lobes to the
    /// model (eval, sampler and .bsdf/.binary exports use it; the shader
    /// exports refuse it). For energy-conservation studies only: measured
    /// tables already hold multiple scattering, and on fitted materials the
    /// term costs 14-25 dB rendering PSNR (docs/fitting.md).
    #[arg(long)]
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub compensate: bool,
}

impl FitFlags {
    /// The library configuration these flags describe, for `model`.
    pub fn config(&self, model: ModelKind) -> FitConfig {
        let base = defaults();
        FitConfig {
            model,
            lobes: self.lobes,
            nodes: self.nodes,
            weighting: self.weighting,
            epsilon: self.epsilon,
            epsilon_median: self.epsilon_median,
            epsilon_median_untrusted: self.epsilon_median_untrusted,
            grazing_trust: self.grazing_trust,
            max_theta: self.max_theta,
            max_theta_h: self.max_theta_h,
            max_sweeps: self.max_sweeps,
            tol: self.tol,
            g_method: self.g_method,
            smooth_g: self.smooth_g,
            d_monotone_from: if self.free_d_tail {
                None
            } else {
                self.d_monotone_from.or(base.d_monotone_from)
            },
            accelerate: base.accelerate && !self.no_accelerate,
            threads: self.threads,
            diffuse: self.diffuse,
            coarse: self.coarse.clone(),
            coarse_tol: self.coarse_tol,
            coarse_max_sweeps: self.coarse_max_sweeps,
            keep_coarse_g: self.keep_coarse_g,
            kept_g_tol: self.kept_g_tol,
            gauss_newton: self.gauss_newton,
            coarse_gauss_newton: self.coarse_gauss_newton.unwrap_or(base.coarse_gauss_newton),
            taper_from: self.taper_from,
            masking: self.masking,
            pool_scale_below: Some(self.pool_scale_below).filter(|&d| d > 0.0),
            pool_scale_below_untrusted: Some(self.pool_scale_below_untrusted).filter(|&d| d > 0.0),
            compensate: self.compensate,
            energy_scale: self.energy_scale,
        }
    }
}

/// A fit error in terms of the flag that caused it.
pub fn flag_message(e: &FitError) -> String {
    use crate::solver::SolverError as S;
    match e {
        FitError::Nodes(n) => format!(
            "--nodes must be {} to {}, got {n}",
            crate::fit::NODES.start(),
            crate::fit::NODES.end()
        ),
        FitError::Solver(s) => match s {
            S::Lobes(n) => format!("--lobes must be 1 to {MAX_LOBES}, got {n}"),
            S::MaxSweeps => "--max-sweeps must be at least 1".into(),
            S::Tolerance(t) => format!("--tol must be a non-negative number, got {t}"),
            S::MonotoneFrom(t) => format!("--d-monotone-from must be 0 to 90 degrees, got {t}"),
            S::SmoothG(s) => format!("--smooth-g must be positive, got {s}"),
            S::MaskedLobe(_) | S::Start(_) | S::GaussNewtonCg | S::GaussNewtonBelow(_) => {
                e.to_string()
            }
        },
        FitError::Threads { .. } | FitError::TooManyThreads { .. } => format!("--threads: {e}"),
        FitError::Range { name, .. } => format!("--{}: {e}", name.replace('_', "-")),
        FitError::Samples(_)
        | FitError::Ggx(_)
        | FitError::Unrepresentable { .. }
        | FitError::Remeasure { .. }
        | FitError::AutoNeedsTable => e.to_string(),
    }
}

/// A progress bar for a fit of `kind` (hidden when `show` is false or the
/// kind has no sweeps), and the observer that drives it.
pub fn progress(
    config: &FitConfig,
    show: bool,
) -> (indicatif::ProgressBar, impl FnMut(usize, &SweepReport)) {
    let parts = match config.model {
        ModelKind::Factor => 1,
        ModelKind::IndependentG => 3,
        // Auto runs several fits: no one bar counts them.
        ModelKind::Ggx | ModelKind::Auto => 0,
    };
    let bar = if show && parts > 0 {
        indicatif::ProgressBar::new((parts * config.max_sweeps) as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    if config.model == ModelKind::Factor {
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} fitting [{bar:30}] {pos}/{len} sweeps  {msg}  {elapsed}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
    }
    let max = config.max_sweeps as u64;
    let independent = config.model == ModelKind::IndependentG;
    let b = bar.clone();
    let observer = move |c: usize, r: &SweepReport| {
        b.set_position(c as u64 * max + r.sweep as u64);
        b.set_message(if independent {
            format!("channel {c}, objective {:.6e}", r.objective)
        } else {
            format!("objective {:.6e} (-{:.1e})", r.objective, r.rel_decrease)
        });
    };
    (bar, observer)
}

/// Fit with a progress bar (shown when `show` is true).
pub fn fit_with_progress(
    samples: &MeasuredSamples,
    config: &FitConfig,
    show: bool,
) -> Result<Fitted, CliError> {
    let (bar, mut observer) = progress(config, show);
    let fitted = fit(samples, config, &mut observer)?;
    bar.finish_and_clear();
    Ok(fitted)
}

/// `npf fit`'s arguments.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// Measured BRDF: MERL .binary (isotropic layout) or UTIA .bin
    /// (anisotropic layout, 2010 parameters for three lobes); or a folder,
    /// whose every .binary and .bin table is fitted into the -o folder.
    pub input: PathBuf,
    /// Read the input as this format instead of detecting it.
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
    /// Output model; the extension picks the form (.json or .npfb). For a
    /// folder input, the output folder (created if missing): one model per
    /// table, named after it, and summary.csv.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Folder input only: the form of the models written [default: json].
    #[arg(long, value_enum)]
    pub form: Option<ModelForm>,
    /// Folder input only: tables fitted at once, each with its share of
    /// --threads [default: from the cores and the free memory].
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// How to fit.
    #[command(flatten)]
    pub config: FitFlags,
    /// Which model to fit: the shared-factor model or a baseline (see docs/evaluation.md).
    #[arg(long, value_enum, default_value_t = defaults().model)]
    pub model: ModelKind,
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
    #[arg(hide_short_help = true, help_heading = ADVANCED)]
    pub budget_metric: BudgetMetric,
}

/// `--form`: the model file form of a folder fit's outputs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelForm {
    /// JSON, with the fit's provenance (sweeps, time, errors).
    Json,
    /// Compact binary (.npfb), the model alone.
    Npfb,
}

impl ModelForm {
    /// The file extension of the form.
    pub fn extension(self) -> &'static str {
        match self {
            ModelForm::Json => "json",
            ModelForm::Npfb => "npfb",
        }
    }
}

/// What `--budget` minimises.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum BudgetMetric {
    /// RMSE of log(1 + f cos theta_i).
    LogRmse,
    /// Relative cosine-weighted RMSE.
    RelRmse,
}

/// The summary `npf fit` and `npf demo` print after a fit.
pub fn print_summary(f: &Fitted) {
    let m = &f.metrics;
    eprintln!(
        "fitted {} parameters ({} lobes) in {:.2} s, {} sweeps ({}), objective {:.6e}",
        // The factor tables and the diffuse form's own (a separable P).
        f.result.model.param_count() + f.result.model.diffuse_form.param_count(),
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

/// Run `npf fit`: one table, or every table of a folder
/// (see [`super::fit_folder`]).
pub fn run(args: FitArgs) -> CliResult {
    if args.input.is_dir() {
        return super::fit_folder::run(args);
    }
    if let Some(form) = args.form {
        return Err(CliError::Message(format!(
            "--form {}: only for a folder input (a single output's extension picks its form)",
            form.extension()
        )));
    }
    if args.jobs.is_some() {
        return Err(CliError::Message("--jobs: only for a folder input".into()));
    }
    crate::phases::mark("start");
    modelfile::Form::of(&args.output)?;
    let config = args.config.config(args.model);
    config.validate()?;
    // The input first: a missing or unreadable table is the problem to
    // report, not an output that happens to exist already.
    npf_data_loaders::sniff::open_regular(&args.input, "a measured table")?;
    check_outputs(&[&args.output], &[&args.input], args.force)?;
    crate::phases::mark("checks");
    let fitted = fit_table(&args.input, &args.output, &args, &config, !args.quiet)?;
    if !args.quiet {
        print_summary(&fitted);
        eprintln!("wrote {}", args.output.display());
    }
    Ok(())
}

/// Read `input`, fit it as `args` asks (a plain fit, or a `--target` /
/// `--budget` selection) and write the model to `output`; `verbose` shows
/// the sweep progress bar and the selection's trial lines.
pub(super) fn fit_table(
    input: &std::path::Path,
    output: &std::path::Path,
    args: &FitArgs,
    config: &FitConfig,
    verbose: bool,
) -> Result<Fitted, CliError> {
    // (clap refuses --model with --target or --budget.)
    if config.model == ModelKind::Auto {
        let source = input.display().to_string();
        let stamp = file_stamp(input);
        let table = npf_data_loaders::Table::read(input, args.format.map(Into::into))?;
        // The judge renders the table read between its nodes, as a fit
        // interpolates (a truncating read holds each node across its bin,
        // docs/fitting.md); then the table goes into the fit.
        let opts = crate::judge::judge_options();
        let (judge, data): (_, crate::samples::SampleData) = match table {
            npf_data_loaders::Table::Merl(t) => (
                crate::judge::Judge::new(&crate::bsdf::InterpolatedMerl(&t), opts),
                npf_data_loaders::MerlSamples::new(t, &source).into(),
            ),
            npf_data_loaders::Table::Utia(t) => (
                crate::judge::Judge::new(&t, opts),
                npf_data_loaders::Table::Utia(t).samples(&source).into(),
            ),
        };
        crate::phases::mark("read + judge's reference");
        if crate::samples::SampleSource::sample_count(&data) == 0 {
            return Err(super::no_samples(input));
        }
        let reread = reread_checked(input, args.format, stamp);
        let mut observer = |_: usize, _: &SweepReport| {};
        let fitted = crate::auto::fit_owned(data, reread, &judge, config, &mut observer)?;
        if verbose {
            print_auto(&fitted);
        }
        return write_fitted(output, args, fitted);
    }
    let selection = match (args.target, args.budget) {
        (Some(target), _) => Selection::Target(target),
        (None, Some(budget)) => {
            let metric = match args.budget_metric {
                BudgetMetric::LogRmse => Target::LogRmse(f64::INFINITY),
                BudgetMetric::RelRmse => Target::RelRmse(f64::INFINITY),
            };
            Selection::Budget(budget, metric)
        }
        (None, None) => {
            // Neither the samples nor the table are held during the sweeps
            // (the fit's peak memory): the table is read again for the
            // error measures (its samples made piece by piece, not all
            // held), and refused if the file changed meanwhile. A MERL
            // table's samples are never made as records.
            let stamp = file_stamp(input);
            let data = super::read_fit_data(input, args.format)?;
            crate::phases::mark("read + samples");
            let reread = reread_checked(input, args.format, stamp);
            let (bar, mut observer) = progress(config, verbose);
            let fitted = crate::fit::fit_owned(data, reread, config, &mut observer)?;
            bar.finish_and_clear();
            return write_fitted(output, args, fitted);
        }
    };
    let (table, samples) = super::read_measured(input, args.format)?;
    crate::phases::mark("read + samples");
    // A rendering-PSNR target renders the input table once as the reference.
    let reference = match &selection {
        Selection::Target(target) if target.needs_render() => {
            Some(crate::evaluation::Reference::new(
                super::table_bsdf(&table),
                &samples,
                Default::default(),
            ))
        }
        _ => None,
    };
    let fitted = select(&samples, verbose, config, selection, reference.as_ref())?;
    drop(table);
    write_fitted(output, args, fitted)
}

/// Reads `input` again for the error measures after a fit, refused if it
/// changed since `stamp` ([`file_stamp`]) was taken.
fn reread_checked(
    input: &std::path::Path,
    format: Option<super::FormatArg>,
    stamp: Option<(u64, std::time::SystemTime)>,
) -> impl FnOnce() -> Result<npf_data_loaders::Table, FitError> + Send + '_ {
    move || {
        let changed = |problem: String| FitError::Remeasure {
            source_name: input.display().to_string(),
            problem,
        };
        if file_stamp(input) != stamp {
            return Err(changed("the input changed during the fit".into()));
        }
        npf_data_loaders::Table::read(input, format.map(Into::into))
            .map_err(|e| changed(format!("reading it again: {e}")))
    }
}

/// The input's size and modification time (`None` if unreadable): what
/// tells a file changed between two reads.
fn file_stamp(path: &std::path::Path) -> Option<(u64, std::time::SystemTime)> {
    let m = std::fs::metadata(path).ok()?;
    Some((m.len(), m.modified().ok()?))
}

/// Write a fitted model to `output`.
/// Auto's candidates, their mean render PSNR and the choice (stderr).
fn print_auto(fitted: &Fitted) {
    let Some(auto) = fitted.info.selection.as_ref().and_then(|s| s.get("auto")) else {
        return;
    };
    for c in auto["candidates"].as_array().into_iter().flatten() {
        eprintln!(
            "auto: {:<28} render {:.2} dB (mean of {} scenes), log RMSE {:.4e}, {:.1} s",
            c["name"].as_str().unwrap_or("?"),
            c["render"]["mean_db"].as_f64().unwrap_or(f64::NAN),
            c["render"]["psnr_db"].as_array().map_or(0, Vec::len),
            c["log_rmse"].as_f64().unwrap_or(f64::NAN),
            c["seconds"].as_f64().unwrap_or(f64::NAN),
        );
    }
    eprintln!("auto: chose {}", auto["chosen"].as_str().unwrap_or("?"));
}

fn write_fitted(
    output: &std::path::Path,
    args: &FitArgs,
    fitted: Fitted,
) -> Result<Fitted, CliError> {
    modelfile::write(
        output,
        &ModelFile {
            model: fitted.result.model.clone(),
            fit: Some(fitted.info.clone()),
        },
        args.force,
    )?;
    crate::phases::mark("write");
    Ok(fitted)
}

enum Selection {
    Target(Target),
    Budget(usize, Target),
}

/// Model selection: fits candidates (see `selection`), keeps the chosen
/// fit, and records the choice and every trial in the fit record.
fn select(
    samples: &MeasuredSamples,
    verbose: bool,
    base: &FitConfig,
    how: Selection,
    reference: Option<&crate::evaluation::Reference>,
) -> Result<Fitted, CliError> {
    let mut kept: Vec<Fitted> = Vec::new();
    let mut try_candidate = |c: Candidate| -> Result<(Scores, f64), CliError> {
        let config = FitConfig {
            model: ModelKind::Factor,
            lobes: c.lobes,
            nodes: c.nodes,
            ..base.clone()
        };
        let f = fit(samples, &config, &mut |_, _| {})?;
        let render_psnr_db = match reference {
            Some(r) => Some(
                r.evaluate_model(config.max_theta, &f.result.model)
                    .map_err(|e| CliError::Message(e.to_string()))?
                    .0
                    .render_psnr_db,
            ),
            None => None,
        };
        if verbose {
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
            if verbose {
                eprintln!(
                    "choosing the smallest model with {} {} {}",
                    target.name(),
                    target.relation(),
                    target.threshold()
                );
            }
            let (i, met, trials) = selection::smallest_meeting(target, &mut try_candidate)?;
            if !met && verbose {
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
            let Some((i, trials)) = selection::best_within(budget, metric, &mut try_candidate)?
            else {
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
    if verbose {
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
