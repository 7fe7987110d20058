//! `npf fit`'s arguments: the flags every fitting command shares and
//! those of `npf fit` itself.

use crate::fit::{FitConfig, ModelKind};
use crate::samples::Weighting;
use crate::selection::Target;
use crate::solver::{DiffuseKind, GMethod};
use clap::Args;
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

/// `npf fit`'s arguments.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// Measured BRDF: MERL .binary (isotropic layout) or UTIA .bin
    /// (anisotropic layout, 2010 parameters for three lobes), or an
    /// isotropic RGL .bsdf file (read as Mitsuba 3's measured plugin reads
    /// it, tabulated on MERL's nodes); or a folder, whose every .binary and
    /// .bin table is fitted into the -o folder.
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
