//! Fit benchmark: fits every MERL table in a folder with the default
//! configuration (what `npf fit IN -o OUT` does: the same data-decided
//! floor, grazing cut-off and pooling, the same coarse schedule; without
//! `npf fit`'s overlap of the full set's build and the error measures'
//! reference with the coarse level) and prints a Markdown table
//! per material: wall time (load, sample set, fit), sweeps, final objective,
//! cosine-weighted and log RMSE, peak memory, and where the fit's time goes.
//!
//!     cargo run --release --example fit_bench -- DATA_DIR [--threads N] [--max-sweeps N]
//!         [--coarse 8,2] [--coarse-tol T] [--coarse-max-sweeps N] [--tol T]
//!         [--save-dir DIR] [--golden-g]
//!
//! `--coarse` lists the decimation factors of coarse-to-fine levels run
//! before the full set (`npf::coarse`; `--coarse 1` is a plain fit; the
//! default is `FitConfig::default()`'s); `--save-dir` writes each model
//! as DIR/NAME.npfb (for `npf compare`); `--golden-g` updates G by
//! golden-section search (the fit whose D once ran off along the D x G
//! valley, docs/report.md).
//!
//! Each material runs in its own child process so that its peak resident
//! memory (Linux VmHWM) is its own. Make DATA_DIR with
//! `python3 ../shared/tools/nbrdf2merl.py ../shared/data/merl-nbrdf --out-dir DATA_DIR`.

use npf::fit::FitConfig;
use npf::loaders::MerlTable;
use npf::metrics::compare_model;
use npf::model::Layout;
use npf::modelfile::{write, ModelFile};
use npf::samples::SampleOptions;
use npf::solver::{init, FitOptions, Stage};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The value after `--name`, if given.
fn flag(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

/// The fit's settings, as flags.
struct Settings {
    max_sweeps: usize,
    tol: f64,
    coarse: Vec<usize>,
    coarse_tol: f64,
    coarse_max_sweeps: usize,
    save_dir: Option<String>,
    golden: bool,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let threads = args
        .iter()
        .position(|a| a == "--threads")
        .and_then(|i| args.get(i + 1))
        .map(|v| v.parse::<usize>().expect("--threads N"))
        .unwrap_or(0);
    let max_sweeps = args
        .iter()
        .position(|a| a == "--max-sweeps")
        .and_then(|i| args.get(i + 1))
        .map(|v| v.parse::<usize>().expect("--max-sweeps N"))
        .unwrap_or(FitOptions::default().max_sweeps);
    let d = FitConfig::default();
    let settings = Settings {
        max_sweeps,
        tol: flag(&args, "--tol").map_or(d.tol, |v| v.parse().expect("--tol T")),
        coarse: flag(&args, "--coarse").map_or(d.coarse.clone(), |v| {
            v.split(',')
                .map(|f| f.parse().expect("--coarse 8,2"))
                .collect()
        }),
        coarse_tol: flag(&args, "--coarse-tol")
            .map_or(d.coarse_tol, |v| v.parse().expect("--coarse-tol T")),
        coarse_max_sweeps: flag(&args, "--coarse-max-sweeps").map_or(d.coarse_max_sweeps, |v| {
            v.parse().expect("--coarse-max-sweeps N")
        }),
        save_dir: flag(&args, "--save-dir"),
        golden: args.iter().any(|a| a == "--golden-g"),
    };
    if let Some(i) = args.iter().position(|a| a == "--one") {
        let result = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| one(Path::new(&args[i + 1]), &settings));
        match result {
            Ok(line) => println!("{line}"),
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        }
        return;
    }
    let Some(dir) = args.first().filter(|a| !a.starts_with("--")) else {
        eprintln!("usage: fit_bench DATA_DIR [--threads N]");
        std::process::exit(2);
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| {
            eprintln!("{dir}: {e}");
            std::process::exit(1)
        })
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "binary"))
        .collect();
    files.sort();
    println!("| material | samples fitted | load + set (s) | fit (s) | wall (s) | sweeps | converged | objective | cos RMSE | rel. cos RMSE | log RMSE | peak RSS (MB) | ms/sweep: D / F / G / d,s / gauge / extrap. | coarse levels: factor x sweeps (s) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for f in files {
        let coarse: Vec<String> = settings.coarse.iter().map(|f| f.to_string()).collect();
        let mut child = Command::new(std::env::current_exe().unwrap());
        child.args([
            "--one",
            f.to_str().unwrap(),
            "--threads",
            &threads.to_string(),
            "--max-sweeps",
            &max_sweeps.to_string(),
            "--tol",
            &settings.tol.to_string(),
            "--coarse",
            &coarse.join(","),
            "--coarse-tol",
            &settings.coarse_tol.to_string(),
            "--coarse-max-sweeps",
            &settings.coarse_max_sweeps.to_string(),
        ]);
        if let Some(dir) = &settings.save_dir {
            child.args(["--save-dir", dir]);
        }
        if settings.golden {
            child.arg("--golden-g");
        }
        let out = child.output().expect("run child");
        let name = f.file_stem().unwrap().to_string_lossy();
        if out.status.success() {
            print!("| {name} {}", String::from_utf8_lossy(&out.stdout));
        } else {
            println!(
                "| {name} | failed: {} |",
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
    }
}

/// One material, in this process: returns the rest of its table row.
fn one(path: &Path, s: &Settings) -> Result<String, String> {
    let t0 = Instant::now();
    let table = MerlTable::read(path).map_err(|e| e.to_string())?;
    let source = path.display().to_string();
    let samples = table.samples(&source);
    // As in `npf fit`: the table is not held during the fit, and is read
    // again for the error measures.
    drop(table);
    // As in `npf fit`: the floor, grazing cut-off and pooling the data
    // decide (the floor rule), counted with the read.
    let so = FitConfig::default().sample_options_for(&samples);
    let read = t0.elapsed().as_secs_f64();
    let opts = FitOptions {
        max_sweeps: s.max_sweeps,
        tol: s.tol,
        g_method: if s.golden {
            npf::solver::GMethod::Golden
        } else {
            FitOptions::default().g_method
        },
        ..Default::default()
    };
    let layout = Layout::default();
    let start = init::initial_factors(layout, opts.lobes);
    let mut quiet = |_: &npf::solver::SweepReport| {};
    let schedule = npf::coarse::Schedule {
        factors: &s.coarse,
        tol: s.coarse_tol,
        max_sweeps: s.coarse_max_sweeps,
        // As `npf fit` on an isotropic table.
        keep_g: FitConfig::default().keep_coarse_g.unwrap_or(true),
        kept_g_tol: FitConfig::default().kept_g_tol.unwrap_or(2.0 * s.tol),
        gauss_newton: FitConfig::default().coarse_gauss_newton,
    };
    // Owned: the samples are freed before the full set's sweeps (as in
    // `npf fit`) and made again from the table for the error measures.
    let owned = npf::samples::SampleData::from(samples);
    let fitted = npf::coarse::fit(owned, (layout, so), schedule, opts, start, &mut quiet)
        .map_err(|e| e.to_string())?;
    let (res, levels) = (fitted.result, fitted.levels);
    // The full set is built while the coarse levels run: "load + set" ends
    // when it is ready, "fit" is the rest.
    let prep = read + fitted.set_seconds;
    let fit_seconds = t0.elapsed().as_secs_f64() - prep;
    if let Some(dir) = &s.save_dir {
        let name = path.file_stem().unwrap().to_string_lossy();
        let out = Path::new(dir).join(format!("{name}.npfb"));
        let file = ModelFile {
            model: res.model.clone(),
            fit: None,
        };
        write(&out, &file, true).map_err(|e| e.to_string())?;
    }
    let wall = t0.elapsed().as_secs_f64();
    npf::memory::release_free();
    let samples = MerlTable::read(path)
        .map_err(|e| e.to_string())?
        .samples(&source);
    let m = compare_model(&samples, SampleOptions::default().max_theta_deg, &res.model);
    // Mean milliseconds per sweep in each kind of stage (summed over lobes).
    let mut ms = [0.0f64; 6];
    for r in &res.history {
        for s in &r.stages {
            let k = match s.stage {
                Stage::D(_) => 0,
                Stage::F => 1,
                Stage::G(_) | Stage::SmoothG(_) => 2,
                Stage::DiffuseAndScales | Stage::DiffuseForm => 3,
                Stage::Gauge => 4,
                // The trials between sweeps (Gauss-Newton: anisotropic fits only).
                Stage::Extrapolate | Stage::GaussNewton => 5,
            };
            ms[k] += s.seconds * 1e3;
        }
    }
    let n = res.history.len().max(1) as f64;
    let stages: Vec<String> = ms.iter().map(|v| format!("{:.0}", v / n)).collect();
    Ok(format!(
        "| {} | {:.2} | {:.2} | {:.2} | {} | {} | {:.17e} | {:.3e} | {:.4} | {:.3e} | {:.0} | {} | {} |",
        fitted.set_len,
        prep,
        fit_seconds,
        wall,
        res.history.len(),
        if res.converged { "yes" } else { "no" },
        res.objective,
        m.cos_rmse,
        m.rel_cos_rmse,
        m.log_rmse,
        peak_rss_mb().unwrap_or(f64::NAN),
        stages.join(" / "),
        levels
            .iter()
            .map(|l| format!("{} x {} ({:.2})", l.factor, l.sweeps, l.seconds))
            .collect::<Vec<_>>()
            .join(", ")
    ))
}

/// Peak resident set size of this process (Linux), in MiB.
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
