//! What the sampler tests share: directions, a sphere quadrature on
//! refined panels, a chi-square p-value, and a three-lobe model.
#![allow(dead_code)] // each test binary uses its own subset

use npf::bsdf::Bsdf;
use npf::model::{Layout, Model};
use npf::synth::known_factor_model;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

pub type Vec3 = [f64; 3];

pub use npf::sampling::{GL4_W as GL_W, GL4_X as GL_X};

pub fn three_lobes() -> Model {
    known_factor_model(Layout::default(), &[0.02, 0.15, 0.5])
}

pub fn wo_at(theta_deg: f64) -> Vec3 {
    let t = theta_deg.to_radians();
    [t.sin(), 0.0, t.cos()]
}

pub fn spherical(theta: f64, phi: f64) -> Vec3 {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// Panel edges on [lo, hi]: a uniform grid plus geometric refinement
/// (from 1e-6 outwards) around each focus point.
pub fn panel_edges(lo: f64, hi: f64, uniform: usize, focus: &[f64]) -> Vec<f64> {
    let h = (hi - lo) / uniform as f64;
    let mut e: Vec<f64> = (0..=uniform).map(|k| lo + h * k as f64).collect();
    for &x0 in focus {
        let mut w = 1e-6;
        while w < h {
            for x in [x0 - w, x0 + w] {
                if x > lo && x < hi {
                    e.push(x);
                }
            }
            w *= 1.25;
        }
    }
    e.sort_by(f64::total_cmp);
    e.dedup_by(|b, a| (*b - *a).abs() < 1e-12);
    e
}

/// Integral of f(wi) over theta in [t0, t1], phi in [p0, p1] (composite
/// Gauss-Legendre on the given panel edges).
pub fn integrate(f: &impl Fn(Vec3) -> f64, thetas: &[f64], phis: &[f64]) -> f64 {
    let mut sum = 0.0;
    for tw in thetas.windows(2) {
        for pw in phis.windows(2) {
            for (xt, wt) in GL_X.iter().zip(GL_W) {
                let t = 0.5 * (tw[0] + tw[1]) + 0.5 * (tw[1] - tw[0]) * xt;
                let jt = 0.5 * (tw[1] - tw[0]) * wt * t.sin();
                for (xp, wp) in GL_X.iter().zip(GL_W) {
                    let p = 0.5 * (pw[0] + pw[1]) + 0.5 * (pw[1] - pw[0]) * xp;
                    sum += jt * 0.5 * (pw[1] - pw[0]) * wp * f(spherical(t, p));
                }
            }
        }
    }
    sum
}

/// ln Gamma (Lanczos, g = 7).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (Numerical Recipes' gammq).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut sum) = (a, 1.0 / a);
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / 1e-300;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < 1e-300 {
                d = 1e-300;
            }
            c = b + an / c;
            if c.abs() < 1e-300 {
                c = 1e-300;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// The chi-square p-value of observed against expected counts, cells
/// expecting fewer than 5 pooled into one.
pub fn pooled_p_value(expected: &[f64], observed: &[f64]) -> f64 {
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    for (e, o) in expected.iter().zip(observed) {
        if *e < 5.0 {
            pool_e += e;
            pool_o += o;
        } else {
            chi2 += (o - e).powi(2) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e).powi(2) / pool_e;
        dof += 1;
    }
    gamma_q((dof - 1) as f64 / 2.0, chi2 / 2.0)
}

/// Chi-square of draws from `draw` against `pdf` on a 16 x 32 (theta_i,
/// phi_i) grid, plus one cell for the lost draws; cells expecting fewer
/// than 5 are pooled.
pub fn grid_p_value(draw: &dyn Bsdf, pdf: &dyn Bsdf, wo: Vec3, n: usize, seed: u64) -> f64 {
    let (nt, np) = (16, 32);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut obs = vec![0.0; nt * np + 1];
    for _ in 0..n {
        let Some(s) = draw.sample(wo, rng.gen(), [rng.gen(), rng.gen()]) else {
            obs[nt * np] += 1.0;
            continue;
        };
        let t = s.wi[2].clamp(0.0, 1.0).acos();
        let p = s.wi[1].atan2(s.wi[0]).rem_euclid(2.0 * PI);
        let i = ((t / (PI / 2.0) * nt as f64) as usize).min(nt - 1);
        let j = ((p / (2.0 * PI) * np as f64) as usize).min(np - 1);
        obs[i * np + j] += 1.0;
    }
    let mut expected = Vec::with_capacity(nt * np + 1);
    for i in 0..nt {
        for j in 0..np {
            let cell = |k: usize, m: usize, span: f64| {
                panel_edges(
                    k as f64 * span / m as f64,
                    (k + 1) as f64 * span / m as f64,
                    6,
                    &[],
                )
            };
            let (th, ph) = (cell(i, nt, PI / 2.0), cell(j, np, 2.0 * PI));
            expected.push(n as f64 * integrate(&|wi| pdf.pdf(wo, wi), &th, &ph));
        }
    }
    let inside: f64 = expected.iter().sum();
    expected.push((n as f64 - inside).max(0.0));
    pooled_p_value(&expected, &obs)
}
