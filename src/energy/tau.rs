//! Refitting the seed's τ from simulated energies per scattering order.
//!
//! For each roughness the simulated order energies are averaged over the
//! incident hemisphere (the seed's white-furnace integral, 2π ∫ E_n μ dμ, by
//! Gauss–Legendre in μ) and divided by the whole multiple-scattering energy
//! at reflectance 1, Σ_{m≥2} E_m(1). Orders 2..=6 are then fitted with the
//! seed's model: a1 √(τF0)^(n²) (conductor) or a1 (τρ)^n (diffuse), either
//! with a1 tied to τ by the seed's normalisation or with a1 free.

use super::microfacet::Ndf;
use super::quad::gauss_legendre01;
use super::series::{a1_diffuse, a1_fresnel};
use super::simulate::{simulate, OrderEnergies, SimConfig, Surface, ORDER_BINS};
use std::f64::consts::PI;

/// The simulated data of one τ study.
#[derive(Clone, Debug)]
pub struct TauStudy {
    /// The microsurface simulated.
    pub surface: Surface,
    /// Its normal distribution.
    pub ndf: Ndf,
    /// The roughnesses fitted over.
    pub alphas: Vec<f64>,
    /// Includes 1.0 (the normalisation).
    pub reflectances: Vec<f64>,
    /// y[α][r][n − 2] for orders n = 2..=6.
    pub y: Vec<Vec<[f64; 5]>>,
}

/// A fitted τ (and the a1 that goes with it).
#[derive(Clone, Copy, Debug)]
pub struct TauFit {
    /// The fitted tau.
    pub tau: f64,
    /// The first-order coefficient a1 of the seed's model (tied or free).
    pub a1: f64,
    /// RMS residual over the fitted orders.
    pub rms: f64,
}

/// Runs the walks for a study: `n_mu` Gauss–Legendre incidence cosines per
/// roughness, `paths` walks each.
#[allow(clippy::too_many_arguments)] // the study's parameters, each a CLI flag
pub fn run_study(
    surface: Surface,
    ndf: Ndf,
    alphas: &[f64],
    reflectances: &[f64],
    n_mu: usize,
    paths: usize,
    seed: u64,
    tick: &(dyn Fn(u64) + Sync),
) -> TauStudy {
    let mut refl = reflectances.to_vec();
    if !refl.contains(&1.0) {
        refl.push(1.0);
    }
    let one = refl.iter().position(|&r| r == 1.0).unwrap_or(0);
    let rule = gauss_legendre01(n_mu);
    let configs: Vec<SimConfig> = alphas
        .iter()
        .flat_map(|&alpha| {
            let refl = refl.clone();
            rule.iter().map(move |&(mu, _)| SimConfig {
                surface,
                ndf,
                alpha,
                theta: mu.acos(),
                reflectances: refl.clone(),
                paths,
            })
        })
        .collect();
    let results = simulate(&configs, seed, tick);
    let y = results
        .chunks(n_mu)
        .map(|per_mu| hemispherical_orders(per_mu, &rule, one))
        .collect();
    TauStudy {
        surface,
        ndf,
        alphas: alphas.to_vec(),
        reflectances: refl,
        y,
    }
}

/// Cosine-weighted hemispherical averages of orders 2..=6 for each
/// reflectance, over the multiple-scattering total at reflectance index `one`.
fn hemispherical_orders(
    per_mu: &[Vec<OrderEnergies>],
    rule: &[(f64, f64)],
    one: usize,
) -> Vec<[f64; 5]> {
    let avg = |r: usize, bin: usize| -> f64 {
        per_mu
            .iter()
            .zip(rule)
            .map(|(res, &(mu, w))| 2.0 * PI * w * mu * res[r].mean[bin])
            .sum()
    };
    let ms_total: f64 = (1..ORDER_BINS).map(|b| avg(one, b)).sum();
    let n_refl = per_mu.first().map_or(0, |v| v.len());
    (0..n_refl)
        .map(|r| std::array::from_fn(|i| avg(r, i + 1) / ms_total))
        .collect()
}

impl TauStudy {
    /// Order n's shape in τ·reflectance, without a1.
    fn shape(&self, n: u32, x: f64) -> f64 {
        match self.surface {
            Surface::Conductor => x.sqrt().powi((n * n) as i32),
            Surface::Diffuse => x.powi(n as i32),
        }
    }

    fn tied_a1(&self, tau: f64) -> f64 {
        match self.surface {
            Surface::Conductor => a1_fresnel(tau),
            Surface::Diffuse => a1_diffuse(tau),
        }
    }

    /// (y, shape) pairs of the chosen roughness indices at τ.
    fn pairs(&self, alphas: &[usize], tau: f64) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        for &k in alphas {
            for (r, &refl) in self.reflectances.iter().enumerate() {
                for n in 2..=6u32 {
                    out.push((self.y[k][r][n as usize - 2], self.shape(n, tau * refl)));
                }
            }
        }
        out
    }

    /// τ (with a1 tied or free) minimising the squared residuals over the
    /// roughness indices `alphas`.
    pub fn fit(&self, alphas: &[usize], tied: bool) -> TauFit {
        let eval = |tau: f64| -> (f64, f64) {
            let p = self.pairs(alphas, tau);
            let a1 = if tied {
                self.tied_a1(tau)
            } else {
                let num: f64 = p.iter().map(|(y, g)| y * g).sum();
                let den: f64 = p.iter().map(|(_, g)| g * g).sum();
                if den > 0.0 {
                    num / den
                } else {
                    0.0
                }
            };
            let sse = p.iter().map(|(y, g)| (y - a1 * g).powi(2)).sum::<f64>();
            (sse, a1)
        };
        // A coarse scan, then golden-section search around its best point.
        let grid: Vec<f64> = (1..200).map(|i| i as f64 / 200.0).collect();
        let best = grid
            .iter()
            .copied()
            .min_by(|&a, &b| eval(a).0.total_cmp(&eval(b).0))
            .unwrap_or(0.5);
        let (mut lo, mut hi) = ((best - 0.005).max(1e-6), (best + 0.005).min(1.0 - 1e-6));
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..80 {
            let (x1, x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if eval(x1).0 < eval(x2).0 {
                hi = x2;
            } else {
                lo = x1;
            }
        }
        let tau = 0.5 * (lo + hi);
        let (sse, a1) = eval(tau);
        let count = self.pairs(alphas, tau).len().max(1);
        TauFit {
            tau,
            a1,
            rms: (sse / count as f64).sqrt(),
        }
    }
}
