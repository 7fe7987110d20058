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
}

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
    let eval: Box<dyn Fn(Vec3, Vec3) -> [f64; 3]> = if is_bsdf {
        let b = RglBrdf::read(&args.model)?;
        Box::new(move |wo, wi| b.eval(wo, wi))
    } else {
        let model = modelfile::read(&args.model)?.model;
        Box::new(move |wo, wi| model.eval(wo, wi))
    };
    println!("theta_i,phi_i,theta_o,phi_o,r,g,b");
    for q in args.angles.chunks(4) {
        let wi = spherical(q[0].to_radians(), q[1].to_radians());
        let wo = spherical(q[2].to_radians(), q[3].to_radians());
        // The convention: zero at the horizon. cos(90 deg) rounds to 6e-17,
        // not 0, so the model alone would return a (huge) non-zero value.
        let v = if q[0] >= 90.0 || q[2] >= 90.0 {
            [0.0; 3]
        } else {
            eval(wo, wi)
        };
        println!(
            "{},{},{},{},{:.9e},{:.9e},{:.9e}",
            q[0], q[1], q[2], q[3], v[0], v[1], v[2]
        );
    }
    Ok(())
}
