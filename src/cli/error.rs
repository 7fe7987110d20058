//! How a command fails: one error type, its messages in terms of the
//! flags that caused them.

use crate::fit::FitError;
use crate::solver::MAX_LOBES;

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
    #[error("{}", flag_message(.0))]
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

/// A fit error in terms of the flag that caused it.
pub fn flag_message(e: &FitError) -> String {
    use crate::solver::SolverError as S;
    match e {
        FitError::Nodes(n) => format!(
            "--nodes must be {} to {}, got {n}",
            crate::fit::NODES.start(),
            crate::fit::NODES.end()
        ),
        FitError::Solver(s) => match s {
            S::Lobes(n) => format!("--lobes must be 1 to {MAX_LOBES}, got {n}"),
            S::MaxSweeps => "--max-sweeps must be at least 1".into(),
            S::Tolerance(t) => format!("--tol must be a non-negative number, got {t}"),
            S::MonotoneFrom(t) => format!("--d-monotone-from must be 0 to 90 degrees, got {t}"),
            S::SmoothG(s) => format!("--smooth-g must be positive, got {s}"),
            S::MaskedLobe(_) | S::Start(_) | S::GaussNewtonCg | S::GaussNewtonBelow(_) => {
                e.to_string()
            }
        },
        FitError::Threads { .. } | FitError::TooManyThreads { .. } => format!("--threads: {e}"),
        FitError::Range { name, .. } => format!("--{}: {e}", name.replace('_', "-")),
        FitError::Samples(_)
        | FitError::Ggx(_)
        | FitError::Unrepresentable { .. }
        | FitError::Remeasure { .. }
        | FitError::AutoNeedsTable => e.to_string(),
    }
}
