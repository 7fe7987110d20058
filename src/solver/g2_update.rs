//! The G pass for height-correlated masking (one control point at a time).
//!
//! With G2 = Gi Go / (Gi + Go - Gi Go) in place of Gi Go, a sample's model
//! value is no longer a polynomial in one control value, so the exact cubic
//! of `g_update` does not apply. For a point changed by t, a sample's G
//! values become Gi + u t and Go + v t and its residual moves by B_C dP(t)
//! (B_C = s_C D F / (cos cos), dP the change of G2), so the objective
//! changes by exactly
//!   dE(t) = sum_samples 2 S_r dP(t) + S_a dP(t)^2
//! (S_r = sum_C w r B, S_a = sum_C w B^2, as in `g_update`). A few
//! safeguarded Gauss-Newton steps on t (derivative and curvature from
//! dG2/dGi = Go^2 / (Gi + Go - Gi Go)^2) look for a lower dE, the point
//! stays in [0, 1] (G is a G1 here), and the best step is applied only if
//! dE < 0, so the objective never rises.

use super::chunked_sum;
use super::g_work::{apply_work, GPassStats, GWork};
use super::state::State;
use crate::model::height_correlated;
use crate::samples::FitSet;

/// Gauss-Newton passes per control point.
const STEPS: usize = 4;

/// G2 and its derivative along (u, v) at G values (a, b), clamped like
/// [`height_correlated`].
#[inline]
fn g2_and_slope(a: f64, b: f64, u: f64, v: f64) -> (f64, f64) {
    let (ca, cb) = (a.clamp(0.0, 1.0), b.clamp(0.0, 1.0));
    let den = ca + cb - ca * cb;
    if den <= 0.0 {
        return (0.0, 0.0);
    }
    let g = if ca <= 0.0 || cb <= 0.0 {
        0.0
    } else {
        ca * cb / den
    };
    // Clamped coordinates do not move the value.
    let da = if (0.0..1.0).contains(&a) {
        cb * cb / (den * den)
    } else {
        0.0
    };
    let db = if (0.0..1.0).contains(&b) {
        ca * ca / (den * den)
    } else {
        0.0
    };
    (g, da * u + db * v)
}

/// The per-point steps of lobe m's G pass under height-correlated masking
/// (see the module notes), after `g_update::update_g` filled `work`; the
/// G method is not read (`Fixed` never gets here; `Cubic` and `Golden`
/// both use the Gauss-Newton search).
pub(crate) fn g2_points(
    set: &FitSet,
    st: &mut State,
    m: usize,
    work: &mut [GWork],
    mut stats: GPassStats,
) -> GPassStats {
    let inc = &set.g_inc;
    for k in 0..inc.has_data.len() {
        if !inc.has_data[k] {
            continue;
        }
        let range = inc.entries(k);
        // dE(t), dE'(t) and the Gauss-Newton curvature, in chunk order.
        let pass = |wv: &[GWork], t: f64| -> [f64; 3] {
            chunked_sum(range.len(), |r| {
                let mut acc = [0.0; 3];
                for e in range.start + r.start..range.start + r.end {
                    let x = &wv[inc.sample[e] as usize];
                    let (u, v) = (f64::from(inc.u[e]), f64::from(inc.v[e]));
                    let p0 = height_correlated(x.gi, x.go);
                    let (p, slope) = g2_and_slope(x.gi + u * t, x.go + v * t, u, v);
                    let dp = p - p0;
                    acc[0] += 2.0 * x.sr * dp + x.sa * dp * dp;
                    acc[1] += 2.0 * (x.sr + x.sa * dp) * slope;
                    acc[2] += 2.0 * x.sa * slope * slope;
                }
                acc
            })
        };
        let x0 = st.factors.g[m][k];
        let (lo, hi) = (-x0.max(0.0), 1.0 - x0);
        let (mut best_t, mut best_e) = (0.0, 0.0);
        let mut t = 0.0;
        for step in 0..STEPS {
            let [e, g, h] = pass(&work[..], t);
            if step > 0 {
                if e < best_e {
                    best_t = t;
                    best_e = e;
                } else {
                    // Overshot: halve back towards the best point so far.
                    t = 0.5 * (t + best_t);
                    continue;
                }
            }
            if !(h > 0.0) || g == 0.0 {
                break;
            }
            let next = (t - g / h).clamp(lo, hi);
            if (next - t).abs() <= 1e-12 * (1.0 + x0.abs()) {
                break;
            }
            t = next;
        }
        if best_t == 0.0 || !(best_e < 0.0) {
            stats.rejected += 1;
            continue;
        }
        stats.accepted += 1;
        stats.worst_accepted = stats.worst_accepted.max(best_e);
        st.factors.g[m][k] = x0 + best_t;
        // Each sample appears once in a point's list.
        for e in range.clone() {
            let x = &mut work[inc.sample[e] as usize];
            let (u, v) = (f64::from(inc.u[e]), f64::from(inc.v[e]));
            let dp = height_correlated(x.gi + u * best_t, x.go + v * best_t)
                - height_correlated(x.gi, x.go);
            x.sr += x.sa * dp;
            x.gi += u * best_t;
            x.go += v * best_t;
        }
    }
    apply_work(set, st, m, work, height_correlated);
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_matches_a_finite_difference() {
        for (a, b, u, v) in [
            (0.3, 0.7, 0.5, 0.2),
            (0.9, 0.1, 0.0, 1.0),
            (0.5, 0.5, 1.0, 1.0),
        ] {
            let (g, s) = g2_and_slope(a, b, u, v);
            let h = 1e-6;
            let fd = (height_correlated(a + u * h, b + v * h)
                - height_correlated(a - u * h, b - v * h))
                / (2.0 * h);
            assert!((g - height_correlated(a, b)).abs() < 1e-15);
            assert!((s - fd).abs() < 1e-6, "{a} {b}: {s} vs {fd}");
        }
        // G2 of G1 = 1 on both sides is 1; with one side 0 it is 0.
        assert_eq!(height_correlated(1.0, 1.0), 1.0);
        assert_eq!(height_correlated(0.0, 0.8), 0.0);
        // Never below the separable product.
        assert!(height_correlated(0.4, 0.6) >= 0.4 * 0.6);
    }
}
