//! Subcommand implementations of the `npf` program, one module each.
//! Every command returns a [`CliError`] instead of panicking.

pub mod energy;

/// Any failure a command reports: a message naming the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Load(#[from] npf_data_loaders::LoadError),
    #[error("{0}")]
    Message(String),
}

pub type CliResult = Result<(), CliError>;
