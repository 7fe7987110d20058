//! The tables of the exported sampler, computed once at export time and
//! written next to the factor tables. Everything is stored as f32, and the
//! generated `sample` and `pdf` read the same stored values, so the pdf is
//! exactly the density `sample` draws with whatever the rounding.

use crate::bsdf::{half_vector_quadrature, GL4_W, GL4_X};
use crate::model::{DiffuseForm, Model};
use npf_data_loaders::geometry::Angles;
use std::f64::consts::{FRAC_PI_2, PI};

/// Cells per D-axis interval of the half-vector tables.
const SUBCELLS: usize = 4;
/// View angles of the selection table: theta_o = k / (VIEWS - 1) * VIEW_MAX_DEG.
pub(super) const VIEWS: usize = 16;
/// The last view angle of the selection table (degrees).
pub(super) const VIEW_MAX_DEG: f64 = 89.0;
/// Least selection probability of a component with mass (before
/// renormalisation), so the mixture covers all of f.
const FLOOR: f64 = 0.01;
/// Strata of the albedo quadrature behind the selection (u; twice in phi).
const ALBEDO_GRID: usize = 48;
/// Rec. 709 luminance weighs the channels into one selection.
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The exported sampler's tables.
#[derive(Clone, Debug, PartialEq)]
pub struct SamplerTables {
    /// Cell edges in t = sin^2 theta_h, strictly increasing from 0 to 1
    /// (shared by every lobe: the D axis is).
    pub edges: Vec<f32>,
    /// Per lobe, the cdf at the edges (0 to exactly 1; all 0 for a lobe
    /// without mass), lobes one after the other.
    pub cdf: Vec<f32>,
    /// Whether lobe m has a half-vector table (it is never chosen otherwise).
    pub has_table: Vec<bool>,
    /// Selection probabilities, VIEWS rows of (1 + lobes), diffuse first.
    pub selection: Vec<f32>,
}

fn luminance(v: [f64; 3]) -> f64 {
    v.iter().zip(LUMINANCE).map(|(a, b)| a * b).sum()
}

impl SamplerTables {
    /// The tables of a valid model.
    pub fn new(model: &Model) -> Self {
        let edges = edges(model);
        let mut cdf = Vec::with_capacity(edges.len() * model.lobes.len());
        let mut has_table = Vec::new();
        for lobe in &model.lobes {
            let c = if lobe.s.iter().all(|&s| s <= 0.0) {
                None
            } else {
                lobe_cdf(model, &edges, &lobe.d, &lobe.g)
            };
            has_table.push(c.is_some());
            cdf.extend(c.unwrap_or_else(|| vec![0.0; edges.len()]));
        }
        let selection = selection(model, &has_table);
        SamplerTables {
            edges,
            cdf,
            has_table,
            selection,
        }
    }
}

/// SUBCELLS cells per D-axis interval, as f32 and deduplicated after the
/// rounding (so the stored cells are never empty).
fn edges(model: &Model) -> Vec<f32> {
    let axis = model.layout.d.theta;
    let end = axis.coord(FRAC_PI_2);
    let cells = (end.ceil() as usize).max(1) * SUBCELLS;
    let mut e: Vec<f32> = (0..=cells)
        .map(|j| {
            let p = (j as f64 / SUBCELLS as f64).min(end);
            axis.angle_at(p).sin().powi(2) as f32
        })
        .collect();
    e[0] = 0.0;
    e[cells] = 1.0;
    e.dedup_by(|b, a| *b <= *a);
    e
}

/// A bound of |G(theta_i) G(theta_o)| over the configurations of half angle
/// theta_h, divided by its value at 0: one of theta_i, theta_o is at least
/// theta_h, so max_{theta >= theta_h} |G| times max |G| bounds it. It only
/// keeps a D that is huge where G vanishes (a fitted far tail) from taking
/// the lobe's draws; any positive weight keeps the sampler exact.
fn g_weight(model: &Model, g: &[f32]) -> Option<impl Fn(f64) -> f64> {
    const STEPS: usize = 720;
    let step = FRAC_PI_2 / STEPS as f64;
    let axis = model.layout.g.theta;
    let g_at = |theta: f64| axis.stencil(theta).apply_f32(g).abs();
    // tail[k] = max of |G| over [k step, pi/2].
    let mut tail: Vec<f64> = (0..=STEPS).map(|k| g_at(k as f64 * step)).collect();
    for k in (0..STEPS).rev() {
        tail[k] = tail[k].max(tail[k + 1]);
    }
    let top = tail[0];
    (top > 0.0 && top.is_finite()).then_some(move |theta_h: f64| {
        let k = ((theta_h / step).floor().max(0.0) as usize).min(STEPS);
        tail[k] / top
    })
}

/// The cdf of one lobe's cells: mass = integral of D * weight dt over the
/// cell (4-point Gauss-Legendre), cells under 1e-6 of the total dropped.
fn lobe_cdf(model: &Model, edges: &[f32], d: &[f32], g: &[f32]) -> Option<Vec<f32>> {
    let weight = g_weight(model, g)?;
    let axis = model.layout.d.theta;
    let mut mass: Vec<f64> = edges
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0] as f64, w[1] as f64);
            GL4_X
                .iter()
                .zip(GL4_W)
                .map(|(x, wt)| {
                    let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
                    let theta = t.sqrt().min(1.0).asin();
                    // A 2-D D: its phi-average (the column mean) at theta.
                    let dv = column_mean(model, d, theta)
                        .unwrap_or_else(|| axis.stencil(theta).apply_f32(d));
                    0.5 * (b - a) * wt * dv.max(0.0) * weight(theta)
                })
                .sum()
        })
        .collect();
    let total: f64 = mass.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    mass.iter_mut()
        .filter(|m| **m < 1e-6 * total)
        .for_each(|m| *m = 0.0);
    let total: f64 = mass.iter().sum();
    let mut acc = 0.0;
    let mut cdf = vec![0.0f32];
    for m in &mass {
        acc += m;
        cdf.push((acc / total).min(1.0) as f32);
    }
    *cdf.last_mut().expect("cells") = 1.0;
    Some(cdf)
}

/// The mean over phi of a 2-D D table at theta (None for a 1-D table).
fn column_mean(model: &Model, d: &[f32], theta: f64) -> Option<f64> {
    let grid = model.layout.d;
    let phi = grid.phi?;
    let st = grid.theta.stencil(theta);
    let n = phi.n;
    Some(
        (0..n)
            .map(|j| {
                st.entries()
                    .map(|(k, w)| w * d[k * n + j] as f64)
                    .sum::<f64>()
            })
            .sum::<f64>()
            / n as f64,
    )
}

/// Selection probabilities at the VIEWS view angles: each component's
/// directional albedo (luminance; diffuse exact, lobes by the albedo
/// quadrature), floored at FLOOR for components with mass, normalised.
fn selection(model: &Model, has_table: &[bool]) -> Vec<f32> {
    let lobes = model.lobes.len();
    let has_diffuse = model.diffuse.iter().any(|&d| d > 0.0);
    let present: Vec<bool> = std::iter::once(has_diffuse)
        .chain(has_table.iter().copied())
        .collect();
    let count = present.iter().filter(|&&p| p).count();
    let mut table = Vec::with_capacity(VIEWS * (1 + lobes));
    for k in 0..VIEWS {
        let theta_o = (k as f64 / (VIEWS - 1) as f64 * VIEW_MAX_DEG).to_radians();
        let lobe_albedo = half_vector_quadrature(
            theta_o,
            ALBEDO_GRID,
            2 * ALBEDO_GRID,
            lobes,
            |wo, wi, w, acc| {
                model.lobe_terms(&Angles::from_directions(wi, wo), |m, t| {
                    acc[m] += luminance(t).max(0.0) * w;
                });
            },
        );
        // The diffuse term's exact albedo: pi d for Lambert (as always
        // computed), pi d P(theta_o) for the separable form.
        let diffuse = match separable_p(model) {
            None => luminance(model.diffuse.map(f64::from)) * PI,
            Some(_) => luminance(model.diffuse_albedo(theta_o)),
        };
        let a: Vec<f64> = std::iter::once(diffuse)
            .chain(lobe_albedo)
            .zip(&present)
            .map(|(a, &p)| if p && a.is_finite() { a.max(0.0) } else { 0.0 })
            .collect();
        let total: f64 = a.iter().sum();
        let p: Vec<f64> = a
            .iter()
            .zip(&present)
            .map(|(&a, &p)| match (p, total > 0.0) {
                (false, _) => 0.0,
                (true, true) => (a / total).max(FLOOR),
                (true, false) => 1.0 / count as f64,
            })
            .collect();
        let sum: f64 = p.iter().sum();
        table.extend(
            p.iter()
                .map(|v| if sum > 0.0 { (v / sum) as f32 } else { 0.0 }),
        );
    }
    table
}

/// P of a separable diffuse form (the one non-Lambertian form the
/// exports evaluate).
pub(super) fn separable_p(model: &Model) -> Option<&[f32]> {
    match &model.diffuse_form {
        DiffuseForm::Separable { p } => Some(p),
        _ => None,
    }
}
