//! `npf report DATA_DIR -o REPORT_DIR`: fit every configuration on every
//! MERL table of a folder, evaluate each fit (docs/evaluation.md), and write
//! a Markdown report, CSV/JSON results, sphere images, factor plots, the
//! speed-vs-accuracy chart and a convergence chart.
//!
//! Jobs (material x configuration) run in parallel, `--jobs` at a time; each
//! fit and its evaluation run on one thread, so "fit seconds" is one-thread
//! wall-clock time (other processes on the machine still add noise).

use super::{CliError, CliResult};
use crate::baselines::{fit_kind, ModelKind};
use crate::cli::fit::FitConfig;
use crate::evaluation::{Evaluation, Reference};
use crate::model::Model;
use crate::render::{encode_png, Image, RenderOptions};
use crate::samples::Weighting;
use crate::solver::GMethod;
use clap::Args;
use npf_data_loaders::atomic::write_bytes_atomic;
use npf_data_loaders::{MeasuredSamples, MerlTable};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Folder of MERL tables (*.binary).
    #[arg(required_unless_present = "list")]
    pub data: Option<PathBuf>,
    /// Report folder (created; must be empty or absent unless --force).
    #[arg(short, long, required_unless_present = "list")]
    pub output: Option<PathBuf>,
    /// Configurations to run, comma-separated (default: all; see --list).
    #[arg(long, value_delimiter = ',')]
    pub configs: Vec<String>,
    /// Only these materials (file stems), comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Fits run at the same time (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
    /// Render resolution (pixels square).
    #[arg(long, default_value_t = 128)]
    pub res: usize,
    /// Environment quadrature strata in elevation.
    #[arg(long, default_value_t = 24)]
    pub n_theta: usize,
    /// Override every configuration's sweep limit (quick trial runs).
    #[arg(long)]
    pub max_sweeps: Option<usize>,
    /// Material of the convergence chart (default: gold-metallic-paint if present, else the first).
    #[arg(long)]
    pub convergence: Option<String>,
    /// Skip the convergence chart (it refits three configurations several times).
    #[arg(long)]
    pub no_convergence: bool,
    /// Fit nothing: write the report from REPORT_DIR/rows.jsonl (every fit a
    /// run finished, e.g. one stopped early), the saved models and
    /// convergence.json.
    #[arg(long)]
    pub from_rows: bool,
    /// With --from-rows: recompute every measure from the saved models
    /// (after a change to the measures; fit times and sweeps are kept).
    #[arg(long, requires = "from_rows")]
    pub reevaluate: bool,
    /// List the configurations and exit.
    #[arg(long)]
    pub list: bool,
    /// Write into an existing, non-empty report folder.
    #[arg(long)]
    pub force: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// One fitted configuration of the benchmark.
#[derive(Clone, Debug)]
pub struct Configuration {
    pub name: &'static str,
    pub what: &'static str,
    pub kind: ModelKind,
    pub lobes: usize,
    pub g_method: GMethod,
    pub weighting: Weighting,
}

/// All benchmark configurations, in report order.
pub fn configurations() -> Vec<Configuration> {
    let c = |name, what, kind, lobes, g_method, weighting| Configuration {
        name,
        what,
        kind,
        lobes,
        g_method,
        weighting,
    };
    use GMethod::*;
    use ModelKind::*;
    use Weighting::*;
    vec![
        c(
            "sf-3",
            "shared-factor, 3 lobes, cubic G, compressive weights (npf's default)",
            Factor,
            3,
            Cubic,
            Compressive,
        ),
        c(
            "sf-2",
            "shared-factor, 2 lobes",
            Factor,
            2,
            Cubic,
            Compressive,
        ),
        c(
            "sf-1",
            "shared-factor, 1 lobe",
            Factor,
            1,
            Cubic,
            Compressive,
        ),
        c(
            "sf-3-golden",
            "3 lobes, G by golden-section search",
            Factor,
            3,
            Golden,
            Compressive,
        ),
        c(
            "sf-3-fixed-g",
            "3 lobes, G left at its initial Smith shape",
            Factor,
            3,
            Fixed,
            Compressive,
        ),
        c(
            "sf-3-cosine-l2",
            "3 lobes, cosine-weighted L2 weights",
            Factor,
            3,
            Cubic,
            CosineL2,
        ),
        c(
            "sf-3-uniform",
            "3 lobes, uniform weights",
            Factor,
            3,
            Cubic,
            Uniform,
        ),
        c(
            "independent-g",
            "Bagher et al.'s Independent-G (per-channel D, F, G; golden-section G)",
            IndependentG,
            1,
            Golden,
            Compressive,
        ),
        c(
            "ggx",
            "analytic GGX + Lambert, Schlick F (10 parameters)",
            Ggx,
            1,
            Cubic,
            Compressive,
        ),
    ]
}

/// `npf fit`'s defaults, from its own argument definitions.
pub fn default_fit_config() -> FitConfig {
    #[derive(clap::Parser)]
    struct P {
        #[command(flatten)]
        c: FitConfig,
    }
    <P as clap::Parser>::parse_from(["npf"]).c
}

impl Configuration {
    pub fn fit_config(&self, max_sweeps: Option<usize>) -> FitConfig {
        let mut c = default_fit_config();
        c.lobes = self.lobes;
        c.g_method = self.g_method;
        c.weighting = self.weighting;
        c.threads = 1;
        if let Some(s) = max_sweeps {
            c.max_sweeps = s;
        }
        c
    }

    pub fn params(&self) -> usize {
        self.kind
            .effective_params(&crate::model::Layout::default(), self.lobes)
    }
}

/// One row of the results.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    pub material: String,
    pub config: String,
    pub params: usize,
    pub seconds: f64,
    pub sweeps: usize,
    pub converged: bool,
    pub objective: f64,
    pub eval: Option<Evaluation>,
    pub error: Option<String>,
    /// (sweep, objective, seconds) of every sweep.
    #[serde(skip)]
    pub history: Vec<(usize, f64, f64)>,
}

struct MaterialData {
    table: MerlTable,
    samples: MeasuredSamples,
    image: Image,
}

fn io_err(path: &Path, e: std::io::Error) -> CliError {
    CliError::Message(format!("{}: {e}", path.display()))
}

fn write_file(path: &Path, bytes: &[u8]) -> CliResult {
    write_bytes_atomic(path, true, bytes)?;
    Ok(())
}

fn write_png(path: &Path, image_res: usize, rgb: &[u8]) -> CliResult {
    let png = encode_png(image_res as u32, image_res as u32, rgb)
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
    write_file(path, &png)
}

fn load_material<'a>(
    slot: &'a OnceLock<Result<MaterialData, String>>,
    material: &(String, PathBuf),
    out: &Path,
    render_opts: RenderOptions,
) -> &'a Result<MaterialData, String> {
    slot.get_or_init(|| {
        let (name, path) = material;
        let table = MerlTable::read(path).map_err(|e| e.to_string())?;
        let samples = table.samples(&path.display().to_string());
        if samples.samples.is_empty() {
            return Err(format!("{}: no valid samples", path.display()));
        }
        let image = Reference::new(&table, &samples, render_opts).image;
        write_png(
            &out.join(name).join("reference.png"),
            image.res,
            &image.to_rgb8(),
        )
        .map_err(|e| e.to_string())?;
        Ok(MaterialData {
            table,
            samples,
            image,
        })
    })
}

fn one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> Result<T, CliError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| CliError::Message(format!("cannot start a worker thread: {e}")))?;
    Ok(pool.install(f))
}

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
    };
    // Plain OS threads pull jobs from a queue; each job runs in its own
    // one-thread rayon pool. (Outer rayon workers waiting on an inner pool
    // would steal further jobs and run them all at once.)
    let threads = if args.jobs == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        args.jobs
    };
    let data: Vec<OnceLock<Result<MaterialData, String>>> =
        materials.iter().map(|_| OnceLock::new()).collect();
    // Configuration-major, in priority order, so that a run stopped early
    // (rows.jsonl keeps every finished fit; --from-rows reports them) has
    // the main comparisons on every material first.
    let priority = |name: &str| {
        ["sf-3", "independent-g", "ggx", "sf-1", "sf-2"]
            .iter()
            .position(|p| *p == name)
            .unwrap_or(5)
    };
    let mut order: Vec<usize> = (0..configs.len()).collect();
    order.sort_by_key(|&c| (priority(configs[c].name), c));
    let jobs: Vec<(usize, usize)> = order
        .iter()
        .flat_map(|&c| (0..materials.len()).map(move |m| (m, c)))
        .collect();
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
        .filter(|c| ["sf-3", "sf-3-golden", "sf-3-fixed-g"].contains(&c.name))
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
    let mut factor_models: Mutex<Vec<(usize, String, Model)>> = Mutex::new(Vec::new());
    let load = |m: usize| load_material(&data[m], &materials[m], out, render_opts);
    let run_job = |m: usize, c: &Configuration| -> Row {
        let (name, _) = &materials[m];
        let mut row = Row {
            material: name.clone(),
            config: c.name.into(),
            params: c.params(),
            seconds: f64::NAN,
            sweeps: 0,
            converged: false,
            objective: f64::NAN,
            eval: None,
            error: None,
            history: Vec::new(),
        };
        let res = one_thread(|| -> Result<(), String> {
            let md = load(m).as_ref().map_err(|e| e.clone())?;
            let config = c.fit_config(args.max_sweeps);
            let (fit, _) = fit_kind(&md.samples, &config, c.kind, &mut |_, _| {})?;
            row.seconds = fit.seconds;
            row.sweeps = fit.history.len();
            row.converged = fit.converged;
            row.objective = fit.objective;
            row.history = fit
                .history
                .iter()
                .map(|h| (h.sweep, h.objective, h.elapsed))
                .collect();
            let reference = Reference {
                table: &md.table,
                samples: &md.samples,
                image: md.image.clone(),
                render: render_opts,
            };
            let (eval, image) = reference
                .evaluate_model(config.max_theta, &fit.model)
                .map_err(|e| e.to_string())?;
            let dir = out.join(name);
            write_png(
                &dir.join(format!("{}.png", c.name)),
                image.res,
                &image.to_rgb8(),
            )
            .map_err(|e| e.to_string())?;
            write_png(
                &dir.join(format!("{}-diff.png", c.name)),
                image.res,
                &crate::render::difference_rgb8(&md.image, &image, super::compare::DIFF_GAIN),
            )
            .map_err(|e| e.to_string())?;
            let file = crate::modelfile::ModelFile {
                model: fit.model.clone(),
                fit: None,
            };
            crate::modelfile::write(&dir.join(format!("{}.json", c.name)), &file, true)
                .map_err(|e| e.to_string())?;
            if c.kind == ModelKind::Factor && c.name == "sf-3" || c.kind == ModelKind::IndependentG
            {
                factor_models
                    .lock()
                    .map_err(|_| "a worker failed".to_string())?
                    .push((m, c.name.to_string(), fit.model.clone()));
            }
            row.eval = Some(eval);
            Ok(())
        });
        match res {
            Ok(Ok(())) => {}
            Ok(Err(e)) => row.error = Some(e),
            Err(e) => row.error = Some(e.to_string()),
        }
        row
    };
    let t0 = std::time::Instant::now();
    let next = AtomicUsize::new(0);
    let n_conv = conv_material.map_or(0, |_| conv_configs.len());
    let done: Mutex<Vec<Row>> = Mutex::new(Vec::new());
    let conv_done: Mutex<Vec<(usize, String, Convergence)>> = Mutex::new(Vec::new());
    let rows_log = Mutex::new(());
    std::thread::scope(|scope| {
        if args.from_rows {
            return;
        }
        for _ in 0..threads {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                if k < jobs.len() {
                    let (m, c) = jobs[k];
                    let row = run_job(m, &configs[c]);
                    bar.inc(1);
                    bar.set_message(format!(
                        "{} {}: {}",
                        row.material,
                        row.config,
                        match (&row.eval, &row.error) {
                            (Some(e), _) =>
                                format!("{:.1} dB in {:.1} s", e.render_psnr_db, row.seconds),
                            (_, Some(e)) => format!("failed: {e}"),
                            _ => String::new(),
                        }
                    ));
                    if let (Ok(_guard), Ok(line)) = (rows_log.lock(), serde_json::to_string(&row)) {
                        use std::io::Write;
                        let _ = std::fs::OpenOptions::new()
                            .create(true)
                            .append(true)
                            .open(out.join("rows.jsonl"))
                            .and_then(|mut f| writeln!(f, "{line}"));
                    }
                    if let Ok(mut d) = done.lock() {
                        d.push(row);
                    }
                } else if k < jobs.len() + n_conv {
                    let i = k - jobs.len();
                    let (Some(m), c) = (conv_material, conv_configs[i]) else {
                        break;
                    };
                    let r = convergence_run(
                        &data[m],
                        &materials[m],
                        out,
                        c,
                        render_opts,
                        args.max_sweeps,
                    );
                    bar.inc(1);
                    if let Ok(mut d) = conv_done.lock() {
                        d.push((i, c.name.to_string(), r));
                    }
                } else {
                    break;
                }
            });
        }
    });
    let mut rows = done
        .into_inner()
        .map_err(|_| CliError::Message("a worker failed".into()))?;
    let mut conv_loaded = None;
    if args.from_rows {
        let path = out.join("rows.jsonl");
        let text = std::fs::read_to_string(&path).map_err(|e| io_err(&path, e))?;
        for (k, line) in text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
        {
            let row: Row = serde_json::from_str(line).map_err(|e| {
                CliError::Message(format!("{}: line {}: {e}", path.display(), k + 1))
            })?;
            let known = materials.iter().any(|m| m.0 == row.material)
                && configs.iter().any(|c| c.name == row.config);
            if known {
                rows.retain(|r| !(r.material == row.material && r.config == row.config));
                rows.push(row);
            }
        }
        if args.reevaluate {
            for (m, material) in materials.iter().enumerate() {
                let md = load_material(&data[m], material, out, render_opts)
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
                    if let Ok(f) = crate::modelfile::read(&p) {
                        let max_theta = default_fit_config().max_theta;
                        r.eval = Some(
                            reference
                                .evaluate_model(max_theta, &f.model)
                                .map_err(|e| CliError::Message(e.to_string()))?
                                .0,
                        );
                    }
                }
                bar.inc(1);
            }
            let mut text = String::new();
            for r in &rows {
                text.push_str(
                    &serde_json::to_string(r).map_err(|e| CliError::Message(e.to_string()))?,
                );
                text.push('\n');
            }
            write_file(&out.join("rows.jsonl"), text.as_bytes())?;
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
    let mut conv_v = conv_done
        .into_inner()
        .map_err(|_| CliError::Message("a worker failed".into()))?;
    conv_v.sort_by_key(|c| c.0);
    let conv: Option<Vec<(String, Convergence)>> = if args.from_rows {
        conv_loaded
    } else {
        conv_material.map(|_| conv_v.into_iter().map(|c| (c.1, c.2)).collect())
    };
    if let (Some(c), false) = (&conv, args.from_rows) {
        let json = serde_json::to_string_pretty(c).map_err(|e| CliError::Message(e.to_string()))?;
        write_file(&out.join("convergence.json"), json.as_bytes())?;
    }
    bar.finish_and_clear();
    let total_seconds = t0.elapsed().as_secs_f64();
    // Results files.
    let json = serde_json::to_string_pretty(&rows).map_err(|e| CliError::Message(e.to_string()))?;
    write_file(&out.join("results.json"), json.as_bytes())?;
    write_file(&out.join("results.csv"), csv_text(&rows).as_bytes())?;
    // Charts.
    let mut chart_notes = Vec::new();
    if crate::charts::ensure_font() {
        let names: Vec<&str> = configs.iter().map(|c| c.name).collect();
        crate::charts::speed_accuracy(out, &rows, &names)?;
        let models = factor_models
            .into_inner()
            .map_err(|_| CliError::Message("a worker failed".into()))?;
        for (m, config, model) in &models {
            let path = out.join(&materials[*m].0).join(format!("factors-{config}"));
            crate::charts::factor_plot(&path, &materials[*m].0, config, model)?;
        }
        if let (Some(conv), Some(m)) = (&conv, conv_material) {
            crate::charts::convergence(out, &materials[m].0, conv)?;
        }
    } else {
        chart_notes.push(
            "no TrueType font found (looked for DejaVuSans): charts were not drawn".to_string(),
        );
    }
    let md = markdown(
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

/// One checkpoint of a convergence run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    pub sweeps: usize,
    pub seconds: f64,
    pub objective: f64,
    pub render_psnr_db: f64,
}

/// A convergence run: the full history of objectives, and the rendering
/// PSNR at sweep 1, 2, 4, 8, ... (refits stopped after k sweeps; the solver
/// is deterministic, so they are the full fit's first k sweeps).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Convergence {
    pub history: Vec<(usize, f64, f64)>,
    pub initial_objective: f64,
    pub checkpoints: Vec<Checkpoint>,
    pub error: Option<String>,
}

fn convergence_run(
    slot: &OnceLock<Result<MaterialData, String>>,
    material: &(String, PathBuf),
    out: &Path,
    c: &Configuration,
    render_opts: RenderOptions,
    max_sweeps: Option<usize>,
) -> Convergence {
    let r = one_thread(|| -> Result<Convergence, String> {
        let md = load_material(slot, material, out, render_opts)
            .as_ref()
            .map_err(|e| e.clone())?;
        let config = c.fit_config(max_sweeps);
        let (full, _) = fit_kind(&md.samples, &config, c.kind, &mut |_, _| {})?;
        let reference = Reference {
            table: &md.table,
            samples: &md.samples,
            image: md.image.clone(),
            render: render_opts,
        };
        let mut conv = Convergence {
            history: full
                .history
                .iter()
                .map(|h| (h.sweep, h.objective, h.elapsed))
                .collect(),
            initial_objective: full.initial_objective,
            ..Default::default()
        };
        let n = full.history.len();
        let mut k = 1;
        while k < n {
            let mut cfg = config.clone();
            cfg.max_sweeps = k;
            let (part, _) = fit_kind(&md.samples, &cfg, c.kind, &mut |_, _| {})?;
            let bsdf = crate::bsdf::NpfBxdf::new(part.model.clone()).map_err(|e| e.to_string())?;
            let img = crate::render::render(render_opts, &bsdf);
            conv.checkpoints.push(Checkpoint {
                sweeps: part.history.len(),
                seconds: part.seconds,
                objective: part.objective,
                render_psnr_db: crate::render::psnr(&reference.image, &img)
                    .map_err(|e| e.to_string())?,
            });
            k *= 2;
        }
        let bsdf = crate::bsdf::NpfBxdf::new(full.model.clone()).map_err(|e| e.to_string())?;
        let img = crate::render::render(render_opts, &bsdf);
        conv.checkpoints.push(Checkpoint {
            sweeps: n,
            seconds: full.seconds,
            objective: full.objective,
            render_psnr_db: crate::render::psnr(&reference.image, &img)
                .map_err(|e| e.to_string())?,
        });
        Ok(conv)
    });
    match r {
        Ok(Ok(c)) => c,
        Ok(Err(e)) => Convergence {
            error: Some(e),
            ..Default::default()
        },
        Err(e) => Convergence {
            error: Some(e.to_string()),
            ..Default::default()
        },
    }
}

fn csv_text(rows: &[Row]) -> String {
    let mut s = String::from("material,config,params,seconds,sweeps,converged,objective,samples,cos_rmse,rel_cos_rmse,log_rmse,numeric_psnr_db,albedo_err_0,albedo_err_30,albedo_err_60,albedo_err_75,render_psnr_db,error\n");
    for r in rows {
        let e = r.eval.as_ref();
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        let alb: Vec<String> = (0..4)
            .map(|k| f(e.and_then(|e| e.albedo.get(k)).map(|a| a.rel_error)))
            .collect();
        s.push_str(&format!(
            "{},{},{},{:.3},{},{},{:.6e},{},{},{},{},{},{},{},\"{}\"\n",
            r.material,
            r.config,
            r.params,
            r.seconds,
            r.sweeps,
            r.converged,
            r.objective,
            e.map_or(0, |e| e.metrics.samples),
            f(e.map(|e| e.metrics.cos_rmse)),
            f(e.map(|e| e.metrics.rel_cos_rmse)),
            f(e.map(|e| e.metrics.log_rmse)),
            f(e.map(|e| e.numeric_psnr_db)),
            alb.join(","),
            f(e.map(|e| e.render_psnr_db)),
            r.error.clone().unwrap_or_default().replace('"', "'")
        ));
    }
    s
}

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

#[allow(clippy::too_many_arguments)]
fn markdown(
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
    let _ = writeln!(s, "- `MATERIAL/reference.png`, `MATERIAL/CONFIG.png`, `MATERIAL/CONFIG-diff.png` (|difference| x {}), `MATERIAL/CONFIG.json` (the model)", super::compare::DIFF_GAIN);
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
