//! A fitted model's energy against its table's: the post-fit per-channel
//! scale of untrusted tables.
//!
//! Why: the compressive weighting fits relative error, so where a table's
//! cells vary along phi_d (which no isotropic model follows) the fit lands
//! near their harmonic rather than arithmetic mean and the model reflects
//! too little light (chm_mint: 13-25 % below the table's albedo). The
//! scale k_C = sum(w m_C) / sum(w f_C) compares the energy the table (m)
//! and the model (f) send towards a viewer, with w = J cos theta_i cos
//! theta_o, J = cos theta_d sin theta_d sin theta_h sqrt(theta_h) the solid
//! angle of a MERL cell (theta_h = (i/90)^2 pi/2, so d theta_h ~
//! sqrt(theta_h) di). The peak cells (theta_h below a few degrees) are
//! left out: their phi_d variation is what no isotropic model can follow
//! (with them, an albedo ratio costs cc_amber_citrine 1 dB). Measured
//! choice of the constants: BENCHMARKS.md as of 4d8d1ee, "post-fit energy scales".

use crate::metrics::MerlReference;
use crate::model::Model;
use npf_data_loaders::merl::MerlTable;

/// Where the scale is read and when it is applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyScaleRule {
    /// Cells with theta_h below this (degrees) are left out.
    pub from_theta_h_deg: f64,
    /// The scale is applied only when some channel is off by more than
    /// this fraction (small scales cost the well-fitted tables more than
    /// they give: a 1 % scale lowered cardboard by 0.3 dB at 45 dB).
    pub dead_zone: f64,
}

/// The default rule: measured on the 26 shared tables (BENCHMARKS.md as of 4d8d1ee).
pub const DEFAULT_RULE: EnergyScaleRule = EnergyScaleRule {
    from_theta_h_deg: 5.0,
    dead_zone: 0.05,
};

/// The per-channel ratio of the table's energy to the model's (see the
/// module's comment) over the table's valid cells with theta_i and
/// theta_o at most `max_theta_deg` and theta_h at least
/// `rule.from_theta_h_deg` (an isotropic model; the sums are added in
/// piece order, so the same for any thread count). A channel the model leaves black (or with no
/// cells) gets 1. `None` for an anisotropic model (its cells are not
/// those of a MERL table's grid).
pub fn energy_ratio(
    table: &MerlTable,
    max_theta_deg: f64,
    rule: &EnergyScaleRule,
    model: &Model,
) -> Option<[f64; 3]> {
    if !model.layout.is_isotropic() {
        return None;
    }
    let min_h = rule.from_theta_h_deg.to_radians();
    let pieces = crate::metrics::map_model_cells(
        table,
        max_theta_deg,
        model,
        || ([0.0f64; 3], [0.0f64; 3]),
        |(m, f), cell, v, ci, co| {
            let a = cell.angles;
            if a.theta_h < min_h {
                return;
            }
            let j = a.theta_d.cos() * a.theta_d.sin() * a.theta_h.sin() * a.theta_h.sqrt();
            let w = j * ci * co;
            for c in 0..3 {
                m[c] += w * cell.rgb[c];
                f[c] += w * v[c];
            }
        },
    );
    Some(ratio(pieces))
}

/// [`energy_ratio`] from the error measures' prepared reference of
/// `table` ([`MerlReference`]): the same cells, pieces and arithmetic, so
/// the same bits, without the cell walk (the weight's sines and cosines
/// once per (theta_h, theta_d) row). `None` where the reference does not
/// apply (see [`MerlReference::compare`]).
pub fn energy_ratio_prepared(
    reference: &MerlReference,
    table: &MerlTable,
    max_theta_deg: f64,
    rule: &EnergyScaleRule,
    model: &Model,
) -> Option<[f64; 3]> {
    let min_h = rule.from_theta_h_deg.to_radians();
    let pieces = reference.map_cells(
        table,
        max_theta_deg,
        model,
        // The sums, and the row's angles and weight last computed.
        |_| ([0.0f64; 3], [0.0f64; 3], (f64::NAN, f64::NAN), 0.0),
        |(m, f, row, j), cell| {
            let (theta_h, theta_d) = cell.half_diff;
            if theta_h < min_h {
                return;
            }
            if *row != cell.half_diff {
                *row = cell.half_diff;
                *j = theta_d.cos() * theta_d.sin() * theta_h.sin() * theta_h.sqrt();
            }
            let w = *j * cell.cos[0] * cell.cos[1];
            for c in 0..3 {
                m[c] += w * cell.rgb[c];
                f[c] += w * cell.value[c];
            }
        },
    )?;
    Some(ratio(pieces.into_iter().map(|(m, f, _, _)| (m, f))))
}

/// The ratios of the pieces' sums added in piece order (1 for a channel
/// the model leaves black).
fn ratio(pieces: impl IntoIterator<Item = ([f64; 3], [f64; 3])>) -> [f64; 3] {
    let (mut m, mut f) = ([0.0f64; 3], [0.0f64; 3]);
    for (pm, pf) in pieces {
        for c in 0..3 {
            m[c] += pm[c];
            f[c] += pf[c];
        }
    }
    std::array::from_fn(|c| {
        let k = m[c] / f[c];
        if f[c] > 0.0 && k.is_finite() && k > 0.0 {
            k
        } else {
            1.0
        }
    })
}

/// Whether `rule` applies `k` (some channel off by more than the dead zone).
pub fn applies(rule: &EnergyScaleRule, k: &[f64; 3]) -> bool {
    k.iter().any(|k| (k - 1.0).abs() > rule.dead_zone)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;

    #[test]
    fn a_table_scaled_by_k_reads_k() {
        let model = crate::synth::known_factor_model(Layout::default(), &[0.1, 0.3]);
        let table = crate::reconstruct::to_merl(&model);
        let k = [0.8, 1.0, 1.25];
        let scaled = MerlTable::from_fn(|th, td, pd| {
            let a = npf_data_loaders::geometry::Angles::from_half_diff(th, 0.0, td, pd);
            (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| {
                let v = model.eval_angles(&a);
                std::array::from_fn(|c| v[c] * k[c])
            })
        });
        let got = energy_ratio(&scaled, 85.0, &DEFAULT_RULE, &model).unwrap();
        for c in 0..3 {
            // The table holds the model's own values (f32 nodes, f64 cells).
            assert!((got[c] - k[c]).abs() < 1e-6 * k[c], "{got:?}");
        }
        assert!(applies(&DEFAULT_RULE, &got));
        let same = energy_ratio(&table, 85.0, &DEFAULT_RULE, &model).unwrap();
        assert!(same.iter().all(|k| (k - 1.0).abs() < 1e-6), "{same:?}");
        assert!(!applies(&DEFAULT_RULE, &same));
    }
}
