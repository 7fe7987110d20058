//! `npf energy ...` (owned by the energy-toolkit work; placeholder until it lands).
use super::CliResult;

#[derive(clap::Subcommand)]
pub enum EnergyCommand {}

pub fn run(cmd: EnergyCommand) -> CliResult {
    match cmd {}
}
