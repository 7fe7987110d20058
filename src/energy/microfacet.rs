//! Isotropic microfacet distributions (GGX, Beckmann) and their Smith terms.
//!
//! Everything is written with the projected area σ(μ) = μ(1 + Λ(μ)) rather
//! than Λ, because σ stays finite at grazing angles (σ(0) = α/2 for GGX,
//! α/(2√π) for Beckmann) where Λ diverges.

use std::f64::consts::PI;

/// Normal distribution of the microfacets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Ndf {
    /// GGX (Trowbridge-Reitz); its D is `crate::microfacet`'s.
    Ggx,
    /// Beckmann.
    Beckmann,
}

/// How the shadowing of the light and the masking of the view combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Masking {
    /// G1(ωi)·G1(ωo): the seed's model.
    Uncorrelated,
    /// 1/(1 + Λ(ωi) + Λ(ωo)): what the random walk's first order reproduces.
    HeightCorrelated,
}

impl Ndf {
    /// Projected area σ(μ) = μ(1 + Λ(μ)) of the microsurface seen from μ ∈ [0, 1].
    pub fn sigma(self, mu: f64, alpha: f64) -> f64 {
        let mu = mu.clamp(0.0, 1.0);
        let sin = (1.0 - mu * mu).max(0.0).sqrt();
        match self {
            Ndf::Ggx => 0.5 * (mu + (mu * mu + alpha * alpha * sin * sin).sqrt()),
            Ndf::Beckmann => {
                if alpha * sin == 0.0 {
                    return mu;
                }
                let a = mu / (alpha * sin);
                0.5 * mu * libm::erfc(-a) + alpha * sin * (-a * a).exp() / (2.0 * PI.sqrt())
            }
        }
    }

    /// Smith Λ for a direction with cosine `cos` in [-1, 1] (negative below
    /// the horizon, where Λ(−ω) = −1 − Λ(ω)). Infinite at the horizon.
    pub fn lambda(self, cos: f64, alpha: f64) -> f64 {
        let up = self.sigma(cos.abs(), alpha) / cos.abs() - 1.0;
        if cos >= 0.0 {
            up
        } else {
            -1.0 - up
        }
    }

    /// tan²θ of a normal drawn from D(m)·cos θm with the uniform variate `xi`.
    pub fn tan2_from_cdf(self, xi: f64, alpha: f64) -> f64 {
        match self {
            Ndf::Ggx => alpha * alpha * xi / (1.0 - xi),
            Ndf::Beckmann => -alpha * alpha * (-xi).ln_1p(),
        }
    }

    /// D(m) for a normal with cosine `cos_m`.
    pub fn d(self, cos_m: f64, alpha: f64) -> f64 {
        if cos_m <= 0.0 {
            return 0.0;
        }
        let c2 = cos_m * cos_m;
        let a2 = alpha * alpha;
        match self {
            // The one analytic GGX (crate::microfacet).
            Ndf::Ggx => crate::microfacet::ggx_d_cos2(c2, alpha),
            Ndf::Beckmann => {
                let tan2 = (1.0 - c2) / c2;
                (-tan2 / a2).exp() / (PI * a2 * c2 * c2)
            }
        }
    }
}

impl Masking {
    /// G2/μo for a reflection pair; finite at μo = 0.
    pub fn g2_over_mu_o(self, ndf: Ndf, mu_o: f64, mu_i: f64, alpha: f64) -> f64 {
        if mu_i <= 0.0 || mu_o < 0.0 {
            return 0.0;
        }
        let so = ndf.sigma(mu_o, alpha);
        let si = ndf.sigma(mu_i, alpha);
        match self {
            Masking::Uncorrelated => mu_i / (so * si),
            Masking::HeightCorrelated => {
                // μo(1 + Λo + Λi) = σo + μo(σi/μi − 1), times μi.
                let den = mu_i * so + mu_o * (si - mu_i);
                if den > 0.0 {
                    mu_i / den
                } else {
                    0.0
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ggx_sigma_matches_the_seed_denominator() {
        // The seed writes G1/(2μ) = 1/(μ + sqrt(α² + (1 − α²)μ²)).
        for &(mu, a) in &[(0.3f64, 0.5f64), (0.9, 0.1), (0.0, 0.7)] {
            let seed = 1.0 / (mu + (a * a + (1.0 - a * a) * mu * mu).sqrt());
            assert!((1.0 / (2.0 * Ndf::Ggx.sigma(mu, a)) - seed).abs() < 1e-12);
        }
    }

    #[test]
    fn lambda_below_horizon_is_reflected() {
        for ndf in [Ndf::Ggx, Ndf::Beckmann] {
            let up = ndf.lambda(0.4, 0.6);
            assert!((ndf.lambda(-0.4, 0.6) + 1.0 + up).abs() < 1e-12);
        }
    }
}
