//! How residuals are weighted: the weighting forms and the options of a
//! sample set, and the pooled peak weights of the grazing rows.

use npf_data_loaders::MeasuredSamples;
use serde::{Deserialize, Serialize};

/// How residuals are weighted in the least-squares objective.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// w = (cos theta_i / (rho cos theta_i + eps))^2: the linearisation of the
    /// squared error of log(rho cos theta_i + eps), i.e. relative error on
    /// cosine-weighted values with an absolute floor eps. Rendered radiance is
    /// rho cos, and the eye and tone mapping judge it roughly relatively, so
    /// a peak of 1e4 and a diffuse value of 1e-2 both count; eps stops
    /// near-black samples from dominating. It depends only on the data, so
    /// every AWLS element update stays an exact weighted least-squares solve.
    Compressive,
    /// w = cos^2 theta_i: plain L2 on cosine-weighted values (dominated by
    /// specular peaks).
    CosineL2,
    /// w = 1: plain L2 on BRDF values.
    Uniform,
}

/// How samples become the weighted sample set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleOptions {
    /// The residual weighting.
    pub weighting: Weighting,
    /// The floor eps of the compressive weight, in 1/sr (cosine-weighted).
    pub epsilon: f64,
    /// Grazing cut-off: samples with theta_i or theta_o above this angle
    /// (degrees) are left out of the fit. Measurements near the horizon are
    /// the noisiest and matter least in renderings (they are foreshortened).
    pub max_theta_deg: f64,
    /// D cells above this half angle (degrees) are not free: they hold the
    /// value of the last free cell. Only near-grazing samples (theta_i and
    /// theta_o both close to the cut-off) reach them, and there D trades
    /// scale with an equally unconstrained grazing G; left free, a lobe can
    /// put all its mass into such a cell.
    pub max_theta_h_deg: f64,
    /// Grazing taper: samples whose larger elevation max(theta_i, theta_o)
    /// lies past this angle (degrees) are trusted less, their weight
    /// multiplied by (90 - theta) / (90 - taper), falling linearly to 0 at
    /// the horizon. With a cut-off near 90 degrees the fit then follows the
    /// grazing data's trend without letting the noisiest cells dominate.
    /// `None`: full weight up to the cut-off.
    #[serde(default)]
    pub taper_from_deg: Option<f64>,
    /// Pooled weight scale near the mirror direction: a compressive weight
    /// of a sample with theta_h below this angle (degrees) uses the mean
    /// of the samples sharing its theta_h and theta_d (over phi_d) in
    /// place of its own value. There phi_d barely moves the directions, so
    /// an isotropic BRDF hardly depends on it; where a table's peak does
    /// (by a factor of 10 in some RGL tables), weights of 1 / rho^2 pull
    /// the fit to the lowest values and the peak renders far too dim.
    /// `None`: every sample's own value.
    #[serde(default)]
    pub pool_scale_below_deg: Option<f64>,
}

impl Default for SampleOptions {
    fn default() -> Self {
        SampleOptions {
            weighting: Weighting::Compressive,
            epsilon: 1e-3,
            max_theta_deg: 85.0,
            max_theta_h_deg: 75.0,
            taper_from_deg: None,
            pool_scale_below_deg: Some(1.6),
        }
    }
}

impl SampleOptions {
    /// The weight of a sample of value `rho` at incidence cosine `cos_i`.
    pub fn weight(&self, rho: f64, cos_i: f64) -> f64 {
        match self.weighting {
            Weighting::Compressive => (cos_i / (rho * cos_i + self.epsilon)).powi(2),
            Weighting::CosineL2 => cos_i * cos_i,
            Weighting::Uniform => 1.0,
        }
    }

    /// The grazing taper's factor for a sample whose larger elevation is
    /// `theta` (radians): 1 without a taper or before it.
    pub fn taper(&self, theta: f64) -> f64 {
        match self.taper_from_deg {
            Some(from) if theta > from.to_radians() => {
                let half_pi = std::f64::consts::FRAC_PI_2;
                ((half_pi - theta) / (half_pi - from.to_radians())).clamp(0.0, 1.0)
            }
            _ => 1.0,
        }
    }
}

/// The mean value of each (theta_h, theta_d) row of samples below the
/// pooling angle ([`SampleOptions::pool_scale_below_deg`]).
pub(super) struct PooledScales {
    limit: f64,
    rows: KeyMap<(i64, i64), [f64; 3]>,
}

/// A hash map for keys of quantised angles: FxHash instead of SipHash
/// (the keys come from the data, not from an adversary), a few times
/// faster on the samples' integer tuples. Lookups give the same values as
/// any other map, and no result depends on its iteration order.
pub(crate) type KeyMap<K, V> = rustc_hash::FxHashMap<K, V>;

/// `y.round() as i64` (half away from zero, saturating, NaN to 0) without
/// the C library's `round` call, which the default x86-64 target cannot
/// inline: the keys of every sample are quantised with it.
#[inline]
pub(crate) fn round_to_i64(y: f64) -> i64 {
    let t = y as i64;
    // Exact: below 2^52 t is y's integer part, above y is an integer (or
    // t saturated, and the step below saturates too).
    let f = y - t as f64;
    if f >= 0.5 {
        t.saturating_add(1)
    } else if f <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

impl PooledScales {
    /// The value a sample's weight is computed from.
    pub(super) fn scale(&self, a: &npf_data_loaders::geometry::Angles, own: [f64; 3]) -> [f64; 3] {
        if a.theta_h >= self.limit {
            return own;
        }
        *self.rows.get(&row_key(a)).unwrap_or(&own)
    }
}

pub(super) fn row_key(a: &npf_data_loaders::geometry::Angles) -> (i64, i64) {
    let q = |x: f64| round_to_i64(x * 1e7);
    (q(a.theta_h), q(a.theta_d))
}

/// The pooling angle (radians) where pooling applies: on, and under the
/// compressive weighting (the only one that reads the values).
pub(super) fn pool_limit(o: &SampleOptions) -> Option<f64> {
    let limit = o.pool_scale_below_deg?.to_radians();
    (o.weighting == Weighting::Compressive && limit > 0.0).then_some(limit)
}

/// Row means of the samples inside the cut-off below the pooling angle
/// (summed in input order: deterministic); `None` when pooling is off or
/// the weighting does not depend on the values.
pub(super) fn pooled_scales(
    samples: &MeasuredSamples,
    o: &SampleOptions,
    cut: f64,
) -> Option<PooledScales> {
    let limit = pool_limit(o)?;
    // Serial: a parallel filter's collected pieces, freed in the worker
    // threads' heaps during the set build, raised peak memory by 4-9 MB.
    let mut sums: KeyMap<(i64, i64), ([f64; 3], usize)> = Default::default();
    for s in &samples.samples {
        let a = &s.angles;
        if a.theta_h < limit && a.theta_i <= cut && a.theta_o <= cut {
            let e = sums.entry(row_key(a)).or_insert(([0.0; 3], 0));
            for c in 0..3 {
                e.0[c] += s.rgb[c];
            }
            e.1 += 1;
        }
    }
    let rows = sums
        .into_iter()
        .map(|(k, (sum, n))| (k, sum.map(|v| v / n as f64)))
        .collect();
    Some(PooledScales { limit, rows })
}
