//! Rusinkiewicz half/difference angles and the directions they stand for.
//!
//! Local shading frame: normal +z. The half vector h has angles (theta_h,
//! phi_h); the difference vector d is wi expressed in the frame where h is the
//! pole (rotate by -phi_h about z, then by -theta_h about y).

/// A direction or vector in the local shading frame (normal +z).
pub type Vec3 = [f64; 3];

/// Angles of one (wi, wo) configuration in both parameterisations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angles {
    /// Polar angle of the half vector.
    pub theta_h: f64,
    /// Azimuth of the half vector.
    pub phi_h: f64,
    /// Polar angle of the difference vector (wi in the half vector's frame).
    pub theta_d: f64,
    /// Azimuth of the difference vector.
    pub phi_d: f64,
    /// Polar angle of wi (towards the light).
    pub theta_i: f64,
    /// Azimuth of wi.
    pub phi_i: f64,
    /// Polar angle of wo (towards the viewer).
    pub theta_o: f64,
    /// Azimuth of wo.
    pub phi_o: f64,
}

/// The dot product.
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The unit vector along `a`.
pub fn normalize(a: Vec3) -> Vec3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// The unit direction with polar angle `theta` and azimuth `phi`.
pub fn spherical(theta: f64, phi: f64) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    [st * cp, st * sp, ct]
}

/// (theta, phi) of a unit vector, theta in [0, pi], phi in (-pi, pi].
pub fn angles_of(v: Vec3) -> (f64, f64) {
    (v[2].clamp(-1.0, 1.0).acos(), v[1].atan2(v[0]))
}

fn rotate_z(v: Vec3, a: f64) -> Vec3 {
    rotate_z_sc(v, a.sin_cos())
}

/// Rotation about z by the angle whose (sine, cosine) is `(s, c)`.
#[inline(always)]
fn rotate_z_sc(v: Vec3, (s, c): (f64, f64)) -> Vec3 {
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

fn rotate_y(v: Vec3, a: f64) -> Vec3 {
    rotate_y_sc(v, a.sin_cos())
}

/// Rotation about y by the angle whose (sine, cosine) is `(s, c)`.
#[inline(always)]
fn rotate_y_sc(v: Vec3, (s, c): (f64, f64)) -> Vec3 {
    [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
}

/// (wi, wo) from half/difference angles.
pub fn directions_from_half_diff(
    theta_h: f64,
    phi_h: f64,
    theta_d: f64,
    phi_d: f64,
) -> (Vec3, Vec3) {
    directions_from_half_diff_sc(
        theta_h.sin_cos(),
        phi_h.sin_cos(),
        theta_d.sin_cos(),
        phi_d.sin_cos(),
    )
}

/// [`directions_from_half_diff`] from each angle's `(sin, cos)`: the same
/// arithmetic, for callers on a grid that tabulate the sines and cosines
/// of its few distinct angles once.
#[inline(always)]
pub fn directions_from_half_diff_sc(
    theta_h: (f64, f64),
    phi_h: (f64, f64),
    theta_d: (f64, f64),
    phi_d: (f64, f64),
) -> (Vec3, Vec3) {
    let ((st, ct), (sp, cp)) = (theta_d, phi_d);
    let d = [st * cp, st * sp, ct];
    let d_mirror = [-d[0], -d[1], d[2]];
    let wi = rotate_z_sc(rotate_y_sc(d, theta_h), phi_h);
    let wo = rotate_z_sc(rotate_y_sc(d_mirror, theta_h), phi_h);
    (wi, wo)
}

/// Half/difference angles from (wi, wo); both must be unit vectors.
pub fn half_diff_from_directions(wi: Vec3, wo: Vec3) -> (f64, f64, f64, f64) {
    let h = normalize([wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]]);
    let (theta_h, phi_h) = angles_of(h);
    let d = rotate_y(rotate_z(wi, -phi_h), -theta_h);
    let (theta_d, phi_d) = angles_of(d);
    (theta_h, phi_h, theta_d, phi_d)
}

impl Angles {
    /// The configuration given by Rusinkiewicz half/difference angles.
    pub fn from_half_diff(theta_h: f64, phi_h: f64, theta_d: f64, phi_d: f64) -> Self {
        let (wi, wo) = directions_from_half_diff(theta_h, phi_h, theta_d, phi_d);
        let (theta_i, phi_i) = angles_of(wi);
        let (theta_o, phi_o) = angles_of(wo);
        Angles {
            theta_h,
            phi_h,
            theta_d,
            phi_d,
            theta_i,
            phi_i,
            theta_o,
            phi_o,
        }
    }

    /// The configuration of two unit directions above the surface.
    pub fn from_directions(wi: Vec3, wo: Vec3) -> Self {
        let (theta_h, phi_h, theta_d, phi_d) = half_diff_from_directions(wi, wo);
        let (theta_i, phi_i) = angles_of(wi);
        let (theta_o, phi_o) = angles_of(wo);
        Angles {
            theta_h,
            phi_h,
            theta_d,
            phi_d,
            theta_i,
            phi_i,
            theta_o,
            phi_o,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_diff_round_trip() {
        for &(th, ph, td, pd) in &[
            (0.3, 0.0, 0.7, 1.1),
            (1.2, 0.4, 0.2, -2.0),
            (0.05, -1.0, 1.3, 2.9),
        ] {
            let (wi, wo) = directions_from_half_diff(th, ph, td, pd);
            let (a, b, c, d) = half_diff_from_directions(wi, wo);
            for (x, y) in [(a, th), (b, ph), (c, td), (d, pd)] {
                assert!((x - y).abs() < 1e-12, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn swapping_phi_d_swaps_in_and_out_elevations() {
        let (wi, wo) = directions_from_half_diff(0.4, 0.0, 0.6, 0.5);
        let (wi2, wo2) = directions_from_half_diff(0.4, 0.0, 0.6, std::f64::consts::PI - 0.5);
        assert!((wi[2] - wo2[2]).abs() < 1e-14 && (wo[2] - wi2[2]).abs() < 1e-14);
    }
}
