//! A format-independent set of measured samples.

use crate::geometry::Angles;

/// One valid measurement: its configuration and RGB value in 1/sr.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredSample {
    /// The configuration.
    pub angles: Angles,
    /// Linear RGB BRDF value (1/sr).
    pub rgb: [f64; 3],
}

/// The valid measurements of one file. Missing samples are not in the set.
#[derive(Clone, Debug, Default)]
pub struct MeasuredSamples {
    /// Where the samples came from (a file name), for messages.
    pub source: String,
    /// True for isotropic data (phi_h carries no information).
    pub isotropic: bool,
    /// The valid measurements.
    pub samples: Vec<MeasuredSample>,
    /// How many cells of the source were missing (negative or absent).
    pub missing: usize,
}
