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

use crate::metrics::{compare, Metrics};
use crate::render::{psnr, render, Image, RenderOptions};
use npf_data_loaders::geometry::{half_diff_from_directions, spherical, Angles, Vec3};
use npf_data_loaders::{MeasuredSamples, MerlTable};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The view angles (degrees) albedo is compared at.
pub const ALBEDO_VIEWS_DEG: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

/// The table as a BRDF of local directions: MERL's truncating lookup, 0 for
/// missing cells and below the horizon.
pub fn table_brdf(table: &MerlTable) -> impl Fn(Vec3, Vec3) -> [f64; 3] + Sync + '_ {
    move |wi, wo| {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let (th, _ph, td, pd) = half_diff_from_directions(wi, wo);
        table.lookup(th, td, pd).unwrap_or([0.0; 3])
    }
}

/// Numerical PSNR (dB) of a model over the samples within the cut-off.
pub fn numeric_psnr(
    samples: &MeasuredSamples,
    max_theta_deg: f64,
    model: impl Fn(&Angles) -> [f64; 3] + Sync,
) -> f64 {
    let cut = max_theta_deg.to_radians();
    let (sum, n, peak) = samples
        .samples
        .par_chunks(8192)
        .map(|chunk| {
            let (mut sum, mut n, mut peak) = (0.0f64, 0usize, 0.0f64);
            for s in chunk {
                let a = &s.angles;
                if a.theta_i > cut || a.theta_o > cut {
                    continue;
                }
                let ci = a.theta_i.cos();
                let v = model(a);
                for c in 0..3 {
                    sum += ((v[c] - s.rgb[c]) * ci).powi(2);
                    peak = peak.max(s.rgb[c] * ci);
                }
                n += 3;
            }
            (sum, n, peak)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold((0.0, 0, 0.0f64), |a, b| {
            (a.0 + b.0, a.1 + b.1, a.2.max(b.2))
        });
    if n == 0 || sum == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (peak * peak / (sum / n as f64)).log10()
}

/// Directional albedo of a BRDF at view angle `theta_o` (radians):
/// integral of f(wi, wo) cos theta_i over the incident hemisphere, by a
/// fixed midpoint grid over the half vector h (wi = 2 (wo.h) h - wo,
/// dOmega_i = 4 (wo.h) dOmega_h) with theta_h = (pi/2) u^2 (the MERL
/// spacing, fine near the specular peak: the first node is 0.0014 degrees
/// off it), 160 strata in u and 320 in phi_h.
pub fn albedo(theta_o: f64, f: impl Fn(Vec3, Vec3) -> [f64; 3] + Sync) -> [f64; 3] {
    let (nu, nphi) = (160usize, 320usize);
    let wo = spherical(theta_o, 0.0);
    let dphi = 2.0 * std::f64::consts::PI / nphi as f64;
    let du = 1.0 / nu as f64;
    (0..nu)
        .into_par_iter()
        .map(|a| {
            let u = (a as f64 + 0.5) * du;
            let theta_h = std::f64::consts::FRAC_PI_2 * u * u;
            // d theta_h = pi u du.
            let w_theta = theta_h.sin() * std::f64::consts::PI * u * du * dphi;
            let mut acc = [0.0; 3];
            for b in 0..nphi {
                let h = spherical(theta_h, (b as f64 + 0.5) * dphi);
                let oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                if oh <= 0.0 {
                    continue;
                }
                let wi = [
                    2.0 * oh * h[0] - wo[0],
                    2.0 * oh * h[1] - wo[1],
                    2.0 * oh * h[2] - wo[2],
                ];
                if wi[2] <= 0.0 {
                    continue;
                }
                let v = f(wi, wo);
                let w = wi[2] * 4.0 * oh * w_theta;
                for c in 0..3 {
                    acc[c] += v[c] * w;
                }
            }
            acc
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
}

/// Albedo of model and reference at one view angle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlbedoError {
    pub theta_o_deg: f64,
    pub reference: [f64; 3],
    pub model: [f64; 3],
    /// |a_model - a_ref| / a_ref, averaged over channels (0 when both are 0).
    pub rel_error: f64,
}

pub fn albedo_errors(
    reference: impl Fn(Vec3, Vec3) -> [f64; 3] + Sync,
    model: impl Fn(Vec3, Vec3) -> [f64; 3] + Sync,
) -> Vec<AlbedoError> {
    ALBEDO_VIEWS_DEG
        .iter()
        .map(|&deg| {
            let r = albedo(deg.to_radians(), &reference);
            let m = albedo(deg.to_radians(), &model);
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
    pub metrics: Metrics,
    pub numeric_psnr_db: f64,
    pub albedo: Vec<AlbedoError>,
    /// Largest albedo error over the view angles.
    pub max_albedo_error: f64,
    pub render_psnr_db: f64,
}

/// What the reference side of a comparison needs, computed once per table.
pub struct Reference<'a> {
    pub table: &'a MerlTable,
    pub samples: &'a MeasuredSamples,
    pub image: Image,
    pub render: RenderOptions,
}

impl<'a> Reference<'a> {
    pub fn new(
        table: &'a MerlTable,
        samples: &'a MeasuredSamples,
        render_opts: RenderOptions,
    ) -> Self {
        Reference {
            table,
            samples,
            image: render(render_opts, table_brdf(table)),
            render: render_opts,
        }
    }

    /// Evaluate a BRDF given both ways (angles for the sample metrics,
    /// directions for albedo and rendering); returns the test image too.
    pub fn evaluate(
        &self,
        max_theta_deg: f64,
        at_angles: impl Fn(&Angles) -> [f64; 3] + Sync,
        at_dirs: impl Fn(Vec3, Vec3) -> [f64; 3] + Sync,
    ) -> Result<(Evaluation, Image), String> {
        let metrics = compare(self.samples, max_theta_deg, &at_angles);
        let numeric_psnr_db = numeric_psnr(self.samples, max_theta_deg, &at_angles);
        let albedo = albedo_errors(table_brdf(self.table), &at_dirs);
        let image = render(self.render, &at_dirs);
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

    pub fn evaluate_model(
        &self,
        max_theta_deg: f64,
        model: &crate::model::Model,
    ) -> Result<(Evaluation, Image), String> {
        self.evaluate(
            max_theta_deg,
            |a| model.eval_angles(a),
            |wi, wo| model.eval(wi, wo),
        )
    }

    pub fn evaluate_table(
        &self,
        max_theta_deg: f64,
        other: &MerlTable,
    ) -> Result<(Evaluation, Image), String> {
        self.evaluate(
            max_theta_deg,
            |a| {
                other
                    .lookup(a.theta_h, a.theta_d, a.phi_d)
                    .unwrap_or([0.0; 3])
            },
            table_brdf(other),
        )
    }
}
