//! The separable diffuse factor's table P, updated inside the sweep.
//!
//! The diffuse term d_C P(theta_i) P(theta_o) has the structure of one
//! lobe's masking product G(theta_i) G(theta_o) with B_C = d_C in place of
//! s_C D F / (cos cos): P is linear in each node value, so a node changed
//! by t changes the objective by exactly the quartic of [`super::g_update`],
//! and the same rule (the best real root of its cubic derivative, or the
//! bound 0) updates each node in turn. The pass then rounds P to the model's
//! f32 and rescales it to the form's gauge (2 int P(mu) mu dmu = 1); the
//! caller ([`super::diffuse::refresh`]) re-solves d and s for it and keeps
//! it only if the objective fell, so the objective never rises.

use super::g_update::best_cubic_step;
use super::g_work::{apply_entry, cubic_sums, GWork};
use super::state::State;
use crate::grid::{Axis, Grid, StencilTable};
use crate::model::{separable_mean, DiffuseForm};
use crate::samples::{FitSet, GIncidence};
use rayon::prelude::*;

/// For each node of P, the samples whose P(theta_i) (weight u) or
/// P(theta_o) (weight v) read it.
pub(crate) fn incidence(set: &FitSet, nodes: usize) -> GIncidence {
    let grid = Grid::line(Axis::Closed { n: nodes });
    let at = |which: usize| {
        StencilTable::from_fn(grid.stencil_width(), set.len(), |j| {
            grid.stencil(set.dirs[j][which] as f64, 0.0)
        })
    };
    let total_w: Vec<f64> = set.w.iter().map(|w| w[0] + w[1] + w[2]).collect();
    GIncidence::build(nodes, &at(0), &at(1), &total_w)
}

/// The next P: one cubic-rule pass over the nodes from the state's P and
/// residuals, nodes no weighted sample reads set by [`fill_unread`],
/// rescaled to the form's gauge. `None` when the state's form is not
/// separable.
pub(crate) fn next_p(set: &FitSet, st: &State, inc: &GIncidence) -> Option<Vec<f32>> {
    let DiffuseForm::Separable { p } = &st.diffuse_form else {
        return None;
    };
    let mut x: Vec<f64> = p.iter().map(|&v| v as f64).collect();
    let d = st.factors.diffuse;
    let mut work: Vec<GWork> = st
        .cache
        .par_iter()
        .enumerate()
        .map(|(j, c)| {
            let w = &set.w[j];
            let (mut sr, mut sa) = (0.0, 0.0);
            for ch in 0..3 {
                sr += w[ch] * c.r[ch] * d[ch];
                sa += w[ch] * d[ch] * d[ch];
            }
            GWork {
                sr,
                sa,
                ..Default::default()
            }
        })
        .collect();
    // P(theta_i), P(theta_o) of every sample from the lists' weights (the
    // interpolation was done once, when the lists were built).
    for (k, &xk) in x.iter().enumerate() {
        let r = inc.entries(k);
        for ((&s, &u), &v) in inc.sample[r.clone()]
            .iter()
            .zip(&inc.u[r.clone()])
            .zip(&inc.v[r])
        {
            let wk = &mut work[s as usize];
            wk.gi += f64::from(u) * xk;
            wk.go += f64::from(v) * xk;
        }
    }
    for (k, xk) in x.iter_mut().enumerate() {
        if !inc.has_data[k] {
            continue;
        }
        let r = inc.entries(k);
        let (sample, u, v) = (&inc.sample[r.clone()], &inc.u[r.clone()], &inc.v[r]);
        let c = cubic_sums(&work, sample, u, v);
        let t = best_cubic_step(&c, *xk);
        if t != 0.0 {
            *xk += t;
            for ((&s, &u), &v) in sample.iter().zip(u).zip(v) {
                apply_entry(&mut work[s as usize], u, v, t);
            }
        }
    }
    fill_unread(&mut x, &inc.has_data);
    let p: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let mean = separable_mean(&p);
    if !(mean.is_finite() && mean > 0.0) {
        return None;
    }
    Some(x.iter().map(|&v| (v / mean) as f32).collect())
}

/// Nodes no sample reads take the value of the last read node before them
/// (those before the first read node, its value): the data end towards the
/// horizon, and P is held flat past them.
fn fill_unread(x: &mut [f64], read: &[bool]) {
    let Some(first) = read.iter().position(|&r| r) else {
        return;
    };
    let mut last = x[first];
    for (k, (xk, &r)) in x.iter_mut().zip(read).enumerate() {
        if r {
            last = *xk;
        } else if k > first {
            *xk = last;
        }
    }
    let head = x[first];
    x[..first].fill(head);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unread_nodes_take_the_last_read_value_before_them() {
        let mut x = vec![9.0, 2.0, 3.0, 9.0, 5.0, 9.0, 9.0];
        let read = [false, true, true, false, true, false, false];
        fill_unread(&mut x, &read);
        assert_eq!(x, vec![2.0, 2.0, 3.0, 3.0, 5.0, 5.0, 5.0]);
    }

    #[test]
    fn mean_is_the_integral_of_the_interpolated_table() {
        // A P that is not constant (the closed form's slope terms count):
        // against a midpoint rule of int P(theta) sin(2 theta) dtheta.
        let p = [0.2f32, 1.5, 0.9, 1.1, 0.0];
        let n = 200_000;
        let h = std::f64::consts::FRAC_PI_2 / n as f64;
        let quad: f64 = (0..n)
            .map(|i| {
                let t = (i as f64 + 0.5) * h;
                crate::model::table_at(&p, t) * (2.0 * t).sin() * h
            })
            .sum();
        let m = separable_mean(&p);
        assert!((m - quad).abs() < 1e-9, "{m} vs {quad}");
    }

    #[test]
    fn mean_of_a_constant_table_is_the_constant() {
        // 2 int_0^1 c mu dmu = c, whatever the node count.
        for n in [2, 5, 16] {
            let m = separable_mean(&vec![0.75; n]);
            assert!((m - 0.75).abs() < 1e-12, "{n} nodes: {m}");
        }
    }
}
