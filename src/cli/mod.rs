//! Subcommand implementations of the `npf` program, one module each.
//! Every command returns a [`CliError`] instead of panicking.

pub mod compare;
pub mod demo;
pub mod energy;
pub mod eval;
pub mod fit;
pub mod info;
pub mod reconstruct;
pub mod report;
pub mod sample;

use std::path::Path;

/// Any failure a command reports: a message naming the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Load(#[from] npf_data_loaders::LoadError),
    #[error(transparent)]
    Model(#[from] crate::modelfile::ModelFileError),
    #[error("{0}")]
    Message(String),
}

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
