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
pub mod export;
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
