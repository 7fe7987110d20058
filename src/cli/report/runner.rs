//! The job scheduler: (material x configuration) fits run on plain OS
//! threads pulling from one queue, each in its own one-thread rayon pool, and
//! each writes its images and model next to the report.

use super::configs::Configuration;
use super::convergence::{self, Convergence};
use super::rows::{self, Row};
use super::workspace::{one_thread, write_png, Workspace};
use crate::cli::CliError;
use crate::evaluation::Reference;
use crate::fit::{fit_model, FitConfig, ModelKind};
use crate::model::Model;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The factor models the report plots: (material, configuration, model).
pub type FactorModels = Mutex<Vec<(usize, String, Model)>>;

/// Fit configuration `c` on material `m`, evaluate it and write its images
/// and model; a failure is recorded in the row.
pub fn run_job(
    ws: &Workspace,
    m: usize,
    c: &Configuration,
    max_sweeps: Option<usize>,
    factor_models: &FactorModels,
) -> Row {
    let (name, _) = &ws.materials[m];
    let render_opts = ws.render;
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
        let md = ws.load(m).as_ref().map_err(|e| e.clone())?;
        let config = c.fit_config(max_sweeps);
        let (fit, _) =
            fit_model(&md.samples, &config, &mut |_, _| {}).map_err(|e| e.to_string())?;
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
        // Every configuration is scored on the default cut-off's samples
        // (a configuration may fit further out, e.g. sf-3-taper).
        let (eval, image) = reference
            .evaluate_model(FitConfig::default().max_theta, &fit.model)
            .map_err(|e| e.to_string())?;
        let dir = ws.out.join(name);
        write_png(
            &dir.join(format!("{}.png", c.name)),
            image.res,
            &image.to_rgb8(),
        )
        .map_err(|e| e.to_string())?;
        write_png(
            &dir.join(format!("{}-diff.png", c.name)),
            image.res,
            &crate::render::difference_rgb8(&md.image, &image, crate::cli::compare::DIFF_GAIN),
        )
        .map_err(|e| e.to_string())?;
        let file = crate::modelfile::ModelFile {
            model: fit.model.clone(),
            fit: None,
        };
        crate::modelfile::write(&dir.join(format!("{}.json", c.name)), &file, true)
            .map_err(|e| e.to_string())?;
        if c.kind == ModelKind::Factor && c.name == "sf-3" || c.kind == ModelKind::IndependentG {
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
}

/// What to run: the fits, then (optionally) the convergence runs.
pub struct Plan<'a> {
    /// (material, configuration index) in run order.
    pub jobs: Vec<(usize, usize)>,
    /// The configurations `jobs` index.
    pub configs: &'a [Configuration],
    /// The convergence material and configurations, if any.
    pub convergence: Option<(usize, Vec<&'a Configuration>)>,
    /// Override of every configuration's sweep limit.
    pub max_sweeps: Option<usize>,
}

/// The order of jobs: configuration-major, in priority order, so that a
/// run stopped early (rows.jsonl keeps every finished fit; --from-rows
/// reports them) has the main comparisons on every material first.
pub fn job_order(configs: &[Configuration], materials: usize) -> Vec<(usize, usize)> {
    let priority = |name: &str| {
        ["sf-3", "independent-g", "ggx", "sf-1", "sf-2"]
            .iter()
            .position(|p| *p == name)
            .unwrap_or(5)
    };
    let mut order: Vec<usize> = (0..configs.len()).collect();
    order.sort_by_key(|&c| (priority(configs[c].name), c));
    order
        .iter()
        .flat_map(|&c| (0..materials).map(move |m| (m, c)))
        .collect()
}

/// What `run_all` hands back: the rows and the convergence runs.
type RowsAndConvergence = (Vec<Row>, Vec<(String, Convergence)>);

/// Run the plan on `threads` OS threads, appending every finished row to
/// rows.jsonl. Returns the rows (in completion order) and the convergence
/// runs (in configuration order). (Outer rayon workers waiting on an inner
/// pool would steal further jobs and run them all at once, hence plain
/// threads.)
pub fn run_all(
    ws: &Workspace,
    plan: &Plan,
    threads: usize,
    bar: &indicatif::ProgressBar,
    factor_models: &FactorModels,
) -> Result<RowsAndConvergence, CliError> {
    let jobs = &plan.jobs;
    let next = AtomicUsize::new(0);
    let n_conv = plan.convergence.as_ref().map_or(0, |(_, c)| c.len());
    let done: Mutex<Vec<Row>> = Mutex::new(Vec::new());
    let conv_done: Mutex<Vec<(usize, String, Convergence)>> = Mutex::new(Vec::new());
    let rows_log = Mutex::new(());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                if k < jobs.len() {
                    let (m, c) = jobs[k];
                    let row = run_job(ws, m, &plan.configs[c], plan.max_sweeps, factor_models);
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
                    rows::append(ws.out, &row, &rows_log);
                    if let Ok(mut d) = done.lock() {
                        d.push(row);
                    }
                } else if k < jobs.len() + n_conv {
                    let i = k - jobs.len();
                    let Some((m, configs)) = &plan.convergence else {
                        break;
                    };
                    let c = configs[i];
                    let r = convergence::run(ws, *m, c, plan.max_sweeps);
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
    let rows = done
        .into_inner()
        .map_err(|_| CliError::Message("a worker failed".into()))?;
    let mut conv = conv_done
        .into_inner()
        .map_err(|_| CliError::Message("a worker failed".into()))?;
    conv.sort_by_key(|c| c.0);
    Ok((rows, conv.into_iter().map(|c| (c.1, c.2)).collect()))
}
