//! `npf sample MODEL --theta-o DEG --n N [--seed S] [-o OUT.csv]`: draws
//! from the model's importance sampler (see docs/sampling.md).
//!
//! wo = (sin theta_o, 0, cos theta_o). One CSV line per sample after a
//! header: `wi_x,wi_y,wi_z,pdf,w_r,w_g,w_b` with w = f cos(theta_i) / pdf;
//! a draw below the horizon has pdf and w zero, so the mean of w estimates
//! the directional albedo. A summary goes to standard error.

use super::{check_output, CliError, CliResult};
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
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
}

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
    if let Some(out) = &args.output {
        check_output(out, args.force)?;
    }
    let model = modelfile::read(&args.model)?.model;
    let bxdf = NpfBxdf::new(model)
        .map_err(|e| CliError::Message(format!("{}: invalid model: {e}", args.model.display())))?;
    let theta = args.theta_o.to_radians();
    let wo = [theta.sin(), 0.0, theta.cos()];
    let mut sum = [0.0f64; 3];
    let mut lost = 0u64;
    let mut write = |w: &mut dyn Write| -> io::Result<()> {
        let mut rng = Pcg64::seed_from_u64(args.seed);
        writeln!(w, "wi_x,wi_y,wi_z,pdf,w_r,w_g,w_b")?;
        for _ in 0..args.n {
            let (ul, u0, u1): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
            let s = bxdf.sample(wo, ul, [u0, u1]);
            if s.is_lost() {
                lost += 1;
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
