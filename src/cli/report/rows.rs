//! Row persistence: every finished fit is appended to `rows.jsonl` (so a run
//! stopped early can be reported with `--from-rows`), and the results are
//! written as `results.json` and `results.csv`.

use super::workspace::write_file;
use crate::cli::{CliError, CliResult};
use crate::evaluation::Evaluation;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Mutex;

/// One row of the results.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// Material (file stem).
    pub material: String,
    /// Configuration name.
    pub config: String,
    /// The model's parameter count.
    pub params: usize,
    /// Fit wall-clock seconds (one thread).
    pub seconds: f64,
    /// Sweeps run.
    pub sweeps: usize,
    /// Whether the fit met its tolerance before the sweep limit.
    pub converged: bool,
    /// Final objective.
    pub objective: f64,
    /// The evaluation, if the fit succeeded.
    pub eval: Option<Evaluation>,
    /// Why the fit or its evaluation failed.
    pub error: Option<String>,
    /// (sweep, objective, seconds) of every sweep.
    #[serde(skip)]
    pub history: Vec<(usize, f64, f64)>,
}

/// Append one row to `out/rows.jsonl` (best effort: the row is also kept in
/// memory; `lock` serialises the writers).
pub fn append(out: &Path, row: &Row, lock: &Mutex<()>) {
    if let (Ok(_guard), Ok(line)) = (lock.lock(), serde_json::to_string(row)) {
        use std::io::Write;
        let _ = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(out.join("rows.jsonl"))
            .and_then(|mut f| writeln!(f, "{line}"));
    }
}

/// The rows of a `rows.jsonl` file, in file order (blank lines skipped).
pub fn read(path: &Path) -> Result<Vec<Row>, CliError> {
    // Bounded: a rows file of 1 GiB would be some 200,000 fits.
    let bytes = npf_data_loaders::sniff::read_bounded(path, 1 << 30, "a rows.jsonl file")?;
    let text = String::from_utf8(bytes)
        .map_err(|_| CliError::Message(format!("{}: not UTF-8 text", path.display())))?;
    let mut rows = Vec::new();
    for (k, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        rows.push(
            serde_json::from_str(line).map_err(|e| {
                CliError::Message(format!("{}: line {}: {e}", path.display(), k + 1))
            })?,
        );
    }
    Ok(rows)
}

/// Replace `path` by these rows, one JSON object a line.
pub fn rewrite(path: &Path, rows: &[Row]) -> CliResult {
    let mut text = String::new();
    for r in rows {
        text.push_str(&serde_json::to_string(r).map_err(|e| CliError::Message(e.to_string()))?);
        text.push('\n');
    }
    write_file(path, text.as_bytes())
}

/// Write `results.json` and `results.csv` into `out`.
pub fn write_results(out: &Path, rows: &[Row]) -> CliResult {
    let json = serde_json::to_string_pretty(rows).map_err(|e| CliError::Message(e.to_string()))?;
    write_file(&out.join("results.json"), json.as_bytes())?;
    write_file(&out.join("results.csv"), &csv_bytes(rows)?)
}

/// The CSV columns, in order.
pub const CSV_HEADER: [&str; 18] = [
    "material",
    "config",
    "params",
    "seconds",
    "sweeps",
    "converged",
    "objective",
    "samples",
    "cos_rmse",
    "rel_cos_rmse",
    "log_rmse",
    "numeric_psnr_db",
    "albedo_err_0",
    "albedo_err_30",
    "albedo_err_60",
    "albedo_err_75",
    "render_psnr_db",
    "error",
];

/// The rows as CSV (quoted where a field needs it, by the `csv` crate).
pub fn csv_bytes(rows: &[Row]) -> Result<Vec<u8>, CliError> {
    let fail = |e: csv::Error| CliError::Message(format!("results.csv: {e}"));
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(CSV_HEADER).map_err(fail)?;
    for r in rows {
        let e = r.eval.as_ref();
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        let mut record = vec![
            r.material.clone(),
            r.config.clone(),
            r.params.to_string(),
            format!("{:.3}", r.seconds),
            r.sweeps.to_string(),
            r.converged.to_string(),
            format!("{:.6e}", r.objective),
            e.map_or(0, |e| e.metrics.samples).to_string(),
            f(e.map(|e| e.metrics.cos_rmse)),
            f(e.map(|e| e.metrics.rel_cos_rmse)),
            f(e.map(|e| e.metrics.log_rmse)),
            f(e.map(|e| e.numeric_psnr_db)),
        ];
        record.extend((0..4).map(|k| f(e.and_then(|e| e.albedo.get(k)).map(|a| a.rel_error))));
        record.push(f(e.map(|e| e.render_psnr_db)));
        record.push(r.error.clone().unwrap_or_default());
        w.write_record(&record).map_err(fail)?;
    }
    w.into_inner()
        .map_err(|e| CliError::Message(format!("results.csv: {e}")))
}
