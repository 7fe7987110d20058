//! What a fit is asked: the model kind, every option with its one default
//! ([`FitConfig`]), the limits options are checked against, and how a fit
//! can fail.

use crate::model::Layout;
use crate::samples::{SampleError, SampleOptions, SampleSource, Weighting};
use crate::solver::{DiffuseKind, FitOptions, GMethod, SolverError};
use serde::{Deserialize, Serialize};

/// Which model a fit produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// The shared-factor model (1 to 3 lobes).
    Factor,
    /// Bagher et al.'s Independent-G model: one lobe, per-channel D, F, G
    /// (816 parameters at 90 values per table).
    IndependentG,
    /// Analytic GGX + Lambert with Schlick Fresnel (10 parameters).
    Ggx,
    /// Of factor, factor with separable diffuse, Independent-G and factor
    /// with cosine-L2 weights, the form whose renders (five scenes) are
    /// closest to the measured table's; the model file records the choice
    /// and every candidate (docs/fitting.md, src/auto.rs).
    Auto,
}

impl ModelKind {
    /// The kebab-case name used on the command line and in model files.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Factor => "factor",
            ModelKind::IndependentG => "independent-g",
            ModelKind::Ggx => "ggx",
            ModelKind::Auto => "auto",
        }
    }

    /// The number of free parameters the model really has (the stored form
    /// may hold more: structural zeros or tabulated analytic factors).
    pub fn effective_params(self, layout: &Layout, lobes: usize) -> usize {
        match self {
            // Auto's count is its choice's; the default's until it chooses.
            ModelKind::Factor | ModelKind::Auto => layout.param_count(lobes),
            ModelKind::IndependentG => 3 * (2 + layout.d.len() + layout.f.len() + layout.g.len()),
            ModelKind::Ggx => 10,
        }
    }
}

/// Everything a fit is set up with. `FitConfig::default()` holds npf's
/// defaults (taken from [`SampleOptions::default`] and
/// [`FitOptions::default`], the solver's own), and the `npf` program's
/// flags take theirs from it.
#[derive(Clone, Debug, PartialEq)]
pub struct FitConfig {
    /// Which model to fit.
    pub model: ModelKind,
    /// Specular lobes (1 to 3); the factor model's only (Independent-G has
    /// one lobe per channel, GGX one lobe).
    pub lobes: usize,
    /// Values per factor table (D, F, G), 4 to 90: 90 is MERL's resolution;
    /// fewer give smaller models on the same axes. Every model kind is
    /// tabulated on this layout.
    pub nodes: usize,
    /// Residual weighting (see docs/fitting.md).
    pub weighting: Weighting,
    /// Least floor of the compressive weight (cosine-weighted 1/sr); the
    /// floor a fit uses is [`FitConfig::epsilon_for`].
    pub epsilon: f64,
    /// The compressive floor as a fraction of the data's median
    /// cosine-weighted value: a fit's floor is the larger of `epsilon` and
    /// this times that median (0: `epsilon` alone). A floor far below the
    /// data's typical level lets near-black and exactly-zero cells (which
    /// no rendering can see) dominate the objective (BENCHMARKS.md as of 4d8d1ee, issue 16).
    pub epsilon_median: f64,
    /// The same fraction for data that do not look like a trustworthy
    /// measurement: clamped (at least [`CLAMPED_ZERO_FRACTION`](crate::fit::CLAMPED_ZERO_FRACTION) of a
    /// channel's samples inside the cut-off exactly 0, as where a
    /// resampling clamped negative values) or, with `grazing_trust` on,
    /// not reciprocal at grazing angles ([`GrazingRule::asymmetry`](crate::fit::GrazingRule::asymmetry) at
    /// least `grazing_trust`). Such a table's near-black cells are no level
    /// to fit relatively. The larger of the two fractions applies
    /// ([`FitConfig::floor_rule`]; 0: off).
    pub epsilon_median_untrusted: f64,
    /// Grazing trust decided by the data: a table that is not clamped
    /// ([`FloorRule::clamped`](crate::fit::FloorRule::clamped)) and whose grazing cells agree with their reciprocal
    /// partners (upper quartile of the relative asymmetry below this) is fitted to
    /// [`GRAZING_MAX_THETA`](crate::fit::GRAZING_MAX_THETA) with weights tapering from
    /// [`GRAZING_TAPER_FROM`](crate::fit::GRAZING_TAPER_FROM) ([`FitConfig::grazing_rule`]); other tables at
    /// `max_theta`. 0: off. Only when `taper_from` is not set and `max_theta`
    /// is its default (a cut-off the user chose is kept).
    pub grazing_trust: f64,
    /// Grazing cut-off (degrees): samples with theta_i or theta_o above it
    /// are left out.
    pub max_theta: f64,
    /// D cells above this half angle (degrees) hold the last free cell's value.
    pub max_theta_h: f64,
    /// Sweep limit.
    pub max_sweeps: usize,
    /// Stop when a sweep lowers the objective by less than this fraction.
    pub tol: f64,
    /// How G control points are updated.
    pub g_method: GMethod,
    /// Gaussian smoothing of G after each update (sigma in control points),
    /// kept only if it does not raise the objective.
    pub smooth_g: Option<f64>,
    /// D may not rise with theta_h past this angle (degrees); `None` leaves
    /// the D tail free.
    pub d_monotone_from: Option<f64>,
    /// Extrapolation between sweeps (false: plain AWLS).
    pub accelerate: bool,
    /// Worker threads (0: all cores). Results are identical for any count.
    pub threads: usize,
    /// The factor model's diffuse form (docs/fitting.md).
    pub diffuse: DiffuseKind,
    /// Coarse-to-fine levels ([`crate::coarse`]): decimation factors of the
    /// sample sets fitted before the full one, coarsest first (empty: fit
    /// the full set only). Factor kinds only.
    pub coarse: Vec<usize>,
    /// The tolerance of the decimated levels (their sweeps are cheap, so
    /// they may run further than the full set's `tol`).
    pub coarse_tol: f64,
    /// The sweep limit of the decimated levels. A coarse sweep costs about
    /// a 16th of a full one, and a level that stops at its limit leaves the
    /// rest of a long descent to full sweeps (BENCHMARKS.md as of 4d8d1ee, issue 15,
    /// "the extrapolation's tail projection").
    pub coarse_max_sweeps: usize,
    /// Hold G on the full set where the coarse levels fitted it
    /// ([`crate::coarse::Schedule::keep_g`]): `None` does so on isotropic
    /// layouts (measured on the 16 MERL and 10 RGL tables: the G pass was
    /// half of each full sweep, BENCHMARKS.md as of 4d8d1ee issue 15) and updates G on
    /// anisotropic ones, whose 6 x 48 G tables were not measured this way.
    pub keep_coarse_g: Option<bool>,
    /// The full set's tolerance when G is kept from the coarse level (in
    /// place of `tol`, which plain and anisotropic fits keep); `None`:
    /// twice `tol`, so a tighter `tol` still tightens it. Measured on the
    /// 16 MERL tables: 6e-3 (twice the default) stops every full set after
    /// 2 sweeps (2-4 at 3e-3) and moves the rendering PSNR by at most
    /// 0.03 dB (BENCHMARKS.md as of 4d8d1ee, "Idle checks of 2026-12-03 night").
    pub kept_g_tol: Option<f64>,
    /// Joint Gauss-Newton steps between sweeps (`solver::gauss_newton`):
    /// `None` uses them on anisotropic layouts only (where AWLS alone
    /// leaves blended lobes slowly: docs/anisotropic.md), `Some` forces.
    pub gauss_newton: Option<bool>,
    /// Joint Gauss-Newton steps on the coarse levels, where AWLS crawls
    /// ([`crate::coarse::Schedule::gauss_newton`]), whatever
    /// `gauss_newton` says of the full set.
    pub coarse_gauss_newton: bool,
    /// Grazing taper (degrees): past it a sample's weight falls linearly to
    /// 0 at the horizon ([`SampleOptions::taper_from_deg`]); `None`: none.
    pub taper_from: Option<f64>,
    /// The factor model's masking-shadowing form (docs/fitting.md).
    pub masking: crate::model::Masking,
    /// Pooled compressive weights below this half angle (degrees;
    /// [`SampleOptions::pool_scale_below_deg`]); `None`: off.
    pub pool_scale_below: Option<f64>,
    /// The pooling angle for untrusted tables ([`FloorRule::untrusted`](crate::fit::FloorRule::untrusted));
    /// the larger of the two applies; `None`: off.
    pub pool_scale_below_untrusted: Option<f64>,
    /// Add Kulla-Conty's multiple-scattering term of the fitted lobes to
    /// the model ([`crate::model::Compensation`]); for energy-conservation
    /// studies, not appearance fits (docs/fitting.md: it adds energy
    /// measured data do not have).
    pub compensate: bool,
    /// The post-fit per-channel energy scale of d and every s
    /// ([`crate::energy::scale`], read from the re-read MERL table):
    /// `None` applies it to untrusted isotropic tables only (the rule that
    /// also pools their scales), `Some(true)` to every MERL table,
    /// `Some(false)` never. Factor models without compensation only.
    pub energy_scale: Option<bool>,
}

impl Default for FitConfig {
    fn default() -> Self {
        let s = SampleOptions::default();
        let o = FitOptions::default();
        FitConfig {
            model: ModelKind::Factor,
            lobes: o.lobes,
            nodes: Layout::default().d.len(),
            weighting: s.weighting,
            epsilon: s.epsilon,
            epsilon_median: EPSILON_MEDIAN,
            epsilon_median_untrusted: EPSILON_MEDIAN_UNTRUSTED,
            grazing_trust: GRAZING_TRUST,
            max_theta: s.max_theta_deg,
            max_theta_h: s.max_theta_h_deg,
            max_sweeps: o.max_sweeps,
            tol: o.tol,
            g_method: o.g_method,
            smooth_g: o.smooth_g,
            d_monotone_from: o.d_monotone_from_deg,
            accelerate: o.accelerate,
            threads: 0,
            diffuse: o.diffuse,
            // One level at a 32nd of the samples (BENCHMARKS.md as of 4d8d1ee, issue 15),
            // run to 1e-4: at 1e-3 it stopped on the plateau of a crawl
            // (violet-acrylic: sweep 23 of about 200; the crawl ends 16 %
            // lower), which the full set, holding G, cannot leave;
            // the 100-sweep limit keeps every MERL fit under 2 s (issue 16,
            // BENCHMARKS.md as of 4d8d1ee "Issue 16 under its own protocol").
            coarse: vec![32],
            coarse_tol: 1e-4,
            coarse_max_sweeps: 100,
            keep_coarse_g: None,
            kept_g_tol: None,
            gauss_newton: None,
            coarse_gauss_newton: false,
            taper_from: s.taper_from_deg,
            masking: o.masking,
            pool_scale_below: s.pool_scale_below_deg,
            pool_scale_below_untrusted: Some(POOL_SCALE_BELOW_UNTRUSTED),
            compensate: false,
            energy_scale: None,
        }
    }
}

/// Largest [`FitConfig::epsilon_median`]: a floor above the median makes
/// the weighting plain least squares on more than half the samples.
pub const MAX_EPSILON_MEDIAN: f64 = 10.0;

/// Accepted coarse-to-fine decimation factors (1: the level is skipped;
/// beyond 64 a MERL table leaves too few samples per factor entry).
pub const COARSE_FACTORS: std::ops::RangeInclusive<usize> = 1..=64;

/// Fewest and most values per factor table.
pub const NODES: std::ops::RangeInclusive<usize> = 4..=90;

/// Largest `epsilon` (cosine-weighted 1/sr): above every measured
/// cosine-weighted value, the compressive weighting is already plain least
/// squares scaled by 1/epsilon^2; larger floors only underflow the
/// objective towards 0 (a "converged" fit of nothing).
pub const MAX_EPSILON: f64 = 1e3;

/// Largest measured value a fit accepts (1/sr). Models store f32 (at most
/// 3.4e38) and the solver multiplies factors and squares residuals, so data
/// beyond this cannot be represented; no real BRDF comes near it.
pub const MAX_SAMPLE_VALUE: f64 = 1e30;

/// Most worker threads per core ([`max_threads`]).
pub const THREADS_PER_CORE: usize = 4;

/// Largest `threads`: [`THREADS_PER_CORE`] per core of this machine. More
/// only costs start-up time and memory (results do not depend on it).
pub fn max_threads() -> usize {
    THREADS_PER_CORE * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Why a fit could not be set up or run. Messages name the problem in the
/// library's terms; the `npf` program adds its flag names.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// `nodes` outside [`NODES`].
    #[error("the values per factor table must be {min} to {max}, got {0}", min = NODES.start(), max = NODES.end())]
    Nodes(usize),
    /// The worker pool could not start.
    #[error("cannot start {threads} threads: {source}")]
    Threads {
        /// Threads asked for.
        threads: usize,
        /// The pool's error.
        source: rayon::ThreadPoolBuildError,
    },
    /// The samples could not be turned into a fit set.
    #[error(transparent)]
    Samples(#[from] SampleError),
    /// The solver's options or start were refused.
    #[error(transparent)]
    Solver(#[from] SolverError),
    /// The GGX baseline fit failed.
    #[error(transparent)]
    Ggx(#[from] crate::baselines::GgxFitError),
    /// More threads than [`max_threads`].
    #[error("at most {max} threads ({THREADS_PER_CORE} per core on this machine; 0 uses every core), got {threads}")]
    TooManyThreads {
        /// Threads asked for.
        threads: usize,
        /// The limit.
        max: usize,
    },
    /// An option outside its documented range (the option's name, the range, the value).
    #[error("{name} must be {range}, got {}", short_number(*.value))]
    Range {
        /// The option (library name).
        name: &'static str,
        /// The accepted range, in words.
        range: String,
        /// The value given.
        value: f64,
    },
    /// The input could not be read again for the error measures after the
    /// fit ([`fit_owned`](crate::fit::fit_owned)): it vanished or changed meanwhile.
    #[error("{source_name}: cannot measure the fit's errors: {problem}")]
    Remeasure {
        /// The samples' source.
        source_name: String,
        /// What went wrong.
        problem: String,
    },
    /// `ModelKind::Auto` given to a fit that has no measured table to
    /// render: auto is [`crate::auto::fit`].
    #[error(
        "the auto model is chosen by rendering the measured table: fit it with npf::auto::fit"
    )]
    AutoNeedsTable,
    /// The data, or the fitted model, cannot be represented in the model's
    /// storage precision (f32) or gave non-finite measures.
    #[error("{source_name}: {problem}")]
    Unrepresentable {
        /// The samples' source.
        source_name: String,
        /// What cannot be represented.
        problem: String,
    },
}

/// A number as a user typed it: 1e300, not 300 digits.
fn short_number(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl FitConfig {
    /// The layout every model kind is tabulated on (`nodes` values per table).
    pub fn layout(&self) -> Layout {
        Layout::isotropic(self.nodes)
    }

    /// The layout a fit of `samples` uses: [`FitConfig::layout`] for
    /// isotropic data, [`Layout::anisotropic`] (2010 parameters for three
    /// lobes; `nodes` does not apply) for anisotropic data such as UTIA tables.
    pub fn layout_for<S: SampleSource + ?Sized>(&self, samples: &S) -> Layout {
        if samples.is_isotropic() {
            self.layout()
        } else {
            Layout::anisotropic()
        }
    }

    /// The sample-set options (weighting and cut-offs), with the floor
    /// `epsilon` as given ([`FitConfig::sample_options_for`] resolves it).
    pub fn sample_options(&self) -> SampleOptions {
        SampleOptions {
            weighting: self.weighting,
            epsilon: self.epsilon,
            max_theta_deg: self.max_theta,
            max_theta_h_deg: self.max_theta_h,
            taper_from_deg: self.taper_from,
            pool_scale_below_deg: self.pool_scale_below,
        }
    }

    /// The solver options.
    pub fn fit_options(&self) -> FitOptions {
        FitOptions {
            lobes: self.lobes,
            max_sweeps: self.max_sweeps,
            tol: self.tol,
            g_method: self.g_method,
            smooth_g: self.smooth_g,
            accelerate: self.accelerate,
            trace_stages: false,
            d_monotone_from_deg: self.d_monotone_from,
            channel_mask: FitOptions::default().channel_mask,
            diffuse: self.diffuse,
            gauss_newton: self.gauss_newton.unwrap_or(false),
            masking: self.masking,
            ..FitOptions::default()
        }
    }

    /// The parameter count of the model this configuration fits.
    pub fn effective_params(&self) -> usize {
        self.model.effective_params(&self.layout(), self.lobes)
    }

    /// Refuse a configuration the solver cannot run, before any work. The
    /// solver's own checks ([`FitOptions::validate`]) are the only range
    /// checks of its options.
    pub fn validate(&self) -> Result<(), FitError> {
        if !NODES.contains(&self.nodes) {
            return Err(FitError::Nodes(self.nodes));
        }
        if self.threads > max_threads() {
            return Err(FitError::TooManyThreads {
                threads: self.threads,
                max: max_threads(),
            });
        }
        if !(self.epsilon > 0.0 && self.epsilon <= MAX_EPSILON) {
            return Err(FitError::Range {
                name: "epsilon",
                range: format!("in (0, {MAX_EPSILON:e}]"),
                value: self.epsilon,
            });
        }
        for (name, v) in [
            ("epsilon_median", self.epsilon_median),
            ("epsilon_median_untrusted", self.epsilon_median_untrusted),
        ] {
            if !(0.0..=MAX_EPSILON_MEDIAN).contains(&v) {
                return Err(FitError::Range {
                    name,
                    range: format!("in [0, {MAX_EPSILON_MEDIAN}]"),
                    value: v,
                });
            }
        }
        // An asymmetry |a - b| / (a + b) lies in [0, 1].
        if !(0.0..=1.0).contains(&self.grazing_trust) {
            return Err(FitError::Range {
                name: "grazing_trust",
                range: "in [0, 1]".into(),
                value: self.grazing_trust,
            });
        }
        for (name, v) in [
            ("max_theta", self.max_theta),
            ("max_theta_h", self.max_theta_h),
        ] {
            if !(v > 0.0 && v <= 90.0) {
                return Err(FitError::Range {
                    name,
                    range: "in (0, 90] degrees".into(),
                    value: v,
                });
            }
        }
        for (name, p) in [
            ("pool_scale_below", self.pool_scale_below),
            (
                "pool_scale_below_untrusted",
                self.pool_scale_below_untrusted,
            ),
        ] {
            if let Some(t) = p.filter(|t| !(*t > 0.0 && *t <= 90.0)) {
                return Err(FitError::Range {
                    name,
                    range: "in (0, 90] degrees".into(),
                    value: t,
                });
            }
        }
        if let Some(t) = self.taper_from.filter(|t| !(0.0..90.0).contains(t)) {
            return Err(FitError::Range {
                name: "taper_from",
                range: "in [0, 90) degrees".into(),
                value: t,
            });
        }
        // A Gaussian wider than the table only averages it, at a cost that
        // grows with the width.
        if let Some(sg) = self.smooth_g.filter(|&sg| sg > self.nodes as f64) {
            return Err(FitError::Range {
                name: "smooth_g",
                range: format!("positive and at most the values per table ({})", self.nodes),
                value: sg,
            });
        }
        if let Some(t) = self.kept_g_tol.filter(|t| !(*t >= 0.0 && t.is_finite())) {
            return Err(FitError::Range {
                name: "kept_g_tol",
                range: "finite and non-negative".into(),
                value: t,
            });
        }
        if !(self.coarse_tol >= 0.0 && self.coarse_tol.is_finite()) {
            return Err(FitError::Range {
                name: "coarse_tol",
                range: "finite and non-negative".into(),
                value: self.coarse_tol,
            });
        }
        if self.coarse_max_sweeps == 0 {
            return Err(FitError::Range {
                name: "coarse_max_sweeps",
                range: "at least 1".into(),
                value: 0.0,
            });
        }
        if let Some(&f) = self.coarse.iter().find(|f| !COARSE_FACTORS.contains(f)) {
            return Err(FitError::Range {
                name: "coarse",
                range: format!(
                    "a list of decimation factors {} to {}",
                    COARSE_FACTORS.start(),
                    COARSE_FACTORS.end()
                ),
                value: f as f64,
            });
        }
        self.fit_options().validate()?;
        Ok(())
    }
}

/// The default [`FitConfig::epsilon_median`]: off. Measured on the 16 MERL
/// and 10 RGL tables (BENCHMARKS.md as of 4d8d1ee, issue 16), 0.3 raises the RGL tables
/// by up to 9 dB but lowers polyurethane-foam by 0.76 dB and
/// silver-metallic-paint by 0.51, so it is an option, not the default.
pub const EPSILON_MEDIAN: f64 = 0.0;

/// The default [`FitConfig::epsilon_median_untrusted`]: on the 8 clamped RGL
/// tables 0.6 renders better than 0.3 on 6 and than 1.0 on 5 (paper_blue
/// prefers 0.3); on the 16 MERL tables it changes nothing (none is
/// untrusted but black-obsidian, and 0.6 of its median is below
/// `epsilon`). BENCHMARKS.md as of 4d8d1ee,
/// issue 16, "data-decided floor and grazing trust".
pub const EPSILON_MEDIAN_UNTRUSTED: f64 = 0.6;

/// The default [`FitConfig::grazing_trust`]: the upper quartile is
/// 0.04-0.15 on the 16 MERL tables and 0.26-0.60 on the 10 RGL ones, whose
/// grazing cells mislead a fit (a tapered fit to 89 degrees gains up to
/// 2.7 dB on MERL, loses up to 1 dB on RGL). BENCHMARKS.md as of 4d8d1ee, issue 16,
/// "data-decided floor and grazing trust".
pub const GRAZING_TRUST: f64 = 0.2;

/// The default [`FitConfig::pool_scale_below_untrusted`]: every row
/// pooled. Untrusted tables' values vary along phi_d where an isotropic
/// model cannot follow them; own-value weights then fit each row near
/// its harmonic mean, far below what the renderer sums. On the 10 RGL
/// tables full-row pooling renders cc_nothern_aurora at 32.3 dB against
/// 28.9 and chm_mint at 28.0 against 27.1, and no table more than 0.06 dB
/// lower (BENCHMARKS.md as of 4d8d1ee, issue 16, "chm_mint and cc_nothern_aurora").
pub const POOL_SCALE_BELOW_UNTRUSTED: f64 = 90.0;
