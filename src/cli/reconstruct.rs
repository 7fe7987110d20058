//! `npf reconstruct MODEL -o OUT.binary`: a model as a MERL table.

use super::{check_output, CliResult};
use crate::modelfile;
use crate::reconstruct::to_merl;
use clap::Args;
use std::path::PathBuf;

/// `npf reconstruct`'s arguments.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Output MERL table.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Run `npf reconstruct`.
pub fn run(args: ReconstructArgs) -> CliResult {
    check_output(&args.output, args.force)?;
    let file = modelfile::read(&args.model)?;
    to_merl(&file.model).write(&args.output, args.force)?;
    Ok(())
}
