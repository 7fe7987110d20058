//! Measured samples as a fit reads them: records or a MERL grid, by index.

use npf_data_loaders::{MeasuredSample, MeasuredSamples, MerlSamples};
use std::borrow::Cow;

/// What a fit's data rules (the value checks, the floor rule, the grazing
/// rule) read of one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleView {
    /// Polar angle of the half vector.
    pub theta_h: f64,
    /// Polar angle of the difference vector.
    pub theta_d: f64,
    /// Elevation of wi.
    pub theta_i: f64,
    /// Elevation of wo.
    pub theta_o: f64,
    /// Linear RGB value (1/sr).
    pub rgb: [f64; 3],
}

/// Measured samples as a fit reads them, by index: records
/// ([`MeasuredSamples`]) or a MERL table's grid ([`MerlSamples`], no
/// 88-byte record a sample). Both give the same values for the same table.
pub trait SampleSource: Sync {
    /// Where the samples came from, for messages.
    fn source_name(&self) -> &str;
    /// Whether the data are isotropic.
    fn is_isotropic(&self) -> bool;
    /// Number of samples.
    fn sample_count(&self) -> usize;
    /// Cells of the source that are not samples.
    fn missing_count(&self) -> usize;
    /// Sample i's value.
    fn rgb(&self, i: usize) -> [f64; 3];
    /// Sample i's angles and value as the data rules read them.
    fn view(&self, i: usize) -> SampleView;
    /// Sample i's record.
    fn record(&self, i: usize) -> MeasuredSample;
}

impl SampleSource for MeasuredSamples {
    fn source_name(&self) -> &str {
        &self.source
    }
    fn is_isotropic(&self) -> bool {
        self.isotropic
    }
    fn sample_count(&self) -> usize {
        self.samples.len()
    }
    fn missing_count(&self) -> usize {
        self.missing
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        self.samples[i].rgb
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        let s = &self.samples[i];
        let a = &s.angles;
        SampleView {
            theta_h: a.theta_h,
            theta_d: a.theta_d,
            theta_i: a.theta_i,
            theta_o: a.theta_o,
            rgb: s.rgb,
        }
    }
    fn record(&self, i: usize) -> MeasuredSample {
        self.samples[i]
    }
}

impl SampleSource for MerlSamples {
    fn source_name(&self) -> &str {
        self.source()
    }
    fn is_isotropic(&self) -> bool {
        true
    }
    fn sample_count(&self) -> usize {
        self.len()
    }
    fn missing_count(&self) -> usize {
        self.missing()
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        MerlSamples::rgb(self, i)
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        let (theta_h, theta_d) = self.half_diff(i);
        let [theta_i, theta_o] = self.theta(i);
        SampleView {
            theta_h,
            theta_d,
            theta_i,
            theta_o,
            rgb: MerlSamples::rgb(self, i),
        }
    }
    fn record(&self, i: usize) -> MeasuredSample {
        self.sample(i)
    }
}

/// The measured data a fit's sample sets are built from.
pub enum SampleData<'a> {
    /// Sample records, from any source.
    Records(Cow<'a, MeasuredSamples>),
    /// A MERL table's grid: its set is built by index arithmetic
    /// ([`FitSet::build_merl`](crate::samples::FitSet::build_merl)), the same set as from its records.
    Merl(Box<MerlSamples>),
}

impl From<MeasuredSamples> for SampleData<'_> {
    fn from(s: MeasuredSamples) -> Self {
        SampleData::Records(Cow::Owned(s))
    }
}

impl<'a> From<Cow<'a, MeasuredSamples>> for SampleData<'a> {
    fn from(s: Cow<'a, MeasuredSamples>) -> Self {
        SampleData::Records(s)
    }
}

impl From<MerlSamples> for SampleData<'_> {
    fn from(m: MerlSamples) -> Self {
        SampleData::Merl(Box::new(m))
    }
}

/// The same call on either kind of [`SampleData`] (a match, not a
/// virtual call: the rules call these once a sample).
macro_rules! on_data {
    ($data:expr, $s:ident => $e:expr) => {
        match $data {
            $crate::samples::SampleData::Records($s) => {
                let $s: &::npf_data_loaders::MeasuredSamples = $s;
                $e
            }
            $crate::samples::SampleData::Merl($s) => {
                let $s: &::npf_data_loaders::MerlSamples = $s;
                $e
            }
        }
    };
}
pub(crate) use on_data;

impl SampleSource for SampleData<'_> {
    fn source_name(&self) -> &str {
        on_data!(self, s => s.source_name())
    }
    fn is_isotropic(&self) -> bool {
        on_data!(self, s => s.is_isotropic())
    }
    fn sample_count(&self) -> usize {
        on_data!(self, s => s.sample_count())
    }
    fn missing_count(&self) -> usize {
        on_data!(self, s => s.missing_count())
    }
    #[inline]
    fn rgb(&self, i: usize) -> [f64; 3] {
        on_data!(self, s => SampleSource::rgb(s, i))
    }
    #[inline]
    fn view(&self, i: usize) -> SampleView {
        on_data!(self, s => s.view(i))
    }
    fn record(&self, i: usize) -> MeasuredSample {
        on_data!(self, s => s.record(i))
    }
}
