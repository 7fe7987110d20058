//! The sample set of a MERL table, built from its grid.
//!
//! The generic build ([`FitSet::build_for`]) sorts 1.1 M (key, index) pairs
//! to find reciprocal partners and reads each sample's 88-byte record twice
//! in that scattered order. On a MERL table neither is needed: two samples
//! can only merge when their keys (theta_h, theta_d, and the sorted pair
//! of elevations, each to 1e-7 rad) are equal, and the grid's rows of one
//! (theta_h, theta_d) have distinct half and difference angles, so every
//! merge lies within one row of at most 180 samples. Each row is sorted on
//! its own (the generic order restricted to the row), its runs merged as
//! the generic build merges them (first member by index, the others folded
//! in index order), and D's stencils (theta_h only) and F's (theta_d only)
//! are computed once per row and copied. The result is the generic set with
//! its samples in grid-row order: the same merged samples, values, weights,
//! stencils and objective offset, bit for bit; only the order differs.
//! That order puts each D cell's samples (one theta_h band) together and
//! each F cell's in 90 runs, so D and F passes read memory forward.

use super::incidence::GUse;
use super::incidence::{GIncidence, Incidence};
use super::order::key_part;
use super::set::{check_options, merge_into, outside_cut, FitSet, SampleError, SampleStats, Tails};
use super::weighting::{pool_limit, SampleOptions};
use crate::grid::{Grid, Stencil, StencilTable};
use crate::model::Layout;
use npf_data_loaders::merl::MERL_ROWS;
use npf_data_loaders::MerlTable;
use npf_data_loaders::{MeasuredSamples, MerlSamples};
use rayon::prelude::*;

/// Runs of equal keys in one theta_h band of the grid (90 rows), in the
/// generic order restricted to each row.
#[derive(Default)]
struct Band {
    /// The band's kept samples, each row's sorted by (key, index).
    order: Vec<u32>,
    /// Where each run (a merged sample) starts in `order`; one past the
    /// last run at the end.
    runs: Vec<u32>,
}

impl FitSet {
    /// [`FitSet::build_for`] of a MERL table's samples, from its grid: the
    /// same set (see the module's note) in grid-row order, without the
    /// samples' records. Layouts that are not isotropic (no merging, 2-D
    /// stencils) take the generic build on the records.
    pub fn build_merl(
        m: &MerlSamples,
        layout: Layout,
        options: SampleOptions,
        g_use: GUse,
    ) -> Result<Self, SampleError> {
        if !layout.is_isotropic() {
            let records = MeasuredSamples {
                source: m.source().to_string(),
                isotropic: true,
                samples: (0..m.len()).into_par_iter().map(|i| m.sample(i)).collect(),
                missing: m.missing(),
            };
            return Self::build_for(&records, layout, options, g_use);
        }
        check_options(&layout, &options)?;
        let mut lap = crate::phases::Lap::new("set (grid)", m.len());
        let cut = options.max_theta_deg.to_radians();
        let mut stats = SampleStats {
            input: m.len(),
            ..Default::default()
        };
        let bad = |v: &f64| !v.is_finite() || *v < 0.0;
        if let Some(index) = (0..m.len())
            .into_par_iter()
            .position_first(|i| m.rgb(i).iter().any(bad))
        {
            let value = m.rgb(index).into_iter().find(bad).unwrap_or(f64::NAN);
            return Err(SampleError::BadValue {
                source_name: m.source().to_string(),
                index,
                value,
            });
        }
        lap.done("check values");
        let pooled = pooled_rows(m, &options, cut);
        lap.done("pooled scales");
        let rows_per_band = MerlTable::RES_THETA_D;
        let bands: Vec<Band> = (0..MerlTable::RES_THETA_H)
            .into_par_iter()
            .map(|i_th| {
                let mut band = Band::default();
                let mut keyed: Vec<(u32, u32, u32)> = Vec::with_capacity(MerlTable::RES_PHI_D);
                for row in i_th * rows_per_band..(i_th + 1) * rows_per_band {
                    keyed.clear();
                    for i in m.row(row) {
                        let [ti, to] = m.theta(i);
                        if outside_cut(ti, cut) || outside_cut(to, cut) {
                            continue;
                        }
                        let (lo, hi) = if ti > to { (to, ti) } else { (ti, to) };
                        keyed.push((key_part(lo), key_part(hi), i as u32));
                    }
                    keyed.sort_unstable();
                    for (k, &(lo, hi, i)) in keyed.iter().enumerate() {
                        if k == 0 || (keyed[k - 1].0, keyed[k - 1].1) != (lo, hi) {
                            band.runs.push(band.order.len() as u32);
                        }
                        band.order.push(i);
                    }
                }
                band.runs.push(band.order.len() as u32);
                band
            })
            .collect();
        let kept: usize = bands.iter().map(|b| b.order.len()).sum();
        let n: usize = bands.iter().map(|b| b.runs.len() - 1).sum();
        lap.done("rows");
        stats.cut = stats.input - kept;
        if kept == 0 {
            return Err(SampleError::Empty {
                source_name: m.source().to_string(),
                input: stats.input,
                cut: stats.cut,
                max_theta_deg: options.max_theta_deg,
            });
        }
        stats.merged_pairs = kept - n;
        stats.fitted = n;
        let tails = Tails::new(&layout, &options);
        let (dg, fg, gg): (Grid, Grid, Grid) = (layout.d, layout.f, layout.g);
        // D's stencil per theta_h row, F's per theta_d row (phi_h = 0 and
        // 1-D tables: the generic build's per-sample stencils, computed once;
        // `Grid::extend` leaves a 1-D table's theta stencil as it is).
        let node = |i_th, i_td| MerlTable::node_angles(i_th, i_td, 0);
        let d_rows: Vec<Stencil> = (0..MerlTable::RES_THETA_H)
            .map(|i_th| dg.extend(tails.d(node(i_th, 0).0), 0.0))
            .collect();
        let f_rows: Vec<Stencil> = (0..MerlTable::RES_THETA_D)
            .map(|i_td| fg.stencil(node(0, i_td).1, 0.0))
            .collect();
        let (mut y, mut w) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let (mut inv_cc, mut dirs) = (vec![0.0; n], vec![[0.0f32; 3]; n]);
        let mut d_st = StencilTable::zeroed(dg.stencil_width(), n);
        let mut f_st = StencilTable::zeroed(fg.stencil_width(), n);
        let mut gi_st = StencilTable::zeroed(gg.stencil_width(), n);
        let mut go_st = StencilTable::zeroed(gg.stencil_width(), n);
        // Each band's own part of every output array.
        let mut parts = Vec::with_capacity(bands.len());
        {
            let (mut y, mut w, mut inv_cc, mut dirs) =
                (&mut y[..], &mut w[..], &mut inv_cc[..], &mut dirs[..]);
            let mut tables = [&mut d_st, &mut f_st, &mut gi_st, &mut go_st].map(|t| {
                let width = t.width;
                (width, &mut t.idx[..], &mut t.w[..])
            });
            for band in &bands {
                let len = band.runs.len() - 1;
                let (y0, y1) = y.split_at_mut(len);
                let (w0, w1) = w.split_at_mut(len);
                let (c0, c1) = inv_cc.split_at_mut(len);
                let (r0, r1) = dirs.split_at_mut(len);
                (y, w, inv_cc, dirs) = (y1, w1, c1, r1);
                let st = tables.each_mut().map(|(width, idx, wt)| {
                    let (i0, i1) = std::mem::take(idx).split_at_mut(len * *width);
                    let (w0, w1) = std::mem::take(wt).split_at_mut(len * *width);
                    (*idx, *wt) = (i1, w1);
                    (*width, i0, w0)
                });
                parts.push((band, y0, w0, c0, r0, st));
            }
        }
        let limit = pool_limit(&options);
        // A sample's value and weights, as the generic build's `value_at`.
        let value_at = |i: usize, cos_i: f64| {
            let rgb = m.rgb(i);
            let [ti, to] = m.theta(i);
            let t = options.taper(ti.max(to));
            let row = m.cell(i) / MerlTable::RES_PHI_D;
            let (th, _) = m.half_diff(i);
            let scale = match limit {
                Some(limit) if th < limit => pooled[row].unwrap_or(rgb),
                _ => rgb,
            };
            (rgb, scale.map(|v| options.weight(v, cos_i) * t))
        };
        // Per band: the shares of the offset of its merged members, by
        // member index.
        let shares: Vec<Vec<(u32, [f64; 3])>> = parts
            .into_par_iter()
            .map(|(band, y, w, inv_cc, dirs, mut st)| {
                let mut shares = Vec::new();
                for (k, run) in band.runs.windows(2).enumerate() {
                    let members = &band.order[run[0] as usize..run[1] as usize];
                    let first = members[0] as usize;
                    let [t_i, t_o] = m.theta(first);
                    let (ci, co) = (t_i.cos(), t_o.cos());
                    let (ti, to) = if t_i > t_o { (t_o, t_i) } else { (t_i, t_o) };
                    inv_cc[k] = 1.0 / (ci * co);
                    dirs[k] = [
                        ti as f32,
                        to as f32,
                        cos_azimuth_difference(m, first) as f32,
                    ];
                    (y[k], w[k]) = value_at(first, ci);
                    for &index in &members[1..] {
                        let index = index as usize;
                        let (ry, rw) = value_at(index, m.theta(index)[0].cos());
                        shares.push((index as u32, merge_into(&mut y[k], &mut w[k], ry, rw)));
                    }
                    let cell = m.cell(first);
                    let row = cell / MerlTable::RES_PHI_D;
                    let (i_th, i_td) = (row / rows_per_band, row % rows_per_band);
                    let gi_theta = tails.g(ti);
                    let go_theta = tails.g(to);
                    let stencils = [&d_rows[i_th], &f_rows[i_td], &gi_theta, &go_theta];
                    for ((width, idx, wt), s) in st.iter_mut().zip(stencils) {
                        let r = k * *width..(k + 1) * *width;
                        StencilTable::store(s, &mut idx[r.clone()], &mut wt[r]);
                    }
                }
                shares.sort_unstable_by_key(|s| s.0);
                shares
            })
            .collect();
        // Summed in input order of the members, as the generic build sums.
        let mut offset = 0.0;
        for (_, share) in shares.iter().flatten() {
            for v in share {
                offset += v;
            }
        }
        drop((shares, bands));
        lap.done("merge + stencils");
        // The generic build's set, its samples in another order.
        let values = (y, w, inv_cc, dirs);
        let stencils = [d_st, f_st, gi_st, go_st];
        let set = FitSet::assembled((layout, options), values, stencils, (offset, stats));
        Ok(set.with_incidences(g_use, &mut lap))
    }
}

/// cos(phi_i - phi_o) of sample i, symmetric in the two directions (so
/// unchanged by the generic build's swap), from the directions' horizontal
/// parts: the generic build's cos(atan2 - atan2) without its two atan2
/// calls, equal to it in f64 up to rounding (a few 1e-16), so equal in the
/// f32 the set stores but for an f32 ulp in rare cases. Straight up (no
/// horizontal part, azimuth 0 by atan2's convention for +0) it takes the
/// generic path's formula.
fn cos_azimuth_difference(m: &MerlSamples, i: usize) -> f64 {
    let (wi, wo) = m.directions(i);
    let r = |w: [f64; 3]| (w[0] * w[0] + w[1] * w[1]).sqrt();
    let (ri, ro) = (r(wi), r(wo));
    if ri > 0.0 && ro > 0.0 {
        ((wi[0] * wo[0] + wi[1] * wo[1]) / (ri * ro)).clamp(-1.0, 1.0)
    } else {
        (wi[1].atan2(wi[0]) - wo[1].atan2(wo[0])).cos()
    }
}

/// The generic build's pooled scales per grid row: the mean value of the
/// row's samples inside the cut-off (summed in sample order), for rows
/// below the pooling angle that have any; `None` elsewhere.
fn pooled_rows(m: &MerlSamples, o: &SampleOptions, cut: f64) -> Vec<Option<[f64; 3]>> {
    let mut rows = vec![None; MERL_ROWS];
    let Some(limit) = pool_limit(o) else {
        return rows;
    };
    for (row, mean) in rows.iter_mut().enumerate() {
        let (th, _, _) = MerlTable::node_angles(row / MerlTable::RES_THETA_D, 0, 0);
        if th >= limit {
            break;
        }
        let (mut sum, mut count) = ([0.0; 3], 0usize);
        for i in m.row(row) {
            let [ti, to] = m.theta(i);
            if ti <= cut && to <= cut {
                let rgb = m.rgb(i);
                for c in 0..3 {
                    sum[c] += rgb[c];
                }
                count += 1;
            }
        }
        if count > 0 {
            *mean = Some(sum.map(|v| v / count as f64));
        }
    }
    rows
}

/// Test support: whether two sets are the same up to the order of their
/// samples (the grid path's set against the generic one): the same
/// samples (values, weights, geometric terms, stencils; cos(phi_i - phi_o)
/// to an f32 ulp), the same objective offset and counts, and the same
/// incidence lists and colourings under the samples' correspondence.
/// `Err` says what differs first.
#[doc(hidden)]
pub fn same_up_to_order(a: &FitSet, b: &FitSet) -> Result<(), String> {
    if a.len() != b.len() || a.stats != b.stats {
        return Err(format!("counts differ: {:?} vs {:?}", a.stats, b.stats));
    }
    if a.objective_offset.to_bits() != b.objective_offset.to_bits() {
        return Err(format!(
            "objective offsets differ: {:e} vs {:e}",
            a.objective_offset, b.objective_offset
        ));
    }
    // Every sample's exact content but cos(phi_i - phi_o), as bits.
    let key = |s: &FitSet, j: usize| {
        let mut k: Vec<u64> = s.y[j].iter().chain(&s.w[j]).map(|v| v.to_bits()).collect();
        k.push(s.inv_cc[j].to_bits());
        k.extend(s.dirs[j][..2].iter().map(|v| v.to_bits() as u64));
        for t in [&s.d_st, &s.f_st, &s.gi_st, &s.go_st] {
            let r = j * t.width..(j + 1) * t.width;
            k.extend(t.idx[r.clone()].iter().map(|&i| i as u64));
            k.extend(t.w[r].iter().map(|w| w.to_bits() as u64));
        }
        k
    };
    let ranked = |s: &FitSet| {
        let mut keyed: Vec<(Vec<u64>, usize)> = (0..s.len()).map(|j| (key(s, j), j)).collect();
        keyed.sort_unstable();
        let mut rank = vec![0usize; s.len()];
        for (r, (_, j)) in keyed.iter().enumerate() {
            rank[*j] = r;
        }
        (keyed, rank)
    };
    let ((ka, ra), (kb, rb)) = (ranked(a), ranked(b));
    for ((x, ja), (y, jb)) in ka.iter().zip(&kb) {
        if x != y {
            return Err(format!(
                "sample {ja} (first set) has no equal in the second"
            ));
        }
        let (ca, cb) = (a.dirs[*ja][2], b.dirs[*jb][2]);
        if (ca.to_bits() as i64 - cb.to_bits() as i64).abs() > 1 {
            return Err(format!("cos(phi_i - phi_o) {ca} vs {cb}"));
        }
    }
    let lists = |rank: &[usize], inc: &Incidence| {
        (0..inc.start.len() - 1)
            .map(|k| {
                let mut l: Vec<(usize, u32)> = inc
                    .entries(k)
                    .map(|e| (rank[inc.sample[e] as usize], inc.weight[e].to_bits()))
                    .collect();
                l.sort_unstable();
                l
            })
            .collect::<Vec<_>>()
    };
    for (name, ia, ib) in [("D", &a.d_inc, &b.d_inc), ("F", &a.f_inc, &b.f_inc)] {
        if lists(&ra, ia) != lists(&rb, ib) || ia.has_data != ib.has_data || ia.colors != ib.colors
        {
            return Err(format!("{name} incidences differ"));
        }
    }
    let g_lists = |rank: &[usize], g: &GIncidence| {
        (0..g.start.len() - 1)
            .map(|k| {
                let mut l: Vec<(usize, u32, u32)> = g
                    .entries(k)
                    .map(|e| {
                        (
                            rank[g.sample[e] as usize],
                            g.u[e].to_bits(),
                            g.v[e].to_bits(),
                        )
                    })
                    .collect();
                l.sort_unstable();
                l
            })
            .collect::<Vec<_>>()
    };
    if g_lists(&ra, &a.g_inc) != g_lists(&rb, &b.g_inc) || a.g_inc.has_data != b.g_inc.has_data {
        return Err("G incidences differ".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::Weighting;

    /// A synthetic table with scattered missing cells.
    fn table() -> MerlTable {
        let truth = crate::synth::known_factor_model(Layout::default(), &[0.05, 0.3]);
        let mut raw = crate::reconstruct::to_merl(&truth).raw().to_vec();
        for at in (0..MerlTable::CELLS).step_by(7919) {
            raw[at] = -1.0;
        }
        MerlTable::from_raw(raw)
    }

    /// The grid path's set is the generic build's up to sample order,
    /// under the default options, a taper with a wider cut-off and pooling
    /// angle, and the plain L2 weighting; and it is the same for any
    /// thread count.
    #[test]
    fn the_grid_set_is_the_generic_set_in_another_order() {
        let t = table();
        let samples = t.samples("t");
        let grid = MerlSamples::new(t, "t");
        let layout = Layout::default();
        let wide = SampleOptions {
            max_theta_deg: 89.0,
            taper_from_deg: Some(80.0),
            pool_scale_below_deg: Some(12.0),
            ..Default::default()
        };
        let plain = SampleOptions {
            weighting: Weighting::CosineL2,
            ..Default::default()
        };
        for so in [SampleOptions::default(), wide, plain] {
            let generic = FitSet::build_for(&samples, layout, so, GUse::Updated).unwrap();
            let sets: Vec<FitSet> = [1, 3]
                .map(|threads| {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    pool.install(|| FitSet::build_merl(&grid, layout, so, GUse::Updated).unwrap())
                })
                .into();
            assert!(generic.stats.merged_pairs > 0 && generic.stats.cut > 0);
            same_up_to_order(&sets[0], &generic).unwrap();
            let (a, b) = (&sets[0], &sets[1]);
            assert!(a.y == b.y && a.w == b.w && a.inv_cc == b.inv_cc && a.dirs == b.dirs);
            assert!(
                a.d_st == b.d_st && a.f_st == b.f_st && a.gi_st == b.gi_st && a.go_st == b.go_st
            );
            assert_eq!(a.objective_offset.to_bits(), b.objective_offset.to_bits());
            assert!(a.g_inc.sample == b.g_inc.sample && a.d_inc.sample == b.d_inc.sample);
        }
    }

    /// Bad values and empty sets give the generic build's errors.
    #[test]
    fn bad_and_empty_tables_give_the_generic_errors() {
        let layout = Layout::default();
        let so = SampleOptions::default();
        let mut raw = table().raw().to_vec();
        raw[MerlTable::CELLS + MerlTable::index(40, 30, 20)] = f64::NAN;
        let t = MerlTable::from_raw(raw);
        let generic = FitSet::build(&t.samples("t"), layout, so).unwrap_err();
        let grid =
            FitSet::build_merl(&MerlSamples::new(t, "t"), layout, so, GUse::Updated).unwrap_err();
        assert!(matches!(grid, SampleError::BadValue { .. }), "{grid}");
        assert_eq!(grid.to_string(), generic.to_string());
        // Only grazing cells, all past a 10-degree cut-off.
        let t = MerlTable::from_fn(|th, td, _| (th + td > 1.2).then_some([0.1; 3]));
        let tight = SampleOptions {
            max_theta_deg: 10.0,
            ..so
        };
        let generic = FitSet::build(&t.samples("t"), layout, tight).unwrap_err();
        let grid = FitSet::build_merl(&MerlSamples::new(t, "t"), layout, tight, GUse::Updated)
            .unwrap_err();
        assert!(matches!(grid, SampleError::Empty { .. }), "{grid}");
        assert_eq!(grid.to_string(), generic.to_string());
    }
}
