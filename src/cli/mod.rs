//! Subcommand implementations of the `npf` program, one module each.
//! Every command returns a [`CliError`] instead of panicking.

//! Only this module (built with the default `cli` feature) uses clap,
//! indicatif, plotters and png; the library never imports it.

mod checks;
pub mod compare;
pub mod demo;
pub mod energy;
pub mod energy_plot;
mod error;
pub mod eval;
pub mod export;
pub mod fit;
mod fit_args;
pub mod fit_folder;
mod fit_table;
pub mod fonts;
pub mod info;
mod input;
pub mod png;
pub mod reconstruct;
pub mod report;
pub mod sample;
pub mod signals;
pub mod view;

pub use checks::{check_output, check_outputs, check_threads};
pub use error::{flag_message, CliError, CliResult};
pub use input::{read_fit_data, read_measured, table_bsdf, FormatArg};
