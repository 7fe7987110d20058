//! Directional albedo E(μ, α) = ∫ f(ωo, ωi) cos θi dωi with F = 1 (or ρ = 1),
//! its tables, and the average E_avg(α) = 2π ∫ E(μ) μ dμ (maximum π).

use super::microfacet::{Masking, Ndf};
use super::quad::integrate;
use rayon::prelude::*;
use std::f64::consts::PI;

/// The two models of the seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Model {
    /// GGX with uncorrelated Smith masking, F = 1.
    Ggx,
    /// Oren–Nayar with σ = π/2·α, ρ = 1.
    OrenNayar,
}

/// Absolute tolerance of the albedo quadrature; refining it to 1e-12 moves
/// table entries by at most 1.8e-9 (see docs/energy.md).
pub const DEFAULT_TOL: f64 = 1e-10;

impl Model {
    /// Default table resolution (per axis).
    pub fn default_res(self) -> usize {
        match self {
            Model::Ggx => 128,
            Model::OrenNayar => 32,
        }
    }

    /// Name in file names and reports.
    pub fn name(self) -> &'static str {
        match self {
            Model::Ggx => "ggx",
            Model::OrenNayar => "oren-nayar",
        }
    }

    /// E(μ, α) to about `tol` absolute.
    pub fn albedo(self, mu: f64, alpha: f64, tol: f64) -> f64 {
        match self {
            Model::Ggx => specular_albedo(Ndf::Ggx, Masking::Uncorrelated, mu, alpha, tol),
            Model::OrenNayar => oren_nayar_albedo(mu, alpha),
        }
    }

    /// The axis along which α is interpolated: Oren–Nayar depends on σ²,
    /// so it is nearly linear in α² (this halves its furnace error).
    pub fn alpha_axis(self) -> AlphaAxis {
        match self {
            Model::Ggx => AlphaAxis::Linear,
            Model::OrenNayar => AlphaAxis::Squared,
        }
    }
}

/// Albedo of a specular microfacet BRDF D·G2/(4μiμo) with F = 1.
///
/// Integrates over the half vector h, with θh mapped so that D(h)cos θh is
/// uniform in ξ, and over the azimuth φ of h up to where the mirrored
/// direction reaches the horizon; inside that range the integrand is smooth.
pub fn specular_albedo(ndf: Ndf, masking: Masking, mu_o: f64, alpha: f64, tol: f64) -> f64 {
    if alpha <= 0.0 {
        return 1.0;
    }
    let mu_o = mu_o.clamp(0.0, 1.0);
    let sin_o = (1.0 - mu_o * mu_o).sqrt();
    let per_xi = |xi: f64| {
        let tan2 = ndf.tan2_from_cdf(xi, alpha);
        let cos_h = 1.0 / (1.0 + tan2).sqrt();
        let sin_h = (tan2.sqrt() * cos_h).min(1.0);
        let cos_2h = cos_h * cos_h - sin_h * sin_h;
        let s = sin_o * 2.0 * sin_h * cos_h;
        // μi = 2(ωo·h)cos θh − μo > 0  ⇔  cos φ > −μo cos 2θh / (sin θo sin 2θh).
        let phi_max = if s <= 1e-300 {
            if cos_2h > 0.0 {
                PI
            } else {
                0.0
            }
        } else {
            (-mu_o * cos_2h / s).clamp(-1.0, 1.0).acos()
        };
        let per_phi = |phi: f64| {
            let o_h = sin_o * sin_h * phi.cos() + mu_o * cos_h;
            let mu_i = 2.0 * o_h * cos_h - mu_o;
            o_h * masking.g2_over_mu_o(ndf, mu_o, mu_i, alpha) / cos_h
        };
        integrate(per_phi, 0.0, phi_max, tol)
    };
    integrate(per_xi, 0.0, 1.0, tol) / PI
}

/// Oren–Nayar coefficients A, B for roughness α (σ = π/2·α).
pub fn oren_nayar_ab(alpha: f64) -> (f64, f64) {
    let s2 = (0.5 * PI * alpha).powi(2);
    (1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09))
}

/// Oren–Nayar BRDF (ρ = 1) from the polar cosines and the azimuth difference.
pub fn oren_nayar_brdf(mu_o: f64, mu_i: f64, cos_dphi: f64, alpha: f64) -> f64 {
    let (a, b) = oren_nayar_ab(alpha);
    let (mu_max, mu_min) = if mu_o > mu_i {
        (mu_o, mu_i)
    } else {
        (mu_i, mu_o)
    };
    // sin(max θ) tan(min θ): the larger angle has the smaller cosine.
    let sin_big = (1.0 - mu_min * mu_min).max(0.0).sqrt();
    let tan_small = (1.0 - mu_max * mu_max).max(0.0).sqrt() / mu_max;
    (a + b * cos_dphi.max(0.0) * sin_big * tan_small) / PI
}

/// Oren–Nayar albedo in closed form: the azimuth integral of max(0, cos φ) is
/// 2 and both polar pieces are elementary,
/// E = A + (2B/π)[sin θo ∫_μo^1 √(1−x²)dx + tan θo ∫_0^μo x√(1−x²)dx].
pub fn oren_nayar_albedo(mu_o: f64, alpha: f64) -> f64 {
    let (a, b) = oren_nayar_ab(alpha);
    let mu = mu_o.clamp(0.0, 1.0);
    let s = (1.0 - mu * mu).sqrt();
    let upper = s * (PI / 4.0 - 0.5 * (mu * s + mu.asin()));
    // tan θo (1 − s³)/3, written to stay finite (→ 0) as μo → 0.
    let lower = if mu > 0.0 {
        s / mu * (1.0 - s * s * s) / 3.0
    } else {
        0.0
    };
    a + 2.0 * b / PI * (upper + lower)
}

/// How α is turned into an interpolation weight between two table nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlphaAxis {
    /// Linear in alpha.
    Linear,
    /// Linear in alpha^2.
    Squared,
}

/// E on the grid μj = j/(n−1), αk = k/(n−1), plus E_avg at each αk.
#[derive(Clone, Debug)]
pub struct AlbedoTable {
    /// The model tabulated.
    pub model: Model,
    /// Nodes in mu.
    pub n_mu: usize,
    /// Nodes in alpha.
    pub n_alpha: usize,
    /// E, α-major: `e[k * n_mu + j]` is E(μj, αk).
    pub e: Vec<f64>,
    /// E_avg(αk), by quadrature of E itself (not of the table).
    pub e_avg: Vec<f64>,
    /// E_avg(αk) of the bilinear table, 2π ∫ E_table μ dμ: the normaliser of
    /// f_ms, so that f_ms restores exactly what the table says is missing.
    pub e_avg_table: Vec<f64>,
    /// How alpha is interpolated.
    pub alpha_axis: AlphaAxis,
}

/// Node `i` of an `n`-node grid on [0, 1].
pub fn node(i: usize, n: usize) -> f64 {
    i as f64 / (n - 1) as f64
}

/// E_avg(α) = 2π ∫ E(μ, α) μ dμ by nested adaptive quadrature.
pub fn average_albedo(model: Model, alpha: f64, tol: f64) -> f64 {
    if model == Model::OrenNayar {
        // E is smooth in μ here, but the quadrature costs nothing either way.
        return 2.0 * PI * integrate(|mu| oren_nayar_albedo(mu, alpha) * mu, 0.0, 1.0, tol);
    }
    2.0 * PI * integrate(|mu| model.albedo(mu, alpha, tol * 0.1) * mu, 0.0, 1.0, tol)
}

impl AlbedoTable {
    /// Builds the table in parallel; `tick` is called once per α row.
    pub fn build(
        model: Model,
        n_mu: usize,
        n_alpha: usize,
        tol: f64,
        tick: &(dyn Fn() + Sync),
    ) -> AlbedoTable {
        let rows: Vec<(Vec<f64>, f64)> = (0..n_alpha)
            .into_par_iter()
            .map(|k| {
                let alpha = node(k, n_alpha);
                let row = (0..n_mu)
                    .map(|j| model.albedo(node(j, n_mu), alpha, tol))
                    .collect();
                let avg = average_albedo(model, alpha, tol);
                tick();
                (row, avg)
            })
            .collect();
        let mut e = Vec::with_capacity(n_mu * n_alpha);
        let mut e_avg = Vec::with_capacity(n_alpha);
        for (row, avg) in rows {
            e.extend(row);
            e_avg.push(avg);
        }
        let mut table = AlbedoTable {
            model,
            n_mu,
            n_alpha,
            e,
            e_avg,
            e_avg_table: Vec::new(),
            alpha_axis: model.alpha_axis(),
        };
        table.e_avg_table = (0..n_alpha)
            .map(|k| PI - table.missing_energy(table.alpha(k)))
            .collect();
        table
    }

    /// Node j of the mu axis.
    pub fn mu(&self, j: usize) -> f64 {
        node(j, self.n_mu)
    }

    /// Node k of the alpha axis.
    pub fn alpha(&self, k: usize) -> f64 {
        node(k, self.n_alpha)
    }

    /// Cell index and weight of `x` on an `n`-node grid over [0, 1].
    fn cell(x: f64, n: usize) -> (usize, f64) {
        let t = x.clamp(0.0, 1.0) * (n - 1) as f64;
        let i = (t.floor() as usize).min(n - 2);
        (i, t - i as f64)
    }

    pub(crate) fn alpha_cell(&self, alpha: f64) -> (usize, f64) {
        let (k, t) = Self::cell(alpha, self.n_alpha);
        match self.alpha_axis {
            AlphaAxis::Linear => (k, t),
            AlphaAxis::Squared => {
                let (a0, a1) = (self.alpha(k), self.alpha(k + 1));
                let a = alpha.clamp(0.0, 1.0);
                (k, (a * a - a0 * a0) / (a1 * a1 - a0 * a0))
            }
        }
    }

    /// Bilinear E(μ, α) (clamped to the grid).
    pub fn lookup(&self, mu: f64, alpha: f64) -> f64 {
        let (j, u) = Self::cell(mu, self.n_mu);
        let (k, v) = self.alpha_cell(alpha);
        let at = |k: usize, j: usize| self.e[k * self.n_mu + j];
        let row = |k: usize| at(k, j) * (1.0 - u) + at(k, j + 1) * u;
        row(k) * (1.0 - v) + row(k + 1) * v
    }

    /// E_avg(α) of the table, interpolated like E.
    pub fn lookup_avg(&self, alpha: f64) -> f64 {
        let (k, v) = self.alpha_cell(alpha);
        self.e_avg_table[k] * (1.0 - v) + self.e_avg_table[k + 1] * v
    }
}
