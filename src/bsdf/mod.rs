//! The renderer-facing BSDF interface, in pbrt-v4's shape, and its
//! implementations (see docs/sampling.md).
//!
//! Every direction is a unit vector in the local shading frame (normal +z),
//! and every function takes the outgoing (view) direction `wo` first, the
//! incident (light) direction `wi` second:
//!
//! - [`Bsdf::eval`]`(wo, wi)`: the BRDF value per channel (1/sr);
//! - [`Bsdf::sample`]`(wo, uc, u)`: a wi drawn for wo, with its pdf and the
//!   Monte Carlo weight f cos theta_i / pdf; `None` when nothing is drawn or
//!   the draw leaves the upper hemisphere (the mass it had is "lost": the
//!   pdf then integrates to 1 minus that mass over the hemisphere);
//! - [`Bsdf::pdf`]`(wo, wi)`: exactly the density `sample` draws wi with.
//!
//! Implementations: the factor model with its tabulated sampler
//! ([`NpfBxdf`]), the analytic GGX + Lambert baseline
//! ([`crate::microfacet::GgxParams`]), and a measured MERL table
//! ([`npf_data_loaders::MerlTable`], cosine-weighted sampling). The
//! renderer ([`crate::render`]), the comparison ([`crate::evaluation`]) and
//! the directional [`albedo`] take any of them.

// `!(x > 0.0)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod anisotropic;
mod batch;
mod compensated;
mod f64x2;
mod factor;
mod flat;
mod ggx;
mod lanes;
mod measured;
pub use measured::InterpolatedMerl;
mod utia;

pub use anisotropic::{AnisoSampler, PHI_SUB, THETA_SUB};
pub use batch::{Directions, SampleBatch};
pub use compensated::Compensated;
pub use factor::{
    NpfBxdf, COVERAGE_SHARE, GL4_W, GL4_X, NEGLIGIBLE_CELL, PHI_CELLS, SELECTION_FLOOR, SUBCELLS,
    VIEW_NODES,
};
pub use flat::{acos, FlatEval, FLAT_LOBES};

use npf_data_loaders::geometry::{spherical, Angles, Vec3};
use npf_data_loaders::MerlTable;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Which part of a BSDF's sampling mixture drew a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// Cosine-weighted hemisphere.
    Diffuse,
    /// Half vector from specular lobe m's distribution, reflected about wo.
    Lobe(usize),
}

/// One draw of a BSDF. [`NpfBxdf::sample`] also reports draws that leave
/// the upper hemisphere (or a `wo` at or below the horizon): they have
/// `pdf = 0` and zero `f`/`weight` (their direction is reported, but they
/// carry no light); [`Bsdf::sample`] returns `None` for them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Incident direction, unit length, local frame.
    pub wi: Vec3,
    /// BRDF value f(wo, wi) per channel (1/sr).
    pub f: [f64; 3],
    /// Density of wi per solid angle, exactly [`Bsdf::pdf`].
    pub pdf: f64,
    /// f cos(theta_i) / pdf per channel (the Monte Carlo weight).
    pub weight: [f64; 3],
    /// The mixture component that drew wi.
    pub component: Component,
}

/// The name [`NpfBxdf`] has always used for its draws.
pub type BxdfSample = BsdfSample;

impl BsdfSample {
    pub(crate) fn lost(wi: Vec3, component: Component) -> Self {
        BsdfSample {
            wi,
            f: [0.0; 3],
            pdf: 0.0,
            weight: [0.0; 3],
            component,
        }
    }

    /// A draw with its value and weight, or a lost one when the pdf or the
    /// direction is not usable.
    pub(crate) fn new(wi: Vec3, f: [f64; 3], pdf: f64, component: Component) -> Self {
        if !(pdf > 0.0 && pdf.is_finite() && wi[2] > 0.0) {
            return BsdfSample::lost(wi, component);
        }
        BsdfSample {
            wi,
            f,
            pdf,
            // One division for the three channels.
            weight: {
                let k = wi[2] / pdf;
                f.map(|v| v * k)
            },
            component,
        }
    }

    /// True when the draw left the upper hemisphere (it carries no light).
    pub fn is_lost(&self) -> bool {
        self.pdf == 0.0
    }
}

/// Why a BSDF could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BsdfError {
    /// The model failed its validation (sizes, finite, non-negative).
    #[error(transparent)]
    InvalidModel(#[from] crate::model::ModelError),
    /// A batch call's slices differ in length.
    #[error("{what}: {found} entries where the batch has {expected}")]
    BatchLength {
        /// Which slice.
        what: &'static str,
        /// The batch's length (its first slice's).
        expected: usize,
        /// This slice's length.
        found: usize,
    },
}

/// A reflectance model a renderer can evaluate and importance-sample
/// (pbrt-v4's BxDF interface, reflection only). See the module notes for
/// the conventions; every implementation is total: no input panics, random
/// numbers outside [0, 1) are clamped.
pub trait Bsdf {
    /// BRDF value f(wo, wi) per channel (1/sr); zero when either direction
    /// is at or below the horizon, never negative.
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3];

    /// Draws wi for wo: `uc` picks the mixture component, `u` the direction
    /// within it. `None` when the draw carries no light (it left the upper
    /// hemisphere, or wo is at or below it).
    fn sample(&self, wo: Vec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample>;

    /// Density (per solid angle of wi) with which [`Bsdf::sample`] draws wi
    /// given wo; zero when either direction is at or below the horizon.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64;

    /// The value at a configuration given by angles (what measured samples
    /// carry); by default [`Bsdf::eval`] at its directions. Tables and
    /// models indexed by angles override it to skip the round trip.
    fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        self.eval(spherical(a.theta_o, a.phi_o), spherical(a.theta_i, a.phi_i))
    }
}

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

/// Clamps a random number into [0, 1] (NaN to 0).
#[inline]
pub(crate) fn unit(u: f64) -> f64 {
    if u.is_finite() {
        u.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Cosine-weighted hemisphere (Malley's method with a uniform disk). The
/// azimuth 2 pi u[1]'s sine and cosine come from polynomials (within
/// 1e-15 of libm's `sin_cos`, tested), the same arithmetic as the batch
/// draw's lanes, so both give the same bits.
#[inline]
pub fn cosine_hemisphere(u: [f64; 2]) -> Vec3 {
    let (sp, cp) = factor::turn_sin_cos(unit(u[1]));
    cosine_direction(unit(u[0]), sp, cp)
}

/// The cosine-weighted direction of u0 in [0, 1] (the disk radius's
/// square) at the azimuth of sine `sp` and cosine `cp`, lane by lane.
#[inline(always)]
fn cosine_direction<V: lanes::Lanes>(u0: V, sp: V, cp: V) -> [V; 3] {
    let r = u0.sqrt();
    let z = (V::splat(1.0) - u0).max(V::splat(0.0)).sqrt();
    [r * cp, r * sp, z]
}

/// Density of [`cosine_hemisphere`]: cos theta_i / pi above the horizon.
#[inline]
pub fn cosine_hemisphere_pdf(wi: Vec3) -> f64 {
    if wi[2] > 0.0 {
        wi[2] / PI
    } else {
        0.0
    }
}

/// A cosine-weighted draw for a BSDF without a sampler of its own (the
/// measured tables, the analytic references); `None` when `wo` is at or
/// below the horizon or the draw carries no light.
pub(crate) fn cosine_draw(bsdf: &dyn Bsdf, wo: Vec3, u: [f64; 2]) -> Option<BsdfSample> {
    if !(wo[2] > 0.0) {
        return None;
    }
    let wi = cosine_hemisphere(u);
    let s = BsdfSample::new(
        wi,
        bsdf.eval(wo, wi),
        cosine_pdf_for(wo, wi),
        Component::Diffuse,
    );
    (!s.is_lost()).then_some(s)
}

/// The density of [`cosine_draw`]: zero for `wo` at or below the horizon.
pub(crate) fn cosine_pdf_for(wo: Vec3, wi: Vec3) -> f64 {
    if !(wo[2] > 0.0) {
        return 0.0;
    }
    cosine_hemisphere_pdf(wi)
}

/// Reflection of `wo` about the unit vector `h`.
#[inline]
pub(crate) fn reflect(wo: Vec3, h: Vec3) -> Vec3 {
    let k = 2.0 * (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]);
    [k * h[0] - wo[0], k * h[1] - wo[1], k * h[2] - wo[2]]
}

/// [`reflect`] of `wo` about `h` with the cosine wo . h, where that cosine
/// is positive and the reflection lies above the surface (a half vector
/// that reflects `wo` into the upper hemisphere).
#[inline]
pub(crate) fn reflect_up(wo: Vec3, h: Vec3) -> Option<(Vec3, f64)> {
    let oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    if oh <= 0.0 {
        return None;
    }
    let wi = reflect(wo, h);
    (wi[2] > 0.0).then_some((wi, oh))
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

/// Uniform numbers in [0, 1) from a xorshift generator seeded with `seed`
/// (non-zero): the unit tests' fixed, dependency-free random stream.
#[cfg(test)]
pub(crate) fn test_uniforms(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}
