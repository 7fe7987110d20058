//! Least-squares fits of E_avg(α) = π + Σ c_p α^p, the form of the seed's
//! analytic fits (the constant is pinned to π, the value at α = 0).

use super::albedo::AlbedoTable;
use nalgebra::{DMatrix, DVector};
use std::f64::consts::PI;

/// A polynomial π + Σ c_p α^p over the given powers.
#[derive(Clone, Debug, PartialEq)]
pub struct AvgFit {
    /// Powers of alpha of the terms.
    pub powers: Vec<i32>,
    /// Coefficients of the terms.
    pub coeffs: Vec<f64>,
}

impl AvgFit {
    /// The polynomial π + Σ c_p α^p at alpha.
    pub fn eval(&self, alpha: f64) -> f64 {
        PI + self
            .powers
            .iter()
            .zip(&self.coeffs)
            .map(|(&p, c)| c * alpha.powi(p))
            .sum::<f64>()
    }

    /// Largest |fit − E_avg| over the table's α nodes.
    pub fn max_error(&self, table: &AlbedoTable) -> f64 {
        (0..table.n_alpha)
            .map(|k| (self.eval(table.alpha(k)) - table.e_avg[k]).abs())
            .fold(0.0, f64::max)
    }

    /// "π − 0.446898·α − …" as the seed prints it.
    pub fn formula(&self) -> String {
        let mut s = String::from("pi");
        for (&p, &c) in self.powers.iter().zip(&self.coeffs) {
            let sign = if c < 0.0 { '-' } else { '+' };
            s += &format!(" {sign} {:.6}*a^{p}", c.abs());
        }
        s
    }
}

/// The seed's analytic fits of E_avg.
pub fn seed_fit(model: super::Model) -> AvgFit {
    match model {
        super::Model::Ggx => AvgFit {
            powers: vec![1, 2, 3, 4],
            coeffs: vec![-0.446898, -5.72019, 6.61848, -2.41727],
        },
        super::Model::OrenNayar => AvgFit {
            powers: vec![2, 3, 4],
            coeffs: vec![-7.49231, 11.4409, -5.05903],
        },
    }
}

/// Least squares over the table's α nodes with the seed's powers.
pub fn fit_avg(table: &AlbedoTable) -> AvgFit {
    let powers = seed_fit(table.model).powers;
    let n = table.n_alpha;
    let a = DMatrix::from_fn(n, powers.len(), |k, p| table.alpha(k).powi(powers[p]));
    let b = DVector::from_fn(n, |k, _| table.e_avg[k] - PI);
    // SVD is ample for a 4-column system and copes with any conditioning.
    let coeffs = a
        .svd(true, true)
        .solve(&b, 1e-14)
        .map(|c| c.iter().copied().collect())
        .unwrap_or_else(|_| vec![0.0; powers.len()]);
    AvgFit { powers, coeffs }
}
