//! The BSDF interface in pbrt-v4's shape: [`Bsdf`] (eval, sample, pdf), the
//! sample it draws, and its errors.

use npf_data_loaders::geometry::{spherical, Angles, Vec3};

/// Which part of a BSDF's sampling mixture drew a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    /// Cosine-weighted hemisphere.
    Diffuse,
    /// Half vector from specular lobe m's distribution, reflected about wo.
    Lobe(usize),
}

/// One draw of a BSDF. [`NpfBxdf::sample`](crate::bsdf::NpfBxdf::sample) also reports draws that leave
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

/// The name [`NpfBxdf`](crate::bsdf::NpfBxdf) has always used for its draws.
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
