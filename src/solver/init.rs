//! Initial factors: GGX-shaped lobes of increasing roughness.
//!
//! Lobe m starts as a GGX distribution with roughness alpha_m (narrow to
//! wide: 0.03, 0.12, 0.45 for three lobes) and its uncorrelated Smith G1,
//! F = 1, and (d, s) solved exactly for that shape. The first D update then
//! re-shapes every D freely (each D entry has a closed-form update), so the
//! start mostly sets how the lobes divide the peak, the sheen and the
//! broad part of the reflectance between them.

use super::state::Factors;
use crate::grid::Grid;
use crate::model::Layout;

/// The GGX roughness each lobe starts from.
pub fn start_alphas(lobes: usize) -> Vec<f64> {
    match lobes {
        1 => vec![0.2],
        2 => vec![0.05, 0.35],
        _ => vec![0.03, 0.12, 0.45],
    }
}

pub use crate::grid::theta_table;
pub use crate::microfacet::{ggx_d, ggx_g1};

/// The starting factors of a fit with `lobes` lobes (isotropic shapes on
/// either layout: the first sweeps give them their azimuthal structure).
pub fn initial_factors(layout: Layout, lobes: usize) -> Factors {
    initial_factors_with(layout, &start_alphas(lobes))
}

/// [`initial_factors`] with given per-lobe start roughnesses.
pub fn initial_factors_with(layout: Layout, alphas: &[f64]) -> Factors {
    let lobes = alphas.len();
    let table = |grid: Grid, f: &dyn Fn(f64) -> f64| theta_table(grid, f);
    Factors {
        layout,
        diffuse: [0.0; 3],
        s: vec![[1.0; 3]; lobes],
        d: alphas
            .iter()
            .map(|&a| table(layout.d, &|t| ggx_d(t, a)))
            .collect(),
        g: alphas
            .iter()
            .map(|&a| table(layout.g, &|t| ggx_g1(t, a)))
            .collect(),
        f: [
            vec![1.0; layout.f.len()],
            vec![1.0; layout.f.len()],
            vec![1.0; layout.f.len()],
        ],
        masking: Default::default(),
    }
}
