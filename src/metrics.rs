//! Error measures between measured samples and a model.
//!
//! All are over the valid samples within the grazing cut-off (theta_i and
//! theta_o at most `max_theta_deg`), every channel counted:
//! - cosine-weighted RMSE: sqrt(mean ((rho_model - rho) cos theta_i)^2), 1/sr;
//! - relative cosine-weighted RMSE: sqrt(sum ((rho_model - rho) cos)^2 / sum (rho cos)^2);
//! - log RMSE: sqrt(mean (ln(1 + rho_model cos) - ln(1 + rho cos))^2), the
//!   measure Neural-BRDF trains on, which does not let the peak dominate.

use crate::model::Model;
use npf_data_loaders::MeasuredSamples;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub samples: usize,
    pub max_theta_deg: f64,
    pub cos_rmse: f64,
    pub rel_cos_rmse: f64,
    pub log_rmse: f64,
}

impl Metrics {
    pub fn is_finite(&self) -> bool {
        [self.cos_rmse, self.rel_cos_rmse, self.log_rmse]
            .iter()
            .all(|v| v.is_finite())
    }
}

pub fn compare(
    samples: &MeasuredSamples,
    max_theta_deg: f64,
    model: impl Fn(&npf_data_loaders::geometry::Angles) -> [f64; 3] + Sync,
) -> Metrics {
    let cut = max_theta_deg.to_radians();
    let sums = samples
        .samples
        .par_chunks(8192)
        .map(|chunk| {
            let mut acc = [0.0f64; 4];
            for s in chunk {
                let a = &s.angles;
                if a.theta_i > cut || a.theta_o > cut {
                    continue;
                }
                let ci = a.theta_i.cos();
                let v = model(a);
                for c in 0..3 {
                    let e = (v[c] - s.rgb[c]) * ci;
                    acc[0] += e * e;
                    acc[1] += (s.rgb[c] * ci).powi(2);
                    acc[2] += ((v[c] * ci).ln_1p() - (s.rgb[c] * ci).ln_1p()).powi(2);
                }
                acc[3] += 1.0;
            }
            acc
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold([0.0; 4], |a, b| {
            [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]
        });
    let n = sums[3] * 3.0;
    Metrics {
        samples: sums[3] as usize,
        max_theta_deg,
        cos_rmse: (sums[0] / n).sqrt(),
        // Zero error against a black reference is zero relative error.
        rel_cos_rmse: if sums[0] == 0.0 {
            0.0
        } else {
            (sums[0] / sums[1]).sqrt()
        },
        log_rmse: (sums[2] / n).sqrt(),
    }
}

pub fn compare_model(samples: &MeasuredSamples, max_theta_deg: f64, model: &Model) -> Metrics {
    compare(samples, max_theta_deg, |a| model.eval_angles(a))
}
