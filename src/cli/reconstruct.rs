//! `npf reconstruct MODEL -o OUT.{binary,bin}`: a model as a MERL table or
//! a UTIA table (an anisotropic model only as UTIA).

use super::{check_output, CliError, CliResult, FormatArg};
use crate::modelfile;
use crate::reconstruct::{to_merl, to_utia};
use clap::Args;
use std::path::PathBuf;

/// `npf reconstruct`'s arguments.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Output table: MERL (.binary) or UTIA (.bin); an anisotropic model
    /// needs UTIA.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write this format whatever the extension.
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Run `npf reconstruct`.
pub fn run(args: ReconstructArgs) -> CliResult {
    check_output(&args.output, args.force)?;
    let file = modelfile::read(&args.model)?;
    // The extension picks the format; any other extension keeps the
    // model's natural one (MERL for isotropic, UTIA for anisotropic models).
    let ext = args.output.extension().and_then(|e| e.to_str());
    let format = match (args.format, ext.map(str::to_ascii_lowercase).as_deref()) {
        (Some(f), _) => f,
        (None, Some("binary")) => FormatArg::Merl,
        (None, Some("bin")) => FormatArg::Utia,
        _ if file.model.layout.is_isotropic() => FormatArg::Merl,
        _ => FormatArg::Utia,
    };
    match format {
        FormatArg::Merl if !file.model.layout.is_isotropic() => Err(CliError::Message(format!(
            "{}: an anisotropic model cannot be written as a MERL table (isotropic); write a UTIA .bin",
            args.model.display()
        ))),
        FormatArg::Merl => Ok(to_merl(&file.model).write(&args.output, args.force)?),
        FormatArg::Utia => Ok(to_utia(&file.model).write(&args.output, args.force)?),
    }
}
