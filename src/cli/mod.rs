//! Subcommand implementations of the `npf` program, one module each.
//! Every command returns a [`CliError`] instead of panicking.

//! Only this module (built with the default `cli` feature) uses clap,
//! indicatif, plotters and png; the library never imports it.

pub mod charts;
pub mod compare;
pub mod demo;
pub mod energy;
pub mod energy_plot;
pub mod eval;
pub mod fit;
pub mod info;
pub mod png;
pub mod reconstruct;
pub mod report;
pub mod sample;

use std::path::Path;

/// Any failure a command reports: a message naming the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Reading or writing a table or file.
    #[error(transparent)]
    Load(#[from] npf_data_loaders::LoadError),
    /// Reading or writing a model file.
    #[error(transparent)]
    Model(#[from] crate::modelfile::ModelFileError),
    /// A fit's set-up or run, in terms of the flags that set it up.
    #[error("{}", fit::flag_message(.0))]
    Fit(#[from] crate::fit::FitError),
    /// Any other library error.
    #[error(transparent)]
    Lib(#[from] crate::Error),
    /// A command's own message.
    #[error("{0}")]
    Message(String),
}

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
        return Err(CliError::Message(format!(
            "{}: the table holds no valid samples (all cells missing)",
            path.display()
        )));
    }
    Ok((table, samples))
}

/// The table as the reference BSDF of a comparison (MERL lookup, UTIA
/// quadrilinear interpolation).
pub fn table_bsdf(table: &npf_data_loaders::Table) -> &(dyn crate::bsdf::Bsdf + Sync) {
    match table {
        npf_data_loaders::Table::Merl(t) => t,
        npf_data_loaders::Table::Utia(t) => t,
    }
}

/// What a command returns.
pub type CliResult = Result<(), CliError>;

/// Refuse early (before any work) to overwrite an output, and fail early on
/// an output folder that does not exist.
pub fn check_output(path: &Path, force: bool) -> CliResult {
    if path.exists() && !force {
        return Err(CliError::Message(format!(
            "{}: already exists (pass --force to overwrite)",
            path.display()
        )));
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(CliError::Message(format!(
            "{}: the output folder {} does not exist",
            path.display(),
            parent.display()
        )));
    }
    // Outputs are written through a temporary file in the same folder:
    // find out now, not after a long fit, whether that is possible.
    tempfile::NamedTempFile::new_in(parent).map_err(|e| {
        CliError::Message(format!(
            "{}: cannot write in {}: {e}",
            path.display(),
            parent.display()
        ))
    })?;
    Ok(())
}
