//! The weighted sample set ([`FitSet`]) and its generic build: checks,
//! stencils, tail folding and the merge of reciprocal pairs.

use crate::grid::{Axis, Grid, Stencil, StencilTable, Weight};
use crate::model::Layout;
use npf_data_loaders::MeasuredSamples;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::incidence::{DisjointWrites, GIncidence, GUse, Incidence};
use super::order::{bucket_sort, prefetch_sample, sort_key, Key, KEY_CHUNK, PIECE, PREFETCH_RUNS};
use super::source::SampleData;
use super::weighting::{pooled_scales, SampleOptions};

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

/// The layout's and the options' own checks, before any set is built.
pub(super) fn check_options(layout: &Layout, options: &SampleOptions) -> Result<(), SampleError> {
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
pub(super) struct Tails {
    layout: Layout,
    d_free: usize,
    g_free: usize,
}

impl Tails {
    pub(super) fn new(layout: &Layout, options: &SampleOptions) -> Self {
        Tails {
            layout: *layout,
            d_free: last_free_node(&layout.d.theta, options.max_theta_h_deg.to_radians()),
            g_free: last_free_g_node(layout, options.max_theta_deg.to_radians()),
        }
    }

    /// D's folded theta stencil at a half angle.
    #[inline]
    pub(super) fn d(&self, theta_h: f64) -> Stencil {
        fold_tail(self.layout.d.theta.stencil(theta_h), self.d_free, |_| 1.0)
    }

    /// G's folded theta stencil at an elevation.
    #[inline]
    pub(super) fn g(&self, theta: f64) -> Stencil {
        let (n_g, g_free) = (self.layout.g.n_theta(), self.g_free);
        let ramp = |k: usize| (n_g - 1 - k) as f64 / (n_g - 1 - g_free) as f64;
        fold_tail(self.layout.g.theta.stencil(theta), g_free, ramp)
    }
}

/// Re-express a theta stencil on tied tail entries through the last free
/// entry L: value_k = value_L * tie(k) for k > L. Applied before the phi
/// product, so in a 2-D table the tie holds per phi column.
pub(super) fn fold_tail(st: Stencil, last_free: usize, tie: impl Fn(usize) -> f64) -> Stencil {
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

/// Whether an elevation is past the cut-off (at most pi/2) or has a
/// non-positive cosine. On [0, cut] the cosine is positive, so it is only
/// computed for negative angles.
#[inline]
pub(super) fn outside_cut(theta: f64, cut: f64) -> bool {
    theta > cut || (theta < 0.0 && theta.cos() <= 0.0)
}

/// Merge sample r (value `ry`, weights `rw`) into the merged sample (y, w):
/// its share of the objective's constant part, per channel.
pub(super) fn merge_into(
    y: &mut [f64; 3],
    w: &mut [f64; 3],
    ry: [f64; 3],
    rw: [f64; 3],
) -> [f64; 3] {
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
    pub(super) fn assembled(
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
    pub(super) fn with_incidences(mut self, g_use: GUse, lap: &mut crate::phases::Lap) -> Self {
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
    use crate::samples::round_to_i64;

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
