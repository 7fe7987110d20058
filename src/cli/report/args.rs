//! `npf report`'s arguments.

use clap::Args;
use std::path::PathBuf;

/// `npf report`'s arguments.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Folder of MERL tables (*.binary).
    #[arg(required_unless_present = "list")]
    pub data: Option<PathBuf>,
    /// Report folder (created; must be empty or absent unless --force).
    #[arg(short, long, required_unless_present = "list")]
    pub output: Option<PathBuf>,
    /// Configurations to run, comma-separated (default: all; see --list).
    #[arg(long, value_delimiter = ',')]
    pub configs: Vec<String>,
    /// Only these materials (file stems), comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Fits run at the same time (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
    /// Render resolution (pixels square).
    #[arg(long, default_value_t = 128)]
    pub res: usize,
    /// Environment quadrature strata in elevation.
    #[arg(long, default_value_t = 24)]
    pub n_theta: usize,
    /// Override every configuration's sweep limit (quick trial runs).
    #[arg(long)]
    pub max_sweeps: Option<usize>,
    /// Material of the convergence chart (default: gold-metallic-paint if present, else the first).
    #[arg(long)]
    pub convergence: Option<String>,
    /// Skip the convergence chart (it refits three configurations several times).
    #[arg(long)]
    pub no_convergence: bool,
    /// Fit nothing: write the report from REPORT_DIR/rows.jsonl (every fit a
    /// run finished, e.g. one stopped early), the saved models and
    /// convergence.json.
    #[arg(long)]
    pub from_rows: bool,
    /// With --from-rows: recompute every measure from the saved models
    /// (after a change to the measures; fit times and sweeps are kept).
    #[arg(long, requires = "from_rows")]
    pub reevaluate: bool,
    /// List the configurations and exit.
    #[arg(long)]
    pub list: bool,
    /// Write into an existing, non-empty report folder.
    #[arg(long)]
    pub force: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}
