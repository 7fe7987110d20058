//! What a solver run is asked to do: lobes, G's update method, the diffuse
//! form, tolerances and sweeps ([`FitOptions`]), and how it can fail.

use serde::{Deserialize, Serialize};

/// The most specular lobes a model may have.
pub const MAX_LOBES: usize = 3;

/// How the G control points are updated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum GMethod {
    /// Exact: the best real root of the cubic derivative (or the bound 0).
    Cubic,
    /// Golden-section search on each control point (Bagher et al.'s fallback).
    Golden,
    /// G stays at its initial Smith shape.
    Fixed,
}

/// Which diffuse form a fit uses ([`crate::model::DiffuseForm`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum DiffuseKind {
    /// Constant d_C (the paper's).
    #[default]
    Lambert,
    /// d_C (1 - E(theta_i)) (1 - E(theta_o)) / (1 - E_avg), E from the
    /// fitted specular lobes, refreshed between sweeps.
    EnergyCoupled,
    /// Oren-Nayar's rough diffuse, sigma refreshed between sweeps.
    OrenNayar,
    /// d_C P(theta_i) P(theta_o), one table P shared by the channels,
    /// updated every sweep by the cubic element rule (Ashikhmin-Shirley-type
    /// coupled diffuse; Lambert when P = 1).
    Separable,
}

/// Options of one AWLS fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Specular lobes, 1 to 3.
    pub lobes: usize,
    /// The most sweeps to run.
    pub max_sweeps: usize,
    /// Stop when a sweep lowers the objective by less than this fraction.
    pub tol: f64,
    /// How G is updated.
    pub g_method: GMethod,
    /// Gaussian smoothing of G (standard deviation in control points, along
    /// theta in every phi column) after each G update, kept only when it
    /// does not raise the objective.
    pub smooth_g: Option<f64>,
    /// After each sweep, try the extrapolated point x + beta (x - x_prev)
    /// and keep it only if it lowers the objective. AWLS is coordinate
    /// descent and crawls along narrow valleys; this cuts the sweeps needed.
    pub accelerate: bool,
    /// Record the objective after every stage of every sweep (costs one
    /// pass over the samples per stage; for tests and diagnostics).
    pub trace_stages: bool,
    /// D^m past this half angle (degrees) may not rise above the cell
    /// before it. There only grazing samples, where G is small, see D, so
    /// D and G can trade scale without bound (D -> 1e30, G -> 1e-16); a
    /// non-increasing tail, as every microfacet NDF of a gloss lobe has,
    /// removes that freedom. `None` leaves the tail free.
    pub d_monotone_from_deg: Option<f64>,
    /// Which channels each lobe may light: `channel_mask[m][c] == false`
    /// holds s_c^m at exactly 0 (in the start, the d, s solve, the gauge and
    /// the extrapolation). All true by default. Independent-G is three lobes
    /// with lobe C lighting channel C only.
    #[serde(default = "all_channels")]
    pub channel_mask: [[bool; 3]; MAX_LOBES],
    /// The diffuse form: its factor is held fixed within a sweep and
    /// refreshed after the sweep's d, s solve, each refresh kept only when
    /// the objective falls.
    #[serde(default)]
    pub diffuse: DiffuseKind,
    /// After each sweep, try a joint damped Gauss-Newton step over every
    /// factor ([`gauss_newton`](crate::solver::gauss_newton)), kept only if it lowers the objective.
    #[serde(default)]
    pub gauss_newton: bool,
    /// Conjugate-gradient iterations (passes over the samples) per joint
    /// step at most.
    #[serde(default = "default_gauss_newton_cg")]
    pub gauss_newton_cg: usize,
    /// Try the joint step only after sweeps that lowered the objective by
    /// less than this fraction (where AWLS crawls); `None`: after every
    /// sweep (as the back-off allows).
    #[serde(default)]
    pub gauss_newton_below: Option<f64>,
    /// How each lobe combines G at the two directions: separable (the
    /// paper's) or height-correlated, whose G pass is [`g2_update`](crate::solver::g2_update).
    #[serde(default)]
    pub masking: crate::model::Masking,
    /// Hold a separable diffuse form's P where it starts (the full set
    /// after a coarse level that fitted it, as G is held there: P is as
    /// smooth as G, and its per-sample stencils would be the full set's
    /// largest cache).
    #[serde(default)]
    pub hold_p: bool,
}

fn default_gauss_newton_cg() -> usize {
    CG_ITERATIONS
}

fn all_channels() -> [[bool; 3]; MAX_LOBES] {
    [[true; 3]; MAX_LOBES]
}

/// The channel mask of Independent-G: lobe C lights channel C only.
pub const INDEPENDENT_CHANNELS: [[bool; 3]; MAX_LOBES] = [
    [true, false, false],
    [false, true, false],
    [false, false, true],
];

impl FitOptions {
    /// Check the options' ranges.
    pub fn validate(&self) -> Result<(), SolverError> {
        if !(1..=MAX_LOBES).contains(&self.lobes) {
            return Err(SolverError::Lobes(self.lobes));
        }
        if self.max_sweeps == 0 {
            return Err(SolverError::MaxSweeps);
        }
        if !(self.tol >= 0.0 && self.tol.is_finite()) {
            return Err(SolverError::Tolerance(self.tol));
        }
        if let Some(t) = self.d_monotone_from_deg {
            if !(0.0..=90.0).contains(&t) {
                return Err(SolverError::MonotoneFrom(t));
            }
        }
        if let Some(s) = self.smooth_g {
            if !(s > 0.0 && s.is_finite()) {
                return Err(SolverError::SmoothG(s));
            }
        }
        if self.gauss_newton_cg == 0 {
            return Err(SolverError::GaussNewtonCg);
        }
        if let Some(b) = self.gauss_newton_below {
            if !(b > 0.0 && b.is_finite()) {
                return Err(SolverError::GaussNewtonBelow(b));
            }
        }
        if let Some(m) = (0..self.lobes).find(|&m| self.channel_mask[m] == [false; 3]) {
            return Err(SolverError::MaskedLobe(m));
        }
        Ok(())
    }
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            lobes: 3,
            max_sweeps: 50,
            tol: 3e-3,
            g_method: GMethod::Cubic,
            smooth_g: None,
            accelerate: true,
            trace_stages: false,
            d_monotone_from_deg: Some(60.0),
            channel_mask: all_channels(),
            diffuse: DiffuseKind::Lambert,
            gauss_newton: false,
            gauss_newton_cg: CG_ITERATIONS,
            gauss_newton_below: None,
            masking: crate::model::Masking::Separable,
            hold_p: false,
        }
    }
}

/// Why a fit could not run. Messages name the problem; a command line adds
/// its flag names.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolverError {
    /// Lobe count outside 1 to [`MAX_LOBES`].
    #[error("lobes must be 1 to {MAX_LOBES}, got {0}")]
    Lobes(usize),
    /// Zero sweeps.
    #[error("the sweep limit must be at least 1")]
    MaxSweeps,
    /// A negative or non-finite tolerance.
    #[error("the tolerance must be a non-negative number, got {0}")]
    Tolerance(f64),
    /// A monotone-tail angle outside 0 to 90 degrees.
    #[error("the D monotone-tail angle must be 0 to 90 degrees, got {0}")]
    MonotoneFrom(f64),
    /// A non-positive smoothing width.
    #[error("the G smoothing width must be positive, got {0}")]
    SmoothG(f64),
    /// A lobe that may light no channel.
    #[error("lobe {0} is masked in every channel")]
    MaskedLobe(usize),
    /// No conjugate-gradient iteration for the joint step.
    #[error("the joint step needs at least one conjugate-gradient iteration")]
    GaussNewtonCg,
    /// A joint-step threshold that is not a positive finite fraction.
    #[error("the joint step's threshold must be a positive fraction, got {0}")]
    GaussNewtonBelow(f64),
    /// A starting model on another layout (or lobe count) than the fit.
    #[error("the starting model does not match the fit: {0}")]
    Start(String),
}

/// Conjugate-gradient iterations per step by default
/// ([`FitOptions::gauss_newton_cg`]).
pub const CG_ITERATIONS: usize = 25;
