//! Everything `npf compare` and `npf report` measure about a model against
//! its reference table (definitions in `docs/evaluation.md`):
//!
//! - the [`crate::metrics`] errors over the valid samples within the grazing
//!   cut-off (cosine-weighted RMSE, its relative form, log(1 + rho cos) RMSE);
//! - numerical PSNR over the same samples: 10 log10(peak^2 / MSE) of the
//!   cosine-weighted values rho cos theta_i, peak = the largest reference
//!   value rho cos theta_i, every channel counted;
//! - directional albedo a(theta_o) = integral of rho cos theta_i over the
//!   incident hemisphere, at theta_o = 0, 30, 60, 75 degrees, by a fixed
//!   midpoint grid over the half vector (see [`albedo`]) for both table
//!   (MERL lookup) and model; the error is
//!   |a_model - a_ref| / a_ref averaged over channels;
//! - rendering PSNR of a sphere (see [`crate::render`]).

use crate::bsdf::{Bsdf, BsdfError, NpfBxdf};
use crate::metrics::Metrics;
use crate::render::{psnr, render, Image, RenderError, RenderOptions};
use npf_data_loaders::{MeasuredSamples, MerlTable};

use serde::{Deserialize, Serialize};

pub use crate::bsdf::albedo;

/// The view angles (degrees) albedo is compared at.
pub const ALBEDO_VIEWS_DEG: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

/// Why a comparison failed.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The model could not be turned into a BSDF.
    #[error(transparent)]
    Bsdf(#[from] BsdfError),
    /// The renders could not be compared.
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// Numerical PSNR (dB) of a BSDF over the samples within the cut-off.
pub fn numeric_psnr(
    samples: &MeasuredSamples,
    max_theta_deg: f64,
    bsdf: &(dyn Bsdf + Sync),
) -> f64 {
    psnr_of(&crate::metrics::sums(samples, max_theta_deg, |a| {
        bsdf.eval_angles(a)
    }))
}

fn psnr_of(s: &crate::metrics::Sums) -> f64 {
    let n = 3 * s.count;
    if n == 0 || s.sq_err == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (s.peak * s.peak / (s.sq_err / n as f64)).log10()
}

/// Albedo of model and reference at one view angle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlbedoError {
    /// The view angle (degrees).
    pub theta_o_deg: f64,
    /// Albedo of the reference per channel.
    pub reference: [f64; 3],
    /// Albedo of the model per channel.
    pub model: [f64; 3],
    /// |a_model - a_ref| / a_ref, averaged over channels (0 when both are 0).
    pub rel_error: f64,
}

/// Albedo of both BSDFs at every [`ALBEDO_VIEWS_DEG`] angle.
pub fn albedo_errors(reference: &(dyn Bsdf + Sync), model: &(dyn Bsdf + Sync)) -> Vec<AlbedoError> {
    ALBEDO_VIEWS_DEG
        .iter()
        .map(|&deg| {
            let r = albedo(deg.to_radians(), reference);
            let m = albedo(deg.to_radians(), model);
            let rel = (0..3)
                .map(|c| {
                    let d = (m[c] - r[c]).abs();
                    if d == 0.0 {
                        0.0
                    } else {
                        d / r[c].abs().max(1e-12)
                    }
                })
                .sum::<f64>()
                / 3.0;
            AlbedoError {
                theta_o_deg: deg,
                reference: r,
                model: m,
                rel_error: rel,
            }
        })
        .collect()
}

/// All measures of one model against one table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The sample error measures.
    pub metrics: Metrics,
    /// Numerical PSNR (dB).
    pub numeric_psnr_db: f64,
    /// Albedo at each view angle.
    pub albedo: Vec<AlbedoError>,
    /// Largest albedo error over the view angles.
    pub max_albedo_error: f64,
    /// Rendering PSNR (dB).
    pub render_psnr_db: f64,
}

/// What the reference side of a comparison needs, computed once per table.
pub struct Reference<'a> {
    /// The reference: a measured table (MERL lookup, or UTIA's
    /// quadrilinear interpolation) or an analytic BRDF; it is rendered and
    /// its albedo taken, while the sample measures use `samples`.
    pub table: &'a (dyn Bsdf + Sync),
    /// Its samples.
    pub samples: &'a MeasuredSamples,
    /// Its render.
    pub image: Image,
    /// The render settings (used for the test images too).
    pub render: RenderOptions,
}

impl<'a> Reference<'a> {
    /// Renders the reference once.
    pub fn new(
        table: &'a (dyn Bsdf + Sync),
        samples: &'a MeasuredSamples,
        render_opts: RenderOptions,
    ) -> Self {
        Reference {
            table,
            samples,
            image: render(render_opts, table),
            render: render_opts,
        }
    }

    /// Evaluate any BSDF (its angle form for the sample metrics, its
    /// directions for albedo and rendering); returns the test image too.
    pub fn evaluate(
        &self,
        max_theta_deg: f64,
        bsdf: &(dyn Bsdf + Sync),
    ) -> Result<(Evaluation, Image), EvalError> {
        let sums = crate::metrics::sums(self.samples, max_theta_deg, |a| bsdf.eval_angles(a));
        let metrics = sums.metrics(max_theta_deg);
        let numeric_psnr_db = psnr_of(&sums);
        let albedo = albedo_errors(self.table, bsdf);
        let image = render(self.render, bsdf);
        let render_psnr_db = psnr(&self.image, &image)?;
        Ok((
            Evaluation {
                metrics,
                numeric_psnr_db,
                max_albedo_error: albedo.iter().map(|a| a.rel_error).fold(0.0, f64::max),
                albedo,
                render_psnr_db,
            },
            image,
        ))
    }

    /// [`Reference::evaluate`] for a factor model (through its [`NpfBxdf`]).
    pub fn evaluate_model(
        &self,
        max_theta_deg: f64,
        model: &crate::model::Model,
    ) -> Result<(Evaluation, Image), EvalError> {
        self.evaluate(max_theta_deg, &NpfBxdf::new(model.clone())?)
    }

    /// [`Reference::evaluate`] for a second MERL table.
    pub fn evaluate_table(
        &self,
        max_theta_deg: f64,
        other: &MerlTable,
    ) -> Result<(Evaluation, Image), EvalError> {
        self.evaluate(max_theta_deg, other)
    }
}
