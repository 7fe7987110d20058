//! The multiple-scattering lobe f_ms = (1 − E(μo))(1 − E(μi)) / (π − E_avg)
//! (seed eq. 6, E_avg with maximum π) and the white-furnace check.

use super::albedo::{average_albedo, AlbedoTable};
use rayon::prelude::*;
use std::f64::consts::PI;

impl AlbedoTable {
    /// f_ms(μo, μi; α) from the tables.
    pub fn f_ms(&self, mu_o: f64, mu_i: f64, alpha: f64) -> f64 {
        let den = PI - self.lookup_avg(alpha);
        if den <= 0.0 {
            return 0.0;
        }
        (1.0 - self.lookup(mu_o, alpha)) * (1.0 - self.lookup(mu_i, alpha)) / den
    }

    /// 2π ∫ (1 − E_table(μ, α)) μ dμ: exact for the piecewise-linear lookup
    /// (two Gauss points per cell integrate a quadratic exactly).
    pub(crate) fn missing_energy(&self, alpha: f64) -> f64 {
        let g = 0.5 / 3f64.sqrt();
        let h = 1.0 / (self.n_mu - 1) as f64;
        let mut sum = 0.0;
        for j in 0..self.n_mu - 1 {
            let c = (j as f64 + 0.5) * h;
            for mu in [c - g * h, c + g * h] {
                sum += (1.0 - self.lookup(mu, alpha)) * mu * 0.5 * h;
            }
        }
        2.0 * PI * sum
    }
}

/// One α of the white-furnace test: ∫∫ f cos cos (the single-scattering
/// lobe, by quadrature), ∫∫ f_ms cos cos (from the tables) and their sum,
/// which must be π.
#[derive(Clone, Copy, Debug)]
pub struct FurnacePoint {
    /// The roughness.
    pub alpha: f64,
    /// Double integral of the single-scattering lobe.
    pub single: f64,
    /// Double integral of f_ms.
    pub compensation: f64,
}

impl FurnacePoint {
    /// single + compensation (pi when energy is conserved).
    pub fn sum(&self) -> f64 {
        self.single + self.compensation
    }

    /// |sum - pi|.
    pub fn error(&self) -> f64 {
        (self.sum() - PI).abs()
    }
}

/// The furnace test at `n_alpha` evenly spaced α in [0, 1], which falls
/// between the table's nodes unless the grids coincide.
pub fn furnace(table: &AlbedoTable, n_alpha: usize, tol: f64) -> Vec<FurnacePoint> {
    (0..n_alpha)
        .into_par_iter()
        .map(|k| {
            let alpha = super::albedo::node(k, n_alpha);
            let single = average_albedo(table.model, alpha, tol);
            let den = PI - table.lookup_avg(alpha);
            // f_ms separates, so its double integral is the square of one integral.
            let compensation = if den > 0.0 {
                table.missing_energy(alpha).powi(2) / den
            } else {
                0.0
            };
            FurnacePoint {
                alpha,
                single,
                compensation,
            }
        })
        .collect()
}

/// Largest |sum − π| of a furnace run.
pub fn max_error(points: &[FurnacePoint]) -> f64 {
    points.iter().map(FurnacePoint::error).fold(0.0, f64::max)
}
