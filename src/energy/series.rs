//! The seed's multiple-scattering factors for varying reflectance.
//!
//! Specular: order n keeps a_n(F0) = a1·√(τ F0)^(n²), so the factor is
//! Σ_{n≥2} a1 q^(n²) with q = √(τ F0), a Jacobi theta series:
//! Σ_{n≥2} q^(n²) = (θ3(0, q) − 1)/2 − q. Diffuse: a_n(ρ) = a1 (τρ)^n, a
//! geometric series a1 (τρ)²/(1 − τρ). a1 makes either sum 1 at F0 = ρ = 1.

/// τ the seed fitted for the specular (Fresnel) factor.
pub const SEED_TAU_F0: f64 = 0.5701186887948128;
/// a1 the seed prints for the specular factor.
pub const SEED_A1_F0: f64 = 0.41689949289258743;
/// τ the seed fitted for the diffuse-albedo factor.
pub const SEED_TAU_RHO: f64 = 0.284304;
/// a1 the seed prints for the diffuse factor.
pub const SEED_A1_RHO: f64 = 8.85447;

/// Jacobi θ3(0, q) = 1 + 2 Σ_{n≥1} q^(n²), for 0 ≤ q < 1.
pub fn theta3(q: f64) -> f64 {
    1.0 + 2.0 * theta_tail(q, 1)
}

/// Σ_{n≥from} q^(n²); stops when the terms no longer change the sum.
fn theta_tail(q: f64, from: u32) -> f64 {
    let mut sum = 0.0;
    for n in from.. {
        let term = q.powi((n * n) as i32);
        sum += term;
        if term <= sum * 1e-17 || term == 0.0 || n > 100_000 {
            break;
        }
    }
    sum
}

/// a1 = 1 / Σ_{n≥2} √τ^(n²) = 2 / (θ3(0, √τ) − 1 − 2√τ).
pub fn a1_fresnel(tau: f64) -> f64 {
    let q = tau.sqrt();
    2.0 / (theta3(q) - 1.0 - 2.0 * q)
}

/// Amplitude of scattering order n: a1 √(τ F0)^(n²).
pub fn fresnel_order(n: u32, f0: f64, tau: f64) -> f64 {
    a1_fresnel(tau) * (tau * f0).sqrt().powi((n * n) as i32)
}

/// Σ_{n≥2} a1 √(τ F0)^(n²); 1 at F0 = 1.
pub fn fresnel_factor(f0: f64, tau: f64) -> f64 {
    a1_fresnel(tau) * theta_tail((tau * f0).sqrt(), 2)
}

/// a1 = (1 − τ)/τ², from Σ_{n≥2} a1 τ^n = a1 τ²/(1 − τ) = 1.
pub fn a1_diffuse(tau: f64) -> f64 {
    (1.0 - tau) / (tau * tau)
}

/// Amplitude of scattering order n: a1 (τρ)^n.
pub fn diffuse_order(n: u32, rho: f64, tau: f64) -> f64 {
    a1_diffuse(tau) * (tau * rho).powi(n as i32)
}

/// Σ_{n≥2} a1 (τρ)^n = a1 (τρ)²/(1 − τρ); 1 at ρ = 1.
pub fn diffuse_factor(rho: f64, tau: f64) -> f64 {
    let r = tau * rho;
    a1_diffuse(tau) * r * r / (1.0 - r)
}

/// One constant of the seed checked against its own definition.
#[derive(Clone, Debug)]
pub struct ConstantCheck {
    /// The constant's name.
    pub name: &'static str,
    /// The value the seed states.
    pub stated: f64,
    /// The value recomputed from its definition.
    pub from_definition: f64,
}

impl ConstantCheck {
    /// Holds to the digits the seed prints (relative 1e-6).
    pub fn holds(&self) -> bool {
        (self.stated - self.from_definition).abs() <= 1e-6 * self.from_definition.abs()
    }
}

/// The a1 constants the seed derives from its τ values.
pub fn check_seed_constants() -> Vec<ConstantCheck> {
    vec![
        ConstantCheck {
            name: "a1 (Fresnel, tau = 0.5701186887948128)",
            stated: SEED_A1_F0,
            from_definition: a1_fresnel(SEED_TAU_F0),
        },
        ConstantCheck {
            name: "a1 (diffuse, tau = 0.284304)",
            stated: SEED_A1_RHO,
            from_definition: a1_diffuse(SEED_TAU_RHO),
        },
    ]
}
