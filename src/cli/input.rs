//! Reading a command's measured input.

use super::error::CliError;
use std::path::Path;

/// `--format`: read a measured table as this format instead of detecting
/// it (see [`npf_data_loaders::detect`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatArg {
    /// MERL .binary (isotropic).
    Merl,
    /// UTIA .bin (anisotropic).
    Utia,
}

impl From<FormatArg> for npf_data_loaders::Format {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Merl => npf_data_loaders::Format::Merl,
            FormatArg::Utia => npf_data_loaders::Format::Utia,
        }
    }
}

/// Reads a measured table (MERL or UTIA, detected unless `format` forces
/// one) and its samples, refusing one without any valid cell.
pub fn read_measured(
    path: &Path,
    format: Option<FormatArg>,
) -> Result<(npf_data_loaders::Table, npf_data_loaders::MeasuredSamples), CliError> {
    let table = npf_data_loaders::Table::read(path, format.map(Into::into))?;
    let samples = table.samples(&path.display().to_string());
    if samples.samples.is_empty() {
        return Err(no_samples(path));
    }
    Ok((table, samples))
}

/// Reads a measured table as [`read_measured`] does, into the data a fit
/// reads: a MERL table's grid ([`npf_data_loaders::MerlSamples`], no
/// per-sample records), other tables' samples.
pub fn read_fit_data(
    path: &Path,
    format: Option<FormatArg>,
) -> Result<crate::samples::SampleData<'static>, CliError> {
    use crate::samples::SampleSource;
    let source = path.display().to_string();
    let data: crate::samples::SampleData =
        match npf_data_loaders::Table::read(path, format.map(Into::into))? {
            npf_data_loaders::Table::Merl(t) => {
                npf_data_loaders::MerlSamples::new(t, &source).into()
            }
            table => table.samples(&source).into(),
        };
    if data.sample_count() == 0 {
        return Err(no_samples(path));
    }
    Ok(data)
}

pub(super) fn no_samples(path: &Path) -> CliError {
    CliError::Message(format!(
        "{}: the table holds no valid samples (all cells missing)",
        path.display()
    ))
}

/// The table as the reference BSDF of a comparison (MERL lookup, UTIA
/// quadrilinear interpolation).
pub fn table_bsdf(table: &npf_data_loaders::Table) -> &(dyn crate::bsdf::Bsdf + Sync) {
    match table {
        npf_data_loaders::Table::Merl(t) => t,
        npf_data_loaders::Table::Utia(t) => t,
    }
}
