//! `npf info FILE`: what a MERL table or a model file holds.

use super::{CliError, CliResult};
use crate::modelfile::{self, Form};
use clap::Args;
use npf_data_loaders::MerlTable;
use std::path::PathBuf;

/// `npf info`'s arguments.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A MERL table (.binary) or a model (.json, .npfb).
    pub file: PathBuf,
}

/// Run `npf info`.
pub fn run(args: InfoArgs) -> CliResult {
    let path = &args.file;
    let bytes = std::fs::metadata(path)
        .map_err(|e| npf_data_loaders::LoadError::io(path, e))?
        .len();
    if Form::of(path).is_ok() {
        let file = modelfile::read(path)?;
        let m = &file.model;
        println!("{}: npf model, valid", path.display());
        println!("  file size      {bytes} bytes");
        let kind = crate::fit::kind_of(file.fit.as_ref());
        println!("  model kind     {}", kind.name());
        println!("  lobes          {}", m.lobe_count());
        println!(
            "  parameters     {} ({} bytes as f32)",
            m.param_count(),
            4 * m.param_count()
        );
        println!(
            "  layout         D {:?}, F {:?}, G {:?}",
            m.layout.d, m.layout.f, m.layout.g
        );
        println!("  diffuse        {:?}", m.diffuse);
        for (i, l) in m.lobes.iter().enumerate() {
            let dmax = l.d.iter().cloned().fold(0.0f32, f32::max);
            println!("  lobe {i}         s {:?}, max D {dmax:.4e}", l.s);
        }
        if let Some(fit) = &file.fit {
            println!("  fitted from    {}", fit.source);
            println!(
                "  fit            {} sweeps ({}), {:.2} s, {} threads, weighting {}, G {}",
                fit.sweeps,
                if fit.converged {
                    "converged"
                } else {
                    "sweep limit"
                },
                fit.seconds,
                fit.threads,
                fit.weighting,
                fit.g_method
            );
            if let Some(e) = &fit.metrics {
                println!("  errors         cosine-weighted RMSE {:.4e} (relative {:.4e}), log RMSE {:.4e}", e.cos_rmse, e.rel_cos_rmse, e.log_rmse);
            }
        }
        return Ok(());
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("binary") || bytes == MerlTable::FILE_BYTES {
        let table = MerlTable::read(path)?;
        let valid = table.valid_cells();
        let mut max = [0.0f64; 3];
        let mut sum = [0.0f64; 3];
        for i in 0..MerlTable::CELLS {
            if let Some(v) = table.cell(i) {
                for c in 0..3 {
                    max[c] = max[c].max(v[c]);
                    sum[c] += v[c];
                }
            }
        }
        println!("{}: MERL table, valid", path.display());
        println!("  file size      {bytes} bytes");
        println!("  dimensions     90 x 90 x 180 (theta_h, theta_d, phi_d), 3 channels");
        println!(
            "  valid cells    {valid} of {} ({} missing)",
            MerlTable::CELLS,
            MerlTable::CELLS - valid
        );
        println!(
            "  max (1/sr)     {:.4e} {:.4e} {:.4e}",
            max[0], max[1], max[2]
        );
        let n = valid.max(1) as f64;
        println!(
            "  mean (1/sr)    {:.4e} {:.4e} {:.4e}",
            sum[0] / n,
            sum[1] / n,
            sum[2] / n
        );
        return Ok(());
    }
    Err(CliError::Message(format!(
        "{}: not a MERL table (.binary) or an npf model (.json, .npfb): it is {}",
        path.display(),
        npf_data_loaders::sniff::describe(path)
    )))
}
