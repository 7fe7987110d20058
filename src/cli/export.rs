//! `npf export MODEL -o OUT`: a model in a renderer's format, chosen by
//! OUT's extension (`.bsdf`, `.binary`, `.glsl`, `.h`, `.brdf`; see
//! docs/export.md and docs/shader_export.md).

use super::{check_outputs, CliError, CliResult};
use crate::export::{export, ExportError, ExportOptions, Format, RglOptions};
use crate::modelfile;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

/// `npf export`'s arguments.
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Output file; its extension picks the format: .bsdf (RGL tensor file, Mitsuba 3; pbrt-v4 with --spectral),
    /// .binary (MERL table), .glsl (GLSL eval/pdf/sample functions), .h (C99 header with the
    /// same three functions) or .brdf (BRDF Explorer analytic file).
    #[arg(short, long)]
    pub output: PathBuf,
    /// .bsdf: write `spectra` + `wavelengths` (Smits RGB upsampling; pbrt-v4, Mitsuba spectral variants) instead of `rgb`.
    #[arg(long)]
    pub spectral: bool,
    /// .bsdf: theta_i nodes (2 to 512).
    #[arg(long, default_value_t = RglOptions::default().theta_i)]
    pub theta_i: usize,
    /// .bsdf: sample-grid nodes per axis of `rgb`/`luminance` (2 to 512).
    #[arg(long, default_value_t = RglOptions::default().samples)]
    pub samples: usize,
    /// .bsdf: `vndf` nodes per axis (2 to 512).
    #[arg(long, default_value_t = RglOptions::default().vndf)]
    pub vndf: usize,
    /// .bsdf: `ndf`/`sigma` nodes along theta (2 to 512).
    #[arg(long, default_value_t = RglOptions::default().ndf)]
    pub ndf: usize,
    /// .bsdf of an anisotropic model: phi_i nodes over [-180, 180] degrees (2 to 512).
    #[arg(long, default_value_t = RglOptions::default().phi_i)]
    pub phi_i: usize,
    /// .bsdf: least share of the proxy NDF's constant part, in [0, 1) (the fraction of sample nodes kept for the broad part of the BRDF).
    #[arg(long, default_value_t = RglOptions::default().broad)]
    pub broad: f64,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print nothing on success.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Run `npf export`.
pub fn run(args: ExportArgs) -> CliResult {
    let flag = |e: ExportError| match e {
        ExportError::UnknownFormat(_) => {
            CliError::Message(format!("{}: {e}", args.output.display()))
        }
        ExportError::Option(m) => CliError::Message(
            format!("--{m}")
                .replace("--theta_i", "--theta-i")
                .replace("--phi_i", "--phi-i"),
        ),
        other => CliError::Message(format!("{}: {other}", args.model.display())),
    };
    let format = Format::of(&args.output).map_err(flag)?;
    let opts = ExportOptions {
        rgl: RglOptions {
            theta_i: args.theta_i,
            samples: args.samples,
            vndf: args.vndf,
            ndf: args.ndf,
            phi_i: args.phi_i,
            broad: args.broad,
            spectral: args.spectral,
        },
    };
    opts.rgl.validate().map_err(flag)?;
    if args.spectral && format != Format::Rgl {
        return Err(CliError::Message(
            "--spectral applies to .bsdf outputs only".into(),
        ));
    }
    // Never overwrite the input, even with --force.
    // Refuses an output that is the input under any name (links, `..`),
    // a directory, a special file, or an existing file without --force.
    check_outputs(&[&args.output], &[&args.model], args.force)?;
    let model = modelfile::read(&args.model)?.model;
    let start = Instant::now();
    let bytes = export(&model, &args.output, &opts, args.force).map_err(|e| match e {
        ExportError::Write(l) => CliError::Load(l),
        e => flag(e),
    })?;
    if !args.quiet {
        eprintln!(
            "wrote {} ({} bytes, {:.1} KiB) in {:.2} s",
            args.output.display(),
            bytes,
            bytes as f64 / 1024.0,
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
