//! The sampler's per-lobe tables, built once from a model: cells in
//! t = sin^2 theta_h and relative azimuth, per view angle, proportional to
//! the lobe's visible normals weighted by G and F.

use super::azimuth::PHI_CELLS;
use super::quadrature::{GL4_W, GL4_X};
use crate::model::Model;
use crate::sampling::PiecewiseConstant2D;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// Sub-cells per D-axis interval in the half-vector tables: 4 x 90 = 360
/// cells per lobe for the default layout.
pub const SUBCELLS: usize = 4;

/// Share of a view table's mass spread as plain D (times the G bound) over
/// every azimuth, whatever the view: the lobe then covers every half vector
/// where D has mass, and weights stay bounded between view nodes.
/// (2% rather than 10%: near-Lambertian fits sample better, 2x lower
/// variance on white-fabric, see docs/sampling.md.)
pub const COVERAGE_SHARE: f64 = 0.02;

/// Cells whose mass is below this fraction of the lobe's total get none:
/// never drawn, and pdf is zero there (other components still cover them).
pub const NEGLIGIBLE_CELL: f64 = 1e-6;

/// The t = sin^2 theta_h edges of the half-vector tables: every interval
/// of the D axis split into SUBCELLS parts, from t = 0 to exactly 1.
pub(super) fn t_edges(model: &Model) -> Vec<f64> {
    let axis = model.layout.d.theta;
    let end = axis.coord(FRAC_PI_2);
    let cells = (end.ceil() as usize).max(1) * SUBCELLS;
    let mut edges: Vec<f64> = (0..=cells)
        .map(|j| {
            let p = (j as f64 / SUBCELLS as f64).min(end);
            axis.angle_at(p).sin().powi(2)
        })
        .collect();
    edges[0] = 0.0;
    edges[cells] = 1.0;
    edges.dedup_by(|b, a| *b <= *a);
    edges
}

/// The guide table of [`NpfBxdf::t_cell`]: 2 entries per cell, over
/// u = t^(1/4) in [0, 1).
pub(super) fn t_guide(edges: &[f64]) -> Vec<u32> {
    let n = edges.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let g = 2 * n;
    (0..g)
        .map(|b| {
            let t = (b as f64 / g as f64).powi(4);
            (edges.partition_point(|&e| e <= t).saturating_sub(1)).min(n - 1) as u32
        })
        .collect()
}

/// Gauss-Legendre points per azimuth cell in the table masses.
pub(super) const PHI_GAUSS: usize = 2;

/// The VIEW_NODES half-vector tables of lobe m: for view node k (wo_k at
/// theta_k, azimuth 0), cell (i, j) of (t, |phi|) holds
///
///   mass = integral over the cell of D(theta_h) [ max(0, wo_k.h) / cos theta_h
///          * G+(theta_i) F(theta_d) [wi_k above the horizon] ] dt dphi
///
/// (the visible normals of D, per solid angle D max(0, wo.h), times the
/// lobe's shadowing of wi and its Fresnel luminance, both normalised by
/// their largest values; 4 x 2 Gauss-Legendre points per cell), renormalised
/// and mixed with a COVERAGE_SHARE of the view-independent D B table (B the
/// G-product bound of [`g_product_bound`]), which keeps every half vector
/// where D has mass covered at every view. Cells below NEGLIGIBLE_CELL of
/// the total get none. The tables are exactly normalised, and pdf is
/// exactly what sample draws, whatever the quadrature's accuracy.
pub(super) fn lobe_tables(
    model: &Model,
    m: usize,
    edges: &[f64],
) -> Option<Vec<PiecewiseConstant2D>> {
    let lobe = &model.lobes[m];
    let (d_axis, g_axis, f_axis) = (
        model.layout.d.theta,
        model.layout.g.theta,
        model.layout.f.theta,
    );
    if edges.len() < 2 {
        return None;
    }
    let bound = g_product_bound(model, &lobe.g);
    let b_max = bound(0.0);
    if !(b_max > 0.0 && b_max.is_finite()) {
        return None;
    }
    // G+ and the lobe's Fresnel luminance (with its scales), normalised.
    let g_plus = |theta: f64| g_axis.stencil(theta).apply_f32(&lobe.g).max(0.0);
    let f_lum: Vec<f32> = (0..model.fresnel[0].len())
        .map(|k| {
            (0..3)
                .map(|c| LUMINANCE[c] * lobe.s[c] as f64 * model.fresnel[c][k] as f64)
                .sum::<f64>() as f32
        })
        .collect();
    let g_max = (0..=360)
        .map(|k| g_plus(k as f64 / 360.0 * FRAC_PI_2))
        .fold(0.0, f64::max);
    let f_max = f_lum.iter().copied().fold(0.0f32, f32::max) as f64;
    let nx = edges.len() - 1;
    let dphi = PI / PHI_CELLS as f64;
    // Gauss points in t per cell: (t, weight, D, D B, sin_h, cos_h).
    let mut points = Vec::with_capacity(nx * 4);
    for w in edges.windows(2) {
        let (a, b) = (w[0], w[1]);
        for (x, wt) in GL4_X.iter().zip(GL4_W) {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let theta = t.sqrt().min(1.0).asin();
            let d = d_axis.stencil(theta).apply_f32(&lobe.d).max(0.0);
            let db = d * (bound(theta) / b_max).min(1.0);
            points.push((
                0.5 * (b - a) * wt,
                d,
                db,
                t.sqrt(),
                (1.0 - t).max(0.0).sqrt(),
            ));
        }
    }
    // The view-independent coverage part (per cell; uniform in phi).
    let cover: Vec<f64> = points
        .chunks(4)
        .map(|p| p.iter().map(|q| q.0 * q.2).sum())
        .collect();
    let cover_total: f64 = cover.iter().sum();
    if !(cover_total > 0.0 && cover_total.is_finite()) {
        return None;
    }
    let shaped = g_max > 0.0 && f_max > 0.0;
    // Views are independent: build them in parallel (each table is the
    // same whatever the thread count).
    let view_table = |k: usize| -> Option<PiecewiseConstant2D> {
        let (sin_o, cos_o) = view_angle(k).sin_cos();
        let mut mass = vec![0.0; nx * PHI_CELLS];
        if shaped {
            for (i, cell) in points.chunks(4).enumerate() {
                for &(wt, d, _, sin_h, cos_h) in cell {
                    if !(d > 0.0 && cos_h > 0.0) {
                        continue;
                    }
                    for j in 0..PHI_CELLS {
                        let mut acc = 0.0;
                        for g in 0..PHI_GAUSS {
                            let x = if PHI_GAUSS == 2 {
                                [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8][g]
                            } else {
                                0.0
                            };
                            let phi = (j as f64 + 0.5 + 0.5 * x) * dphi;
                            let h = [sin_h * phi.cos(), sin_h * phi.sin(), cos_h];
                            let wo_h = sin_o * h[0] + cos_o * h[2];
                            let wi_z = 2.0 * wo_h * cos_h - cos_o;
                            if !(wo_h > 0.0 && wi_z > 0.0) {
                                continue;
                            }
                            let theta_i = wi_z.min(1.0).acos();
                            let theta_d = wo_h.min(1.0).acos();
                            let gi = g_plus(theta_i) / g_max;
                            let fd = f_axis.stencil(theta_d).apply_f32(&f_lum).max(0.0) / f_max;
                            acc += wo_h / cos_h * gi * fd / PHI_GAUSS as f64;
                        }
                        mass[i * PHI_CELLS + j] += wt * d * acc * dphi;
                    }
                }
            }
        }
        let total: f64 = mass.iter().sum();
        let (main, share) = if total > 0.0 && total.is_finite() {
            (1.0 / total, COVERAGE_SHARE)
        } else {
            (0.0, 1.0)
        };
        for (i, &c) in cover.iter().enumerate() {
            for j in 0..PHI_CELLS {
                let v = &mut mass[i * PHI_CELLS + j];
                *v = *v * main * (1.0 - share) + share * c / cover_total / PHI_CELLS as f64;
            }
        }
        for v in mass.iter_mut() {
            if *v < NEGLIGIBLE_CELL / PHI_CELLS as f64 {
                *v = 0.0;
            }
        }
        PiecewiseConstant2D::new(edges.to_vec(), PHI_CELLS, PI, &mass)
    };
    (0..VIEW_NODES).into_par_iter().map(view_table).collect()
}

/// The largest |G(theta_i) G(theta_o)| over the configurations with half
/// angle theta_h, on a 1/8-degree grid: the half vector is the geodesic
/// midpoint of wi and wo, so theta_i + theta_o >= 2 theta_h, each at most
/// pi/2. (On the grid, not a strict bound between grid points; it only
/// weights the table, so the sampler stays exact whatever its accuracy.)
pub(super) fn g_product_bound(model: &Model, g: &[f32]) -> impl Fn(f64) -> f64 {
    const STEPS: usize = 720;
    let step = FRAC_PI_2 / STEPS as f64;
    let gv: Vec<f64> = (0..=STEPS)
        .map(|k| {
            model
                .layout
                .g
                .theta
                .stencil(k as f64 * step)
                .apply_f32(g)
                .abs()
        })
        .collect();
    // suffix[k] = max of gv over [k, STEPS].
    let mut suffix = gv.clone();
    for k in (0..STEPS).rev() {
        suffix[k] = suffix[k].max(suffix[k + 1]);
    }
    // table[s]: the bound when theta_i + theta_o >= s steps.
    let table: Vec<f64> = (0..=2 * STEPS)
        .map(|s| {
            let lo = s.saturating_sub(STEPS);
            (lo..=STEPS)
                .map(|a| gv[a] * suffix[s.saturating_sub(a).min(STEPS)])
                .fold(0.0, f64::max)
        })
        .collect();
    move |theta_h: f64| {
        // Round the sum limit down (a smaller limit gives a larger bound).
        let s = ((2.0 * theta_h / step).floor().max(0.0) as usize).min(2 * STEPS);
        table[s]
    }
}

/// View angles at which the lobe-selection probabilities are tabulated,
/// theta_o = k / (VIEW_NODES - 1) * VIEW_MAX_DEG, linear in between.
pub const VIEW_NODES: usize = 16;

pub(super) const VIEW_MAX_DEG: f64 = 89.0;

pub(super) fn view_angle(k: usize) -> f64 {
    (k as f64 / (VIEW_NODES - 1) as f64 * VIEW_MAX_DEG).to_radians()
}

/// Rec. 709 luminance, which weighs the three channels into one selection.
pub(super) const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];
