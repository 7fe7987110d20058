//! Initial factors: GGX-shaped lobes of increasing roughness.
//!
//! Lobe m starts as a GGX distribution with roughness alpha_m (narrow to
//! wide: 0.03, 0.12, 0.45 for three lobes) and its uncorrelated Smith G1,
//! F = 1, and (d, s) solved exactly for that shape. The first D update then
//! re-shapes every D freely (each D entry has a closed-form update), so the
//! start mostly sets how the lobes divide the peak, the sheen and the
//! broad part of the reflectance between them.

use super::state::Factors;
use crate::model::Layout;

pub fn start_alphas(lobes: usize) -> Vec<f64> {
    match lobes {
        1 => vec![0.2],
        2 => vec![0.05, 0.35],
        _ => vec![0.03, 0.12, 0.45],
    }
}

pub use crate::microfacet::{ggx_d, ggx_g1};

pub fn initial_factors(layout: Layout, lobes: usize) -> Factors {
    let alphas = start_alphas(lobes);
    let table = |axis: crate::interp::Axis, f: &dyn Fn(f64) -> f64| {
        (0..axis.len())
            .map(|k| f(axis.node(k)))
            .collect::<Vec<f64>>()
    };
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
    }
}
