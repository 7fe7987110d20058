//! The `npf` command-line program. Each subcommand lives in `npf::cli::<name>`.

use clap::{Parser, Subcommand};
use npf::cli;
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
    /// Fit a measured BRDF (MERL .binary) with the shared-factor model.
    Fit(cli::fit::FitArgs),
    /// Describe a MERL table or a model file.
    Info(cli::info::InfoArgs),
    /// Write a model back as a MERL table.
    Reconstruct(cli::reconstruct::ReconstructArgs),
    /// Evaluate a model at given directions.
    Eval(cli::eval::EvalArgs),
    /// Write a model for a renderer: .bsdf (RGL tensor file), .binary (MERL table), .glsl (GLSL functions), .h (C99 header) or .brdf (BRDF Explorer).
    Export(cli::export::ExportArgs),
    /// The main job on self-made data: tabulate an analytic BRDF, fit it, export, reconstruct.
    Demo(cli::demo::DemoArgs),
    /// Draw directions from a model's importance sampler (CSV of wi, pdf, weight).
    Sample(cli::sample::SampleArgs),
    /// Error measures and rendering PSNR of a model (or table) against a reference table.
    Compare(cli::compare::CompareArgs),
    /// One self-contained HTML page to look at a fit: a WebGL sphere, the BRDF in the incidence plane, the factors, and a reference table beside it.
    View(cli::view::ViewArgs),
    /// Fit every configuration on every material of a folder and write a benchmark report.
    Report(cli::report::ReportArgs),
    /// Energy-compensation tables, furnace checks and the microsurface simulator.
    #[command(subcommand)]
    Energy(cli::energy::EnergyCommand),
}

fn main() -> ExitCode {
    cli::signals::install();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Fit(a) => cli::fit::run(a),
        Command::Info(a) => cli::info::run(a),
        Command::Reconstruct(a) => cli::reconstruct::run(a),
        Command::Eval(a) => cli::eval::run(a),
        Command::Export(a) => cli::export::run(a),
        Command::Demo(a) => cli::demo::run(a),
        Command::Sample(a) => cli::sample::run(a),
        Command::Compare(a) => cli::compare::run(a),
        Command::View(a) => cli::view::run(a),
        Command::Report(a) => cli::report::run(a),
        Command::Energy(cmd) => cli::energy::run(cmd),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("npf: error: {e}");
            ExitCode::FAILURE
        }
    }
}
