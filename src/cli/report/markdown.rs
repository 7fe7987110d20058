//! The report's Markdown (`report.md`) and the thresholds by which it calls
//! a fit failed or two fits tied.

use super::args::ReportArgs;
use super::configs::Configuration;
use super::convergence::Convergence;
use super::rows::Row;
use std::path::{Path, PathBuf};

/// The median (NaN for none); sorts `v`.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Rendering PSNR below this (dB) counts as a failed fit in the report.
pub const FAIL_PSNR_DB: f64 = 30.0;
/// Albedo error above this (at any view angle) is flagged.
pub const FAIL_ALBEDO: f64 = 0.25;
/// Two rendering PSNRs within this many dB count as a tie.
pub const TIE_DB: f64 = 0.1;

/// The report's Markdown text.
#[allow(clippy::too_many_arguments)]
pub fn markdown(
    args: &ReportArgs,
    configs: &[Configuration],
    materials: &[(String, PathBuf)],
    rows: &[Row],
    conv: Option<&[(String, Convergence)]>,
    conv_material: Option<&str>,
    total_seconds: f64,
    notes: &[String],
) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let get = |m: &str, c: &str| rows.iter().find(|r| r.material == m && r.config == c);
    let _ = writeln!(s, "# npf benchmark report\n");
    if args.from_rows {
        let _ = writeln!(
            s,
            "Rebuilt from `rows.jsonl`{} (the time below is that of this run, not of the fits).\n",
            if args.reevaluate {
                " with every measure recomputed from the saved models"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        s,
        "{} materials from `{}`, {} configurations, {} fits in {:.0} s wall-clock ({} parallel jobs, one thread per fit). Render {}x{} px, environment quadrature {}x{} directions. Definitions: `docs/evaluation.md`.\n",
        materials.len(),
        args.data.as_deref().unwrap_or(Path::new("?")).display(),
        configs.len(),
        rows.len(),
        total_seconds,
        if args.jobs == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            args.jobs
        },
        args.res,
        args.res,
        args.n_theta,
        2 * args.n_theta
    );
    for n in notes {
        let _ = writeln!(s, "Note: {n}\n");
    }
    let _ = writeln!(s, "## Summary per configuration\n");
    let _ = writeln!(s, "| configuration | parameters | median fit s | max fit s | median render PSNR dB | worst render PSNR dB (material) | median numerical PSNR dB | median log RMSE | median max albedo error | failures |");
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for c in configs {
        let rs: Vec<&Row> = rows.iter().filter(|r| r.config == c.name).collect();
        let ok: Vec<&Row> = rs.iter().copied().filter(|r| r.eval.is_some()).collect();
        let mut secs: Vec<f64> = ok.iter().map(|r| r.seconds).collect();
        let max_secs = secs.iter().cloned().fold(f64::NAN, f64::max);
        let mut ps: Vec<f64> = ok
            .iter()
            .map(|r| r.eval.as_ref().map_or(f64::NAN, |e| e.render_psnr_db))
            .collect();
        let worst = ok.iter().min_by(|a, b| {
            let (x, y) = (
                a.eval.as_ref().map_or(f64::NAN, |e| e.render_psnr_db),
                b.eval.as_ref().map_or(f64::NAN, |e| e.render_psnr_db),
            );
            x.total_cmp(&y)
        });
        let mut np: Vec<f64> = ok
            .iter()
            .map(|r| r.eval.as_ref().map_or(f64::NAN, |e| e.numeric_psnr_db))
            .collect();
        let mut lr: Vec<f64> = ok
            .iter()
            .map(|r| r.eval.as_ref().map_or(f64::NAN, |e| e.metrics.log_rmse))
            .collect();
        let mut al: Vec<f64> = ok
            .iter()
            .map(|r| r.eval.as_ref().map_or(f64::NAN, |e| e.max_albedo_error))
            .collect();
        let fails: Vec<String> = rs
            .iter()
            .filter_map(|r| failure(r).map(|f| format!("{} ({f})", r.material)))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.2} | {} | {:.2} | {:.4} | {:.1}% | {} |",
            c.name,
            c.params(),
            median(&mut secs),
            max_secs,
            median(&mut ps),
            worst.map_or("-".into(), |w| format!(
                "{:.2} ({})",
                w.eval.as_ref().map_or(f64::NAN, |e| e.render_psnr_db),
                w.material
            )),
            median(&mut np),
            median(&mut lr),
            100.0 * median(&mut al),
            if fails.is_empty() {
                "none".into()
            } else {
                fails.join("; ")
            }
        );
    }
    let _ = writeln!(s, "\nConfigurations:\n");
    for c in configs {
        let _ = writeln!(s, "- `{}`: {}", c.name, c.what);
    }
    let _ = writeln!(
        s,
        "\nA fit counts as failed when it returned an error, its rendering PSNR is below {FAIL_PSNR_DB} dB, or its albedo error exceeds {:.0}% at some view angle.\n",
        100.0 * FAIL_ALBEDO
    );
    // Head to head.
    if configs.iter().any(|c| c.name == "sf-3") && configs.iter().any(|c| c.name == "independent-g")
    {
        let (mut better, mut tie, mut worse, mut n) = (0, 0, 0, 0);
        let mut worse_list = Vec::new();
        for (m, _) in materials {
            if let (Some(a), Some(b)) = (
                get(m, "sf-3").and_then(|r| r.eval.as_ref()),
                get(m, "independent-g").and_then(|r| r.eval.as_ref()),
            ) {
                n += 1;
                let d = a.render_psnr_db - b.render_psnr_db;
                if d > TIE_DB {
                    better += 1;
                } else if d >= -TIE_DB {
                    tie += 1;
                } else {
                    worse += 1;
                    worse_list.push(format!("{m} ({d:+.2} dB)"));
                }
            }
        }
        let _ = writeln!(s, "## Shared-factor 3 lobes vs Independent-G\n");
        let _ = writeln!(
            s,
            "Rendering PSNR, {n} materials: sf-3 better on {better} (by more than {TIE_DB} dB), tied on {tie}, worse on {worse}{}. (Peng et al. report at least as good on all and better on 88 of 100 MERL materials.)\n",
            if worse_list.is_empty() { String::new() } else { format!(": {}", worse_list.join(", ")) }
        );
    }
    // Material x configuration.
    let _ = writeln!(s, "## Rendering PSNR (dB), material x configuration\n");
    let _ = write!(s, "| material |");
    for c in configs {
        let _ = write!(s, " {} |", c.name);
    }
    let _ = write!(s, "\n|---|");
    for _ in configs {
        let _ = write!(s, "---:|");
    }
    let _ = writeln!(s);
    for (m, _) in materials {
        let _ = write!(s, "| {m} |");
        for c in configs {
            let _ = match get(m, c.name) {
                Some(Row { eval: Some(e), .. }) => write!(s, " {:.2} |", e.render_psnr_db),
                Some(_) => write!(s, " failed |"),
                None => write!(s, " not run |"),
            };
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "\n## All measures\n");
    let _ = writeln!(s, "Errors over the valid samples with theta_i, theta_o <= 85 deg (the fit's cut-off); albedo error: worst of 0, 30, 60, 75 deg.\n");
    let _ = writeln!(s, "| material | configuration | parameters | fit s | sweeps | cos RMSE | rel cos RMSE | log RMSE | numerical PSNR dB | max albedo error | render PSNR dB |");
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (m, _) in materials {
        for c in configs {
            let Some(r) = get(m, c.name) else { continue };
            match (&r.eval, &r.error) {
                (Some(e), _) => {
                    let _ = writeln!(
                        s,
                        "| {m} | {} | {} | {:.1} | {}{} | {:.3e} | {:.4} | {:.4} | {:.2} | {:.1}% | {:.2} |",
                        c.name,
                        r.params,
                        r.seconds,
                        r.sweeps,
                        if r.converged { "" } else { " (limit)" },
                        e.metrics.cos_rmse,
                        e.metrics.rel_cos_rmse,
                        e.metrics.log_rmse,
                        e.numeric_psnr_db,
                        100.0 * e.max_albedo_error,
                        e.render_psnr_db
                    );
                }
                (_, err) => {
                    let _ = writeln!(
                        s,
                        "| {m} | {} | {} | - | - | failed: {} | | | | | |",
                        c.name,
                        r.params,
                        err.clone().unwrap_or_default()
                    );
                }
            }
        }
    }
    if let (Some(conv), Some(cm)) = (conv, conv_material) {
        let _ = writeln!(s, "\n## Convergence ({cm})\n");
        let _ = writeln!(s, "`convergence.svg` / `.png`: objective (relative to the start) and rendering PSNR against sweeps and seconds.\n");
        let _ = writeln!(
            s,
            "| configuration | sweeps | seconds | objective | render PSNR dB |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|");
        for (name, c) in conv {
            if let Some(e) = &c.error {
                let _ = writeln!(s, "| {name} | failed: {e} | | | |");
            }
            for k in &c.checkpoints {
                let _ = writeln!(
                    s,
                    "| {name} | {} | {:.1} | {:.5e} | {:.2} |",
                    k.sweeps, k.seconds, k.objective, k.render_psnr_db
                );
            }
        }
    }
    let _ = writeln!(s, "\n## Files\n");
    let _ = writeln!(
        s,
        "- `results.csv`, `results.json`: every measure of every fit"
    );
    let _ = writeln!(s, "- `speed-accuracy.{{svg,png}}`: fit seconds (log) against rendering PSNR, medians per configuration");
    let _ = writeln!(s, "- `MATERIAL/reference.png`, `MATERIAL/CONFIG.png`, `MATERIAL/CONFIG-diff.png` (|difference| x {}), `MATERIAL/CONFIG.json` (the model)", crate::cli::compare::DIFF_GAIN);
    let _ = writeln!(s, "- `MATERIAL/factors-sf-3.{{svg,png}}`, `MATERIAL/factors-independent-g.{{svg,png}}`: D, F per channel, G per lobe");
    s
}

/// Why a row counts as failed, if it does.
pub fn failure(r: &Row) -> Option<String> {
    if let Some(e) = &r.error {
        return Some(format!("error: {e}"));
    }
    let e = r.eval.as_ref()?;
    if !(e.render_psnr_db >= FAIL_PSNR_DB) {
        return Some(format!("render PSNR {:.1} dB", e.render_psnr_db));
    }
    if !(e.max_albedo_error <= FAIL_ALBEDO) {
        return Some(format!("albedo error {:.0}%", 100.0 * e.max_albedo_error));
    }
    None
}
