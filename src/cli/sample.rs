//! `npf sample MODEL --theta-o DEG --n N [--seed S] [-o OUT.csv]`: draws
//! from the model's importance sampler (see docs/sampling.md).
//!
//! wo = (sin theta_o, 0, cos theta_o). One CSV line per sample after a
//! header: `wi_x,wi_y,wi_z,pdf,w_r,w_g,w_b` with w = f cos(theta_i) / pdf;
//! a draw below the horizon has pdf and w zero, so the mean of w estimates
//! the directional albedo. A summary goes to standard error.

use super::{check_outputs, CliError, CliResult};
use crate::modelfile;
use crate::sampling::NpfBxdf;
use clap::Args;
use npf_data_loaders::atomic::write_atomic;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::io::{self, Write};
use std::path::PathBuf;

/// Largest --n accepted (about 100 bytes of CSV each).
pub const MAX_SAMPLES: u64 = 100_000_000;

/// `npf sample`'s arguments.
#[derive(Args, Debug)]
pub struct SampleArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Polar angle of the outgoing direction wo, degrees in [0, 90).
    #[arg(long, allow_negative_numbers = true)]
    pub theta_o: f64,
    /// Number of samples.
    #[arg(long)]
    pub n: u64,
    /// Seed of the random numbers (PCG64).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the CSV here (atomically) instead of standard output.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also write a PNG: left, the histogram of the drawn wi; right, the
    /// pdf; both as densities over the projected disk (wi_x, wi_y), on one
    /// logarithmic colour scale (4 decades).
    #[arg(long)]
    pub histogram: Option<PathBuf>,
    /// Overwrite existing output files.
    #[arg(long)]
    pub force: bool,
}

/// Cells per side of the histogram over the projected disk.
const HIST_RES: usize = 96;

fn hist_cell(wi: [f64; 3]) -> Option<usize> {
    let f = |v: f64| ((v + 1.0) / 2.0 * HIST_RES as f64).floor();
    let (i, j) = (f(wi[0]), f(wi[1]));
    if (0.0..HIST_RES as f64).contains(&i) && (0.0..HIST_RES as f64).contains(&j) {
        Some(j as usize * HIST_RES + i as usize)
    } else {
        None
    }
}

/// The histogram and the pdf as densities per unit projected area
/// (pdf / cos theta_i; pdf averaged over 4 x 4 points per cell).
fn histogram_png(
    bxdf: &NpfBxdf,
    wo: [f64; 3],
    counts: &[u64],
    n: u64,
    path: &std::path::Path,
    force: bool,
) -> CliResult {
    let cell = 2.0 / HIST_RES as f64;
    let hist: Vec<f64> = counts
        .iter()
        .map(|&c| c as f64 / (n as f64 * cell * cell))
        .collect();
    let mut pdf = vec![0.0; HIST_RES * HIST_RES];
    for j in 0..HIST_RES {
        for i in 0..HIST_RES {
            let mut acc = 0.0;
            for a in 0..4 {
                for b in 0..4 {
                    let x = -1.0 + (i as f64 + (a as f64 + 0.5) / 4.0) * cell;
                    let y = -1.0 + (j as f64 + (b as f64 + 0.5) / 4.0) * cell;
                    let z2 = 1.0 - x * x - y * y;
                    if z2 > 0.0 {
                        let z = z2.sqrt();
                        acc += bxdf.pdf(wo, [x, y, z]) / z;
                    }
                }
            }
            pdf[j * HIST_RES + i] = acc / 16.0;
        }
    }
    let top = hist.iter().chain(&pdf).cloned().fold(0.0, f64::max);
    let scale = 4;
    let (w, h) = (2 * HIST_RES * scale + 8, HIST_RES * scale);
    let mut rgb = vec![0u8; w * h * 3];
    for (panel, values) in [&hist, &pdf].into_iter().enumerate() {
        for j in 0..HIST_RES {
            for i in 0..HIST_RES {
                let v = values[j * HIST_RES + i];
                let c = if top > 0.0 && v > 0.0 {
                    heat(((v / top).log10() / 4.0 + 1.0).clamp(0.0, 1.0))
                } else {
                    [0, 0, 0]
                };
                for dy in 0..scale {
                    for dx in 0..scale {
                        let x = panel * (HIST_RES * scale + 8) + i * scale + dx;
                        // +y up in the picture.
                        let y = (HIST_RES - 1 - j) * scale + dy;
                        rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&c);
                    }
                }
            }
        }
    }
    let png = super::png::encode_png(w as u32, h as u32, &rgb)
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
    npf_data_loaders::atomic::write_bytes_atomic(path, force, &png)?;
    Ok(())
}

/// Black - red - yellow - white.
fn heat(x: f64) -> [u8; 3] {
    let c = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [c(3.0 * x), c(3.0 * x - 1.0), c(3.0 * x - 2.0)]
}

/// Run `npf sample`.
pub fn run(args: SampleArgs) -> CliResult {
    if !(args.theta_o.is_finite() && (0.0..90.0).contains(&args.theta_o)) {
        return Err(CliError::Message(format!(
            "--theta-o {}: must be a number of degrees in [0, 90)",
            args.theta_o
        )));
    }
    if args.n == 0 || args.n > MAX_SAMPLES {
        return Err(CliError::Message(format!(
            "--n {}: must be between 1 and {MAX_SAMPLES}",
            args.n
        )));
    }
    let outs: Vec<&std::path::Path> = [&args.output, &args.histogram]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    check_outputs(&outs, &[&args.model], args.force)?;
    let model = modelfile::read(&args.model)?.model;
    let bxdf = NpfBxdf::new(model)
        .map_err(|e| CliError::Message(format!("{}: invalid model: {e}", args.model.display())))?;
    let theta = args.theta_o.to_radians();
    let wo = [theta.sin(), 0.0, theta.cos()];
    let mut sum = [0.0f64; 3];
    let mut lost = 0u64;
    let mut counts = vec![0u64; HIST_RES * HIST_RES];
    let mut write = |w: &mut dyn Write| -> io::Result<()> {
        let mut rng = Pcg64::seed_from_u64(args.seed);
        writeln!(w, "wi_x,wi_y,wi_z,pdf,w_r,w_g,w_b")?;
        for _ in 0..args.n {
            let (ul, u0, u1): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
            let s = bxdf.sample(wo, ul, [u0, u1]);
            if s.is_lost() {
                lost += 1;
            } else if let Some(k) = hist_cell(s.wi) {
                counts[k] += 1;
            }
            for (acc, w) in sum.iter_mut().zip(s.weight) {
                *acc += w;
            }
            writeln!(
                w,
                "{:.9},{:.9},{:.9},{:.9e},{:.9e},{:.9e},{:.9e}",
                s.wi[0], s.wi[1], s.wi[2], s.pdf, s.weight[0], s.weight[1], s.weight[2]
            )?;
        }
        Ok(())
    };
    match &args.output {
        Some(out) => write_atomic(out, args.force, &mut write)?,
        None => {
            let stdout = io::stdout();
            let mut lock = io::BufWriter::new(stdout.lock());
            let r = write(&mut lock).and_then(|_| lock.flush());
            if let Err(e) = r {
                // A closed pipe (e.g. `| head`) is not an error worth reporting.
                if e.kind() != io::ErrorKind::BrokenPipe {
                    return Err(CliError::Message(format!("writing samples: {e}")));
                }
                return Ok(());
            }
        }
    }
    if let Some(png) = &args.histogram {
        histogram_png(&bxdf, wo, &counts, args.n, png, args.force)?;
    }
    let n = args.n as f64;
    eprintln!(
        "{} samples at theta_o = {} deg: mean w (directional albedo) {:.6e} {:.6e} {:.6e}; \
         {} below the horizon ({:.4}%, tables say {:.4}%); sampling tables {} bytes",
        args.n,
        args.theta_o,
        sum[0] / n,
        sum[1] / n,
        sum[2] / n,
        lost,
        100.0 * lost as f64 / n,
        100.0 * bxdf.lost_mass(wo),
        bxdf.table_bytes()
    );
    Ok(())
}
