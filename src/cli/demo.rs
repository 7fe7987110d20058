//! `npf demo`: the main job on data npf makes itself. Tabulates an analytic
//! GGX + Lambert BRDF as a MERL table, fits it, writes the model in both
//! forms and its reconstruction, and prints the errors.

use super::fit_args::FitFlags;
use super::fit_table::{fit_with_progress, print_summary};
use super::{check_outputs, CliError, CliResult};
use crate::fit::ModelKind;
use crate::metrics::compare;
use crate::modelfile::{self, ModelFile};
use crate::reconstruct::to_merl;
use crate::synth::GgxLambert;
use clap::Args;
use std::path::PathBuf;

/// `npf demo`'s arguments.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Folder for the demo's files (created if missing).
    #[arg(short, long, default_value = "demo")]
    pub out_dir: PathBuf,
    /// How to fit (the `npf fit` options).
    #[command(flatten)]
    pub config: FitFlags,
    /// Overwrite files left by an earlier run.
    #[arg(long)]
    pub force: bool,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The demo material: a glossy gold-like GGX + Lambert BRDF.
pub const DEMO_BRDF: GgxLambert = GgxLambert {
    kd: [0.05, 0.08, 0.12],
    f0: [0.95, 0.64, 0.54],
    alpha: 0.15,
};

/// Run `npf demo`.
pub fn run(args: DemoArgs) -> CliResult {
    let dir = &args.out_dir;
    let names = [
        "ggx-lambert.binary",
        "ggx-lambert.json",
        "ggx-lambert.npfb",
        "ggx-lambert.reconstructed.binary",
    ];
    let paths: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    // Every option first: a refused option must leave nothing behind.
    let config = args.config.config(ModelKind::Factor);
    config.validate()?;
    if dir.exists() && !dir.is_dir() {
        return Err(CliError::Message(format!(
            "{}: is {}, not a folder",
            dir.display(),
            npf_data_loaders::sniff::describe(dir)
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| npf_data_loaders::LoadError::io(dir, e))?;
    let outs: Vec<&std::path::Path> = paths.iter().map(|p| p.as_path()).collect();
    check_outputs(&outs, &[], args.force)?;
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}")
        }
    };
    say(format!(
        "tabulating GGX + Lambert (alpha {}, F0 {:?}, kd {:?}) as a MERL table",
        DEMO_BRDF.alpha, DEMO_BRDF.f0, DEMO_BRDF.kd
    ));
    let table = DEMO_BRDF.table();
    let samples = table.samples(&paths[0].display().to_string());
    let fitted = fit_with_progress(&samples, &config, !args.quiet)?;
    let file = ModelFile {
        model: fitted.result.model.clone(),
        fit: Some(fitted.info.clone()),
    };
    // Written only once the fit succeeded: a failed run leaves nothing.
    table.write(&paths[0], args.force)?;
    modelfile::write(&paths[1], &file, args.force)?;
    modelfile::write(&paths[2], &file, args.force)?;
    let rec = to_merl(&file.model);
    rec.write(&paths[3], args.force)?;
    if !args.quiet {
        print_summary(&fitted);
        let all = compare(&samples, 90.0, |a| file.model.eval_angles(a));
        eprintln!(
            "errors over all {} valid cells: relative cosine-weighted RMSE {:.4e}, log RMSE {:.4e}",
            all.samples, all.rel_cos_rmse, all.log_rmse
        );
        for p in &paths {
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(())
}
