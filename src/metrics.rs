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
use npf_data_loaders::merl::{MerlSamples, MerlTable, SampleCell};
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

/// The model-independent part of the error measures against a MERL table
/// ([`MerlReference::prepare`], from its samples, e.g. while the fit's
/// coarse level runs): for each sample within the cut-off, in sample
/// order, its cell, theta_i and theta_o, their cosines and ln(1 + rho cos)
/// per channel; per piece of [`PIECE`] samples, the reference's own sums
/// (sum (rho cos)^2, peak, count). [`MerlReference::compare`] then adds
/// only the model's part, with the same arithmetic per value and the same
/// pieces, so the same bits as [`compare_model_table`].
pub struct MerlReference {
    max_theta_deg: f64,
    /// Per piece: its first in-cut sample's place in the arrays below, its
    /// reference sums (sq_err, sq_log 0) and a hash of its rgb bits.
    pieces: Vec<(usize, Sums, u64)>,
    /// The arrays' length (the last piece's end).
    len: usize,
    cell: Vec<u32>,
    theta: Vec<[f64; 2]>,
    cos: Vec<[f64; 2]>,
    log_ref: Vec<[f64; 3]>,
}

/// One step of the pieces' rgb hash (FxHash's): a check that the table
/// measured against is the table prepared from, not a security measure.
#[inline(always)]
fn hash_rgb(h: u64, rgb: [f64; 3]) -> u64 {
    rgb.iter().fold(h, |h, x| {
        (h.rotate_left(5) ^ x.to_bits()).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95)
    })
}

impl MerlReference {
    /// The reference part of the measures of `samples` within
    /// `max_theta_deg`, in one serial pass (it runs beside other work).
    /// theta_i and theta_o are the samples' own, the `acos` the measures'
    /// cell walk takes.
    pub fn prepare(samples: &MerlSamples, max_theta_deg: f64) -> Self {
        let cut = max_theta_deg.to_radians();
        let inside = |i: usize| {
            let [ti, to] = samples.theta(i);
            !(ti > cut || to > cut)
        };
        // Exact sizes: these arrays live through the full set's sweeps.
        let len = (0..samples.len()).filter(|&i| inside(i)).count();
        let mut r = MerlReference {
            max_theta_deg,
            pieces: Vec::with_capacity(samples.len().div_ceil(PIECE)),
            len,
            cell: Vec::with_capacity(len),
            theta: Vec::with_capacity(len),
            cos: Vec::with_capacity(len),
            log_ref: Vec::with_capacity(len),
        };
        for lo in (0..samples.len()).step_by(PIECE) {
            let (start, mut acc, mut hash) = (r.cell.len(), Sums::default(), 0);
            for i in lo..(lo + PIECE).min(samples.len()) {
                if !inside(i) {
                    continue;
                }
                let [ti, to] = samples.theta(i);
                let (ci, co) = (ti.cos(), to.cos());
                let rgb = samples.rgb(i);
                acc.add_reference(rgb, ci);
                hash = hash_rgb(hash, rgb);
                r.cell.push(samples.cell(i) as u32);
                r.theta.push([ti, to]);
                r.cos.push([ci, co]);
                r.log_ref.push(rgb.map(|x| (x * ci).ln_1p()));
            }
            r.pieces.push((start, acc, hash));
        }
        r
    }

    /// The measures of an isotropic `model` against `table` (the table the
    /// reference was prepared from) within `max_theta_deg`: those of
    /// [`compare_model_table`], bit for bit. `None` where this path does not
    /// apply (another cut-off, an anisotropic model, a diffuse form that
    /// reads the azimuths) or the table's values are not those prepared
    /// from: the caller takes the general path.
    pub fn compare(&self, table: &MerlTable, max_theta_deg: f64, model: &Model) -> Option<Metrics> {
        let pieces = self.map_cells(
            table,
            max_theta_deg,
            model,
            |p| self.pieces[p].1,
            |acc, c| acc.add_model(c.value, c.rgb, c.cos[0], c.log_ref),
        )?;
        Some(in_order(pieces).metrics(max_theta_deg))
    }

    /// Visits the prepared cells of `table` in sample order with an
    /// isotropic `model`'s value there (the same bits as
    /// [`map_model_cells`]): `visit(acc, cell)` into one `init(piece)` per
    /// piece of [`PIECE`] samples, the pieces computed in parallel and
    /// returned in order. `None` as for [`MerlReference::compare`].
    pub(crate) fn map_cells<R: Send>(
        &self,
        table: &MerlTable,
        max_theta_deg: f64,
        model: &Model,
        init: impl Fn(usize) -> R + Sync + Send,
        visit: impl Fn(&mut R, &PreparedCell) + Sync,
    ) -> Option<Vec<R>> {
        if max_theta_deg.to_bits() != self.max_theta_deg.to_bits()
            || !model.layout.is_isotropic()
            || model.diffuse_form.reads_azimuth()
        {
            return None;
        }
        let raw = table.raw();
        let rgb_at = |at: usize| {
            std::array::from_fn(|c| raw[c * MerlTable::CELLS + at] * MerlTable::SCALE[c])
        };
        (0..self.pieces.len())
            .into_par_iter()
            .map_init(
                // The (theta_h, theta_d) row last evaluated, its angles, F and D values.
                || {
                    (
                        usize::MAX,
                        (0.0, 0.0),
                        [0.0; 3],
                        vec![0.0; model.lobe_count()],
                    )
                },
                |(row, half_diff, f, d), p| {
                    let (start, _, hash) = self.pieces[p];
                    let end = self.pieces.get(p + 1).map_or(self.len, |q| q.0);
                    let mut acc = init(p);
                    let mut seen = 0;
                    for k in start..end {
                        let at = self.cell[k] as usize;
                        let r = at / MerlTable::RES_PHI_D;
                        if *row != r {
                            *row = r;
                            let (i_th, i_td) =
                                (r / MerlTable::RES_THETA_D, r % MerlTable::RES_THETA_D);
                            let (th, td, _) = MerlTable::node_angles(i_th, i_td, 0);
                            *half_diff = (th, td);
                            *f = model.half_diff_factors(th, td, d);
                        }
                        let ([ti, to], [ci, co]) = (self.theta[k], self.cos[k]);
                        let rgb = rgb_at(at);
                        seen = hash_rgb(seen, rgb);
                        let cell = PreparedCell {
                            half_diff: *half_diff,
                            value: model.eval_half_diff((*f, d), (ti, to), (ci, co), 1.0),
                            rgb,
                            cos: [ci, co],
                            log_ref: self.log_ref[k],
                        };
                        visit(&mut acc, &cell);
                    }
                    (seen == hash).then_some(acc)
                },
            )
            .collect()
    }
}

/// One cell of [`MerlReference::map_cells`].
pub(crate) struct PreparedCell {
    /// The node's (theta_h, theta_d).
    pub half_diff: (f64, f64),
    /// The model's value.
    pub value: [f64; 3],
    /// The measured value (1/sr).
    pub rgb: [f64; 3],
    /// cos theta_i, cos theta_o.
    pub cos: [f64; 2],
    /// ln(1 + rho cos theta_i) per channel.
    pub log_ref: [f64; 3],
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
        // The two parts touch different sums, so splitting them keeps each
        // sum's values and order (the prepared path adds them apart).
        self.add_reference(rgb, ci);
        self.add_model(v, rgb, ci, rgb.map(|x| (x * ci).ln_1p()));
    }

    /// [`Sums::add`]'s reference part: sum (rho cos)^2, the peak, the count.
    #[inline(always)]
    fn add_reference(&mut self, rgb: [f64; 3], ci: f64) {
        for x in rgb {
            self.sq_ref += (x * ci).powi(2);
            self.peak = self.peak.max(x * ci);
        }
        self.count += 1;
    }

    /// [`Sums::add`]'s model part, `log_ref` the reference's ln(1 + rho
    /// cos) per channel: each sum takes the same values in the same order.
    #[inline(always)]
    fn add_model(&mut self, v: [f64; 3], rgb: [f64; 3], ci: f64, log_ref: [f64; 3]) {
        for c in 0..3 {
            let e = (v[c] - rgb[c]) * ci;
            self.sq_err += e * e;
            self.sq_log += ((v[c] * ci).ln_1p() - log_ref[c]).powi(2);
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{DiffuseForm, Layout, Masking};
    use crate::synth::{known_factor_model, GgxLambert};

    fn bits(m: &Metrics) -> (usize, [u64; 3]) {
        let v = [m.cos_rmse, m.rel_cos_rmse, m.log_rmse];
        (m.samples, v.map(f64::to_bits))
    }

    /// The measures from a prepared reference are [`compare_model_table`]'s
    /// to the bit, for any thread count, on a MERL table with missing cells
    /// and for models of every kind the path takes (separable and
    /// height-correlated masking, an energy-coupled diffuse form, a
    /// multiple-scattering term, the checked-in 822-parameter fit), and so
    /// is the post-fit energy scale's ratio; it declines what it does not
    /// cover and a table other than its own.
    #[test]
    fn prepared_measures_are_the_table_measures_to_the_bit() {
        let brdf = GgxLambert {
            kd: [0.3, 0.2, 0.1],
            f0: [0.9, 0.6, 0.3],
            alpha: 0.2,
        };
        let table = MerlTable::from_fn(|th, td, pd| {
            // Some cells missing, scattered over the rows.
            if (th * 1e3) as usize % 7 == 3 && pd > 1.0 {
                return None;
            }
            let a = Angles::from_half_diff(th, 0.0, td, pd);
            brdf.eval_angles(&a)
        });
        let known = known_factor_model(Layout::default(), &[0.1, 0.4]);
        let mut coupled = known.clone();
        coupled.masking = Masking::HeightCorrelated;
        coupled.diffuse_form = crate::energy::coupled::energy_coupled_form(&known);
        let mut compensated = known.clone();
        compensated.compensation = Some(crate::energy::coupled::compensation(&known));
        let fitted = crate::modelfile::read(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/ggx-lambert.json"),
        )
        .unwrap()
        .model;
        let samples = MerlSamples::new(table.clone(), "t");
        let whole = Table::Merl(table.clone());
        for max_theta in [85.0, 60.0] {
            let reference = MerlReference::prepare(&samples, max_theta);
            for (label, model) in [
                ("known", &known),
                ("coupled", &coupled),
                ("compensated", &compensated),
                ("fitted", &fitted),
            ] {
                let want = compare_model_table(&whole, max_theta, model);
                assert!(want.samples > 1000 && want.log_rmse > 0.0, "{label}");
                for threads in [1, 3] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let got = pool.install(|| reference.compare(&table, max_theta, model));
                    let got = got.unwrap_or_else(|| panic!("{label}: declined"));
                    assert_eq!(bits(&got), bits(&want), "{label}, {max_theta}, {threads}");
                    // The post-fit energy scale's ratio from the same reference.
                    use crate::energy::scale::{energy_ratio, energy_ratio_prepared};
                    let rule = crate::energy::scale::DEFAULT_RULE;
                    let want = energy_ratio(&table, max_theta, &rule, model).unwrap();
                    let got = pool.install(|| {
                        energy_ratio_prepared(&reference, &table, max_theta, &rule, model)
                    });
                    assert_eq!(
                        got.map(|k| k.map(f64::to_bits)),
                        Some(want.map(f64::to_bits))
                    );
                }
            }
        }
        let reference = MerlReference::prepare(&samples, 85.0);
        // Another cut-off, a form that reads the azimuths, another table.
        assert!(reference.compare(&table, 80.0, &known).is_none());
        let mut oren = known.clone();
        oren.diffuse_form = DiffuseForm::OrenNayar { sigma: 0.3 };
        assert!(reference.compare(&table, 85.0, &oren).is_none());
        let mut raw = table.raw().to_vec();
        let cut = 85f64.to_radians();
        let inside = (samples.len() / 2..samples.len())
            .find(|&i| samples.theta(i).iter().all(|&t| t <= cut))
            .unwrap();
        let at = samples.cell(inside);
        raw[at] *= 1.5;
        let other = MerlTable::from_raw(raw);
        assert!(reference.compare(&other, 85.0, &known).is_none());
    }
}
