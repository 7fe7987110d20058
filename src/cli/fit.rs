//! `npf fit IN.binary -o MODEL.{json,npfb}`: the front door, which sends a
//! folder to [`super::fit_folder`] and a table to `fit_table.rs`.

use super::fit_table::{fit_table, print_summary};
use super::{check_outputs, CliError, CliResult};
use crate::modelfile;

pub use super::fit_args::{BudgetMetric, FitArgs, FitFlags, ModelForm, ADVANCED};
pub use super::fit_table::fit_with_progress;

/// Run `npf fit`: one table, or every table of a folder
/// (see [`super::fit_folder`]).
pub fn run(args: FitArgs) -> CliResult {
    if args.input.is_dir() {
        return super::fit_folder::run(args);
    }
    if let Some(form) = args.form {
        return Err(CliError::Message(format!(
            "--form {}: only for a folder input (a single output's extension picks its form)",
            form.extension()
        )));
    }
    if args.jobs.is_some() {
        return Err(CliError::Message("--jobs: only for a folder input".into()));
    }
    crate::phases::mark("start");
    modelfile::Form::of(&args.output)?;
    let config = args.config.config(args.model);
    config.validate()?;
    // The input first: a missing or unreadable table is the problem to
    // report, not an output that happens to exist already.
    npf_data_loaders::sniff::open_regular(&args.input, "a measured table")?;
    check_outputs(&[&args.output], &[&args.input], args.force)?;
    crate::phases::mark("checks");
    let fitted = fit_table(&args.input, &args.output, &args, &config, !args.quiet)?;
    if !args.quiet {
        print_summary(&fitted);
        eprintln!("wrote {}", args.output.display());
    }
    Ok(())
}
