//! The weighted sample set a fit runs on.
//!
//! Built once from measured samples: every valid sample with its RGB value,
//! per-channel weight and the interpolation stencils of every factor (D and F
//! cells, the Catmull-Rom control points of G at theta_i and theta_o), plus,
//! per table entry, the list of samples that touch it. The solver only reads
//! these arrays; it never recomputes geometry.
//!
//! Reciprocal pairs: the isotropic model depends on (theta_h, theta_d) and on
//! {theta_i, theta_o} as an unordered pair, so the configurations phi_d and
//! pi - phi_d (which swap theta_i and theta_o) always get the same model
//! value. Two samples with the same model value y_1, y_2 and weights w_1, w_2
//! contribute w_1 (m - y_1)^2 + w_2 (m - y_2)^2 = W (m - y)^2 + c with
//! W = w_1 + w_2, y = (w_1 y_1 + w_2 y_2) / W and c = w_1 w_2 (y_1 - y_2)^2 / W,
//! so merging them halves the work and leaves every update exactly the same;
//! c is kept in `objective_offset` so reported objectives are the true ones.
//! Only isotropic samples fitted with an isotropic layout are merged: for
//! an anisotropic model the two configurations differ in phi.
//!
//! Anisotropic layouts read the samples' azimuths too (phi_h for D, phi_i
//! and phi_o for G); their stencils are the products of a theta and a phi
//! stencil, and every tail constraint acts on the theta part, so it holds
//! in every phi column.

use crate::grid::{Axis, Grid, Stencil, StencilTable, Weight};
use crate::model::Layout;
use npf_data_loaders::{MeasuredSample, MeasuredSamples, MerlSamples};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

mod merl;
#[doc(hidden)]
pub use merl::same_up_to_order;

/// What a fit's data rules (the value checks, the floor rule, the grazing
/// rule) read of one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleView {
    /// Polar angle of the half vector.
    pub theta_h: f64,
    /// Polar angle of the difference vector.
    pub theta_d: f64,
    /// Elevation of wi.
    pub theta_i: f64,
    /// Elevation of wo.
    pub theta_o: f64,
    /// Linear RGB value (1/sr).
    pub rgb: [f64; 3],
}

/// Measured samples as a fit reads them, by index: records
/// ([`MeasuredSamples`]) or a MERL table's grid ([`MerlSamples`], no
/// 88-byte record a sample). Both give the same values for the same table.
pub trait SampleSource: Sync {
    /// Where the samples came from, for messages.
    fn source_name(&self) -> &str;
    /// Whether the data are isotropic.
    fn is_isotropic(&self) -> bool;
    /// Number of samples.
    fn sample_count(&self) -> usize;
    /// Cells of the source that are not samples.
    fn missing_count(&self) -> usize;
    /// Sample i's value.
    fn rgb(&self, i: usize) -> [f64; 3];
    /// Sample i's angles and value as the data rules read them.
    fn view(&self, i: usize) -> SampleView;
    /// Sample i's record.
    fn record(&self, i: usize) -> MeasuredSample;
}

impl SampleSource for MeasuredSamples {
    fn source_name(&self) -> &str {
        &self.source
    }
    fn is_isotropic(&self) -> bool {
        self.isotropic
    }
    fn sample_count(&self) -> usize {
        self.samples.len()
    }
    fn missing_count(&self) -> usize {
        self.missing
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        self.samples[i].rgb
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        let s = &self.samples[i];
        let a = &s.angles;
        SampleView {
            theta_h: a.theta_h,
            theta_d: a.theta_d,
            theta_i: a.theta_i,
            theta_o: a.theta_o,
            rgb: s.rgb,
        }
    }
    fn record(&self, i: usize) -> MeasuredSample {
        self.samples[i]
    }
}

impl SampleSource for MerlSamples {
    fn source_name(&self) -> &str {
        self.source()
    }
    fn is_isotropic(&self) -> bool {
        true
    }
    fn sample_count(&self) -> usize {
        self.len()
    }
    fn missing_count(&self) -> usize {
        self.missing()
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        MerlSamples::rgb(self, i)
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        let (theta_h, theta_d) = self.half_diff(i);
        let [theta_i, theta_o] = self.theta(i);
        SampleView {
            theta_h,
            theta_d,
            theta_i,
            theta_o,
            rgb: MerlSamples::rgb(self, i),
        }
    }
    fn record(&self, i: usize) -> MeasuredSample {
        self.sample(i)
    }
}

/// The measured data a fit's sample sets are built from.
pub enum SampleData<'a> {
    /// Sample records, from any source.
    Records(Cow<'a, MeasuredSamples>),
    /// A MERL table's grid: its set is built by index arithmetic
    /// ([`FitSet::build_merl`]), the same set as from its records.
    Merl(Box<MerlSamples>),
}

impl From<MeasuredSamples> for SampleData<'_> {
    fn from(s: MeasuredSamples) -> Self {
        SampleData::Records(Cow::Owned(s))
    }
}

impl<'a> From<Cow<'a, MeasuredSamples>> for SampleData<'a> {
    fn from(s: Cow<'a, MeasuredSamples>) -> Self {
        SampleData::Records(s)
    }
}

impl From<MerlSamples> for SampleData<'_> {
    fn from(m: MerlSamples) -> Self {
        SampleData::Merl(Box::new(m))
    }
}

impl FitSet {
    /// [`FitSet::build_for`] on either kind of data: a MERL table's grid
    /// through [`FitSet::build_merl`] (the same set in grid-row order).
    pub fn build_from(
        data: &SampleData<'_>,
        layout: Layout,
        options: SampleOptions,
        g_use: GUse,
    ) -> Result<Self, SampleError> {
        match data {
            SampleData::Records(s) => Self::build_for(s, layout, options, g_use),
            SampleData::Merl(m) => Self::build_merl(m, layout, options, g_use),
        }
    }
}

/// The same call on either kind of [`SampleData`] (a match, not a
/// virtual call: the rules call these once a sample).
macro_rules! on_data {
    ($data:expr, $s:ident => $e:expr) => {
        match $data {
            $crate::samples::SampleData::Records($s) => {
                let $s: &::npf_data_loaders::MeasuredSamples = $s;
                $e
            }
            $crate::samples::SampleData::Merl($s) => {
                let $s: &::npf_data_loaders::MerlSamples = $s;
                $e
            }
        }
    };
}
pub(crate) use on_data;

impl SampleSource for SampleData<'_> {
    fn source_name(&self) -> &str {
        on_data!(self, s => s.source_name())
    }
    fn is_isotropic(&self) -> bool {
        on_data!(self, s => s.is_isotropic())
    }
    fn sample_count(&self) -> usize {
        on_data!(self, s => s.sample_count())
    }
    fn missing_count(&self) -> usize {
        on_data!(self, s => s.missing_count())
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        on_data!(self, s => SampleSource::rgb(s, i))
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        on_data!(self, s => s.view(i))
    }
    fn record(&self, i: usize) -> MeasuredSample {
        on_data!(self, s => s.record(i))
    }
}

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
struct PooledScales {
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
    fn scale(&self, a: &npf_data_loaders::geometry::Angles, own: [f64; 3]) -> [f64; 3] {
        if a.theta_h >= self.limit {
            return own;
        }
        *self.rows.get(&row_key(a)).unwrap_or(&own)
    }
}

fn row_key(a: &npf_data_loaders::geometry::Angles) -> (i64, i64) {
    let q = |x: f64| round_to_i64(x * 1e7);
    (q(a.theta_h), q(a.theta_d))
}

/// The pooling angle (radians) where pooling applies: on, and under the
/// compressive weighting (the only one that reads the values).
fn pool_limit(o: &SampleOptions) -> Option<f64> {
    let limit = o.pool_scale_below_deg?.to_radians();
    (o.weighting == Weighting::Compressive && limit > 0.0).then_some(limit)
}

/// Row means of the samples inside the cut-off below the pooling angle
/// (summed in input order: deterministic); `None` when pooling is off or
/// the weighting does not depend on the values.
fn pooled_scales(samples: &MeasuredSamples, o: &SampleOptions, cut: f64) -> Option<PooledScales> {
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

/// For each table entry, the samples that touch it and with which weight
/// (CSR layout), plus a colouring: entries of one colour share no sample, so
/// their element updates are independent and may run in parallel.
#[derive(Clone, Debug, Default)]
pub struct Incidence {
    /// Entry k's samples are `start[k]..start[k + 1]` of `sample`/`weight`.
    pub start: Vec<usize>,
    /// The samples touching each entry.
    pub sample: Vec<u32>,
    /// Their interpolation weights.
    pub weight: Vec<Weight>,
    /// Entries grouped so that no two in a group share a sample.
    pub colors: Vec<Vec<usize>>,
    /// Whether any sample with non-zero weight touches the entry.
    pub has_data: Vec<bool>,
}

impl Incidence {
    /// The CSR range of entry k.
    pub fn entries(&self, k: usize) -> std::ops::Range<usize> {
        self.start[k]..self.start[k + 1]
    }

    fn build(cells: usize, stencils: &StencilTable, total_w: &[f64]) -> Self {
        let mut count = vec![0usize; cells];
        for j in 0..stencils.len() {
            for (k, _) in stencils.entries(j) {
                count[k] += 1;
            }
        }
        let mut start = vec![0usize; cells + 1];
        for k in 0..cells {
            start[k + 1] = start[k] + count[k];
        }
        let mut fill = start.clone();
        let mut sample = vec![0u32; start[cells]];
        let mut weight: Vec<Weight> = vec![0.0; start[cells]];
        let mut has_data = vec![false; cells];
        let mut conflict = vec![false; cells * cells];
        for (j, &tw) in total_w.iter().enumerate().take(stencils.len()) {
            for (k, w) in stencils.entries(j) {
                sample[fill[k]] = j as u32;
                weight[fill[k]] = w as Weight;
                fill[k] += 1;
                has_data[k] |= tw > 0.0;
                for (k2, _) in stencils.entries(j) {
                    conflict[k * cells + k2] = true;
                }
            }
        }
        // Greedy colouring in index order: deterministic and, for 1-D linear
        // stencils, the two parities (for bilinear 2-D stencils, four).
        let mut color_of = vec![usize::MAX; cells];
        let mut colors: Vec<Vec<usize>> = Vec::new();
        for k in 0..cells {
            let c = (0..)
                .find(|&c| {
                    colors.get(c).map_or(true, |members: &Vec<usize>| {
                        members.iter().all(|&k2| !conflict[k * cells + k2])
                    })
                })
                .unwrap();
            if c == colors.len() {
                colors.push(Vec::new());
            }
            colors[c].push(k);
            color_of[k] = c;
        }
        Incidence {
            start,
            sample,
            weight,
            colors,
            has_data,
        }
    }
}

/// For each G control point, the samples whose G(theta_i) (weight u) or
/// G(theta_o) (weight v) use it. Both appear in one entry, so a sample
/// occurs at most once per point.
#[derive(Clone, Debug, Default)]
pub struct GIncidence {
    /// Point k's samples are `start[k]..start[k + 1]`.
    pub start: Vec<usize>,
    /// The samples touching each point.
    pub sample: Vec<u32>,
    /// The point's weight in the sample's G(theta_i).
    pub u: Vec<Weight>,
    /// The point's weight in the sample's G(theta_o).
    pub v: Vec<Weight>,
    /// Whether any sample with non-zero weight touches the point.
    pub has_data: Vec<bool>,
}

/// Samples per task of the incidence builds: large enough to amortise a
/// task's per-point counts, small enough to balance two or more threads.
const INCIDENCE_CHUNK: usize = 1 << 15;

/// A slice written at distinct indices from parallel tasks.
struct DisjointWrites<T>(*mut T, usize);
// SAFETY: writers only touch distinct indices (see `write`).
unsafe impl<T: Send> Sync for DisjointWrites<T> {}
impl<T> DisjointWrites<T> {
    fn new(v: &mut [T]) -> Self {
        DisjointWrites(v.as_mut_ptr(), v.len())
    }
    /// SAFETY: no two concurrent calls may pass the same index, and the
    /// slice given to `new` must outlive every call.
    unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.1, "incidence index out of range");
        *self.0.add(i) = value;
    }
}

/// Whether a fit on a [`FitSet`] updates G (and needs its sample lists).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GUse {
    /// G is updated: every point's sample list is built.
    #[default]
    Updated,
    /// G is held fixed: only [`GIncidence::has_data`] is filled.
    Fixed,
}

impl GIncidence {
    /// No sample lists, only which points a weighted sample touches (the
    /// same `has_data` as [`GIncidence::build`]), for sets whose G is
    /// held fixed.
    fn has_data_only(nodes: usize, gi: &StencilTable, go: &StencilTable, total_w: &[f64]) -> Self {
        let mut has_data = vec![false; nodes];
        for (j, _) in total_w.iter().enumerate().filter(|(_, &w)| w > 0.0) {
            for (k, _) in gi.entries(j).chain(go.entries(j)) {
                has_data[k] = true;
            }
        }
        GIncidence {
            start: vec![0; nodes + 1],
            has_data,
            ..Default::default()
        }
    }

    /// The CSR range of point k.
    pub fn entries(&self, k: usize) -> std::ops::Range<usize> {
        self.start[k]..self.start[k + 1]
    }

    /// Built in parallel over chunks of samples: each chunk counts its
    /// entries per point, the counts give every chunk its own slots in each
    /// point's list, and the chunks fill them. The lists are in sample
    /// order, exactly as a serial pass leaves them, for any thread count.
    pub(crate) fn build(
        nodes: usize,
        gi: &StencilTable,
        go: &StencilTable,
        total_w: &[f64],
    ) -> Self {
        const MAX_TOUCHED: usize = 2 * crate::grid::MAX_SUPPORT;
        // The points sample j touches, with its weights in G(theta_i) and G(theta_o).
        let touched = |j: usize, out: &mut [(usize, Weight, Weight); MAX_TOUCHED]| {
            let mut n = 0;
            for (k, w) in gi.entries(j) {
                out[n] = (k, w as Weight, 0.0);
                n += 1;
            }
            for (k, w) in go.entries(j) {
                match out[..n].iter_mut().find(|t| t.0 == k) {
                    Some(t) => t.2 = w as Weight,
                    None => {
                        out[n] = (k, 0.0, w as Weight);
                        n += 1;
                    }
                }
            }
            n
        };
        let n = gi.len();
        let chunks = n.div_ceil(INCIDENCE_CHUNK);
        let chunk = |c: usize| c * INCIDENCE_CHUNK..((c + 1) * INCIDENCE_CHUNK).min(n);
        // Per chunk: entries per point, and whether a weighted sample touches it.
        let counts: Vec<(Vec<usize>, Vec<bool>)> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut buf = [(usize::MAX, 0.0, 0.0); MAX_TOUCHED];
                let (mut count, mut has) = (vec![0usize; nodes], vec![false; nodes]);
                for j in chunk(c) {
                    let used = touched(j, &mut buf);
                    for t in &buf[..used] {
                        count[t.0] += 1;
                        has[t.0] |= total_w[j] > 0.0;
                    }
                }
                (count, has)
            })
            .collect();
        let mut start = vec![0usize; nodes + 1];
        let mut has_data = vec![false; nodes];
        for (count, has) in &counts {
            for k in 0..nodes {
                start[k + 1] += count[k];
                has_data[k] |= has[k];
            }
        }
        for k in 0..nodes {
            start[k + 1] += start[k];
        }
        // Chunk c's first slot in point k's list.
        let mut first = Vec::with_capacity(chunks);
        let mut at = start[..nodes].to_vec();
        for (count, _) in &counts {
            first.push(at.clone());
            for k in 0..nodes {
                at[k] += count[k];
            }
        }
        let total = start[nodes];
        let (mut sample, mut u, mut v) = (vec![0u32; total], vec![0.0; total], vec![0.0; total]);
        let (ws, wu, wv) = (
            DisjointWrites::new(&mut sample),
            DisjointWrites::new(&mut u),
            DisjointWrites::new(&mut v),
        );
        first.into_par_iter().enumerate().for_each(|(c, mut fill)| {
            let mut buf = [(usize::MAX, 0.0, 0.0); MAX_TOUCHED];
            for j in chunk(c) {
                let used = touched(j, &mut buf);
                for &(k, uk, vk) in &buf[..used] {
                    let e = fill[k];
                    fill[k] += 1;
                    // SAFETY: slots fill[k] of chunk c are its own (counted
                    // above), and the vectors outlive this loop.
                    unsafe {
                        ws.write(e, j as u32);
                        wu.write(e, uk);
                        wv.write(e, vk);
                    }
                }
            }
        });
        GIncidence {
            start,
            sample,
            u,
            v,
            has_data,
        }
    }
}

/// The layout's and the options' own checks, before any set is built.
fn check_options(layout: &Layout, options: &SampleOptions) -> Result<(), SampleError> {
    layout.validate()?;
    if !(options.epsilon > 0.0 && options.epsilon.is_finite()) {
        return Err(SampleError::Options(format!(
            "epsilon must be positive, got {}",
            options.epsilon
        )));
    }
    if !(options.max_theta_h_deg > 0.0 && options.max_theta_h_deg <= 90.0) {
        return Err(SampleError::Options(format!(
            "the half-angle limit must be in (0, 90] degrees, got {}",
            options.max_theta_h_deg
        )));
    }
    if !(options.max_theta_deg > 0.0 && options.max_theta_deg <= 90.0) {
        return Err(SampleError::Options(format!(
            "the cut-off must be in (0, 90] degrees, got {}",
            options.max_theta_deg
        )));
    }
    if let Some(t) = options.taper_from_deg {
        if !(0.0..90.0).contains(&t) {
            return Err(SampleError::Options(format!(
                "the grazing taper must start in [0, 90) degrees, got {t}"
            )));
        }
    }
    Ok(())
}

/// Counts of what happened to the input samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SampleStats {
    /// Valid samples in the source.
    pub input: usize,
    /// Left out by the grazing cut-off.
    pub cut: usize,
    /// Reciprocal pairs merged into one sample.
    pub merged_pairs: usize,
    /// Samples the solver sees.
    pub fitted: usize,
}

/// Everything the solver reads, built once.
#[derive(Clone, Debug)]
pub struct FitSet {
    /// The layout the stencils index.
    pub layout: Layout,
    /// The options the set was built with.
    pub options: SampleOptions,
    /// Measured RGB values (merged pairs: their weighted mean).
    pub y: Vec<[f64; 3]>,
    /// Per-channel residual weights.
    pub w: Vec<[f64; 3]>,
    /// 1 / (cos theta_i cos theta_o).
    pub inv_cc: Vec<f64>,
    /// (theta_i, theta_o, cos(phi_i - phi_o)) per sample: what the diffuse
    /// forms read.
    pub dirs: Vec<[f32; 3]>,
    /// D stencils (tail folded).
    pub d_st: StencilTable,
    /// F stencils.
    pub f_st: StencilTable,
    /// G stencils at the incoming direction (tail folded).
    pub gi_st: StencilTable,
    /// G stencils at the outgoing direction (tail folded).
    pub go_st: StencilTable,
    /// Samples per D entry.
    pub d_inc: Incidence,
    /// Samples per F entry.
    pub f_inc: Incidence,
    /// Samples per G control point.
    pub g_inc: GIncidence,
    /// Constant part of the objective from merged pairs.
    pub objective_offset: f64,
    /// What happened to the input samples.
    pub stats: SampleStats,
}

/// Why a sample set could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// A NaN, infinite or negative measured value.
    #[error("{source_name}: sample {index} has a non-finite or negative value {value}")]
    BadValue {
        /// The samples' source.
        source_name: String,
        /// Sample index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Nothing left after the cut-off.
    #[error("{source_name}: no valid samples left to fit ({input} valid in the input, {cut} beyond the {max_theta_deg} degree cut-off)")]
    Empty {
        /// The samples' source.
        source_name: String,
        /// Valid input samples.
        input: usize,
        /// Samples cut.
        cut: usize,
        /// The cut-off.
        max_theta_deg: f64,
    },
    /// Out-of-range sample options.
    #[error("bad sample options: {0}")]
    Options(String),
    /// Anisotropic samples with a layout that cannot represent them.
    #[error("{0}: anisotropic samples need an anisotropic layout")]
    AnisotropicData(String),
    /// The layout itself is invalid.
    #[error(transparent)]
    Layout(#[from] crate::model::ModelError),
}

/// The last G control point at or below the cut-off. Points past it would
/// only be touched by the Catmull-Rom tails of a few samples near the cut
/// and take wild values, so they are not free: they ramp linearly from the
/// last free point to 0 at 90 degrees (see `solver::gauge`).
/// (A theta index: the rule holds in every phi column of a 2-D G.)
pub fn last_free_g_node(layout: &Layout, cut: f64) -> usize {
    last_free_node(&layout.g.theta, cut).min(layout.g.n_theta() - 2)
}

/// The last node of an axis at or below an angle.
pub fn last_free_node(axis: &Axis, limit: f64) -> usize {
    (0..axis.len())
        .rev()
        .find(|&k| axis.node(k) <= limit + 1e-12)
        .unwrap_or(0)
}

/// The tail rules of a layout under a set's options: D cells past the
/// half-angle limit hold the last free cell's value, G points past the
/// cut-off ramp from the last free one to 0 ([`fold_tail`]).
struct Tails {
    layout: Layout,
    d_free: usize,
    g_free: usize,
}

impl Tails {
    fn new(layout: &Layout, options: &SampleOptions) -> Self {
        Tails {
            layout: *layout,
            d_free: last_free_node(&layout.d.theta, options.max_theta_h_deg.to_radians()),
            g_free: last_free_g_node(layout, options.max_theta_deg.to_radians()),
        }
    }

    /// D's folded theta stencil at a half angle.
    #[inline]
    fn d(&self, theta_h: f64) -> Stencil {
        fold_tail(self.layout.d.theta.stencil(theta_h), self.d_free, |_| 1.0)
    }

    /// G's folded theta stencil at an elevation.
    #[inline]
    fn g(&self, theta: f64) -> Stencil {
        let (n_g, g_free) = (self.layout.g.n_theta(), self.g_free);
        let ramp = |k: usize| (n_g - 1 - k) as f64 / (n_g - 1 - g_free) as f64;
        fold_tail(self.layout.g.theta.stencil(theta), g_free, ramp)
    }
}

/// Re-express a theta stencil on tied tail entries through the last free
/// entry L: value_k = value_L * tie(k) for k > L. Applied before the phi
/// product, so in a 2-D table the tie holds per phi column.
fn fold_tail(st: Stencil, last_free: usize, tie: impl Fn(usize) -> f64) -> Stencil {
    let mut slots: [(usize, f64); crate::grid::MAX_SUPPORT] = [(0, 0.0); crate::grid::MAX_SUPPORT];
    let mut n = 0;
    for (k, w) in st.entries() {
        let (k, w) = if k > last_free {
            (last_free, w * tie(k))
        } else {
            (k, w)
        };
        if w == 0.0 {
            continue;
        }
        match (0..n).find(|&i| slots[i].0 == k) {
            Some(i) => slots[i].1 += w,
            None => {
                slots[n] = (k, w);
                n += 1;
            }
        }
    }
    let mut out = Stencil::empty(0);
    for &(k, w) in &slots[..n] {
        out.push(k, w);
    }
    out
}

/// A sample's sort key: (theta_i, theta_o) ordered so that theta_i <=
/// theta_o, then theta_h, theta_d, each quantised to 1e-7 rad; packed
/// 32 bits a component (order-preserving for any angle below 214 rad), so
/// the sort moves 24-byte (key, index) pairs instead of whole records.
fn sort_key(a: &npf_data_loaders::geometry::Angles) -> Key {
    let q = |x: f64| key_part(x) as u128;
    let (lo, hi) = if a.theta_i > a.theta_o {
        (a.theta_o, a.theta_i)
    } else {
        (a.theta_i, a.theta_o)
    };
    Key::from(q(lo) << 96 | q(hi) << 64 | q(a.theta_h) << 32 | q(a.theta_d))
}

/// One component of [`sort_key`]: an angle quantised to 1e-7 rad, as an
/// order-preserving u32.
#[inline]
fn key_part(x: f64) -> u32 {
    let v = round_to_i64(x * 1e7).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
    v as u32 ^ 0x8000_0000
}

/// A 128-bit sort key as two 64-bit halves, high first: the same order as
/// the u128, but 8-byte aligned, so a (key, index) pair takes 24 bytes, not
/// 32, through the key pass, the sort and the merge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
struct Key(u64, u64);

impl From<u128> for Key {
    fn from(k: u128) -> Self {
        Key((k >> 64) as u64, k as u64)
    }
}

/// Input samples per chunk of the key pass (and of the bucket sort's passes).
const KEY_CHUNK: usize = 1 << 16;

/// The pairs of `chunks` (concatenated) in ascending order, as
/// `par_sort_unstable` leaves them (the pairs are distinct, so the order
/// is total and unique). A counting pass distributes them into buckets by
/// the top 32 bits of the key (theta_i's quantised value), chunk by chunk
/// in input order, then each bucket (a few hundred pairs, cache resident)
/// is sorted on its own, in parallel: about half the work of a comparison
/// sort of the whole array.
fn bucket_sort(chunks: Vec<Vec<(Key, u32)>>) -> Vec<(Key, u32)> {
    let top = |p: &(Key, u32)| (p.0 .0 >> 32) as u32;
    let len: usize = chunks.iter().map(Vec::len).sum();
    let (lo, hi) = chunks
        .par_iter()
        .flat_map_iter(|c| c.iter().map(|p| (top(p), top(p))))
        .reduce(|| (u32::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    if len < 2 * KEY_CHUNK || lo >= hi {
        let mut pairs = chunks.concat();
        pairs.par_sort_unstable();
        return pairs;
    }
    // About 256 pairs a bucket; the shift keeps the bucket monotone in the key.
    let want = (len / 256).next_power_of_two().min(1 << 16) as u64;
    let span = u64::from(hi - lo) + 1;
    let shift = (64 - (span.div_ceil(want)).leading_zeros()).min(31);
    let buckets = ((span - 1) >> shift) as usize + 1;
    let bucket = |p: &(Key, u32)| ((top(p) - lo) >> shift) as usize;
    let counts: Vec<Vec<usize>> = chunks
        .par_iter()
        .map(|c| {
            let mut n = vec![0usize; buckets];
            for p in c.iter() {
                n[bucket(p)] += 1;
            }
            n
        })
        .collect();
    // Chunk c's first slot in bucket b: the bucket's start plus the pairs
    // of earlier chunks in it.
    let mut sizes = vec![0usize; buckets];
    let mut firsts = Vec::with_capacity(chunks.len());
    for n in &counts {
        firsts.push(sizes.clone());
        for (s, k) in sizes.iter_mut().zip(n) {
            *s += k;
        }
    }
    let mut start = 0;
    let mut bucket_start = vec![0usize; buckets];
    for (b, &size) in sizes.iter().enumerate() {
        bucket_start[b] = start;
        start += size;
    }
    let mut out = vec![(Key::default(), 0u32); len];
    {
        let slots = DisjointWrites::new(&mut out);
        chunks.par_iter().zip(firsts).for_each(|(c, mut fill)| {
            for p in c.iter() {
                let b = bucket(p);
                // SAFETY: chunk c's slots in each bucket are its own.
                unsafe { slots.write(bucket_start[b] + fill[b], *p) };
                fill[b] += 1;
            }
        });
    }
    drop(chunks);
    let mut parts = Vec::with_capacity(buckets);
    let mut rest = &mut out[..];
    for &size in &sizes {
        let (part, tail) = rest.split_at_mut(size);
        parts.push(part);
        rest = tail;
    }
    parts.into_par_iter().for_each(|part| part.sort_unstable());
    out
}

/// Merged samples per task of the set's main pass.
const PIECE: usize = 4096;

/// How many runs ahead the main pass prefetches its input records.
const PREFETCH_RUNS: usize = 16;

/// Ask for input sample `index`'s record (88 bytes: two or three cache lines) to be
/// brought into cache; a hint only, with no effect on any value.
#[inline(always)]
fn prefetch_sample(samples: &[npf_data_loaders::MeasuredSample], index: u32) {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = samples.get(index as usize) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = (s as *const npf_data_loaders::MeasuredSample).cast::<i8>();
        let last = std::mem::size_of::<npf_data_loaders::MeasuredSample>() - 1;
        // SAFETY: a prefetch reads nothing and faults on no address; the
        // addresses are the record's first byte, 64 bytes on and last byte.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64.min(last)));
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(last));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (samples, index);
}

/// Whether an elevation is past the cut-off (at most pi/2) or has a
/// non-positive cosine. On [0, cut] the cosine is positive, so it is only
/// computed for negative angles.
#[inline]
fn outside_cut(theta: f64, cut: f64) -> bool {
    theta > cut || (theta < 0.0 && theta.cos() <= 0.0)
}

/// Merge sample r (value `ry`, weights `rw`) into the merged sample (y, w):
/// its share of the objective's constant part, per channel.
fn merge_into(y: &mut [f64; 3], w: &mut [f64; 3], ry: [f64; 3], rw: [f64; 3]) -> [f64; 3] {
    let mut share = [0.0; 3];
    for c in 0..3 {
        let wsum = w[c] + rw[c];
        if wsum > 0.0 {
            share[c] = w[c] * rw[c] * (y[c] - ry[c]).powi(2) / wsum;
            y[c] = (w[c] * y[c] + rw[c] * ry[c]) / wsum;
        }
        w[c] = wsum;
    }
    share
}

impl FitSet {
    /// The objective of the all-black model, sum w y^2: the scale of the
    /// data. Residual caches are updated incrementally, so their rounding
    /// error is relative to this, not to the (much smaller) final objective.
    pub fn data_energy(&self) -> f64 {
        self.y
            .iter()
            .zip(&self.w)
            .map(|(y, w)| w[0] * y[0] * y[0] + w[1] * y[1] * y[1] + w[2] * y[2] * y[2])
            .sum::<f64>()
            + self.objective_offset
    }

    /// Build the set: validate, weight, cut, merge reciprocal pairs (isotropic
    /// data and layout only), and precompute every stencil and incidence.
    pub fn build(
        samples: &MeasuredSamples,
        layout: Layout,
        options: SampleOptions,
    ) -> Result<Self, SampleError> {
        Self::build_for(samples, layout, options, GUse::Updated)
    }

    /// [`FitSet::build`] for a fit whose G is updated or held fixed: a set
    /// for [`GUse::Fixed`] skips G's sample lists (a tenth of the build's
    /// time and tens of MB) and keeps only which G points have data, so
    /// a G update on it finds no samples.
    pub fn build_for(
        samples: &MeasuredSamples,
        layout: Layout,
        options: SampleOptions,
        g_use: GUse,
    ) -> Result<Self, SampleError> {
        layout.validate()?;
        if !samples.isotropic && layout.is_isotropic() {
            return Err(SampleError::AnisotropicData(samples.source.clone()));
        }
        let merge = samples.isotropic && layout.is_isotropic();
        check_options(&layout, &options)?;
        let mut lap = crate::phases::Lap::new("set", samples.samples.len());
        let cut = options.max_theta_deg.to_radians();
        let mut stats = SampleStats {
            input: samples.samples.len(),
            ..Default::default()
        };
        if let Some(index) = samples
            .samples
            .par_iter()
            .position_first(|s| s.rgb.iter().any(|v| !v.is_finite() || *v < 0.0))
        {
            let s = &samples.samples[index];
            let &value = s.rgb.iter().find(|v| !v.is_finite() || **v < 0.0).unwrap();
            return Err(SampleError::BadValue {
                source_name: samples.source.clone(),
                index,
                value,
            });
        }
        lap.done("check values");
        let pooled = pooled_scales(samples, &options, cut);
        lap.done("pooled scales");
        // (key, index) of every sample inside the cut-off. G(in) G(out) is
        // symmetric in the two directions, so ordering each pair by
        // elevation (azimuths travel with their elevation) changes no model
        // value.
        // Collected chunk by chunk into vectors of the chunk's size: no
        // growing vector, and no concatenation (the sort reads the chunks).
        let keyed: Vec<Vec<(Key, u32)>> = samples
            .samples
            .par_chunks(KEY_CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut keys = Vec::with_capacity(chunk.len());
                for (k, s) in chunk.iter().enumerate() {
                    let a = &s.angles;
                    if !(outside_cut(a.theta_i, cut) || outside_cut(a.theta_o, cut)) {
                        keys.push((sort_key(a), (c * KEY_CHUNK + k) as u32));
                    }
                }
                keys
            })
            .collect();
        let kept: usize = keyed.iter().map(Vec::len).sum();
        lap.done("keys");
        stats.cut = stats.input - kept;
        if kept == 0 {
            return Err(SampleError::Empty {
                source_name: samples.source.clone(),
                input: stats.input,
                cut: stats.cut,
                max_theta_deg: options.max_theta_deg,
            });
        }
        // Order by theta_i then theta_o: the G control-point lists then read
        // memory mostly forward. Ties are broken by the index, so reciprocal
        // partners (equal keys) end up adjacent and in input order, as a
        // stable sort would leave them.
        let sorted = bucket_sort(keyed);
        lap.done("sort");
        let order: &[(Key, u32)] = &sorted;
        // A sample's value and weights, recomputed from the input wherever
        // they are needed (cheaper than carrying 48 bytes through the sort).
        let value_at = |s: &npf_data_loaders::MeasuredSample, cos_i: f64| {
            let a = &s.angles;
            let t = options.taper(a.theta_i.max(a.theta_o));
            let scale = pooled.as_ref().map_or(s.rgb, |p| p.scale(a, s.rgb));
            (s.rgb, scale.map(|v| options.weight(v, cos_i) * t))
        };
        let value = |index: u32| {
            let s = &samples.samples[index as usize];
            value_at(s, s.angles.theta_i.cos())
        };
        // Each run of equal keys is merged into its first member, folding
        // the others in input order (one merged sample per run).
        let starts: Vec<usize> = if merge {
            (0..order.len())
                .into_par_iter()
                .filter(|&i| i == 0 || order[i - 1].0 != order[i].0)
                .collect()
        } else {
            (0..order.len()).collect()
        };
        lap.done("run starts");
        let starts_ref = &starts;
        let run = move |g: usize| starts_ref[g]..starts_ref.get(g + 1).map_or(order.len(), |&e| e);
        let n = starts.len();
        stats.merged_pairs = order.len() - n;
        stats.fitted = n;
        // One pass over the runs, straight into the set's arrays: the merged
        // value and weights, and for a pair (the usual run: a configuration
        // and its reciprocal) the partner's share of the offset. Longer runs
        // (rare) have their shares computed below.
        // The same pass writes each merged sample's geometric terms, with
        // theta_i <= theta_o (G(in) G(out) is symmetric in the two
        // directions, and azimuths travel with their elevation), and its
        // first member's index, from which the stencils are computed later.
        let tails = Tails::new(&layout, &options);
        let (dg, fg, gg): (Grid, Grid, Grid) = (layout.d, layout.f, layout.g);
        let (mut y, mut w) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let mut pair_share = vec![[0.0; 3]; n];
        let (mut inv_cc, mut dirs) = (vec![0.0; n], vec![[0.0f32; 3]; n]);
        // Each merged sample's first member: the stencils are computed from
        // it once the sort's arrays are freed (4 bytes a sample held across
        // them, not its 64 bytes of angles).
        let mut first_of = vec![0u32; n];
        (
            y.par_chunks_mut(PIECE),
            w.par_chunks_mut(PIECE),
            pair_share.par_chunks_mut(PIECE),
            inv_cc.par_chunks_mut(PIECE),
            dirs.par_chunks_mut(PIECE),
            first_of.par_chunks_mut(PIECE),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(c, (y, w, share, inv_cc, dirs, first_of))| {
                for k in 0..y.len() {
                    let g = c * PIECE + k;
                    // The first members a few runs ahead: their records
                    // are scattered over the input, so each read would
                    // otherwise wait on memory.
                    if let Some(&ahead) = starts.get(g + PREFETCH_RUNS) {
                        prefetch_sample(&samples.samples, order[ahead].1);
                        if let Some(&(_, partner)) = order.get(ahead + 1) {
                            prefetch_sample(&samples.samples, partner);
                        }
                    }
                    let members = &order[run(g)];
                    first_of[k] = members[0].1;
                    let first = &samples.samples[members[0].1 as usize];
                    let a = first.angles;
                    let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
                    let (ti, pi, to, po) = if a.theta_i > a.theta_o {
                        (a.theta_o, a.phi_o, a.theta_i, a.phi_i)
                    } else {
                        (a.theta_i, a.phi_i, a.theta_o, a.phi_o)
                    };
                    inv_cc[k] = 1.0 / (ci * co);
                    dirs[k] = [ti as f32, to as f32, (pi - po).cos() as f32];
                    (y[k], w[k]) = value_at(first, ci);
                    for &(_, index) in &members[1..] {
                        let (ry, rw) = value(index);
                        share[k] = merge_into(&mut y[k], &mut w[k], ry, rw);
                    }
                }
            });
        lap.done("merge + gather");
        // Each merged partner's share of the offset, summed in input order:
        // `share_of[index]` names where the share of input sample `index`
        // is (a pair's in `pair_share`, a longer run's in `run_shares`).
        let mut share_of = vec![u32::MAX; samples.samples.len()];
        {
            let slots = DisjointWrites::new(&mut share_of);
            (0..n)
                .into_par_iter()
                .filter(|&g| run(g).len() == 2)
                // SAFETY: every input sample is in exactly one run.
                .for_each(|g| unsafe { slots.write(order[starts[g] + 1].1 as usize, g as u32) });
        }
        let mut run_shares = Vec::new();
        for g in (0..n).filter(|&g| run(g).len() > 2) {
            let members = &order[run(g)];
            let (mut y, mut w) = value(members[0].1);
            for &(_, index) in &members[1..] {
                let (ry, rw) = value(index);
                share_of[index as usize] = (n + run_shares.len()) as u32;
                run_shares.push(merge_into(&mut y, &mut w, ry, rw));
            }
        }
        let mut offset = 0.0;
        for &at in share_of.iter().filter(|&&at| at != u32::MAX) {
            let at = at as usize;
            let share = if at < n {
                pair_share[at]
            } else {
                run_shares[at - n]
            };
            for v in share {
                offset += v;
            }
        }
        drop((pair_share, share_of, run_shares));
        drop((sorted, starts));
        lap.done("shares + offset");
        let mut d_st = StencilTable::zeroed(dg.stencil_width(), n);
        let mut f_st = StencilTable::zeroed(fg.stencil_width(), n);
        let mut gi_st = StencilTable::zeroed(gg.stencil_width(), n);
        let mut go_st = StencilTable::zeroed(gg.stencil_width(), n);
        (
            first_of.par_chunks(PIECE),
            d_st.par_pieces_mut(PIECE),
            f_st.par_pieces_mut(PIECE),
            gi_st.par_pieces_mut(PIECE),
            go_st.par_pieces_mut(PIECE),
        )
            .into_par_iter()
            .for_each(|(first_of, mut d, mut f, mut gi, mut go)| {
                for (k, &index) in first_of.iter().enumerate() {
                    if let Some(&ahead) = first_of.get(k + PREFETCH_RUNS) {
                        prefetch_sample(&samples.samples, ahead);
                    }
                    let a = samples.samples[index as usize].angles;
                    let ((ti, pi), (to, po)) = if a.theta_i > a.theta_o {
                        ((a.theta_o, a.phi_o), (a.theta_i, a.phi_i))
                    } else {
                        ((a.theta_i, a.phi_i), (a.theta_o, a.phi_o))
                    };
                    d.store(k, &dg.extend(tails.d(a.theta_h), a.phi_h));
                    f.store(k, &fg.stencil(a.theta_d, a.phi_d));
                    gi.store(k, &gg.extend(tails.g(ti), pi));
                    go.store(k, &gg.extend(tails.g(to), po));
                }
            });
        drop(first_of);
        lap.done("stencils");
        let values = (y, w, inv_cc, dirs);
        let stencils = [d_st, f_st, gi_st, go_st];
        let set = FitSet::assembled((layout, options), values, stencils, (offset, stats));
        Ok(set.with_incidences(g_use, &mut lap))
    }

    /// A set of its parts, without incidence lists yet.
    #[allow(clippy::type_complexity)]
    fn assembled(
        (layout, options): (Layout, SampleOptions),
        (y, w, inv_cc, dirs): (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<f64>, Vec<[f32; 3]>),
        [d_st, f_st, gi_st, go_st]: [StencilTable; 4],
        (objective_offset, stats): (f64, SampleStats),
    ) -> Self {
        FitSet {
            layout,
            options,
            y,
            w,
            inv_cc,
            dirs,
            d_st,
            f_st,
            gi_st,
            go_st,
            d_inc: Incidence::default(),
            f_inc: Incidence::default(),
            g_inc: GIncidence::default(),
            objective_offset,
            stats,
        }
    }

    /// The set with the incidence lists of its stencils and weights.
    fn with_incidences(mut self, g_use: GUse, lap: &mut crate::phases::Lap) -> Self {
        let layout = self.layout;
        let total_w: Vec<f64> = self.w.iter().map(|w| w.iter().sum()).collect();
        self.d_inc = Incidence::build(layout.d.len(), &self.d_st, &total_w);
        lap.done("D incidence");
        self.f_inc = Incidence::build(layout.f.len(), &self.f_st, &total_w);
        lap.done("F incidence");
        self.g_inc = match g_use {
            GUse::Updated => GIncidence::build(layout.g.len(), &self.gi_st, &self.go_st, &total_w),
            GUse::Fixed => {
                GIncidence::has_data_only(layout.g.len(), &self.gi_st, &self.go_st, &total_w)
            }
        };
        lap.done("G incidence");
        self
    }

    /// Number of samples the solver sees.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// Whether the set has no samples.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// Approximate heap size in bytes, for reports.
    pub fn heap_bytes(&self) -> usize {
        let per_sample = 2 * 24 + 8 + 12;
        let st = self.d_st.heap_bytes()
            + self.f_st.heap_bytes()
            + self.gi_st.heap_bytes()
            + self.go_st.heap_bytes();
        let weight = std::mem::size_of::<Weight>();
        let inc = |i: &Incidence| i.sample.len() * (4 + weight) + i.start.len() * 8;
        self.len() * per_sample
            + st
            + inc(&self.d_inc)
            + inc(&self.f_inc)
            + self.g_inc.sample.len() * (4 + 2 * weight)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_for_fixed_g_has_the_same_g_points_with_data() {
        let truth = crate::synth::known_factor_model(Layout::default(), &[0.05, 0.3]);
        let mut s = crate::reconstruct::to_merl(&truth).samples("known");
        s.samples = s.samples.into_iter().step_by(40).collect();
        let so = SampleOptions::default();
        let full = FitSet::build(&s, Layout::default(), so).unwrap();
        let lean = FitSet::build_for(&s, Layout::default(), so, GUse::Fixed).unwrap();
        assert_eq!(full.g_inc.has_data, lean.g_inc.has_data);
        assert!(full.g_inc.has_data.iter().any(|&h| h) && full.g_inc.has_data.iter().any(|&h| !h));
        assert!(lean.g_inc.sample.is_empty() && full.g_inc.sample.len() > full.len());
        for k in 0..lean.g_inc.has_data.len() {
            assert!(lean.g_inc.entries(k).is_empty());
        }
        assert_eq!(full.y, lean.y);
    }

    /// splitmix64: a fixed pseudo-random sequence.
    fn mix(i: u64) -> u64 {
        let mut z = i.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// `round_to_i64` is `round() as i64` on halves, near-halves,
    /// integers, huge values, infinities and NaN.
    #[test]
    fn round_to_i64_is_round() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            4503599627370496.0,
            9007199254740993.0,
            9.3e18,
            -9.3e18,
            9.223_372_036_854_776e18,  // i64::MAX as f64 (2^63)
            -9.223_372_036_854_776e18, // i64::MIN as f64
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            1e-320,
        ];
        for i in 0..20_000u64 {
            let x = (mix(i) >> 11) as f64 / (1u64 << 53) as f64;
            xs.push((x - 0.5) * 2e7);
            xs.push((x - 0.5) * 64.0);
            xs.push(f64::from_bits(mix(i + 7)));
        }
        for x in xs {
            assert_eq!(round_to_i64(x), x.round() as i64, "{x:e}");
        }
    }

    /// The bucket sort leaves exactly the order of a comparison sort, for
    /// spread keys, keys with many ties (reciprocal pairs), keys crowded
    /// into one bucket, and any thread count.
    #[test]
    fn bucket_sort_is_a_sort() {
        let n = 300_000u64;
        type Case = (&'static str, Box<dyn Fn(u64) -> u128>);
        let cases: [Case; 3] = [
            (
                "spread",
                Box::new(move |i| (mix(i) as u128) << 64 | mix(i + n) as u128),
            ),
            ("ties", Box::new(|i| ((mix(i / 3) >> 40) as u128) << 96)),
            ("crowded", Box::new(|i| 7u128 << 96 | (mix(i) % 5) as u128)),
        ];
        for (name, key) in cases {
            let pairs: Vec<(Key, u32)> = (0..n).map(|i| (Key::from(key(i)), i as u32)).collect();
            let mut expected = pairs.clone();
            expected.sort_unstable();
            // The halves order keys as the u128s they come from.
            let wide = |k: Key| (k.0 as u128) << 64 | k.1 as u128;
            assert!(expected.windows(2).all(|p| wide(p[0].0) <= wide(p[1].0)));
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                // Whole key chunks, and uneven ones (some empty, as a chunk
                // of samples all past the cut-off leaves).
                for sizes in [&[KEY_CHUNK][..], &[70_001, 0, 3, 40_000, 0]] {
                    let mut chunks = Vec::new();
                    let mut at = 0;
                    for &size in sizes.iter().cycle() {
                        if at == pairs.len() {
                            break;
                        }
                        let end = (at + size).min(pairs.len());
                        chunks.push(pairs[at..end].to_vec());
                        at = end;
                    }
                    let got = pool.install(|| bucket_sort(chunks));
                    assert!(got == expected, "{name}, {threads} threads, {sizes:?}");
                }
            }
        }
    }
}
