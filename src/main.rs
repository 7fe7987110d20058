//! The `npf` command-line program. Each subcommand lives in `npf::cli::<name>`.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "npf",
    version,
    about = "Fit, inspect and use non-parametric factor BRDF models"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Energy-compensation tables, furnace checks and the microsurface simulator.
    #[command(subcommand)]
    Energy(npf::cli::energy::EnergyCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Energy(cmd) => npf::cli::energy::run(cmd),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("npf: error: {e}");
            ExitCode::FAILURE
        }
    }
}
