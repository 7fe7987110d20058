//! `npf compare REF.{binary,bin} MODEL_OR_TABLE... [--images DIR]`: every
//! error measure of `docs/evaluation.md` for model files (.json, .npfb) or
//! other measured tables against a reference table (MERL or UTIA), the
//! reference rendered once for all of them, and optionally (one test) the
//! two sphere renders and their difference as PNG.

use super::png::encode_png;
use super::{check_outputs, CliError, CliResult};
use crate::evaluation::{Evaluation, Reference};
use crate::modelfile::{self, Form};
use crate::render::{difference_rgb8, EnvQuadrature, Image, RenderOptions};
use clap::Args;
use npf_data_loaders::atomic::write_bytes_atomic;
use std::path::{Path, PathBuf};

/// `npf compare`'s arguments.
#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Reference measured BRDF (MERL .binary or UTIA .bin; a UTIA table is
    /// rendered with its quadrilinear interpolation).
    pub reference: PathBuf,
    /// Model files (.json, .npfb) or measured tables to compare; the
    /// reference is rendered once for all of them.
    #[arg(required = true, num_args = 1..)]
    pub test: Vec<PathBuf>,
    /// Read the tables as this format instead of detecting it.
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
    /// Grazing cut-off of the sample metrics (degrees).
    #[arg(long, default_value_t = 85.0)]
    pub max_theta: f64,
    /// Render resolution (pixels square).
    #[arg(long, default_value_t = 128)]
    pub res: usize,
    /// Environment quadrature strata in elevation (twice as many in azimuth);
    /// with `--env half-vector`, strata in sqrt(theta_h) (90 is MERL's
    /// theta_h cells; twice as many in azimuth).
    #[arg(long, default_value_t = 24)]
    pub n_theta: usize,
    /// How the environment light is integrated.
    #[arg(long, value_enum, default_value_t = EnvArg::Sphere)]
    pub env: EnvArg,
    /// How a MERL table is read for the renders: truncate (MERL's reader,
    /// each node's value held across its bin) or interpolate (between the
    /// nodes, the convention the tables are made with).
    #[arg(long, value_enum, default_value_t = ReaderArg::Truncate)]
    pub reader: ReaderArg,
    /// Write reference.png, test.png and difference.png (x8) into this folder.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Print the measures as JSON instead of text (an array when there are
    /// several tests).
    #[arg(long)]
    pub json: bool,
    /// Overwrite existing images.
    #[arg(long)]
    pub force: bool,
}

/// How a MERL table is read for the renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReaderArg {
    /// MERL's reader: the bin's lower-edge node, held across the bin
    Truncate,
    /// Multilinear between the nodes (`MerlTable::lookup_interpolated`)
    Interpolate,
}

/// The render's view of a measured table under `reader`.
fn reader_bsdf<'a>(
    table: &'a npf_data_loaders::Table,
    reader: ReaderArg,
    slot: &'a mut Option<crate::bsdf::InterpolatedMerl<'a>>,
) -> &'a (dyn crate::bsdf::Bsdf + Sync) {
    match (table, reader) {
        (npf_data_loaders::Table::Merl(t), ReaderArg::Interpolate) => {
            slot.insert(crate::bsdf::InterpolatedMerl(t))
        }
        _ => super::table_bsdf(table),
    }
}

/// The environment quadrature (see `npf::render::EnvQuadrature`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EnvArg {
    /// One grid of directions over the sphere for every pixel: cheap; a
    /// peak narrower than its spacing renders as dots
    Sphere,
    /// Per pixel, a grid of half vectors dense near the normal: sharp
    /// highlights converge (use --n-theta 90, MERL's theta_h cells; about
    /// 20 times the sphere grid's cost at 24)
    HalfVector,
}

impl From<EnvArg> for EnvQuadrature {
    fn from(e: EnvArg) -> Self {
        match e {
            EnvArg::Sphere => EnvQuadrature::Sphere,
            EnvArg::HalfVector => EnvQuadrature::HalfVector,
        }
    }
}

/// Most tests `npf compare` takes in one run.
pub const MAX_TESTS: usize = 16;

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
    // Every test is held at once (a MERL table is 35 MB).
    if args.test.len() > MAX_TESTS {
        return Err(CliError::Message(format!(
            "at most {MAX_TESTS} tests per run, got {}",
            args.test.len()
        )));
    }
    let names = ["reference.png", "test.png", "difference.png"];
    if let Some(dir) = &args.images {
        if args.test.len() > 1 {
            return Err(CliError::Message(
                "--images takes one test (it writes one test.png)".into(),
            ));
        }
        if !dir.is_dir() {
            return Err(CliError::Message(format!(
                "{}: the image folder does not exist",
                dir.display()
            )));
        }
        let outs: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
        let outs: Vec<&Path> = outs.iter().map(|p| p.as_path()).collect();
        let mut inputs: Vec<&Path> = vec![&args.reference];
        inputs.extend(args.test.iter().map(|p| p.as_path()));
        check_outputs(&outs, &inputs, args.force)?;
    }
    let (table, samples) = super::read_measured(&args.reference, args.format)?;
    // Every test is read (and refused) before the reference is rendered.
    enum Test {
        Model(Box<crate::model::Model>),
        Table(npf_data_loaders::Table),
    }
    let tests = args
        .test
        .iter()
        .map(|path| {
            Ok(if Form::of(path).is_ok() {
                Test::Model(Box::new(modelfile::read(path)?.model))
            } else {
                Test::Table(npf_data_loaders::Table::read(
                    path,
                    args.format.map(Into::into),
                )?)
            })
        })
        .collect::<Result<Vec<_>, CliError>>()?;
    let opts = RenderOptions {
        res: args.res,
        n_theta: args.n_theta,
        env: args.env.into(),
    };
    let mut slot = None;
    let reference = Reference::new(reader_bsdf(&table, args.reader, &mut slot), &samples, opts);
    let mut evals = Vec::with_capacity(tests.len());
    for (path, test) in args.test.iter().zip(&tests) {
        let (eval, image) = match test {
            Test::Model(model) => reference.evaluate_model(args.max_theta, model),
            Test::Table(other) => {
                let mut slot = None;
                reference.evaluate(args.max_theta, reader_bsdf(other, args.reader, &mut slot))
            }
        }
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
        if !args.json {
            println!("{} against {}", path.display(), args.reference.display());
            print_evaluation(&eval);
        }
        if let Some(dir) = &args.images {
            write_images(dir, names, &reference.image, &image, args.force)?;
        }
        evals.push(eval);
    }
    if args.json {
        let text = if evals.len() == 1 {
            serde_json::to_string_pretty(&evals[0])
        } else {
            serde_json::to_string_pretty(&evals)
        };
        println!("{}", text.map_err(|e| CliError::Message(e.to_string()))?);
    }
    Ok(())
}
