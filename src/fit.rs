//! The library's fit entry point: one [`FitConfig`] (whose `Default` is the
//! only place fit defaults are chosen), one [`fit`] for every [`ModelKind`],
//! and the [`Fitted`] result with its provenance.
//!
//! The `npf` program's flags, the benchmark report and library users all go
//! through here, so a model fitted by any of them is the same model.

use crate::baselines::{fit_ggx, GgxParams};
use crate::coarse::CoarseError;
use crate::metrics::{compare_model, compare_model_table, MerlReference, Metrics};
use crate::model::Layout;
use crate::modelfile::FitInfo;
use crate::samples::{
    round_to_i64, KeyMap, SampleData, SampleError, SampleOptions, SampleSource, SampleView,
    Weighting,
};
use crate::solver::{
    init, DiffuseKind, Factors, FitOptions, FitResult, GMethod, SolverError, SweepReport,
    INDEPENDENT_CHANNELS,
};
use npf_data_loaders::MeasuredSamples;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

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
    /// no rendering can see) dominate the objective (BENCHMARKS.md, issue 16).
    pub epsilon_median: f64,
    /// The same fraction for data that do not look like a trustworthy
    /// measurement: clamped (at least [`CLAMPED_ZERO_FRACTION`] of a
    /// channel's samples inside the cut-off exactly 0, as where a
    /// resampling clamped negative values) or, with `grazing_trust` on,
    /// not reciprocal at grazing angles ([`GrazingRule::asymmetry`] at
    /// least `grazing_trust`). Such a table's near-black cells are no level
    /// to fit relatively. The larger of the two fractions applies
    /// ([`FitConfig::floor_rule`]; 0: off).
    pub epsilon_median_untrusted: f64,
    /// Grazing trust decided by the data: a table that is not clamped
    /// ([`FloorRule::clamped`]) and whose grazing cells agree with their reciprocal
    /// partners (upper quartile of the relative asymmetry below this) is fitted to
    /// [`GRAZING_MAX_THETA`] with weights tapering from
    /// [`GRAZING_TAPER_FROM`] ([`FitConfig::grazing_rule`]); other tables at
    /// `max_theta`. 0: off. Only when `taper_from` is not set.
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
    /// rest of a long descent to full sweeps (BENCHMARKS.md, issue 15,
    /// "the extrapolation's tail projection").
    pub coarse_max_sweeps: usize,
    /// Hold G on the full set where the coarse levels fitted it
    /// ([`crate::coarse::Schedule::keep_g`]): `None` does so on isotropic
    /// layouts (measured on the 16 MERL and 10 RGL tables: the G pass was
    /// half of each full sweep, BENCHMARKS.md issue 15) and updates G on
    /// anisotropic ones, whose 6 x 48 G tables were not measured this way.
    pub keep_coarse_g: Option<bool>,
    /// The full set's tolerance when G is kept from the coarse level (in
    /// place of `tol`, which plain and anisotropic fits keep); `None`:
    /// twice `tol`, so a tighter `tol` still tightens it. Measured on the
    /// 16 MERL tables: 6e-3 (twice the default) stops every full set after
    /// 2 sweeps (2-4 at 3e-3) and moves the rendering PSNR by at most
    /// 0.03 dB (BENCHMARKS.md, "Idle checks of 2026-12-03 night").
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
    /// The pooling angle for untrusted tables ([`FloorRule::untrusted`]);
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
            // One level at a 32nd of the samples (BENCHMARKS.md, issue 15),
            // run to 1e-4: at 1e-3 it stopped on the plateau of a crawl
            // (violet-acrylic: sweep 23 of about 200; the crawl ends 16 %
            // lower), which the full set, holding G, cannot leave;
            // the 100-sweep limit keeps every MERL fit under 2 s (issue 16,
            // BENCHMARKS.md "Issue 16 under its own protocol").
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

/// The default [`FitConfig::epsilon_median`]: off. Measured on the 16 MERL
/// and 10 RGL tables (BENCHMARKS.md, issue 16), 0.3 raises the RGL tables
/// by up to 9 dB but lowers polyurethane-foam by 0.76 dB and
/// silver-metallic-paint by 0.51, so it is an option, not the default.
pub const EPSILON_MEDIAN: f64 = 0.0;

/// The default [`FitConfig::epsilon_median_untrusted`]: on the 8 clamped RGL
/// tables 0.6 renders better than 0.3 on 6 and than 1.0 on 5 (paper_blue
/// prefers 0.3); on the 16 MERL tables it changes nothing (none is
/// untrusted but black-obsidian, and 0.6 of its median is below
/// `epsilon`). BENCHMARKS.md,
/// issue 16, "data-decided floor and grazing trust".
pub const EPSILON_MEDIAN_UNTRUSTED: f64 = 0.6;

/// The default [`FitConfig::pool_scale_below_untrusted`]: every row
/// pooled. Untrusted tables' values vary along phi_d where an isotropic
/// model cannot follow them; own-value weights then fit each row near
/// its harmonic mean, far below what the renderer sums. On the 10 RGL
/// tables full-row pooling renders cc_nothern_aurora at 32.3 dB against
/// 28.9 and chm_mint at 28.0 against 27.1, and no table more than 0.06 dB
/// lower (BENCHMARKS.md, issue 16, "chm_mint and cc_nothern_aurora").
pub const POOL_SCALE_BELOW_UNTRUSTED: f64 = 90.0;

/// The fraction of a channel's samples (inside the cut-off) that must be
/// exactly 0 for the data to count as clamped: 1 in 2,000, above isolated
/// zeros, below the 0.07-23 % of the clamped RGL tables (the 16 MERL have
/// none, black-obsidian apart, whose floor stays at `epsilon`).
pub const CLAMPED_ZERO_FRACTION: f64 = 5e-4;

/// What [`FitConfig::floor_rule`] read from the data and chose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FloorRule {
    /// The largest fraction of one channel's samples inside the cut-off
    /// that are exactly 0.
    pub zero_fraction: f64,
    /// Whether that is at least [`CLAMPED_ZERO_FRACTION`].
    pub clamped: bool,
    /// [`GrazingRule::asymmetry`] (NaN when `grazing_trust` is off or no
    /// grazing cell has a partner).
    pub grazing_asymmetry: f64,
    /// Clamped, or the grazing asymmetry at least `grazing_trust`: the
    /// data get `epsilon_median_untrusted` and the cut-off.
    pub untrusted: bool,
    /// The median of rho cos theta_i (channel mean) inside the cut-off.
    pub median: f64,
    /// The fraction of the median applied (0: none).
    pub median_fraction: f64,
    /// The resulting floor.
    pub epsilon: f64,
}

/// The default [`FitConfig::grazing_trust`]: the upper quartile is
/// 0.04-0.15 on the 16 MERL tables and 0.26-0.60 on the 10 RGL ones, whose
/// grazing cells mislead a fit (a tapered fit to 89 degrees gains up to
/// 2.7 dB on MERL, loses up to 1 dB on RGL). BENCHMARKS.md, issue 16,
/// "data-decided floor and grazing trust".
pub const GRAZING_TRUST: f64 = 0.2;

/// The cut-off of a table whose grazing cells are trusted (degrees).
pub const GRAZING_MAX_THETA: f64 = 89.0;

/// Where the weights of a trusted table's grazing cells start to taper:
/// from the usual cut-off, so the cells a fit saw before keep their
/// weight (a taper from 80 lowered polyurethane-foam by 0.18 dB and left
/// green-latex 0.36 dB below Independent-G; from 85 neither).
pub const GRAZING_TAPER_FROM: f64 = 85.0;

/// What [`FitConfig::grazing_rule`] read from the data and chose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GrazingRule {
    /// Upper quartile over the cells past `max_theta` (up to
    /// [`GRAZING_MAX_THETA`]) of |a - b| / (a + b), a and b the channel
    /// sums of a cell and of its reciprocal partner (theta_i and theta_o
    /// swapped): how far the grazing data are from any reciprocal BRDF.
    /// (The quartile, not the median: the tables whose grazing cells mislead
    /// a fit differ from the rest in their tail of disagreeing cells.)
    pub asymmetry: f64,
    /// Whether the grazing cells are fitted.
    pub trusted: bool,
    /// The cut-off fitted (degrees).
    pub max_theta_deg: f64,
    /// The taper fitted (degrees).
    pub taper_from_deg: Option<f64>,
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
    /// fit ([`fit_owned`]): it vanished or changed meanwhile.
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

    /// The compressive floor a fit of `samples` uses: the larger of
    /// `epsilon` and a fraction of the median over the samples inside the
    /// cut-off of rho cos theta_i (the mean of the channels), at most
    /// [`MAX_EPSILON`]. The fraction is `epsilon_median`, or
    /// `epsilon_median_untrusted` if larger and the data are untrusted
    /// ([`FloorRule`]). Depends on the data alone, so the objective is one
    /// fixed weighted least squares and the fit stays deterministic.
    pub fn floor_rule<S: SampleSource + ?Sized>(&self, samples: &S) -> FloorRule {
        use rayon::prelude::*;
        let cut = self.max_theta.to_radians();
        // Parallel passes: counts are exact in any order, and the median
        // is a rank, the same for any order of the values.
        let inside = || {
            (0..samples.sample_count())
                .into_par_iter()
                .map(|i| samples.view(i))
                .filter(move |s| s.theta_i <= cut && s.theta_o <= cut)
        };
        let (zeros, n) = inside()
            .fold(
                || ([0usize; 3], 0usize),
                |(mut zeros, n), s| {
                    for c in 0..3 {
                        zeros[c] += (s.rgb[c] == 0.0) as usize;
                    }
                    (zeros, n + 1)
                },
            )
            .reduce(
                || ([0usize; 3], 0usize),
                |(a, n), (b, m)| (std::array::from_fn(|c| a[c] + b[c]), n + m),
            );
        let zero_fraction = zeros
            .iter()
            .map(|&z| z as f64 / n.max(1) as f64)
            .fold(0.0, f64::max);
        let clamped = n > 0 && zero_fraction >= CLAMPED_ZERO_FRACTION;
        let grazing_asymmetry = self.grazing_asymmetry(samples).0;
        // NaN (off, or no grazing cells) compares false: not untrusted.
        let untrusted = clamped || grazing_asymmetry >= self.grazing_trust;
        let median_fraction = if untrusted {
            self.epsilon_median.max(self.epsilon_median_untrusted)
        } else {
            self.epsilon_median
        };
        let mut rule = FloorRule {
            zero_fraction,
            clamped,
            grazing_asymmetry,
            untrusted,
            median: 0.0,
            median_fraction,
            epsilon: self.epsilon,
        };
        if median_fraction <= 0.0 {
            return rule;
        }
        let mut v: Vec<f64> = inside()
            .map(|s| (s.rgb[0] + s.rgb[1] + s.rgb[2]) / 3.0 * s.theta_i.cos().max(0.0))
            .filter(|v| v.is_finite())
            .collect();
        if v.is_empty() {
            return rule;
        }
        let mid = v.len() / 2;
        let (_, median, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
        rule.median = *median;
        rule.epsilon = self.epsilon.max(median_fraction * *median).min(MAX_EPSILON);
        rule
    }

    /// The cut-off and taper a fit of `samples` uses: [`GRAZING_MAX_THETA`]
    /// and a taper from [`GRAZING_TAPER_FROM`] when `grazing_trust` is on,
    /// no taper is set and the data are not untrusted (`floor`, from
    /// [`FitConfig::floor_rule`]: not clamped and the grazing cells'
    /// reciprocity asymmetry below `grazing_trust`); else `max_theta` and
    /// `taper_from`. Depends on the data alone.
    pub fn grazing_rule(&self, floor: &FloorRule) -> GrazingRule {
        let trusted = self.grazing_trust > 0.0
            && self.taper_from.is_none()
            && floor.grazing_asymmetry.is_finite()
            && !floor.untrusted;
        GrazingRule {
            asymmetry: floor.grazing_asymmetry,
            trusted,
            max_theta_deg: if trusted {
                GRAZING_MAX_THETA
            } else {
                self.max_theta
            },
            taper_from_deg: if trusted {
                Some(GRAZING_TAPER_FROM)
            } else {
                self.taper_from
            },
        }
    }

    /// [`GrazingRule::asymmetry`] of `samples` and the number of cells it
    /// was read from: (NaN, 0) when `grazing_trust` is off, a taper is set,
    /// the cut-off is already at [`GRAZING_MAX_THETA`] or the data are
    /// anisotropic.
    pub fn grazing_asymmetry<S: SampleSource + ?Sized>(&self, samples: &S) -> (f64, usize) {
        if self.grazing_trust <= 0.0
            || self.taper_from.is_some()
            || self.max_theta >= GRAZING_MAX_THETA
            || !samples.is_isotropic()
        {
            return (f64::NAN, 0);
        }
        use rayon::prelude::*;
        let (lo, hi) = (self.max_theta.to_radians(), GRAZING_MAX_THETA.to_radians());
        let q = |x: f64| round_to_i64(x * 1e6);
        let key = |a: &SampleView, swap: bool| {
            let (i, o) = if swap {
                (a.theta_o, a.theta_i)
            } else {
                (a.theta_i, a.theta_o)
            };
            (q(a.theta_h), q(a.theta_d), q(i), q(o))
        };
        // The band in input order (a later duplicate key overwrites an
        // earlier one, as in a serial pass); the quartile is a rank, the
        // same for any order of the ratios.
        let band: Vec<SampleView> = (0..samples.sample_count())
            .into_par_iter()
            .map(|i| samples.view(i))
            .filter(|s| {
                let t = s.theta_i.max(s.theta_o);
                t > lo && t <= hi
            })
            .collect();
        let value: KeyMap<_, f64> = band
            .iter()
            .map(|s| (key(s, false), s.rgb.iter().sum::<f64>()))
            .collect();
        let mut r: Vec<f64> = band
            .par_iter()
            .filter_map(|s| {
                let a = s.rgb.iter().sum::<f64>();
                let b = *value.get(&key(s, true))?;
                (a + b > 0.0).then(|| (a - b).abs() / (a + b))
            })
            .collect();
        if r.is_empty() {
            return (f64::NAN, 0);
        }
        let upper = 3 * r.len() / 4;
        (*r.select_nth_unstable_by(upper, f64::total_cmp).1, r.len())
    }

    /// The floor [`FitConfig::floor_rule`] chooses for `samples`.
    pub fn epsilon_for<S: SampleSource + ?Sized>(&self, samples: &S) -> f64 {
        self.floor_rule(samples).epsilon
    }

    /// [`FitConfig::sample_options`] with the floor and the grazing
    /// cut-off resolved for `samples`.
    pub fn sample_options_for<S: SampleSource + ?Sized>(&self, samples: &S) -> SampleOptions {
        self.sample_options_with(&self.floor_rule(samples), samples.is_isotropic())
    }

    /// [`FitConfig::sample_options`] with the floor and the grazing
    /// cut-off of a rule already read from the data.
    pub fn sample_options_with(&self, floor: &FloorRule, isotropic: bool) -> SampleOptions {
        let grazing = self.grazing_rule(floor);
        SampleOptions {
            epsilon: floor.epsilon,
            max_theta_deg: grazing.max_theta_deg,
            taper_from_deg: grazing.taper_from_deg,
            pool_scale_below_deg: self.pool_scale_below_for(floor, isotropic),
            ..self.sample_options()
        }
    }

    /// The pooling angle a fit uses: `pool_scale_below`, or
    /// `pool_scale_below_untrusted` if larger and the data are untrusted
    /// and isotropic (a (theta_h, theta_d) row of anisotropic data also
    /// spans phi_h, which the model does follow).
    pub fn pool_scale_below_for(&self, floor: &FloorRule, isotropic: bool) -> Option<f64> {
        match (self.pool_scale_below, self.pool_scale_below_untrusted) {
            (p, Some(u)) if floor.untrusted && isotropic => Some(p.map_or(u, |p| p.max(u))),
            (p, _) => p,
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

/// Whether the post-fit energy scale can apply to `result`: a factor
/// model (d and s are the whole energy) on an isotropic layout, with no
/// multiple-scattering term (which reads the lobes' own energy).
fn scalable(config: &FitConfig, result: &FitResult) -> bool {
    config.model != ModelKind::Ggx
        && !config.compensate
        && result.model.compensation.is_none()
        && result.model.layout.is_isotropic()
}

/// Reads the energy ratio of `result` against `table` and, where the rule
/// applies it, scales d and every lobe's s per channel (factors and model
/// alike; the recorded objective stays the sweeps'). Returns the record.
fn scale_energy(
    (table, reference): (&npf_data_loaders::merl::MerlTable, Option<&MerlReference>),
    max_theta: f64,
    result: &mut FitResult,
) -> serde_json::Value {
    use crate::energy::scale::{applies, energy_ratio, energy_ratio_prepared, DEFAULT_RULE};
    let model = &result.model;
    let prepared =
        reference.and_then(|r| energy_ratio_prepared(r, table, max_theta, &DEFAULT_RULE, model));
    // `scalable` admits isotropic models only.
    let k = prepared
        .or_else(|| energy_ratio(table, max_theta, &DEFAULT_RULE, model))
        .unwrap_or([1.0; 3]);
    let applied = applies(&DEFAULT_RULE, &k);
    if applied {
        let f = &mut result.factors;
        for c in 0..3 {
            f.diffuse[c] *= k[c];
            for s in &mut f.s {
                s[c] *= k[c];
            }
        }
        result.model.diffuse = f.diffuse.map(|x| x as f32);
        for (lobe, s) in result.model.lobes.iter_mut().zip(&f.s) {
            lobe.s = s.map(|x| x as f32);
        }
    }
    serde_json::json!({
        "k": k,
        "applied": applied,
        "from_theta_h_deg": DEFAULT_RULE.from_theta_h_deg,
        "dead_zone": DEFAULT_RULE.dead_zone,
    })
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
