//! The canonical form of a model, and table entries without data.
//!
//! s, D, F and G trade scale: D -> aD, s -> s/a (and likewise F per channel,
//! and G -> bG, s -> s/b^2) leave every model value unchanged. A model's one
//! canonical form:
//! - G^m: the largest control value among those constrained by data is 1
//!   (G(0) = 1 would be fragile: few samples sit near normal incidence);
//! - D^m: 2 pi * integral over theta_h <= 60 degrees of D(theta_h) cos sin
//!   dtheta_h = 1: the projected-area normalisation of a microfacet
//!   distribution, over the part of D that every lobe's data constrain.
//!   (Over the full hemisphere, a lobe whose G vanishes at grazing angles
//!   leaves its grazing D cells free; their mass then sets the scale and
//!   drives s towards overflow. Samplers normalise the full table themselves.)
//! - F_C: F_C(theta_d = 0) = 1 per channel (its maximum instead when F_C(0)
//!   is not above 1e-6 of that maximum), so s_C^m carries colour and F its
//!   angular shape.
//!
//! Entries no sample constrains are filled: D and F from the nearest entry
//! with data; G before the first constrained point takes that value, after
//! the last it holds its value up to the grazing cut-off, and past the cut
//! it ramps linearly to 0 at 90 degrees, which keeps G/cos finite.
//!
//! On a 2-D (theta, phi) table every rule acts along theta in each phi
//! column; a column no sample touches copies the nearest column with data
//! (phi wraps).

use super::state::Factors;
use crate::grid::Grid;
use crate::samples::FitSet;
use ndarray::ArrayViewMut1;

/// D normalisation weights: sum_k q_k D_k = integral over the hemisphere
/// (theta_h <= 60 degrees) of D cos dw, i.e. 2 pi integral D cos sin for a
/// 1-D table.
pub fn d_measure(set: &FitSet) -> Vec<f64> {
    let limit = 60f64.to_radians();
    let grid = set.layout.d;
    match grid.phi {
        None => grid.theta.quadrature_weights(|t| {
            if t <= limit {
                std::f64::consts::TAU * t.cos() * t.sin()
            } else {
                0.0
            }
        }),
        Some(phi) => {
            let qt =
                grid.theta
                    .quadrature_weights(|t| if t <= limit { t.cos() * t.sin() } else { 0.0 });
            let qp = phi.quadrature_weights();
            qt.iter()
                .flat_map(|a| qp.iter().map(move |b| a * b))
                .collect()
        }
    }
}

/// Fill the entries no sample constrains (see the module notes).
pub fn fill_unconstrained(f: &mut Factors, set: &FitSet) {
    let g_free =
        crate::samples::last_free_g_node(&set.layout, set.options.max_theta_deg.to_radians());
    let l = set.layout;
    for m in 0..f.lobes() {
        by_column(&l.d, &mut f.d[m], &set.d_inc.has_data, fill_nearest);
        by_column(&l.g, &mut f.g[m], &set.g_inc.has_data, |g, has| {
            fill_g(g, has, g_free)
        });
    }
    for ch in 0..3 {
        by_column(&l.f, &mut f.f[ch], &set.f_inc.has_data, fill_nearest);
    }
}

/// Apply a 1-D fill to every phi column of a table; then columns without
/// any data take the nearest column with data.
fn by_column(
    grid: &Grid,
    table: &mut [f64],
    has: &[bool],
    mut fill: impl FnMut(ArrayViewMut1<f64>, &[bool]),
) {
    let np = grid.n_phi();
    if np == 1 {
        fill(ArrayViewMut1::from(table), has);
        return;
    }
    let nt = grid.n_theta();
    let column_has = |p: usize| (0..nt).map(|t| has[t * np + p]).collect::<Vec<bool>>();
    let with: Vec<usize> = (0..np).filter(|&p| column_has(p).contains(&true)).collect();
    let mut v = grid.view_mut(table);
    for p in 0..np {
        fill(v.column_mut(p), &column_has(p));
    }
    if with.is_empty() {
        return;
    }
    for p in 0..np {
        if !with.contains(&p) {
            let dist = |q: usize| {
                let d = p.abs_diff(q);
                d.min(np - d)
            };
            let near = *with.iter().min_by_key(|&&q| dist(q)).unwrap();
            let src = v.column(near).to_owned();
            v.column_mut(p).assign(&src);
        }
    }
}

fn fill_nearest(mut t: ArrayViewMut1<f64>, has: &[bool]) {
    let with: Vec<usize> = (0..t.len()).filter(|&k| has[k]).collect();
    if with.is_empty() {
        return;
    }
    for k in 0..t.len() {
        if !has[k] {
            let near = *with
                .iter()
                .min_by_key(|&&i| (i as isize - k as isize).abs())
                .unwrap();
            t[k] = t[near];
        }
    }
}

/// G before the first constrained point takes its value; between the last
/// constrained point and the grazing cut-off (`free`, the last free point)
/// it holds the last constrained value (missing data there says nothing
/// about G, and a microfacet G stays near its last value until grazing
/// angles); past the cut it ramps linearly to 0 at 90 degrees, as the
/// sample set ties those points, which keeps G/cos finite.
fn fill_g(mut g: ArrayViewMut1<f64>, has: &[bool], free: usize) {
    let (Some(first), Some(last)) = (has.iter().position(|&h| h), has.iter().rposition(|&h| h))
    else {
        return;
    };
    for k in 0..first {
        g[k] = g[first];
    }
    let n = g.len() - 1;
    let free = free.max(last).min(n);
    for k in last + 1..=free {
        g[k] = g[last];
    }
    for k in free + 1..=n {
        g[k] = g[free] * (n - k) as f64 / (n - free) as f64;
    }
}

/// The factors by which `normalise` multiplied each table.
#[derive(Clone, Debug, PartialEq)]
pub struct Scales {
    /// Per lobe, D's factor.
    pub d: Vec<f64>,
    /// Per lobe, G's factor.
    pub g: Vec<f64>,
    /// Per channel, F's factor.
    pub f: [f64; 3],
}

/// Rescale to the canonical form; leaves every model value unchanged.
pub fn normalise(f: &mut Factors, set: &FitSet, d_measure: &[f64]) -> Scales {
    let lobes = f.lobes();
    let mut k = Scales {
        d: vec![1.0; lobes],
        g: vec![1.0; lobes],
        f: [1.0; 3],
    };
    // Height-correlated masking reads G as a true G1 (its scale is not
    // traded with s), so only separable G is rescaled.
    let separable = f.masking.is_separable();
    for m in 0..lobes {
        let gmax = f.g[m]
            .iter()
            .zip(&set.g_inc.has_data)
            .filter(|(_, &h)| h)
            .map(|(&v, _)| v)
            .fold(0.0, f64::max);
        if gmax > 0.0 && separable {
            f.g[m].iter_mut().for_each(|v| *v /= gmax);
            f.s[m].iter_mut().for_each(|v| *v *= gmax * gmax);
            k.g[m] = 1.0 / gmax;
        }
        let integral: f64 = f.d[m].iter().zip(d_measure).map(|(v, q)| v * q).sum();
        if integral > 0.0 {
            f.d[m].iter_mut().for_each(|v| *v /= integral);
            f.s[m].iter_mut().for_each(|v| *v *= integral);
            k.d[m] = 1.0 / integral;
        }
    }
    for ch in 0..3 {
        let fmax = f.f[ch].iter().cloned().fold(0.0, f64::max);
        let f0 = if f.f[ch][0] > 1e-6 * fmax {
            f.f[ch][0]
        } else {
            fmax
        };
        if f0 > 0.0 {
            f.f[ch].iter_mut().for_each(|v| *v /= f0);
            f.s.iter_mut().for_each(|s| s[ch] *= f0);
            k.f[ch] = 1.0 / f0;
        }
    }
    k
}
