//! `npf reconstruct MODEL -o OUT.binary`: a model as a MERL table.

use super::{check_outputs, CliError, CliResult};
use crate::modelfile;
use crate::reconstruct::to_merl;
use clap::Args;
use std::path::PathBuf;

/// `npf reconstruct`'s arguments.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Output MERL table (must end in .binary).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Run `npf reconstruct`.
pub fn run(args: ReconstructArgs) -> CliResult {
    let ext = args.output.extension().and_then(|e| e.to_str());
    if !ext.is_some_and(|e| e.eq_ignore_ascii_case("binary")) {
        return Err(CliError::Message(format!(
            "{}: reconstruct writes a MERL table: the output must end in .binary",
            args.output.display()
        )));
    }
    check_outputs(&[&args.output], &[&args.model], args.force)?;
    let file = modelfile::read(&args.model)?;
    to_merl(&file.model).write(&args.output, args.force)?;
    Ok(())
}
