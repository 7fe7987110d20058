//! `npf reconstruct MODEL -o OUT.{binary,bin}`: a model as a MERL table or
//! a UTIA table (an anisotropic model only as UTIA).

use super::{check_outputs, CliError, CliResult, FormatArg};
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
    /// The table format; must agree with the extension (.binary MERL, .bin UTIA).
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Run `npf reconstruct`.
pub fn run(args: ReconstructArgs) -> CliResult {
    // The extension names the table format (a table named .json would
    // pass for a model); --format may only confirm it.
    let ext = args.output.extension().and_then(|e| e.to_str());
    let format = match ext.map(str::to_ascii_lowercase).as_deref() {
        Some("binary") => FormatArg::Merl,
        Some("bin") => FormatArg::Utia,
        _ => {
            let out = args.output.display();
            return Err(CliError::Message(format!(
                "{out}: reconstruct writes a table: the output must end in \
                 .binary (MERL) or .bin (UTIA)"
            )));
        }
    };
    if args.format.is_some_and(|f| f != format) {
        return Err(CliError::Message(format!(
            "{}: --format contradicts the output's extension",
            args.output.display()
        )));
    }
    check_outputs(&[&args.output], &[&args.model], args.force)?;
    let file = modelfile::read(&args.model)?;
    match format {
        FormatArg::Merl if !file.model.layout.is_isotropic() => Err(CliError::Message(format!(
            "{}: an anisotropic model cannot be written as a MERL table (isotropic); write a UTIA .bin",
            args.model.display()
        ))),
        FormatArg::Merl => Ok(to_merl(&file.model).write(&args.output, args.force)?),
        FormatArg::Utia => Ok(to_utia(&file.model).write(&args.output, args.force)?),
    }
}
