//! `npf energy ...`: albedo tables, E_avg fits, white-furnace checks, the
//! seed's reflectance factors and the microsurface simulator.

use super::energy_plot as plot;
use super::{check_output, CliError, CliResult};
use crate::energy::albedo::{AlbedoTable, Model, DEFAULT_TOL};
use crate::energy::compensation::{furnace, max_error, FurnacePoint};
use crate::energy::fit::{fit_avg, seed_fit};
use crate::energy::microfacet::Ndf;
use crate::energy::series::{self, check_seed_constants};
use crate::energy::simulate::{simulate, SimConfig, Surface, ORDER_BINS};
use crate::energy::tau;
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

/// The `npf energy` subcommands.
#[derive(Subcommand)]
pub enum EnergyCommand {
    /// Write the albedo table E(mu, alpha) as CSV lines "mu, alpha, E".
    Table(TableArgs),
    /// Print E_avg(alpha), its least-squares fit and the seed's fit.
    Avg(AvgArgs),
    /// White-furnace check of f + f_ms for every alpha.
    Furnace(FurnaceArgs),
    /// Random walk on a Smith microsurface: energy per scattering order.
    Simulate(SimulateArgs),
    /// Check the seed's series constants and refit its tau by simulation.
    Tau(TauArgs),
    /// Plot E, E_avg and the white-furnace curves (SVG or PNG).
    Plot(PlotArgs),
}

/// Run an `npf energy` subcommand.
pub fn run(cmd: EnergyCommand) -> CliResult {
    match cmd {
        EnergyCommand::Table(a) => run_table(a),
        EnergyCommand::Avg(a) => run_avg(a),
        EnergyCommand::Furnace(a) => run_furnace(a),
        EnergyCommand::Simulate(a) => run_simulate(a),
        EnergyCommand::Tau(a) => run_tau(a),
        EnergyCommand::Plot(a) => run_plot(a),
    }
}

/// Which table to build; shared by every table-based command.
#[derive(Args, Debug, Clone)]
pub struct TableSpec {
    /// Which BRDF the table is of.
    #[arg(long, value_enum, default_value = "ggx")]
    pub model: Model,
    /// Nodes per axis (default 128 for GGX, 32 for Oren-Nayar).
    #[arg(long)]
    pub res: Option<usize>,
    /// Absolute tolerance of the albedo quadrature.
    #[arg(long, default_value_t = DEFAULT_TOL)]
    pub tol: f64,
}

/// A required output file.
#[derive(Args, Debug)]
pub struct Output {
    /// Output file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Overwrite an existing output.
    #[arg(long)]
    pub force: bool,
}

/// An optional output file.
#[derive(Args, Debug)]
pub struct OptionalOutput {
    /// Also write the numbers as CSV.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Overwrite an existing output.
    #[arg(long)]
    pub force: bool,
}

/// `npf energy table`'s arguments.
#[derive(Args, Debug)]
pub struct TableArgs {
    /// The table.
    #[command(flatten)]
    pub spec: TableSpec,
    /// Where to write it.
    #[command(flatten)]
    pub out: Output,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `npf energy avg`'s arguments.
#[derive(Args, Debug)]
pub struct AvgArgs {
    /// The table.
    #[command(flatten)]
    pub spec: TableSpec,
    /// CSV lines "alpha, E_avg".
    #[command(flatten)]
    pub out: OptionalOutput,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `npf energy furnace`'s arguments.
#[derive(Args, Debug)]
pub struct FurnaceArgs {
    /// The table.
    #[command(flatten)]
    pub spec: TableSpec,
    /// Number of evenly spaced alpha in [0, 1] (default 2·res − 1: the
    /// nodes and every midpoint between them).
    #[arg(long)]
    pub alphas: Option<usize>,
    /// CSV lines "alpha, single, compensation, sum".
    #[command(flatten)]
    pub out: OptionalOutput,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `npf energy simulate`'s arguments.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Conductor or diffuse microsurface.
    #[arg(long, value_enum, default_value = "conductor")]
    pub surface: Surface,
    /// Normal distribution of the microsurface.
    #[arg(long, value_enum, default_value = "ggx")]
    pub ndf: Ndf,
    /// Roughness values, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.5")]
    pub alpha: Vec<f64>,
    /// Incidence angles in degrees, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,60")]
    pub theta: Vec<f64>,
    /// F0 (conductor) or rho (diffuse) values, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub reflectance: Vec<f64>,
    /// Walks per (alpha, theta).
    #[arg(long, default_value_t = 100_000)]
    pub paths: usize,
    /// Random seed (results are reproducible for a seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// CSV with one row per (alpha, theta, reflectance).
    #[command(flatten)]
    pub out: OptionalOutput,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `npf energy tau`'s arguments.
#[derive(Args, Debug)]
pub struct TauArgs {
    /// Roughness values, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.2,0.4,0.6,0.8,1.0")]
    pub alpha: Vec<f64>,
    /// F0 or rho values (1 is always added), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0"
    )]
    pub reflectance: Vec<f64>,
    /// Gauss-Legendre incidence cosines for the hemispherical average.
    #[arg(long, default_value_t = 6)]
    pub mu_nodes: usize,
    /// Walks per (alpha, incidence).
    #[arg(long, default_value_t = 20_000)]
    pub paths: usize,
    /// Random seed (results are reproducible for a seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only this surface (default: both).
    #[arg(long, value_enum)]
    pub surface: Option<Surface>,
    /// Only this distribution (default: both).
    #[arg(long, value_enum)]
    pub ndf: Option<Ndf>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `npf energy plot`'s arguments.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The table.
    #[command(flatten)]
    pub spec: TableSpec,
    /// A TrueType font for the labels (default: a system font).
    #[arg(long)]
    pub font: Option<PathBuf>,
    /// FILE.svg or FILE.png.
    #[command(flatten)]
    pub out: Output,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

fn msg(s: impl Into<String>) -> CliError {
    CliError::Message(s.into())
}

fn progress(len: u64, quiet: bool, what: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})") {
        bar.set_style(style);
    }
    bar.set_message(what.to_string());
    bar
}

impl TableSpec {
    fn res(&self) -> Result<usize, CliError> {
        let res = self.res.unwrap_or(self.model.default_res());
        if !(2..=4096).contains(&res) {
            return Err(msg(format!("--res {res}: must be between 2 and 4096")));
        }
        if !(self.tol > 0.0 && self.tol < 1e-3) {
            return Err(msg(format!(
                "--tol {}: must be positive and below 1e-3",
                self.tol
            )));
        }
        Ok(res)
    }

    fn build(&self, quiet: bool) -> Result<AlbedoTable, CliError> {
        let res = self.res()?;
        let bar = progress(res as u64, quiet, self.model.name());
        let table = AlbedoTable::build(self.model, res, res, self.tol, &|| bar.inc(1));
        bar.finish_and_clear();
        Ok(table)
    }
}

/// CSV rows (no header, the seed's format) written atomically.
fn write_csv(path: &Path, force: bool, rows: &[Vec<f64>]) -> CliResult {
    let mut w = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(Vec::new());
    for r in rows {
        w.serialize(r)
            .map_err(|e| msg(format!("{}: {e}", path.display())))?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| msg(format!("{}: {e}", path.display())))?;
    npf_data_loaders::atomic::write_bytes_atomic(path, force, &bytes)?;
    Ok(())
}

fn run_table(a: TableArgs) -> CliResult {
    a.spec.res()?;
    check_output(&a.out.output, a.out.force)?;
    let t = a.spec.build(a.quiet)?;
    let rows: Vec<Vec<f64>> = (0..t.n_alpha)
        .flat_map(|k| {
            let t = &t;
            (0..t.n_mu).map(move |j| vec![t.mu(j), t.alpha(k), t.e[k * t.n_mu + j]])
        })
        .collect();
    write_csv(&a.out.output, a.out.force, &rows)?;
    if !a.quiet {
        eprintln!(
            "wrote {} ({} x {})",
            a.out.output.display(),
            t.n_mu,
            t.n_alpha
        );
    }
    Ok(())
}

fn run_avg(a: AvgArgs) -> CliResult {
    a.spec.res()?;
    if let Some(p) = &a.out.output {
        check_output(p, a.out.force)?;
    }
    let t = a.spec.build(a.quiet)?;
    let ours = fit_avg(&t);
    let seed = seed_fit(t.model);
    println!(
        "{} E_avg over {} alpha nodes (2 pi int E mu dmu, max pi)",
        t.model.name(),
        t.n_alpha
    );
    println!(
        "  our fit : E_avg = {}   max error {:.3e}",
        ours.formula(),
        ours.max_error(&t)
    );
    println!(
        "  seed fit: E_avg = {}   max error {:.3e}",
        seed.formula(),
        seed.max_error(&t)
    );
    if let Some(p) = &a.out.output {
        let rows: Vec<Vec<f64>> = (0..t.n_alpha)
            .map(|k| vec![t.alpha(k), t.e_avg[k]])
            .collect();
        write_csv(p, a.out.force, &rows)?;
    }
    Ok(())
}

fn furnace_points(
    spec: &TableSpec,
    alphas: Option<usize>,
    quiet: bool,
) -> Result<(AlbedoTable, Vec<FurnacePoint>), CliError> {
    let res = spec.res()?;
    let n = alphas.unwrap_or(2 * res - 1);
    if !(2..=100_000).contains(&n) {
        return Err(msg(format!("--alphas {n}: must be between 2 and 100000")));
    }
    let t = spec.build(quiet)?;
    let points = furnace(&t, n, spec.tol.max(1e-12) * 10.0);
    Ok((t, points))
}

fn run_furnace(a: FurnaceArgs) -> CliResult {
    if let Some(p) = &a.out.output {
        check_output(p, a.out.force)?;
    }
    let (t, points) = furnace_points(&a.spec, a.alphas, a.quiet)?;
    let worst = points
        .iter()
        .copied()
        .max_by(|x, y| x.error().total_cmp(&y.error()));
    println!(
        "{} {}x{}: max |int int (f + f_ms) cos cos - pi| = {:.3e} over {} alphas{}",
        t.model.name(),
        t.n_mu,
        t.n_alpha,
        max_error(&points),
        points.len(),
        worst.map_or(String::new(), |w| format!(" (at alpha {:.4})", w.alpha)),
    );
    if let Some(p) = &a.out.output {
        let rows: Vec<Vec<f64>> = points
            .iter()
            .map(|q| vec![q.alpha, q.single, q.compensation, q.sum()])
            .collect();
        write_csv(p, a.out.force, &rows)?;
    }
    Ok(())
}

/// Most walks per configuration of `energy simulate` and `energy tau`
/// (about 100 s per core at 100 ns a walk; memory grows with walks / 4096).
pub const MAX_PATHS: usize = 1_000_000_000;
/// Most walks of one `energy simulate` or `energy tau` run in all.
pub const MAX_TOTAL_PATHS: u64 = 10_000_000_000;

fn check_paths(paths: usize, configs: usize, min: usize) -> CliResult {
    if paths < min {
        return Err(msg(format!(
            "--paths: need at least {min} walks for a standard error"
        )));
    }
    if paths > MAX_PATHS {
        return Err(msg(format!(
            "--paths {paths}: at most {MAX_PATHS} walks per configuration"
        )));
    }
    let total = paths as u64 * configs as u64;
    if total > MAX_TOTAL_PATHS {
        return Err(msg(format!(
            "--paths {paths} over {configs} configurations is {total} walks: at most {MAX_TOTAL_PATHS} in one run"
        )));
    }
    Ok(())
}

fn check_unit(name: &str, values: &[f64], lo: f64, hi: f64) -> CliResult {
    if values.is_empty() {
        return Err(msg(format!("--{name}: give at least one value")));
    }
    for &v in values {
        if !(v >= lo && v <= hi) {
            return Err(msg(format!("--{name} {v}: must be in [{lo}, {hi}]")));
        }
    }
    Ok(())
}

fn run_simulate(a: SimulateArgs) -> CliResult {
    check_unit("alpha", &a.alpha, 1e-3, 4.0)?;
    check_unit("theta", &a.theta, 0.0, 89.9)?;
    check_unit("reflectance", &a.reflectance, 0.0, 1.0)?;
    check_paths(a.paths, a.alpha.len() * a.theta.len(), 2)?;
    if let Some(p) = &a.out.output {
        check_output(p, a.out.force)?;
    }
    let (surface, ndf, paths) = (a.surface, a.ndf, a.paths);
    let reflectance = &a.reflectance;
    let configs: Vec<SimConfig> = a
        .alpha
        .iter()
        .flat_map(|&alpha| {
            a.theta.iter().map(move |&deg| SimConfig {
                surface,
                ndf,
                alpha,
                theta: deg.to_radians(),
                reflectances: reflectance.clone(),
                paths,
            })
        })
        .collect();
    let total = (configs.len() * a.paths) as u64;
    let bar = progress(total, a.quiet, "walks");
    let start = std::time::Instant::now();
    let results = simulate(&configs, a.seed, &|n| bar.inc(n));
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "{:?} {:?}: {} walks in {:.2} s ({:.0} ns/walk)",
        a.surface,
        a.ndf,
        total,
        secs,
        secs * 1e9 / total as f64
    );
    println!("alpha  theta  refl   E1      E2      E3      E4      E5      E6      E7+     total   (+- s.e.)");
    let mut rows = Vec::new();
    for (c, res) in configs.iter().zip(&results) {
        for (&r, e) in c.reflectances.iter().zip(res) {
            let mut line = format!("{:<6} {:<6.1} {:<6}", c.alpha, c.theta.to_degrees(), r);
            for b in 0..ORDER_BINS {
                line += &format!(" {:.4}", e.mean[b]);
            }
            line += &format!("  {:.4} +- {:.1e}", e.total, e.total_stderr);
            println!("{line}");
            let mut row = vec![c.alpha, c.theta.to_degrees(), r];
            for b in 0..ORDER_BINS {
                row.extend([e.mean[b], e.stderr[b]]);
            }
            row.extend([e.total, e.total_stderr]);
            rows.push(row);
        }
    }
    if let Some(p) = &a.out.output {
        write_csv(p, a.out.force, &rows)?;
    }
    Ok(())
}

fn run_tau(a: TauArgs) -> CliResult {
    check_unit("alpha", &a.alpha, 1e-3, 1.0)?;
    check_unit("reflectance", &a.reflectance, 1e-3, 1.0)?;
    if !(1..=64).contains(&a.mu_nodes) {
        return Err(msg("--mu-nodes: must be between 1 and 64"));
    }
    let studies = a.surface.map_or(2, |_| 1) * a.ndf.map_or(2, |_| 1);
    check_paths(a.paths, studies * a.alpha.len() * a.mu_nodes, 2)?;
    println!("The seed's constants against their own definitions:");
    for c in check_seed_constants() {
        println!(
            "  {:<42} stated {:<22} from definition {:<22} {}",
            c.name,
            c.stated,
            c.from_definition,
            if c.holds() { "holds" } else { "DOES NOT HOLD" }
        );
    }
    println!(
        "  sums over n >= 2 at reflectance 1: Fresnel {:.15}, diffuse {:.15}",
        series::fresnel_factor(1.0, series::SEED_TAU_F0),
        series::diffuse_factor(1.0, series::SEED_TAU_RHO)
    );
    let surfaces = a
        .surface
        .map_or(vec![Surface::Conductor, Surface::Diffuse], |s| vec![s]);
    let ndfs = a.ndf.map_or(vec![Ndf::Ggx, Ndf::Beckmann], |n| vec![n]);
    let per_study = (a.alpha.len() * a.mu_nodes * a.paths) as u64;
    let bar = progress(
        per_study * (surfaces.len() * ndfs.len()) as u64,
        a.quiet,
        "walks",
    );
    println!("Refitted tau (orders 2..6, hemispherical averages, a1 tied by the seed's normalisation / free):");
    for &surface in &surfaces {
        let seed_tau = match surface {
            Surface::Conductor => series::SEED_TAU_F0,
            Surface::Diffuse => series::SEED_TAU_RHO,
        };
        for &ndf in &ndfs {
            let start = std::time::Instant::now();
            let study = tau::run_study(
                surface,
                ndf,
                &a.alpha,
                &a.reflectance,
                a.mu_nodes,
                a.paths,
                a.seed,
                &|n| bar.inc(n),
            );
            let secs = start.elapsed().as_secs_f64();
            let all: Vec<usize> = (0..study.alphas.len()).collect();
            let (tied, free) = (study.fit(&all, true), study.fit(&all, false));
            bar.suspend(|| {
                println!(
                    "  {surface:?} {ndf:?}: pooled tau {:.3} (a1 {:.3}, rms {:.1e}) / {:.3} (a1 {:.3}, rms {:.1e}); seed {seed_tau}; {:.1} s",
                    tied.tau, tied.a1, tied.rms, free.tau, free.a1, free.rms, secs
                );
                for (k, alpha) in study.alphas.iter().enumerate() {
                    let (t, f) = (study.fit(&[k], true), study.fit(&[k], false));
                    println!("      alpha {alpha:<4}: tau {:.3} / {:.3}", t.tau, f.tau);
                }
            });
        }
    }
    bar.finish_and_clear();
    Ok(())
}

fn run_plot(a: PlotArgs) -> CliResult {
    a.spec.res()?;
    let ext = a
        .out
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let png = match ext.as_deref() {
        Some("svg") => false,
        Some("png") => true,
        _ => {
            return Err(msg(format!(
                "{}: the output must end in .svg or .png",
                a.out.output.display()
            )))
        }
    };
    check_output(&a.out.output, a.out.force)?;
    plot::register_font(a.font.as_deref()).map_err(msg)?;
    let (t, points) = furnace_points(&a.spec, Some(101), a.quiet)?;
    let path = &a.out.output;
    let bytes = if png {
        // Render next to the target, then move it into place atomically.
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = path.with_file_name(format!(".{name}.{}.tmp.png", std::process::id()));
        let _live = npf_data_loaders::atomic::register_temp(&tmp);
        let drawn = plot::png(&tmp, &t, &points)
            .and_then(|_| std::fs::read(&tmp).map_err(|e| e.to_string()));
        let _ = std::fs::remove_file(&tmp);
        drawn.map_err(|e| msg(format!("{}: {e}", path.display())))?
    } else {
        plot::svg(&t, &points).map_err(|e| msg(format!("{}: {e}", path.display())))?
    };
    npf_data_loaders::atomic::write_bytes_atomic(path, a.out.force, &bytes)?;
    if !a.quiet {
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
