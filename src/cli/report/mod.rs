//! `npf report DATA_DIR -o REPORT_DIR`: fit every configuration on every
//! MERL table of a folder, evaluate each fit (docs/evaluation.md), and write
//! a Markdown report, CSV/JSON results, sphere images, factor plots, the
//! speed-vs-accuracy chart and a convergence chart.
//!
//! Jobs (material x configuration) run in parallel, `--jobs` at a time; each
//! fit and its evaluation run on one thread, so "fit seconds" is one-thread
//! wall-clock time (other processes on the machine still add noise).

//!
//! One module per job: [`configs`] (what is compared), [`runner`] (the job
//! scheduler), [`rows`] (rows.jsonl and the results files), [`convergence`]
//! (the convergence experiment), [`markdown`] (report.md and the failure
//! thresholds); the charts are in [`charts`].

pub mod args;
pub mod charts;
pub mod configs;
pub mod convergence;
pub mod markdown;
pub mod rows;
pub mod runner;
pub mod workspace;

pub use configs::{configurations, Configuration};
pub use convergence::{Checkpoint, Convergence};
pub use markdown::{failure, median, FAIL_ALBEDO, FAIL_PSNR_DB, TIE_DB};
pub use rows::Row;

use super::{CliError, CliResult};
use crate::evaluation::Reference;
use crate::fit::FitConfig;
use crate::render::RenderOptions;
pub use args::ReportArgs;
use runner::{FactorModels, Plan};
use std::path::PathBuf;
use workspace::{io_err, write_file, Workspace};

/// Run `npf report`.
pub fn run(args: ReportArgs) -> CliResult {
    let all = configurations();
    if args.list {
        for c in &all {
            println!("{:<16} {:>4} parameters  {}", c.name, c.params(), c.what);
        }
        return Ok(());
    }
    let (Some(data_dir), Some(out)) = (args.data.clone(), args.output.clone()) else {
        return Err(CliError::Message(
            "report needs DATA_DIR and -o REPORT_DIR".into(),
        ));
    };
    let out = &out;
    let configs: Vec<Configuration> = if args.configs.is_empty() {
        all.clone()
    } else {
        let mut v = Vec::new();
        for name in &args.configs {
            match all.iter().find(|c| c.name == name) {
                Some(c) => v.push(c.clone()),
                None => {
                    return Err(CliError::Message(format!(
                        "unknown configuration {name:?} (npf report --list names them)"
                    )))
                }
            }
        }
        v
    };
    if !(1..=4096).contains(&args.res) || !(1..=1024).contains(&args.n_theta) {
        return Err(CliError::Message(
            "--res must be 1 to 4096 and --n-theta 1 to 1024".into(),
        ));
    }
    crate::cli::check_threads("--jobs", args.jobs)?;
    if args.max_sweeps == Some(0) {
        return Err(CliError::Message("--max-sweeps must be at least 1".into()));
    }
    // Materials.
    let entries = std::fs::read_dir(&data_dir).map_err(|e| io_err(&data_dir, e))?;
    let mut materials: Vec<(String, PathBuf)> = Vec::new();
    for e in entries {
        let p = e.map_err(|e| io_err(&data_dir, e))?.path();
        if p.extension().and_then(|x| x.to_str()) == Some("binary") {
            let stem = p
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("?")
                .to_string();
            if args.materials.is_empty() || args.materials.contains(&stem) {
                materials.push((stem, p));
            }
        }
    }
    materials.sort();
    if materials.is_empty() {
        return Err(CliError::Message(format!(
            "{}: no MERL tables (*.binary){}",
            data_dir.display(),
            if args.materials.is_empty() {
                ""
            } else {
                " matching --materials"
            }
        )));
    }
    // Output folder.
    if out.exists() {
        let non_empty = std::fs::read_dir(out)
            .map_err(|e| io_err(out, e))?
            .next()
            .is_some();
        if non_empty && !args.force && !args.from_rows {
            return Err(CliError::Message(format!(
                "{}: already exists and is not empty (pass --force to write into it)",
                out.display()
            )));
        }
    }
    for (m, _) in &materials {
        std::fs::create_dir_all(out.join(m)).map_err(|e| io_err(out, e))?;
    }
    let render_opts = RenderOptions {
        res: args.res,
        n_theta: args.n_theta,
        env: Default::default(),
    };
    let threads = if args.jobs == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        args.jobs
    };
    let ws = Workspace::new(&materials, out, render_opts);
    let jobs = runner::job_order(&configs, materials.len());
    // Convergence runs.
    let conv_material = if args.no_convergence {
        None
    } else {
        let want = args
            .convergence
            .clone()
            .unwrap_or_else(|| "gold-metallic-paint".into());
        materials
            .iter()
            .position(|(m, _)| *m == want)
            .or_else(|| args.convergence.is_none().then_some(0))
            .map(Some)
            .ok_or_else(|| {
                CliError::Message(format!("--convergence: no material named {want:?}"))
            })?
    };
    let conv_configs: Vec<&Configuration> = all
        .iter()
        .filter(|c| convergence::CONFIGS.contains(&c.name))
        .collect();
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(
            (jobs.len() + conv_material.map_or(0, |_| conv_configs.len())) as u64,
        )
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} report [{bar:30}] {pos}/{len} fits  {msg}  {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let mut factor_models: FactorModels = Default::default();
    let t0 = std::time::Instant::now();
    let (mut rows, conv_v) = if args.from_rows {
        (Vec::new(), Vec::new())
    } else {
        let plan = Plan {
            jobs,
            configs: &configs,
            convergence: conv_material.map(|m| (m, conv_configs.clone())),
            max_sweeps: args.max_sweeps,
        };
        runner::run_all(&ws, &plan, threads, &bar, &factor_models)?
    };
    let mut conv_loaded = None;
    if args.from_rows {
        let path = out.join("rows.jsonl");
        for row in rows::read(&path)? {
            let known = materials.iter().any(|m| m.0 == row.material)
                && configs.iter().any(|c| c.name == row.config);
            if known {
                rows.retain(|r| !(r.material == row.material && r.config == row.config));
                rows.push(row);
            }
        }
        if args.reevaluate {
            let max_theta = FitConfig::default().max_theta;
            for (m, material) in materials.iter().enumerate() {
                let md = ws
                    .load(m)
                    .as_ref()
                    .map_err(|e| CliError::Message(e.clone()))?;
                let reference = Reference {
                    table: &md.table,
                    samples: &md.samples,
                    image: md.image.clone(),
                    render: render_opts,
                };
                for r in rows.iter_mut().filter(|r| r.material == material.0) {
                    let p = out.join(&r.material).join(format!("{}.json", r.config));
                    match crate::modelfile::read(&p) {
                        Ok(f) => {
                            r.eval = Some(
                                reference
                                    .evaluate_model(max_theta, &f.model)
                                    .map_err(|e| CliError::Message(e.to_string()))?
                                    .0,
                            )
                        }
                        // A failed fit has no model; a finished one must
                        // have one, or its old measures would be reported
                        // as if recomputed.
                        Err(e) if r.error.is_none() => {
                            return Err(CliError::Message(format!(
                                "--reevaluate: {} {}: cannot read its model: {e}",
                                r.material, r.config
                            )))
                        }
                        Err(_) => {}
                    }
                }
                bar.inc(1);
            }
            rows::rewrite(&out.join("rows.jsonl"), &rows)?;
        }
        let models = factor_models
            .get_mut()
            .map_err(|_| CliError::Message("a worker failed".into()))?;
        for r in &rows {
            if r.config == "sf-3" || r.config == "independent-g" {
                let p = out.join(&r.material).join(format!("{}.json", r.config));
                let m = materials.iter().position(|m| m.0 == r.material);
                if let (Ok(f), Some(m)) = (crate::modelfile::read(&p), m) {
                    models.push((m, r.config.clone(), f.model));
                }
            }
        }
        let cpath = out.join("convergence.json");
        if let Ok(text) = std::fs::read_to_string(&cpath) {
            conv_loaded = serde_json::from_str::<Vec<(String, Convergence)>>(&text).ok();
        }
    }
    rows.sort_by_key(|r| {
        (
            materials.iter().position(|m| m.0 == r.material),
            configs.iter().position(|c| c.name == r.config),
        )
    });
    let conv: Option<Vec<(String, Convergence)>> = if args.from_rows {
        conv_loaded
    } else {
        conv_material.map(|_| conv_v)
    };
    if let (Some(c), false) = (&conv, args.from_rows) {
        let json = serde_json::to_string_pretty(c).map_err(|e| CliError::Message(e.to_string()))?;
        write_file(&out.join("convergence.json"), json.as_bytes())?;
    }
    bar.finish_and_clear();
    let total_seconds = t0.elapsed().as_secs_f64();
    // Results files.
    rows::write_results(out, &rows)?;
    // Charts.
    let mut chart_notes = Vec::new();
    if crate::cli::fonts::ensure_font() {
        let names: Vec<&str> = configs.iter().map(|c| c.name).collect();
        charts::speed_accuracy(out, &rows, &names)?;
        let models = factor_models
            .into_inner()
            .map_err(|_| CliError::Message("a worker failed".into()))?;
        for (m, config, model) in &models {
            let path = out.join(&materials[*m].0).join(format!("factors-{config}"));
            charts::factor_plot(&path, &materials[*m].0, config, model)?;
        }
        if let (Some(conv), Some(m)) = (&conv, conv_material) {
            charts::convergence(out, &materials[m].0, conv)?;
        }
    } else {
        chart_notes.push(
            "no TrueType font found (looked for DejaVuSans): charts were not drawn".to_string(),
        );
    }
    let md = markdown::markdown(
        &args,
        &configs,
        &materials,
        &rows,
        conv.as_deref(),
        conv_material.map(|m| materials[m].0.as_str()),
        total_seconds,
        &chart_notes,
    );
    write_file(&out.join("report.md"), md.as_bytes())?;
    // The report is written (it says why each fit failed), but a run in
    // which nothing succeeded is a failed run.
    let failed = rows
        .iter()
        .filter(|r| r.eval.is_none() || markdown::failure(r).is_some())
        .count();
    if rows.is_empty() || failed == rows.len() {
        return Err(CliError::Message(format!(
            "{}: every fit failed ({failed} of {}): see {}",
            data_dir.display(),
            rows.len(),
            out.join("report.md").display()
        )));
    }
    if !args.quiet {
        eprintln!(
            "{} fits in {:.0} s; wrote {}",
            rows.len(),
            total_seconds,
            out.join("report.md").display()
        );
    }
    Ok(())
}
