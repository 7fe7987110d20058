//! Integrals over the hemisphere shared by the samplers, the energy terms
//! and the tests: the half-vector quadrature, the directional albedo, any
//! BSDF tabulated as a MERL table, and Gauss-Legendre nodes.

use super::hemisphere::reflect_up;
use super::interface::Bsdf;
use npf_data_loaders::geometry::{spherical, Angles, Vec3};
use npf_data_loaders::MerlTable;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Any BSDF as a MERL table: [`Bsdf::eval_angles`] at every cell's
/// lower-edge node (the convention of MERL's reader and of
/// `nbrdf2merl.py`); cells whose node lies at or below the horizon are
/// missing (-1). The one tabulation of npf (synthetic tables, the GGX
/// baseline's table, reconstructions).
pub fn to_merl(bsdf: &(dyn Bsdf + Sync)) -> MerlTable {
    MerlTable::from_fn(|th, td, pd| {
        let a = Angles::from_half_diff(th, 0.0, td, pd);
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| bsdf.eval_angles(&a))
    })
}

/// Directional albedo of a BSDF at view angle `theta_o` (radians): the
/// integral of f(wo, wi) cos theta_i over the incident hemisphere by
/// [`half_vector_quadrature`] with 160 strata in u and 320 in phi_h (the
/// comparison's albedo, and its tests').
pub fn albedo(theta_o: f64, bsdf: &(dyn Bsdf + Sync)) -> [f64; 3] {
    let a = half_vector_quadrature(theta_o, 160, 320, 3, |wo, wi, w, acc| {
        let v = bsdf.eval(wo, wi);
        for c in 0..3 {
            acc[c] += v[c] * w;
        }
    });
    [a[0], a[1], a[2]]
}

/// The one directional-albedo quadrature of npf: a fixed midpoint grid
/// over the half vector h at view wo = (sin theta_o, 0, cos theta_o), with
/// wi = 2 (wo.h) h - wo and dOmega_i = 4 (wo.h) dOmega_h, theta_h = (pi/2)
/// u^2 (the MERL spacing, fine near the specular peak: with 160 strata the
/// first node is 0.0014 degrees off it), `nu` strata in u and `nphi` in
/// phi_h. At every node with wi above the horizon it calls `add(wo, wi,
/// weight, acc)`, where weight = cos theta_i dOmega_i and `acc` holds
/// `width` sums (channels, or lobes); rows are summed in order, so the
/// result does not depend on the thread count.
pub fn half_vector_quadrature(
    theta_o: f64,
    nu: usize,
    nphi: usize,
    width: usize,
    add: impl Fn(Vec3, Vec3, f64, &mut [f64]) + Sync,
) -> Vec<f64> {
    let wo = spherical(theta_o, 0.0);
    let dphi = 2.0 * PI / nphi as f64;
    let du = 1.0 / nu as f64;
    (0..nu)
        .into_par_iter()
        .map(|a| {
            let u = (a as f64 + 0.5) * du;
            let theta_h = std::f64::consts::FRAC_PI_2 * u * u;
            // d theta_h = pi u du.
            let w_theta = theta_h.sin() * PI * u * du * dphi;
            let mut acc = vec![0.0; width];
            for b in 0..nphi {
                let h = spherical(theta_h, (b as f64 + 0.5) * dphi);
                let Some((wi, oh)) = reflect_up(wo, h) else {
                    continue;
                };
                add(wo, wi, wi[2] * 4.0 * oh * w_theta, &mut acc);
            }
            acc
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold(vec![0.0; width], |mut t, row| {
            for (t, r) in t.iter_mut().zip(row) {
                *t += r;
            }
            t
        })
}

/// 4-point Gauss-Legendre nodes on [-1, 1] (the tests' quadratures use them too).
pub const GL4_X: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];

/// 4-point Gauss-Legendre weights.
pub const GL4_W: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];
