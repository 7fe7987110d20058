//! `npf fit DIR -o OUTDIR`: fit every measured table of a folder.
//!
//! Each `.binary` (MERL) and `.bin` (UTIA) file of DIR becomes
//! `OUTDIR/<stem>.json` (or `.npfb`), fitted as `npf fit` would fit it
//! alone. Everything that can be checked is checked before the first fit
//! (flags, the output folder, clashing output names), so a long run does
//! not stop on a typo. A table that fails is reported and the rest go on;
//! the exit status is non-zero at the end if any failed. Existing outputs
//! are kept (the run resumes) unless `--force`. `OUTDIR/summary.csv` records
//! every table of the run (fitted, skipped or failed); it is this run's own
//! record, rewritten (atomically) by each run. Several tables are fitted
//! at once ([`Plan`]); lines and rows keep the name order.

use super::fit_args::{FitArgs, ModelForm};
use super::fit_table::fit_table;
use super::{CliError, CliResult};
use crate::modelfile;
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

/// The summary's file name in the output folder.
pub const SUMMARY: &str = "summary.csv";

/// What happened to one table.
enum Outcome {
    /// Fitted and written in this run.
    Fitted,
    /// Its output existed and was kept.
    Skipped,
    /// Failed: the message names the file and the problem.
    Failed(String),
}

/// What a worker tells the main thread.
enum Event {
    /// It began the table of this index.
    Started(usize),
    /// It finished the table of this index.
    Done(usize, Row),
}

/// Memory set aside for each concurrent fit when `--jobs` is not given: a
/// MERL fit peaks at about 290 MB; the rest is headroom for glibc's
/// per-thread arenas.
const FIT_MEMORY: u64 = 400 << 20;

/// How many tables are fitted at once, and with how many threads each.
///
/// One fit keeps two cores busy only part of the time (the read, parts of
/// the sample set's construction, the small coarse-level loops, the error
/// re-measure and the write are serial), so a folder is fitted faster as
/// several fits of fewer threads each. Fits do not depend on the thread
/// count, so the models are those of a one-at-a-time run.
struct Plan {
    jobs: usize,
    threads: usize,
}

impl Plan {
    /// `jobs` from `--jobs` (`None`: as many as the thread budget and the
    /// free memory allow); `threads` from `--threads`, the run's budget (0:
    /// every core), shared among the jobs; `todo` tables to fit.
    fn new(jobs: Option<usize>, threads: usize, todo: usize) -> Result<Plan, CliError> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let budget = if threads == 0 { cores } else { threads };
        let jobs = match jobs {
            Some(0) => return Err(CliError::Message("--jobs must be at least 1".into())),
            Some(n) => n,
            None => budget.min(cores).min(memory_jobs()),
        };
        // No more workers than tables to fit (skipped tables cost nothing),
        // so a resumed run's last fits keep all threads.
        let jobs = jobs.min(todo).max(1);
        Ok(Plan {
            jobs,
            threads: (budget / jobs).max(1),
        })
    }

    fn describe(&self) -> String {
        let threads = if self.threads == 1 {
            "thread"
        } else {
            "threads"
        };
        if self.jobs == 1 {
            format!("one at a time, {} {threads}", self.threads)
        } else {
            format!("{} at a time, {} {threads} each", self.jobs, self.threads)
        }
    }
}

/// How many fits of [`FIT_MEMORY`] the available memory holds (at least
/// one; unlimited where the system does not say).
fn memory_jobs() -> usize {
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|m| {
        m.lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
    });
    available.map_or(usize::MAX, |kb| {
        usize::try_from(kb.saturating_mul(1024) / FIT_MEMORY)
            .unwrap_or(usize::MAX)
            .max(1)
    })
}

/// One row of the summary.
struct Row {
    file: String,
    outcome: Outcome,
    parameters: Option<usize>,
    lobes: Option<usize>,
    sweeps: Option<usize>,
    converged: Option<bool>,
    /// This run's wall time for the table (read, fit, write).
    seconds: Option<f64>,
    /// The fit's own time, as its model file records it.
    fit_seconds: Option<f64>,
    objective: Option<f64>,
    log_rmse: Option<f64>,
    rel_cos_rmse: Option<f64>,
}

impl Row {
    fn new(file: String, outcome: Outcome) -> Row {
        Row {
            file,
            outcome,
            parameters: None,
            lobes: None,
            sweeps: None,
            converged: None,
            seconds: None,
            fit_seconds: None,
            objective: None,
            log_rmse: None,
            rel_cos_rmse: None,
        }
    }

    /// Fills the model's figures from a model file's contents.
    fn record(&mut self, file: &modelfile::ModelFile) {
        self.parameters = Some(file.model.param_count());
        if let Some(info) = &file.fit {
            self.lobes = Some(info.lobes);
            self.sweeps = Some(info.sweeps);
            self.converged = Some(info.converged);
            self.fit_seconds = Some(info.seconds);
            self.objective = Some(info.objective);
            if let Some(m) = &info.metrics {
                self.log_rmse = Some(m.log_rmse);
                self.rel_cos_rmse = Some(m.rel_cos_rmse);
            }
        }
    }

    fn status(&self) -> &'static str {
        match self.outcome {
            Outcome::Fitted => "fitted",
            Outcome::Skipped => "skipped",
            Outcome::Failed(_) => "failed",
        }
    }
}

/// Whether a file name is a measured table's (by extension, as
/// `npf_data_loaders::detect` reads them).
fn is_table_name(path: &Path) -> bool {
    let hidden = path
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with('.'));
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    !hidden && (ext.eq_ignore_ascii_case("binary") || ext.eq_ignore_ascii_case("bin"))
}

/// The folder's tables, sorted by name, and how many other entries it has.
fn list_tables(dir: &Path) -> Result<(Vec<PathBuf>, usize), CliError> {
    let read = std::fs::read_dir(dir).map_err(|e| {
        CliError::Message(format!("{}: cannot list the folder: {e}", dir.display()))
    })?;
    let mut tables = Vec::new();
    let mut others = 0;
    for entry in read {
        let entry = entry.map_err(|e| {
            CliError::Message(format!("{}: cannot list the folder: {e}", dir.display()))
        })?;
        let path = entry.path();
        if is_table_name(&path) {
            tables.push(path);
        } else {
            others += 1;
        }
    }
    tables.sort();
    Ok((tables, others))
}

/// Checks (and creates, if missing) the output folder: not the input
/// folder, not a file, writable.
fn prepare_output_dir(out: &Path, input: &Path) -> CliResult {
    let refuse = |why: String| Err(CliError::Message(format!("{}: {why}", out.display())));
    if let Ok(m) = std::fs::metadata(out) {
        if !m.is_dir() {
            return refuse(
                "is not a folder: with a folder input, -o names the output folder".into(),
            );
        }
    } else {
        if out.symlink_metadata().is_ok() {
            return refuse("is a dangling symbolic link, not an output folder".into());
        }
        if modelfile::Form::of(out).is_ok() {
            return refuse(
                "looks like a model file: with a folder input, -o names the output folder".into(),
            );
        }
        std::fs::create_dir(out)
            .or_else(|e| refuse(format!("cannot create the output folder: {e}")))?;
    }
    let (a, b) = (std::fs::canonicalize(out), std::fs::canonicalize(input));
    if let (Ok(a), Ok(b)) = (a, b) {
        if a == b {
            return refuse(
                "is the input folder: choose another output folder (inputs are never written to)"
                    .into(),
            );
        }
    }
    tempfile::NamedTempFile::new_in(out)
        .map(drop)
        .or_else(|e| refuse(format!("cannot write in the output folder: {e}")))
}

/// Run `npf fit DIR -o OUTDIR`.
pub fn run(args: FitArgs) -> CliResult {
    let config = args.config.config(args.model);
    config.validate()?;
    let form = args.form.unwrap_or(ModelForm::Json);
    let (tables, others) = list_tables(&args.input)?;
    if tables.is_empty() {
        return Err(CliError::Message(format!(
            "{}: no measured tables (.binary or .bin files) in the folder",
            args.input.display()
        )));
    }
    // Two tables of one stem (a.binary, a.bin) would write one output twice.
    let output_of = |t: &Path| {
        // The stem plus the form's extension (with_extension would cut a
        // dotted stem such as "a.b").
        let mut name = t.file_stem().unwrap_or_default().to_os_string();
        name.push(".");
        name.push(form.extension());
        args.output.join(name)
    };
    for (k, t) in tables.iter().enumerate() {
        if let Some(other) = tables[..k].iter().find(|o| output_of(o) == output_of(t)) {
            return Err(CliError::Message(format!(
                "{} and {} would both be fitted into {}: rename one",
                other.display(),
                t.display(),
                output_of(t).display()
            )));
        }
    }
    if tables
        .iter()
        .any(|t| output_of(t).file_name() == Some(SUMMARY.as_ref()))
    {
        return Err(CliError::Message(format!(
            "a table's output would be named {SUMMARY}, the run's summary: rename the table"
        )));
    }
    prepare_output_dir(&args.output, &args.input)?;

    let todo = tables
        .iter()
        .filter(|t| args.force || output_of(t).symlink_metadata().is_err())
        .count();
    let plan = Plan::new(args.jobs, config.threads, todo)?;
    let config = crate::fit::FitConfig {
        threads: plan.threads,
        ..config
    };

    let say = !args.quiet;
    if say {
        eprintln!(
            "fitting {} tables from {} into {}{}; {}",
            tables.len(),
            args.input.display(),
            args.output.display(),
            if others > 0 {
                format!(" ({others} other entries ignored)")
            } else {
                String::new()
            },
            plan.describe()
        );
    }
    let bar = if say {
        indicatif::ProgressBar::new(tables.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{bar:30}] {pos}/{len} tables  {msg}  {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let start = Instant::now();
    let name_of = |t: &Path| {
        t.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    // Workers take the tables in name order; their rows come back in any
    // order and are said (and kept) in name order, so the lines and the
    // summary are the same whatever finished first.
    let next = AtomicUsize::new(0);
    let (tx, rx) = mpsc::channel::<Event>();
    let mut done: Vec<Option<Row>> = tables.iter().map(|_| None).collect();
    std::thread::scope(|scope| -> CliResult {
        for j in 0..plan.jobs {
            let tx = tx.clone();
            let (next, tables, config) = (&next, &tables, &config);
            let (args, output_of, name_of) = (&args, &output_of, &name_of);
            std::thread::Builder::new()
                .name(format!("npf-fit-{j}"))
                // The main thread's stack size: the read runs here.
                .stack_size(8 << 20)
                .spawn_scoped(scope, move || loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(table) = tables.get(k) else { break };
                    if tx.send(Event::Started(k)).is_err() {
                        break;
                    }
                    let name = name_of(table);
                    let fitted = std::panic::catch_unwind(AssertUnwindSafe(|| {
                        fit_one(table, &output_of(table), name.clone(), args, config)
                    }));
                    // A bug in one fit is that table's failure; the others go on.
                    let row = fitted.unwrap_or_else(|_| {
                        Row::new(name, Outcome::Failed("internal error (panic)".into()))
                    });
                    // The fit's buffers were freed in whichever thread's
                    // malloc arena held them; hand them back, or the next
                    // table's fit (in other arenas) would stack on them: 4
                    // MERL tables peaked at 581 MB instead of one fit's 434 MB.
                    crate::memory::release_free();
                    if tx.send(Event::Done(k, row)).is_err() {
                        break;
                    }
                })
                .map_err(|e| CliError::Message(format!("cannot start a fitting thread: {e}")))?;
        }
        drop(tx);
        let mut running = std::collections::BTreeSet::new();
        let mut said = 0;
        for event in rx {
            match event {
                Event::Started(k) => {
                    running.insert(k);
                }
                Event::Done(k, row) => {
                    running.remove(&k);
                    done[k] = Some(row);
                    bar.inc(1);
                }
            }
            let names: Vec<String> = running.iter().map(|&k| name_of(&tables[k])).collect();
            bar.set_message(names.join(", "));
            while let Some(Some(row)) = done.get(said) {
                let line = table_line(row, &output_of(&tables[said]));
                // A failure is said even with --quiet.
                if say || matches!(row.outcome, Outcome::Failed(_)) {
                    bar.suspend(|| eprintln!("[{}/{}] {line}", said + 1, tables.len()));
                }
                said += 1;
            }
        }
        Ok(())
    })?;
    // Every worker ran to the end of the list (a worker that could not
    // start leaves the run above with its error).
    let rows: Vec<Row> = done.into_iter().flatten().collect();
    bar.finish_and_clear();

    let summary = args.output.join(SUMMARY);
    write_summary(&summary, &rows)?;
    let count = |f: fn(&Outcome) -> bool| rows.iter().filter(|r| f(&r.outcome)).count();
    let fitted = count(|o| matches!(o, Outcome::Fitted));
    let skipped = count(|o| matches!(o, Outcome::Skipped));
    let failed: Vec<&str> = rows
        .iter()
        .filter(|r| matches!(r.outcome, Outcome::Failed(_)))
        .map(|r| r.file.as_str())
        .collect();
    if say {
        eprintln!(
            "{fitted} fitted, {skipped} skipped, {} failed in {:.1} s; summary in {}",
            failed.len(),
            start.elapsed().as_secs_f64(),
            summary.display()
        );
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(CliError::Message(format!(
            "{} of {} tables failed: {} (see {})",
            failed.len(),
            rows.len(),
            failed.join(", "),
            summary.display()
        )))
    }
}

/// The line said for a finished table.
fn table_line(row: &Row, output: &Path) -> String {
    match &row.outcome {
        Outcome::Fitted => format!(
            "{}: {} parameters, {} sweeps{}, {:.2} s, log RMSE {:.4e} -> {}",
            row.file,
            row.parameters.unwrap_or(0),
            row.sweeps.unwrap_or(0),
            if row.converged == Some(false) {
                " (sweep limit)"
            } else {
                ""
            },
            row.seconds.unwrap_or(0.0),
            row.log_rmse.unwrap_or(f64::NAN),
            output.display()
        ),
        Outcome::Skipped => format!(
            "{}: skipped, {} exists (--force refits)",
            row.file,
            output.display()
        ),
        Outcome::Failed(e) => format!("{}: FAILED: {e}", row.file),
    }
}

/// Fits one table of the folder into `output`, or keeps an existing
/// output; never fails the run.
fn fit_one(
    table: &Path,
    output: &Path,
    name: String,
    args: &FitArgs,
    config: &crate::fit::FitConfig,
) -> Row {
    let t0 = Instant::now();
    if output.symlink_metadata().is_ok() && !args.force {
        // Resume: keep it, and report what it holds.
        return match modelfile::read(output) {
            Ok(file) => {
                let mut row = Row::new(name, Outcome::Skipped);
                row.record(&file);
                row
            }
            Err(e) => Row::new(
                name,
                Outcome::Failed(format!(
                    "{e} (the existing output is kept; --force refits it)"
                )),
            ),
        };
    }
    let result = super::check_output(output, args.force)
        .and_then(|()| fit_table(table, output, args, config, false));
    match result {
        Ok(fitted) => {
            let mut row = Row::new(name, Outcome::Fitted);
            row.record(&modelfile::ModelFile {
                model: fitted.result.model,
                fit: Some(fitted.info),
            });
            row.seconds = Some(t0.elapsed().as_secs_f64());
            row
        }
        Err(e) => {
            let mut row = Row::new(name, Outcome::Failed(e.to_string()));
            row.seconds = Some(t0.elapsed().as_secs_f64());
            row
        }
    }
}

/// Writes the summary CSV atomically (replacing the previous run's).
fn write_summary(path: &Path, rows: &[Row]) -> CliResult {
    let fail = |e: csv::Error| CliError::Message(format!("{}: {e}", path.display()));
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "file",
        "status",
        "parameters",
        "lobes",
        "sweeps",
        "converged",
        "seconds",
        "fit_seconds",
        "objective",
        "log_rmse",
        "rel_cos_rmse",
        "error",
    ])
    .map_err(fail)?;
    fn opt<T: ToString>(v: Option<T>) -> String {
        v.map_or(String::new(), |v| v.to_string())
    }
    let secs = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
    for r in rows {
        w.write_record([
            r.file.clone(),
            r.status().into(),
            opt(r.parameters),
            opt(r.lobes),
            opt(r.sweeps),
            opt(r.converged),
            secs(r.seconds),
            secs(r.fit_seconds),
            opt(r.objective),
            opt(r.log_rmse),
            opt(r.rel_cos_rmse),
            match &r.outcome {
                Outcome::Failed(e) => e.clone(),
                _ => String::new(),
            },
        ])
        .map_err(fail)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))?;
    npf_data_loaders::atomic::write_bytes_atomic(path, true, &bytes)?;
    Ok(())
}
