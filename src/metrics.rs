//! Error measures between measured samples and a model.
//!
//! All are over the valid samples within the grazing cut-off (theta_i and
//! theta_o at most `max_theta_deg`), every channel counted:
//! - cosine-weighted RMSE: sqrt(mean ((rho_model - rho) cos theta_i)^2), 1/sr;
//! - relative cosine-weighted RMSE: sqrt(sum ((rho_model - rho) cos)^2 / sum (rho cos)^2);
//! - log RMSE: sqrt(mean (ln(1 + rho_model cos) - ln(1 + rho cos))^2), the
//!   measure Neural-BRDF trains on, which does not let the peak dominate.

use crate::model::Model;
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::{MeasuredSample, MeasuredSamples, Table};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The error measures of one model against one sample set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Samples within the cut-off.
    pub samples: usize,
    /// The grazing cut-off (degrees) on theta_i and theta_o.
    pub max_theta_deg: f64,
    /// Cosine-weighted RMSE (1/sr).
    pub cos_rmse: f64,
    /// Cosine-weighted RMSE relative to the reference's cosine-weighted norm.
    pub rel_cos_rmse: f64,
    /// RMSE of log(1 + rho cos theta_i).
    pub log_rmse: f64,
}

impl Metrics {
    /// True when every measure is finite.
    pub fn is_finite(&self) -> bool {
        [self.cos_rmse, self.rel_cos_rmse, self.log_rmse]
            .iter()
            .all(|v| v.is_finite())
    }
}

/// The sums behind [`Metrics`] and the numerical PSNR, in one pass over the
/// samples within the cut-off.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sums {
    /// sum ((rho_model - rho) cos)^2 over samples and channels.
    pub sq_err: f64,
    /// sum (rho cos)^2.
    pub sq_ref: f64,
    /// sum (ln(1 + rho_model cos) - ln(1 + rho cos))^2.
    pub sq_log: f64,
    /// Samples counted.
    pub count: usize,
    /// Largest reference value rho cos.
    pub peak: f64,
}

/// Samples per piece of the measures' pass: the sums' order, hence their
/// last bits, depend on it, so every pass uses this one.
const PIECE: usize = 8192;

/// One deterministic pass (fixed chunks, summed in order) over the samples
/// within the cut-off.
pub(crate) fn sums(
    samples: &MeasuredSamples,
    max_theta_deg: f64,
    model: impl Fn(&Angles) -> [f64; 3] + Sync,
) -> Sums {
    let cut = max_theta_deg.to_radians();
    in_order(
        samples
            .samples
            .par_chunks(PIECE)
            .map(|piece| piece_sums(piece, cut, &model))
            .collect(),
    )
}

/// [`sums`] over a table's samples, made piece by piece and never all held
/// ([`Table::map_sample_chunks`]): the same pieces in the same order as
/// [`sums`] of `table.samples(..)`, so the same bits.
pub(crate) fn table_sums(
    table: &Table,
    max_theta_deg: f64,
    model: impl Fn(&Angles) -> [f64; 3] + Sync,
) -> Sums {
    let cut = max_theta_deg.to_radians();
    in_order(table.map_sample_chunks(PIECE, |piece| piece_sums(piece, cut, &model)))
}

/// The sums of one piece of samples, in sample order.
#[inline]
fn piece_sums(piece: &[MeasuredSample], cut: f64, model: &impl Fn(&Angles) -> [f64; 3]) -> Sums {
    let mut acc = Sums::default();
    for s in piece {
        let a = &s.angles;
        if a.theta_i > cut || a.theta_o > cut {
            continue;
        }
        let ci = a.theta_i.cos();
        let v = model(a);
        for c in 0..3 {
            let e = (v[c] - s.rgb[c]) * ci;
            acc.sq_err += e * e;
            acc.sq_ref += (s.rgb[c] * ci).powi(2);
            acc.sq_log += ((v[c] * ci).ln_1p() - (s.rgb[c] * ci).ln_1p()).powi(2);
            acc.peak = acc.peak.max(s.rgb[c] * ci);
        }
        acc.count += 1;
    }
    acc
}

/// The pieces' sums added in piece order.
fn in_order(pieces: Vec<Sums>) -> Sums {
    pieces.into_iter().fold(Sums::default(), |a, b| Sums {
        sq_err: a.sq_err + b.sq_err,
        sq_ref: a.sq_ref + b.sq_ref,
        sq_log: a.sq_log + b.sq_log,
        count: a.count + b.count,
        peak: a.peak.max(b.peak),
    })
}

impl Sums {
    /// The measures of these sums.
    pub(crate) fn metrics(&self, max_theta_deg: f64) -> Metrics {
        let n = self.count as f64 * 3.0;
        Metrics {
            samples: self.count,
            max_theta_deg,
            cos_rmse: (self.sq_err / n).sqrt(),
            // Zero error against a black reference is zero relative error.
            rel_cos_rmse: if self.sq_err == 0.0 {
                0.0
            } else {
                (self.sq_err / self.sq_ref).sqrt()
            },
            log_rmse: (self.sq_log / n).sqrt(),
        }
    }
}

/// The measures of a model given as a function of the sample angles (see
/// the module notes); any [`crate::bsdf::Bsdf`] is one through
/// `|a| bsdf.eval_angles(a)`.
pub fn compare(
    samples: &MeasuredSamples,
    max_theta_deg: f64,
    model: impl Fn(&Angles) -> [f64; 3] + Sync,
) -> Metrics {
    sums(samples, max_theta_deg, model).metrics(max_theta_deg)
}

/// The measures of a factor model ([`Model::eval_angles`]).
pub fn compare_model(samples: &MeasuredSamples, max_theta_deg: f64, model: &Model) -> Metrics {
    compare(samples, max_theta_deg, |a| model.eval_angles(a))
}

/// [`compare_model`] against a table's samples without holding them all
/// (the same numbers as on `table.samples(..)`).
pub fn compare_model_table(table: &Table, max_theta_deg: f64, model: &Model) -> Metrics {
    table_sums(table, max_theta_deg, |a| model.eval_angles(a)).metrics(max_theta_deg)
}
