//! `npf info FILE`: what a measured table (MERL, UTIA) or a model file holds.

use super::CliResult;
use crate::modelfile::{self, Form};
use clap::Args;
use npf_data_loaders::{MerlTable, UtiaTable};
use std::path::PathBuf;

/// `npf info`'s arguments.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A measured table (MERL .binary, UTIA .bin) or a model (.json, .npfb).
    pub file: PathBuf,
    /// Read a table as this format instead of detecting it.
    #[arg(long, value_enum)]
    pub format: Option<super::FormatArg>,
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
        let form_params = m.diffuse_form.param_count();
        if form_params == 0 {
            println!(
                "  parameters     {} ({} bytes as f32)",
                m.param_count(),
                4 * m.param_count()
            );
        } else {
            let all = m.param_count() + form_params;
            println!(
                "  parameters     {all} ({} factor tables + {form_params} diffuse form; {} bytes as f32)",
                m.param_count(),
                4 * all
            );
        }
        println!(
            "  layout         D {:?}, F {:?}, G {:?}",
            m.layout.d, m.layout.f, m.layout.g
        );
        println!("  diffuse        {:?}", m.diffuse);
        println!("  diffuse form   {}", m.diffuse_form.name());
        if let crate::model::DiffuseForm::Separable { p } = &m.diffuse_form {
            println!("  diffuse P      {p:?}");
        }
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
            if let Some(c) = fit.selection.as_ref().and_then(|s| s.get("coarse")) {
                let levels: Vec<String> = c["levels"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|l| format!("1/{} {} sweeps", l["factor"], l["sweeps"]))
                    .collect();
                println!(
                    "  coarse levels  {}; G {} on the full set (tolerance {})",
                    levels.join(", "),
                    c["g_on_full_set"].as_str().unwrap_or("?"),
                    c["full_set_tol"]
                );
            }
            if let Some(a) = fit.selection.as_ref().and_then(|s| s.get("auto")) {
                println!(
                    "  auto           chose {} (mean render PSNR over {} scenes; another form must beat the first by > {} dB)",
                    a["chosen"].as_str().unwrap_or("?"),
                    a["scenes"].as_array().map_or(0, Vec::len),
                    a["margin_db"]
                );
                for c in a["candidates"].as_array().into_iter().flatten() {
                    println!(
                        "    {:<28} render {:.2} dB, linear {:.2} dB, log RMSE {:.4e}, rel. cos RMSE {:.4e}, {:.1} s",
                        c["name"].as_str().unwrap_or("?"),
                        c["render"]["mean_db"].as_f64().unwrap_or(f64::NAN),
                        c["render"]["linear_mean_db"].as_f64().unwrap_or(f64::NAN),
                        c["log_rmse"].as_f64().unwrap_or(f64::NAN),
                        c["rel_cos_rmse"].as_f64().unwrap_or(f64::NAN),
                        c["seconds"].as_f64().unwrap_or(f64::NAN),
                    );
                }
            }
            if let Some(e) = &fit.metrics {
                println!("  errors         cosine-weighted RMSE {:.4e} (relative {:.4e}), log RMSE {:.4e}", e.cos_rmse, e.rel_cos_rmse, e.log_rmse);
            }
        }
        return Ok(());
    }
    let table = npf_data_loaders::Table::read(path, args.format.map(Into::into))?;
    let bsdf = args.format.is_none()
        && path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("bsdf"));
    type Cell<'a> = Box<dyn Fn(usize) -> Option<[f64; 3]> + 'a>;
    let (name, dims, cells, cell): (_, _, _, Cell) = match &table {
        npf_data_loaders::Table::Merl(t) => (
            if bsdf {
                "RGL .bsdf file, read as a MERL table of its BRDF"
            } else {
                "MERL table"
            },
            "90 x 90 x 180 (theta_h, theta_d, phi_d)",
            MerlTable::CELLS,
            Box::new(|i| t.cell(i)),
        ),
        npf_data_loaders::Table::Utia(t) => (
            if bsdf {
                "anisotropic RGL .bsdf file, read as a UTIA table of its BRDF"
            } else {
                "UTIA table"
            },
            "6 x 48 x 6 x 48 (theta_i, phi_i, theta_v, phi_v; 15 / 7.5 deg)",
            UtiaTable::CELLS,
            Box::new(|i| t.cell(i)),
        ),
    };
    let mut valid = 0;
    let mut max = [0.0f64; 3];
    let mut sum = [0.0f64; 3];
    for v in (0..cells).filter_map(cell) {
        valid += 1;
        for c in 0..3 {
            max[c] = max[c].max(v[c]);
            sum[c] += v[c];
        }
    }
    println!("{}: {name}, valid", path.display());
    println!("  file size      {bytes} bytes");
    println!("  dimensions     {dims}, 3 channels");
    println!(
        "  valid cells    {valid} of {cells} ({} missing)",
        cells - valid
    );
    println!(
        "  max            {:.4e} {:.4e} {:.4e}",
        max[0], max[1], max[2]
    );
    let n = valid.max(1) as f64;
    println!(
        "  mean           {:.4e} {:.4e} {:.4e}",
        sum[0] / n,
        sum[1] / n,
        sum[2] / n
    );
    Ok(())
}
