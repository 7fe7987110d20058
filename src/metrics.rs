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
use npf_data_loaders::merl::{MerlTable, SampleCell};
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
        acc.add(model(a), s.rgb, a.theta_i.cos());
    }
    acc
}

/// [`table_sums`] of a factor model: on a MERL table and an isotropic
/// model, the cells are visited without making samples, F and D are
/// evaluated once per (theta_h, theta_d) run of cells, and no azimuth is
/// computed unless the diffuse form reads it; the same arithmetic for
/// every value, so the same bits as the general path.
fn model_table_sums(table: &Table, max_theta_deg: f64, model: &Model) -> Sums {
    let merl = match table {
        Table::Merl(t) if model.layout.is_isotropic() => t,
        _ => return table_sums(table, max_theta_deg, |a| model.eval_angles(a)),
    };
    let pieces = map_model_cells(
        merl,
        max_theta_deg,
        model,
        Sums::default,
        |acc, cell, v, ci, _| acc.add(v, cell.rgb, ci),
    );
    in_order(pieces)
}

/// Visits the valid cells of a MERL table with theta_i and theta_o at most
/// `max_theta_deg`, in sample order, with the value of an isotropic
/// `model` there (the same bits as `eval_angles`) and cos theta_i, cos
/// theta_o: `visit(acc, cell, value, cos_i, cos_o)` into one `init()` per
/// piece of [`PIECE`] cells, the pieces computed in parallel and returned
/// in order. F and D are evaluated once per (theta_h, theta_d) run of
/// cells, and no azimuth is computed unless the diffuse form reads it.
pub(crate) fn map_model_cells<R: Send>(
    merl: &MerlTable,
    max_theta_deg: f64,
    model: &Model,
    init: impl Fn() -> R + Sync + Send,
    visit: impl Fn(&mut R, &SampleCell, [f64; 3], f64, f64) + Sync,
) -> Vec<R> {
    let cut = max_theta_deg.to_radians();
    let azimuths = model.diffuse_form.reads_azimuth();
    // acos as `geometry::angles_of` takes it, so the same theta.
    let theta = |z: f64| z.clamp(-1.0, 1.0).acos();
    let azimuth = |v: [f64; 3]| v[1].atan2(v[0]);
    merl.map_cell_pieces(
        PIECE,
        // The (theta_h, theta_d) row last evaluated, its F and D values.
        || ((usize::MAX, 0), [0.0; 3], vec![0.0; model.lobe_count()]),
        |(row, f, d), piece| {
            let mut acc = init();
            piece.for_each(|cell| {
                let (theta_i, theta_o) = (theta(cell.wi[2]), theta(cell.wo[2]));
                if theta_i > cut || theta_o > cut {
                    return;
                }
                if *row != (cell.i_th, cell.i_td) {
                    *row = (cell.i_th, cell.i_td);
                    *f = model.half_diff_factors(cell.angles.theta_h, cell.angles.theta_d, d);
                }
                let (ci, co) = (theta_i.cos(), theta_o.cos());
                let cos_dphi = if azimuths {
                    (azimuth(cell.wi) - azimuth(cell.wo)).cos()
                } else {
                    1.0
                };
                let v = model.eval_half_diff((*f, d), (theta_i, theta_o), (ci, co), cos_dphi);
                visit(&mut acc, &cell, v, ci, co);
            });
            acc
        },
    )
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
    /// Counts one sample: model value `v`, reference `rgb`, cos theta_i `ci`.
    #[inline(always)]
    fn add(&mut self, v: [f64; 3], rgb: [f64; 3], ci: f64) {
        for c in 0..3 {
            let e = (v[c] - rgb[c]) * ci;
            self.sq_err += e * e;
            self.sq_ref += (rgb[c] * ci).powi(2);
            self.sq_log += ((v[c] * ci).ln_1p() - (rgb[c] * ci).ln_1p()).powi(2);
            self.peak = self.peak.max(rgb[c] * ci);
        }
        self.count += 1;
    }

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
    model_table_sums(table, max_theta_deg, model).metrics(max_theta_deg)
}
