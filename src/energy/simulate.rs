//! Brute-force random walk on a Smith microsurface (Heitz, Hanika, d'Eon,
//! Dachsbacher 2016): energy leaving after each scattering order.
//!
//! Heights are uniform on [−1, 1] (the result does not depend on the height
//! distribution). The geometry of a walk does not depend on F0 or ρ, only its
//! throughput does, so one walk scores every requested reflectance at once
//! (common random numbers, which also correlates the curves smoothly).

use super::microfacet::Ndf;
use rand::Rng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Orders 1..=6 are scored separately; the last bin holds order 7 and above.
pub const ORDER_BINS: usize = 7;
/// Walks still on the surface after this many hits are dropped (never seen
/// with F0 = 1 in practice: the white-furnace totals stay exactly 1).
const MAX_HITS: usize = 100_000;
/// Paths per deterministic random stream.
const CHUNK: usize = 4096;

/// What the microfacets do with light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Surface {
    /// Mirror microfacets with Schlick Fresnel F0.
    Conductor,
    /// Lambertian microfacets with albedo ρ.
    Diffuse,
}

/// One simulated configuration.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// The microsurface simulated.
    pub surface: Surface,
    /// Its normal distribution.
    pub ndf: Ndf,
    /// Its roughness.
    pub alpha: f64,
    /// Incidence angle from the normal, radians.
    pub theta: f64,
    /// F0 (conductor) or ρ (diffuse) values, all scored by the same walks.
    pub reflectances: Vec<f64>,
    /// Paths traced.
    pub paths: usize,
}

/// Mean energy per order bin and in total, with standard errors.
#[derive(Clone, Debug, Default)]
pub struct OrderEnergies {
    /// Mean energy per scattering order.
    pub mean: [f64; ORDER_BINS],
    /// Standard error per scattering order.
    pub stderr: [f64; ORDER_BINS],
    /// Mean total energy.
    pub total: f64,
    /// Standard error of the total.
    pub total_stderr: f64,
}

/// Sums of per-path scores and their squares for one reflectance.
#[derive(Clone, Default)]
struct Moments {
    sum: [f64; ORDER_BINS],
    sq: [f64; ORDER_BINS],
    total: f64,
    total_sq: f64,
}

impl Moments {
    fn add(&mut self, other: &Moments) {
        for b in 0..ORDER_BINS {
            self.sum[b] += other.sum[b];
            self.sq[b] += other.sq[b];
        }
        self.total += other.total;
        self.total_sq += other.total_sq;
    }

    fn finish(&self, n: usize) -> OrderEnergies {
        let nf = n as f64;
        let se = |s: f64, q: f64| {
            if n < 2 {
                return f64::NAN;
            }
            ((q - s * s / nf).max(0.0) / (nf * (nf - 1.0))).sqrt()
        };
        let mut out = OrderEnergies {
            total: self.total / nf,
            total_stderr: se(self.total, self.total_sq),
            ..Default::default()
        };
        for b in 0..ORDER_BINS {
            out.mean[b] = self.sum[b] / nf;
            out.stderr[b] = se(self.sum[b], self.sq[b]);
        }
        out
    }
}

type V3 = [f64; 3];

fn normalize(v: V3) -> V3 {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Uniform height distribution: C1 and its inverse.
fn c1(h: f64) -> f64 {
    (0.5 * (h + 1.0)).clamp(0.0, 1.0)
}

fn inv_c1(u: f64) -> f64 {
    (2.0 * u - 1.0).clamp(-1.0, 1.0)
}

/// Next intersection height along direction `w` from height `h`, or None
/// when the ray leaves the microsurface.
fn sample_height(ndf: Ndf, alpha: f64, w: V3, h: f64, u: f64) -> Option<f64> {
    const FLAT: f64 = 1e-9;
    if w[2] >= 1.0 - 1e-15 {
        return None;
    }
    if w[2].abs() < FLAT {
        // Grazing: hits again at (almost) the same height.
        return Some(h);
    }
    let lambda = ndf.lambda(w[2], alpha);
    if w[2] > 0.0 {
        // Escape with probability G1(w, h) = C1(h)^Λ.
        let g1 = c1(h).powf(lambda);
        if u > 1.0 - g1 {
            return None;
        }
    }
    // C1(h_new) = C1(h) / (1 − U)^(1/Λ); Λ < 0 downwards, so this lowers h.
    let ln = c1(h).ln() - (1.0 - u).ln() / lambda;
    Some(inv_c1(ln.exp()))
}

/// A normal from the visible-normal distribution ∝ max(0, wi·m) D(m), for any
/// `wi` on the sphere (upward rays hit the surface from below the horizon).
fn sample_visible_normal(ndf: Ndf, alpha: f64, wi: V3, rng: &mut impl Rng) -> V3 {
    if ndf == Ndf::Ggx {
        // The one GGX visible-normal sampler (phi first, then the cap height).
        let u = [rng.gen::<f64>(), rng.gen::<f64>()];
        return crate::microfacet::ggx_visible_normal(alpha, wi, u);
    }
    // Stretch to α = 1, sample there, stretch the normal back.
    let ws = normalize([alpha * wi[0], alpha * wi[1], wi[2]]);
    let (sx, sy) = beckmann_visible_slope(ws, rng);
    let m = [-alpha * sx, -alpha * sy, 1.0];
    let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
    if !(l > 0.0) || !l.is_finite() {
        return [0.0, 0.0, 1.0];
    }
    [m[0] / l, m[1] / l, m[2] / l]
}

/// Visible slopes of the α = 1 Beckmann surface seen from `w` (unit).
/// In the frame where w = (sin θ, 0, cos θ) the density is
/// ∝ max(0, cos θ − x sin θ) e^(−x²−y²): y is N(0, ½) and x is drawn by
/// inverting F(x) = cos θ (√π/2) erfc(−x) + (sin θ/2) e^(−x²) on x ≤ cot θ.
fn beckmann_visible_slope(w: V3, rng: &mut impl Rng) -> (f64, f64) {
    let gauss = |rng: &mut dyn rand::RngCore| {
        let u1: f64 = 1.0 - rng.gen::<f64>();
        let u2: f64 = rng.gen();
        (-u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    };
    let y = gauss(rng);
    let sin = (w[0] * w[0] + w[1] * w[1]).sqrt();
    let cos = w[2];
    if sin < 1e-12 {
        return (gauss(rng), y);
    }
    let x0 = cos / sin;
    let x = if x0 < -8.0 {
        // Far below the horizon the density is ≈ u e^(−2|x0|u) in u = x0 − x.
        let (u1, u2): (f64, f64) = (1.0 - rng.gen::<f64>(), 1.0 - rng.gen::<f64>());
        x0 + (u1.ln() + u2.ln()) / (2.0 * x0.abs())
    } else {
        let cdf = |x: f64| cos * 0.5 * PI.sqrt() * libm::erfc(-x) + 0.5 * sin * (-x * x).exp();
        let target = rng.gen::<f64>() * cdf(x0);
        let (mut lo, mut hi) = (x0.min(0.0) - 7.0, x0);
        let mut x = 0.5 * (lo + hi);
        for _ in 0..100 {
            let f = cdf(x) - target;
            if f > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let d = (cos - x * sin) * (-x * x).exp();
            let newton = x - f / d;
            // Newton when it stays in the bracket, bisection otherwise.
            let next = if d > 0.0 && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - x).abs() < 1e-13 * (1.0 + x.abs()) {
                x = next;
                break;
            }
            x = next;
        }
        x
    };
    // Rotate from the frame of w back.
    let (c, s) = (w[0] / sin, w[1] / sin);
    (c * x - s * y, s * x + c * y)
}

/// Cosine-weighted direction about `n`.
fn sample_cosine(n: V3, rng: &mut impl Rng) -> V3 {
    let r = rng.gen::<f64>().sqrt();
    let phi = 2.0 * PI * rng.gen::<f64>();
    let (x, y) = (r * phi.cos(), r * phi.sin());
    let z = (1.0 - r * r).max(0.0).sqrt();
    // Orthonormal basis (Duff et al. 2017).
    let sign = 1f64.copysign(n[2]);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    let t = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
    let bt = [b, sign + n[1] * n[1] * a, -n[1]];
    normalize([
        x * t[0] + y * bt[0] + z * n[0],
        x * t[1] + y * bt[1] + z * n[1],
        x * t[2] + y * bt[2] + z * n[2],
    ])
}

fn schlick(f0: f64, cos: f64) -> f64 {
    f0 + (1.0 - f0) * (1.0 - cos.clamp(0.0, 1.0)).powi(5)
}

/// Runs `paths` walks of one configuration from its own stream and adds
/// their scores; `throughput` is reused scratch.
fn walk_chunk(cfg: &SimConfig, paths: usize, rng: &mut Pcg64) -> Vec<Moments> {
    let nr = cfg.reflectances.len();
    let mut acc = vec![Moments::default(); nr];
    let mut throughput = vec![1.0; nr];
    let wi = [cfg.theta.sin(), 0.0, cfg.theta.cos()];
    for _ in 0..paths {
        throughput.iter_mut().for_each(|t| *t = 1.0);
        let mut w = [-wi[0], -wi[1], -wi[2]];
        let mut h = 1.0 + inv_c1(0.999);
        let mut hits = 0usize;
        let escaped = loop {
            match sample_height(cfg.ndf, cfg.alpha, w, h, rng.gen()) {
                None => break hits > 0,
                Some(nh) => h = nh,
            }
            hits += 1;
            if hits > MAX_HITS {
                break false;
            }
            let back = [-w[0], -w[1], -w[2]];
            let m = sample_visible_normal(cfg.ndf, cfg.alpha, back, rng);
            match cfg.surface {
                Surface::Conductor => {
                    let c = dot(back, m);
                    for (t, &f0) in throughput.iter_mut().zip(&cfg.reflectances) {
                        *t *= schlick(f0, c);
                    }
                    w = normalize([
                        2.0 * c * m[0] - back[0],
                        2.0 * c * m[1] - back[1],
                        2.0 * c * m[2] - back[2],
                    ]);
                }
                Surface::Diffuse => {
                    for (t, &rho) in throughput.iter_mut().zip(&cfg.reflectances) {
                        *t *= rho;
                    }
                    w = sample_cosine(m, rng);
                }
            }
        };
        if escaped {
            let bin = (hits - 1).min(ORDER_BINS - 1);
            for (a, &t) in acc.iter_mut().zip(&throughput) {
                a.sum[bin] += t;
                a.sq[bin] += t * t;
                a.total += t;
                a.total_sq += t * t;
            }
        }
    }
    acc
}

/// Simulates every configuration; deterministic for a given `seed` whatever
/// the thread count, because each chunk of paths has its own PCG stream and
/// chunks are summed in order. `tick(paths)` reports progress.
pub fn simulate(
    configs: &[SimConfig],
    seed: u64,
    tick: &(dyn Fn(u64) + Sync),
) -> Vec<Vec<OrderEnergies>> {
    let jobs: Vec<(usize, usize, usize)> = configs
        .iter()
        .enumerate()
        .flat_map(|(ci, c)| {
            (0..c.paths.div_ceil(CHUNK)).map(move |k| (ci, k, CHUNK.min(c.paths - k * CHUNK)))
        })
        .collect();
    let parts: Vec<Vec<Moments>> = jobs
        .par_iter()
        .map(|&(ci, k, n)| {
            let state = ((seed as u128) << 64) | ci as u128;
            let mut rng = Pcg64::new(state, k as u128);
            let m = walk_chunk(&configs[ci], n, &mut rng);
            tick(n as u64);
            m
        })
        .collect();
    let mut sums: Vec<Vec<Moments>> = configs
        .iter()
        .map(|c| vec![Moments::default(); c.reflectances.len()])
        .collect();
    for (&(ci, _, _), part) in jobs.iter().zip(&parts) {
        for (s, p) in sums[ci].iter_mut().zip(part) {
            s.add(p);
        }
    }
    sums.iter()
        .zip(configs)
        .map(|(s, c)| s.iter().map(|m| m.finish(c.paths)).collect())
        .collect()
}
