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

use crate::grid::{Axis, Grid, Stencil, StencilTable};
use crate::model::Layout;
use npf_data_loaders::MeasuredSamples;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

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
}

impl Default for SampleOptions {
    fn default() -> Self {
        SampleOptions {
            weighting: Weighting::Compressive,
            epsilon: 1e-3,
            max_theta_deg: 85.0,
            max_theta_h_deg: 75.0,
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
    pub weight: Vec<f64>,
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
        let mut weight = vec![0.0; start[cells]];
        let mut has_data = vec![false; cells];
        let mut conflict = vec![false; cells * cells];
        for (j, &tw) in total_w.iter().enumerate().take(stencils.len()) {
            for (k, w) in stencils.entries(j) {
                sample[fill[k]] = j as u32;
                weight[fill[k]] = w;
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
    pub u: Vec<f64>,
    /// The point's weight in the sample's G(theta_o).
    pub v: Vec<f64>,
    /// Whether any sample with non-zero weight touches the point.
    pub has_data: Vec<bool>,
}

impl GIncidence {
    /// The CSR range of point k.
    pub fn entries(&self, k: usize) -> std::ops::Range<usize> {
        self.start[k]..self.start[k + 1]
    }

    fn build(nodes: usize, gi: &StencilTable, go: &StencilTable, total_w: &[f64]) -> Self {
        const MAX_TOUCHED: usize = 2 * crate::grid::MAX_SUPPORT;
        let mut per_node: Vec<Vec<(u32, f64, f64)>> = vec![Vec::new(); nodes];
        for j in 0..gi.len() {
            let mut touched = [(usize::MAX, 0.0, 0.0); MAX_TOUCHED];
            let mut n = 0;
            for (k, w) in gi.entries(j) {
                touched[n] = (k, w, 0.0);
                n += 1;
            }
            for (k, w) in go.entries(j) {
                match touched[..n].iter_mut().find(|t| t.0 == k) {
                    Some(t) => t.2 = w,
                    None => {
                        touched[n] = (k, 0.0, w);
                        n += 1;
                    }
                }
            }
            for &(k, u, v) in &touched[..n] {
                per_node[k].push((j as u32, u, v));
            }
        }
        let mut g = GIncidence {
            start: vec![0],
            ..Default::default()
        };
        for list in per_node {
            let mut data = false;
            for (j, u, v) in list {
                g.sample.push(j);
                g.u.push(u);
                g.v.push(v);
                data |= total_w[j as usize] > 0.0;
            }
            g.has_data.push(data);
            g.start.push(g.sample.len());
        }
        g
    }
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

struct Raw {
    key: (i64, i64, i64, i64),
    y: [f64; 3],
    w: [f64; 3],
    theta_i: f64,
    theta_o: f64,
    phi_i: f64,
    phi_o: f64,
    theta_h: f64,
    phi_h: f64,
    theta_d: f64,
    phi_d: f64,
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
        layout.validate()?;
        if !samples.isotropic && layout.is_isotropic() {
            return Err(SampleError::AnisotropicData(samples.source.clone()));
        }
        let merge = samples.isotropic && layout.is_isotropic();
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
        let cut = options.max_theta_deg.to_radians();
        let mut stats = SampleStats {
            input: samples.samples.len(),
            ..Default::default()
        };
        let q = |x: f64| (x * 1e7).round() as i64;
        let mut raws: Vec<Raw> = Vec::with_capacity(samples.samples.len());
        for (index, s) in samples.samples.iter().enumerate() {
            if let Some(&value) = s.rgb.iter().find(|v| !v.is_finite() || **v < 0.0) {
                return Err(SampleError::BadValue {
                    source_name: samples.source.clone(),
                    index,
                    value,
                });
            }
            let a = &s.angles;
            let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
            if a.theta_i > cut || a.theta_o > cut || ci <= 0.0 || co <= 0.0 {
                stats.cut += 1;
                continue;
            }
            let w = s.rgb.map(|v| options.weight(v, ci));
            // G(in) G(out) is symmetric in the two directions, so ordering
            // each pair by elevation (azimuths travel with their elevation)
            // changes no model value.
            let ((lo, plo), (hi, phi)) = if a.theta_i <= a.theta_o {
                ((a.theta_i, a.phi_i), (a.theta_o, a.phi_o))
            } else {
                ((a.theta_o, a.phi_o), (a.theta_i, a.phi_i))
            };
            raws.push(Raw {
                key: (q(a.theta_h), q(a.theta_d), q(lo), q(hi)),
                y: s.rgb,
                w,
                theta_i: lo,
                theta_o: hi,
                phi_i: plo,
                phi_o: phi,
                theta_h: a.theta_h,
                phi_h: a.phi_h,
                theta_d: a.theta_d,
                phi_d: a.phi_d,
            });
        }
        if raws.is_empty() {
            return Err(SampleError::Empty {
                source_name: samples.source.clone(),
                input: stats.input,
                cut: stats.cut,
                max_theta_deg: options.max_theta_deg,
            });
        }
        // Merge reciprocal partners (first occurrence keeps its place).
        let mut merged: Vec<Raw> = Vec::with_capacity(raws.len());
        let mut offset = 0.0;
        if merge {
            let mut seen: HashMap<(i64, i64, i64, i64), usize> = HashMap::with_capacity(raws.len());
            for r in raws {
                match seen.get(&r.key) {
                    Some(&i) => {
                        let m = &mut merged[i];
                        for c in 0..3 {
                            let wsum = m.w[c] + r.w[c];
                            if wsum > 0.0 {
                                offset += m.w[c] * r.w[c] * (m.y[c] - r.y[c]).powi(2) / wsum;
                                m.y[c] = (m.w[c] * m.y[c] + r.w[c] * r.y[c]) / wsum;
                            }
                            m.w[c] = wsum;
                        }
                        stats.merged_pairs += 1;
                    }
                    None => {
                        seen.insert(r.key, merged.len());
                        merged.push(r);
                    }
                }
            }
        } else {
            merged = raws;
        }
        // Order by theta_i then theta_o: the G control-point lists then read
        // memory mostly forward.
        merged.sort_by(|a, b| {
            a.key
                .2
                .cmp(&b.key.2)
                .then(a.key.3.cmp(&b.key.3))
                .then(a.key.0.cmp(&b.key.0))
                .then(a.key.1.cmp(&b.key.1))
        });
        stats.fitted = merged.len();
        let n = merged.len();
        let mut set = FitSet {
            layout,
            options,
            y: Vec::with_capacity(n),
            w: Vec::with_capacity(n),
            inv_cc: Vec::with_capacity(n),
            dirs: Vec::with_capacity(n),
            d_st: StencilTable::with_capacity(layout.d.stencil_width(), n),
            f_st: StencilTable::with_capacity(layout.f.stencil_width(), n),
            gi_st: StencilTable::with_capacity(layout.g.stencil_width(), n),
            go_st: StencilTable::with_capacity(layout.g.stencil_width(), n),
            d_inc: Incidence::default(),
            f_inc: Incidence::default(),
            g_inc: GIncidence::default(),
            objective_offset: offset,
            stats,
        };
        let g_free = last_free_g_node(&layout, cut);
        let d_free = last_free_node(&layout.d.theta, options.max_theta_h_deg.to_radians());
        let n_g = layout.g.n_theta();
        let g_ramp = move |k: usize| (n_g - 1 - k) as f64 / (n_g - 1 - g_free) as f64;
        let (dg, fg, gg): (Grid, Grid, Grid) = (layout.d, layout.f, layout.g);
        for r in &merged {
            set.y.push(r.y);
            set.w.push(r.w);
            set.inv_cc.push(1.0 / (r.theta_i.cos() * r.theta_o.cos()));
            set.dirs.push([
                r.theta_i as f32,
                r.theta_o as f32,
                (r.phi_i - r.phi_o).cos() as f32,
            ]);
            let d = fold_tail(dg.theta.stencil(r.theta_h), d_free, |_| 1.0);
            set.d_st.push(&dg.extend(d, r.phi_h));
            set.f_st.push(&fg.stencil(r.theta_d, r.phi_d));
            let gi = fold_tail(gg.theta.stencil(r.theta_i), g_free, g_ramp);
            set.gi_st.push(&gg.extend(gi, r.phi_i));
            let go = fold_tail(gg.theta.stencil(r.theta_o), g_free, g_ramp);
            set.go_st.push(&gg.extend(go, r.phi_o));
        }
        let total_w: Vec<f64> = set.w.iter().map(|w| w.iter().sum()).collect();
        set.d_inc = Incidence::build(layout.d.len(), &set.d_st, &total_w);
        set.f_inc = Incidence::build(layout.f.len(), &set.f_st, &total_w);
        set.g_inc = GIncidence::build(layout.g.len(), &set.gi_st, &set.go_st, &total_w);
        Ok(set)
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
        let inc = |i: &Incidence| i.sample.len() * 12 + i.start.len() * 8;
        self.len() * per_sample
            + st
            + inc(&self.d_inc)
            + inc(&self.f_inc)
            + self.g_inc.sample.len() * 20
    }
}
