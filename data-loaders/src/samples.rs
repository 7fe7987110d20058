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

/// Test support: `pieces(chunk)` (run in pools of 1 and 3 threads) must be
/// `all` cut into consecutive pieces of `chunk`, for each chunk size.
#[cfg(test)]
pub(crate) fn assert_pieces_are(
    all: &[MeasuredSample],
    chunks: &[usize],
    pieces: impl Fn(usize) -> Vec<Vec<MeasuredSample>> + Sync,
) {
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for &chunk in chunks {
            let got = pool.install(|| pieces(chunk));
            assert_eq!(got.len(), all.len().div_ceil(chunk));
            assert!(got.iter().rev().skip(1).all(|p| p.len() == chunk));
            assert!(got.concat() == all, "{threads} threads, pieces of {chunk}");
        }
    }
}
