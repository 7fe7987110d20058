//! The geometry of a lobe draw, scalar and in lanes: half vectors, the
//! tables' Jacobian to solid angle, the reflection of a drawn half vector,
//! the azimuth frame of a view.

use super::azimuth::azimuth_sin_cos;
use super::lanes::Lanes;
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::PI;

/// What the lobe Jacobian is made of, from s = wi + wo (h's direction,
/// whose length cancels): `jac = s.z / (4 wo.s)`, the tables' density to
/// solid angle of wi (`cos theta_h / (4 wo.h)`: one division and no square
/// root, `sample` computes it for every draw); valid when s.z > 0, wo.s > 0
/// and t = r2 / |s|^2 < 1, with r2 = s.x^2 + s.y^2.
#[derive(Clone, Copy, Debug)]
pub(super) struct JacobianParts<V> {
    pub(super) s_z: V,
    pub(super) wo_s: V,
    pub(super) r2: V,
    pub(super) jac: V,
}

#[inline(always)]
pub(super) fn jacobian_parts<V: Lanes>(wo: [V; 3], wi: [V; 3]) -> JacobianParts<V> {
    let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let wo_s = wo[0] * s[0] + wo[1] * s[1] + wo[2] * s[2];
    JacobianParts {
        s_z: s[2],
        wo_s,
        r2: s[0] * s[0] + s[1] * s[1],
        // Density per solid angle of h: (table density / 2) over signed
        // azimuths, times dt dphi / dOmega_h = 2 cos theta_h.
        jac: s[2] / (V::splat(4.0) * wo_s),
    }
}

impl JacobianParts<f64> {
    /// The Jacobian when a lobe could have drawn wi (its half vector above
    /// the surface, facing wo, t < 1 as `half_vector` forms t).
    #[inline(always)]
    pub(super) fn valid(&self) -> Option<f64> {
        let ok = self.s_z > 0.0 && self.wo_s > 0.0 && self.r2 < self.r2 + self.s_z * self.s_z;
        ok.then_some(self.jac)
    }
}

/// The Jacobian `cos theta_h / (4 wo.h)` from the tables' density to
/// solid angle of wi, when a lobe could have drawn wi (see
/// [`JacobianParts`]).
#[inline]
pub(super) fn lobe_jacobian(wo: Vec3, wi: Vec3) -> Option<f64> {
    jacobian_parts::<f64>(wo, wi).valid()
}

/// A lobe draw's reflected direction, wo.h and its Jacobian's parts.
#[derive(Clone, Copy, Debug)]
pub(super) struct Reflection<V> {
    pub(super) wi: [V; 3],
    pub(super) wo_h: V,
    pub(super) jac: JacobianParts<V>,
}

/// The half vector of a lobe draw (t = sin^2 theta_h, the azimuth at dv
/// in the cell with centre (sin, cos) `centre`, of sign `sign`, relative
/// to wo's azimuth) and its reflection of wo, lane by lane.
#[inline(always)]
pub(super) fn reflection<V: Lanes>(
    wo: [V; 3],
    t: V,
    sign: V,
    centre: [V; 2],
    dv: V,
) -> Reflection<V> {
    reflection_in(wo, frame_lanes(wo), t, sign, centre, dv)
}

/// `azimuth_frame`'s ex lane by lane (the same values): the unit vector
/// along wo's azimuth (ey = (-ex.y, ex.x)), x for a wo at the normal.
#[inline(always)]
pub(super) fn frame_lanes<V: Lanes>(wo: [V; 3]) -> [V; 2] {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let r2 = wo[0] * wo[0] + wo[1] * wo[1];
    let inv = one / r2.sqrt();
    let tiny = V::splat(1e-30);
    [
        tiny.lt_select(r2, wo[0] * inv, one),
        tiny.lt_select(r2, wo[1] * inv, zero),
    ]
}

/// [`reflection`] given wo's frame ex (`frame_lanes`).
#[inline(always)]
pub(super) fn reflection_in<V: Lanes>(
    wo: [V; 3],
    [ex0, ex1]: [V; 2],
    t: V,
    sign: V,
    centre: [V; 2],
    dv: V,
) -> Reflection<V> {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let (sin_h, cos_h) = (t.sqrt(), (one - t).max(zero).sqrt());
    let (sp, cp) = azimuth_sin_cos(centre, dv);
    let (hx, hy) = (sin_h * cp, sign * sin_h * sp);
    // hx ex + hy ey (hy (-ex.y) added is hy ex.y subtracted, exactly).
    let h = [hx * ex0 - hy * ex1, hx * ex1 + hy * ex0, cos_h];
    let wo_h = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    let k = V::splat(2.0) * wo_h;
    let wi = [k * h[0] - wo[0], k * h[1] - wo[1], k * h[2] - wo[2]];
    Reflection {
        wi,
        wo_h,
        jac: jacobian_parts(wo, wi),
    }
}

/// Fraction of azimuths phi_h for which the reflection of wo (polar angle
/// theta_o) about a half vector with sin^2 theta_h = t falls at or below the
/// horizon: wi_z = 2 (wo.h) cos theta_h - cos theta_o <= 0.
pub(super) fn azimuth_lost_fraction(t: f64, cos_o: f64, sin_o: f64) -> f64 {
    let sin_h = t.max(0.0).sqrt();
    let cos_h = (1.0 - t).max(0.0).sqrt();
    if cos_h <= 0.0 {
        return 1.0;
    }
    // wo.h = sin_o sin_h cos(phi) + cos_o cos_h; lost iff wo.h <= cos_o / (2 cos_h).
    let rhs = cos_o / (2.0 * cos_h) - cos_o * cos_h;
    let k = sin_o * sin_h;
    if k <= 0.0 {
        return if rhs >= 0.0 { 1.0 } else { 0.0 };
    }
    let c = rhs / k;
    if c >= 1.0 {
        1.0
    } else if c <= -1.0 {
        0.0
    } else {
        1.0 - c.acos() / PI
    }
}

/// Unit vectors along wo's azimuth and perpendicular to it in the tangent
/// plane (x and y for a wo at the normal).
#[inline]
pub(super) fn azimuth_frame(wo: Vec3) -> ([f64; 2], [f64; 2]) {
    let r2 = wo[0] * wo[0] + wo[1] * wo[1];
    if !(r2 > 1e-30) {
        return ([1.0, 0.0], [0.0, 1.0]);
    }
    let inv = 1.0 / r2.sqrt();
    let ex = [wo[0] * inv, wo[1] * inv];
    (ex, [-ex[1], ex[0]])
}

/// |phi_h - phi_o| in [0, pi] of a half vector.
#[inline]
pub(super) fn relative_azimuth(h: Vec3, ex: [f64; 2], ey: [f64; 2]) -> f64 {
    let x = h[0] * ex[0] + h[1] * ex[1];
    let y = h[0] * ey[0] + h[1] * ey[1];
    y.abs().atan2(x)
}

/// Half vector of (wi, wo) and sin^2 of its polar angle; None when wi = -wo.
#[inline]
pub(super) fn half_vector(wi: Vec3, wo: Vec3) -> Option<(Vec3, f64)> {
    let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let n2 = dot(s, s);
    if !(n2 > 0.0) {
        return None;
    }
    let inv = 1.0 / n2.sqrt();
    let h = [s[0] * inv, s[1] * inv, s[2] * inv];
    let t = ((s[0] * s[0] + s[1] * s[1]) / n2).min(1.0);
    Some((h, t))
}

pub(super) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
