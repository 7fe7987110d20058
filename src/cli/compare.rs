//! `npf compare REF.{binary,bin} MODEL_OR_TABLE [--images DIR]`: every error
//! measure of `docs/evaluation.md` for a model file (.json, .npfb) or a
//! second measured table against a reference table (MERL or UTIA), and optionally the two
//! sphere renders and their difference as PNG.

use super::png::encode_png;
use super::{check_outputs, CliError, CliResult};
use crate::evaluation::{Evaluation, Reference};
use crate::modelfile::{self, Form};
use crate::render::{difference_rgb8, Image, RenderOptions};
use clap::Args;
use npf_data_loaders::atomic::write_bytes_atomic;
use std::path::{Path, PathBuf};

/// `npf compare`'s arguments.
#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Reference measured BRDF (MERL .binary or UTIA .bin; a UTIA table is
    /// rendered with its quadrilinear interpolation).
    pub reference: PathBuf,
    /// Model file (.json, .npfb) or measured table to compare.
    pub test: PathBuf,
    /// Read the tables as this format instead of detecting it.
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
    /// Grazing cut-off of the sample metrics (degrees).
    #[arg(long, default_value_t = 85.0)]
    pub max_theta: f64,
    /// Render resolution (pixels square).
    #[arg(long, default_value_t = 128)]
    pub res: usize,
    /// Environment quadrature strata in elevation (twice as many in azimuth).
    #[arg(long, default_value_t = 24)]
    pub n_theta: usize,
    /// Write reference.png, test.png and difference.png (x8) into this folder.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Print the measures as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Overwrite existing images.
    #[arg(long)]
    pub force: bool,
}

/// Gain of the difference images (|reference - test| x this).
pub const DIFF_GAIN: f64 = 8.0;

/// Write the reference, test and difference images into `dir`.
pub fn write_images(
    dir: &Path,
    names: [&str; 3],
    reference: &Image,
    test: &Image,
    force: bool,
) -> CliResult {
    let r = reference.res as u32;
    let bufs = [
        reference.to_rgb8(),
        test.to_rgb8(),
        difference_rgb8(reference, test, DIFF_GAIN),
    ];
    for (name, buf) in names.iter().zip(bufs) {
        let path = dir.join(name);
        let png = encode_png(r, r, &buf)
            .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
        write_bytes_atomic(&path, force, &png)?;
    }
    Ok(())
}

/// Print an evaluation's measures, one per line.
pub fn print_evaluation(e: &Evaluation) {
    let m = &e.metrics;
    println!(
        "samples             {} (theta_i, theta_o <= {} deg)",
        m.samples, m.max_theta_deg
    );
    println!(
        "cosine-weighted RMSE {:.4e} 1/sr (relative {:.4e})",
        m.cos_rmse, m.rel_cos_rmse
    );
    println!("log(1 + rho cos) RMSE {:.4e}", m.log_rmse);
    println!("numerical PSNR      {:.2} dB", e.numeric_psnr_db);
    for a in &e.albedo {
        println!(
            "albedo at {:>4.1} deg  ref {:.4} {:.4} {:.4}  test {:.4} {:.4} {:.4}  error {:.2}%",
            a.theta_o_deg,
            a.reference[0],
            a.reference[1],
            a.reference[2],
            a.model[0],
            a.model[1],
            a.model[2],
            100.0 * a.rel_error
        );
    }
    println!("rendering PSNR      {:.2} dB", e.render_psnr_db);
}

/// Run `npf compare`.
pub fn run(args: CompareArgs) -> CliResult {
    if !(args.max_theta > 0.0 && args.max_theta <= 90.0) {
        return Err(CliError::Message(format!(
            "--max-theta must be in (0, 90] degrees, got {}",
            args.max_theta
        )));
    }
    if !(1..=4096).contains(&args.res) || !(1..=1024).contains(&args.n_theta) {
        return Err(CliError::Message(
            "--res must be 1 to 4096 and --n-theta 1 to 1024".into(),
        ));
    }
    let names = ["reference.png", "test.png", "difference.png"];
    if let Some(dir) = &args.images {
        if !dir.is_dir() {
            return Err(CliError::Message(format!(
                "{}: the image folder does not exist",
                dir.display()
            )));
        }
        let outs: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
        let outs: Vec<&Path> = outs.iter().map(|p| p.as_path()).collect();
        check_outputs(&outs, &[&args.reference, &args.test], args.force)?;
    }
    let (table, samples) = super::read_measured(&args.reference, args.format)?;
    let opts = RenderOptions {
        res: args.res,
        n_theta: args.n_theta,
    };
    let reference = Reference::new(super::table_bsdf(&table), &samples, opts);
    let (eval, image) = if Form::of(&args.test).is_ok() {
        let file = modelfile::read(&args.test)?;
        reference.evaluate_model(args.max_theta, &file.model)
    } else {
        let other = npf_data_loaders::Table::read(&args.test, args.format.map(Into::into))?;
        reference.evaluate(args.max_theta, super::table_bsdf(&other))
    }
    .map_err(|e| CliError::Message(e.to_string()))?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&eval).map_err(|e| CliError::Message(e.to_string()))?
        );
    } else {
        println!(
            "{} against {}",
            args.test.display(),
            args.reference.display()
        );
        print_evaluation(&eval);
    }
    if let Some(dir) = &args.images {
        write_images(dir, names, &reference.image, &image, args.force)?;
    }
    Ok(())
}
