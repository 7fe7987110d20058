//! Directions on the hemisphere: the cosine-weighted draw and its pdf
//! (the fallback of every sampler), mirror reflection about a half vector.

use super::azimuth::turn_sin_cos;
use super::interface::{Bsdf, BsdfSample, Component};
use super::lanes;
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::PI;

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
    let (sp, cp) = turn_sin_cos(unit(u[1]));
    cosine_direction(unit(u[0]), sp, cp)
}

/// The cosine-weighted direction of u0 in [0, 1] (the disk radius's
/// square) at the azimuth of sine `sp` and cosine `cp`, lane by lane.
#[inline(always)]
pub(super) fn cosine_direction<V: lanes::Lanes>(u0: V, sp: V, cp: V) -> [V; 3] {
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
