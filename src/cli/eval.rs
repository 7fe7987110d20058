//! `npf eval MODEL THETA_I PHI_I THETA_O PHI_O`: model values at directions.

use super::{CliError, CliResult};
use crate::bsdf::Bsdf;
use crate::modelfile;
use clap::Args;
use npf_data_loaders::geometry::{spherical, Vec3};
use npf_data_loaders::rgl_brdf::RglBrdf;
use std::path::PathBuf;

/// `npf eval`'s arguments.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Model file (.json or .npfb), or an RGL .bsdf file (its BRDF as
    /// Mitsuba 3's measured plugin evaluates it, in RGB; the view, theta_o
    /// phi_o, is the file's conditioning direction).
    pub model: PathBuf,
    /// Directions in degrees, four numbers per configuration:
    /// theta_i phi_i theta_o phi_o [theta_i phi_i theta_o phi_o ...];
    /// theta 0 to 90 (the value at 90, the horizon, is 0).
    #[arg(required = true, num_args = 4.., allow_negative_numbers = true)]
    pub angles: Vec<f64>,
    /// A spectral .bsdf file: the values at these wavelengths (nm,
    /// comma-separated, at most 64) instead of RGB; linear between the
    /// file's wavelength nodes and held beyond its ends, as Mitsuba 3's
    /// spectral variants read it.
    #[arg(long, value_delimiter = ',', value_name = "NM,...")]
    pub wavelengths: Vec<f64>,
}

/// Values of a model or file at (wo, wi), one per output column.
type Evaluator = Box<dyn Fn(Vec3, Vec3) -> Vec<f64>>;

/// Most wavelengths `--wavelengths` takes.
const MAX_WAVELENGTHS: usize = 64;

/// Run `npf eval`.
pub fn run(args: EvalArgs) -> CliResult {
    if args.angles.len() % 4 != 0 {
        return Err(CliError::Message(format!(
            "eval takes angles in groups of four (theta_i phi_i theta_o phi_o), got {}",
            args.angles.len()
        )));
    }
    if let Some(v) = args.angles.iter().find(|v| !v.is_finite()) {
        return Err(CliError::Message(format!(
            "angle {v} is not a finite number"
        )));
    }
    for q in args.angles.chunks(4) {
        for theta in [q[0], q[2]] {
            if !(0.0..=90.0).contains(&theta) {
                return Err(CliError::Message(format!(
                    "theta {theta}: polar angles must be 0 to 90 degrees (a direction below the horizon is not mirrored)"
                )));
            }
        }
    }
    let is_bsdf = args
        .model
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bsdf"));
    let lambdas = &args.wavelengths;
    if lambdas.len() > MAX_WAVELENGTHS {
        return Err(CliError::Message(format!(
            "--wavelengths: {} values, at most {MAX_WAVELENGTHS}",
            lambdas.len()
        )));
    }
    if let Some(l) = lambdas.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
        return Err(CliError::Message(format!(
            "--wavelengths: {l} is not a positive wavelength in nm"
        )));
    }
    let (columns, eval): (Vec<String>, Evaluator) = if is_bsdf {
        let b = RglBrdf::read(&args.model)?;
        if lambdas.is_empty() {
            (
                names(["r", "g", "b"]),
                Box::new(move |wo, wi| b.eval(wo, wi).to_vec()),
            )
        } else if b.wavelengths().is_none() {
            return Err(CliError::Message(format!(
                "{}: --wavelengths needs a spectral .bsdf file (this one has `rgb`, no `spectra`)",
                args.model.display()
            )));
        } else {
            let l = lambdas.clone();
            (
                lambdas.iter().map(|l| format!("{l}nm")).collect(),
                // The view (wo) is the file's conditioning direction.
                Box::new(move |wo, wi| b.spectral_value(wo, wi, &l).unwrap_or_default()),
            )
        }
    } else {
        if !lambdas.is_empty() {
            return Err(CliError::Message(format!(
                "{}: --wavelengths applies to spectral .bsdf files; a model is RGB",
                args.model.display()
            )));
        }
        let model = modelfile::read(&args.model)?.model;
        (
            names(["r", "g", "b"]),
            Box::new(move |wo, wi| model.eval(wo, wi).to_vec()),
        )
    };
    println!("theta_i,phi_i,theta_o,phi_o,{}", columns.join(","));
    for q in args.angles.chunks(4) {
        let wi = spherical(q[0].to_radians(), q[1].to_radians());
        let wo = spherical(q[2].to_radians(), q[3].to_radians());
        // The convention: zero at the horizon. cos(90 deg) rounds to 6e-17,
        // not 0, so the model alone would return a (huge) non-zero value.
        let v = if q[0] >= 90.0 || q[2] >= 90.0 {
            vec![0.0; columns.len()]
        } else {
            eval(wo, wi)
        };
        let values: Vec<String> = v.iter().map(|x| format!("{x:.9e}")).collect();
        println!("{},{},{},{},{}", q[0], q[1], q[2], q[3], values.join(","));
    }
    Ok(())
}

fn names<const N: usize>(n: [&str; N]) -> Vec<String> {
    n.iter().map(|s| s.to_string()).collect()
}
