//! The rules a fit reads from its data before it starts: the compressive
//! floor (raised for untrusted tables), the grazing cut-off and taper, the
//! pooled peak weights of grazing rows, and the post-fit energy rescaling.
//! Each depends on the data alone, so a fit stays deterministic.

use super::config::*;
use crate::metrics::MerlReference;
use crate::samples::{round_to_i64, KeyMap, SampleOptions, SampleSource, SampleView};
use crate::solver::FitResult;
use serde::{Deserialize, Serialize};

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

/// Whether the post-fit energy scale can apply to `result`: a factor
/// model (d and s are the whole energy) on an isotropic layout, with no
/// multiple-scattering term (which reads the lobes' own energy).
pub(super) fn scalable(config: &FitConfig, result: &FitResult) -> bool {
    config.model != ModelKind::Ggx
        && !config.compensate
        && result.model.compensation.is_none()
        && result.model.layout.is_isotropic()
}

/// Reads the energy ratio of `result` against `table` and, where the rule
/// applies it, scales d and every lobe's s per channel (factors and model
/// alike; the recorded objective stays the sweeps'). Returns the record.
pub(super) fn scale_energy(
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

/// The rules a fit reads from its data, asked once by the front door.
impl FitConfig {
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
    /// no taper is set, `max_theta` is the default and the data are not untrusted (`floor`, from
    /// [`FitConfig::floor_rule`]: not clamped and the grazing cells'
    /// reciprocity asymmetry below `grazing_trust`); else `max_theta` and
    /// `taper_from`. Depends on the data alone.
    pub fn grazing_rule(&self, floor: &FloorRule) -> GrazingRule {
        // The rule replaces only the default cut-off: one the user chose
        // (`--max-theta 80`) is theirs to keep.
        let default_cut = self.max_theta == SampleOptions::default().max_theta_deg;
        let trusted = self.grazing_trust > 0.0
            && self.taper_from.is_none()
            && default_cut
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
}
