//! One table through `npf fit`: read, fit (or select under `--target` /
//! `--budget`), write the model and print its summary.

use super::fit_args::{BudgetMetric, FitArgs};
use super::CliError;
use crate::fit::{fit, FitConfig, FitError, Fitted, ModelKind};
use crate::modelfile::{self, ModelFile};
use crate::selection::{self, Candidate, Scores, Target};
use crate::solver::SweepReport;
use npf_data_loaders::MeasuredSamples;

/// The summary `npf fit` and `npf demo` print after a fit.
pub fn print_summary(f: &Fitted) {
    let m = &f.metrics;
    eprintln!(
        "fitted {} parameters ({} lobes) in {:.2} s, {} sweeps ({}), objective {:.6e}",
        // The factor tables and the diffuse form's own (a separable P).
        f.result.model.param_count() + f.result.model.diffuse_form.param_count(),
        f.info.lobes,
        f.info.seconds,
        f.info.sweeps,
        if f.info.converged {
            "converged"
        } else {
            "sweep limit"
        },
        f.info.objective
    );
    eprintln!(
        "errors over {} samples (theta <= {} deg): cosine-weighted RMSE {:.4e} (relative {:.4e}), log RMSE {:.4e}",
        m.samples, m.max_theta_deg, m.cos_rmse, m.rel_cos_rmse, m.log_rmse
    );
}

/// A progress bar for a fit of `kind` (hidden when `show` is false or the
/// kind has no sweeps), and the observer that drives it.
pub fn progress(
    config: &FitConfig,
    show: bool,
) -> (indicatif::ProgressBar, impl FnMut(usize, &SweepReport)) {
    let parts = match config.model {
        ModelKind::Factor => 1,
        ModelKind::IndependentG => 3,
        // Auto runs several fits: no one bar counts them.
        ModelKind::Ggx | ModelKind::Auto => 0,
    };
    let bar = if show && parts > 0 {
        indicatif::ProgressBar::new((parts * config.max_sweeps) as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    if config.model == ModelKind::Factor {
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} fitting [{bar:30}] {pos}/{len} sweeps  {msg}  {elapsed}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
    }
    let max = config.max_sweeps as u64;
    let independent = config.model == ModelKind::IndependentG;
    let b = bar.clone();
    let observer = move |c: usize, r: &SweepReport| {
        b.set_position(c as u64 * max + r.sweep as u64);
        b.set_message(if independent {
            format!("channel {c}, objective {:.6e}", r.objective)
        } else {
            format!("objective {:.6e} (-{:.1e})", r.objective, r.rel_decrease)
        });
    };
    (bar, observer)
}

/// Fit with a progress bar (shown when `show` is true).
pub fn fit_with_progress(
    samples: &MeasuredSamples,
    config: &FitConfig,
    show: bool,
) -> Result<Fitted, CliError> {
    let (bar, mut observer) = progress(config, show);
    let fitted = fit(samples, config, &mut observer)?;
    bar.finish_and_clear();
    Ok(fitted)
}

/// Read `input`, fit it as `args` asks (a plain fit, or a `--target` /
/// `--budget` selection) and write the model to `output`; `verbose` shows
/// the sweep progress bar and the selection's trial lines.
pub(super) fn fit_table(
    input: &std::path::Path,
    output: &std::path::Path,
    args: &FitArgs,
    config: &FitConfig,
    verbose: bool,
) -> Result<Fitted, CliError> {
    // (clap refuses --model with --target or --budget.)
    if config.model == ModelKind::Auto {
        let source = input.display().to_string();
        let stamp = file_stamp(input);
        let table = npf_data_loaders::Table::read(input, args.format.map(Into::into))?;
        // The judge renders the table read between its nodes, as a fit
        // interpolates (a truncating read holds each node across its bin,
        // docs/fitting.md); then the table goes into the fit.
        let opts = crate::judge::judge_options();
        let (judge, data): (_, crate::samples::SampleData) = match table {
            npf_data_loaders::Table::Merl(t) => (
                crate::judge::Judge::new(&crate::bsdf::InterpolatedMerl(&t), opts),
                npf_data_loaders::MerlSamples::new(t, &source).into(),
            ),
            npf_data_loaders::Table::Utia(t) => (
                crate::judge::Judge::new(&t, opts),
                npf_data_loaders::Table::Utia(t).samples(&source).into(),
            ),
        };
        crate::phases::mark("read + judge's reference");
        if crate::samples::SampleSource::sample_count(&data) == 0 {
            return Err(super::input::no_samples(input));
        }
        let reread = reread_checked(input, args.format, stamp);
        let mut observer = |_: usize, _: &SweepReport| {};
        let fitted = crate::auto::fit_owned(data, reread, &judge, config, &mut observer)?;
        if verbose {
            print_auto(&fitted);
        }
        return write_fitted(output, args, fitted);
    }
    let selection = match (args.target, args.budget) {
        (Some(target), _) => Selection::Target(target),
        (None, Some(budget)) => {
            let metric = match args.budget_metric {
                BudgetMetric::LogRmse => Target::LogRmse(f64::INFINITY),
                BudgetMetric::RelRmse => Target::RelRmse(f64::INFINITY),
            };
            Selection::Budget(budget, metric)
        }
        (None, None) => {
            // Neither the samples nor the table are held during the sweeps
            // (the fit's peak memory): the table is read again for the
            // error measures (its samples made piece by piece, not all
            // held), and refused if the file changed meanwhile. A MERL
            // table's samples are never made as records.
            let stamp = file_stamp(input);
            let data = super::read_fit_data(input, args.format)?;
            crate::phases::mark("read + samples");
            let reread = reread_checked(input, args.format, stamp);
            let (bar, mut observer) = progress(config, verbose);
            let fitted = crate::fit::fit_owned(data, reread, config, &mut observer)?;
            bar.finish_and_clear();
            return write_fitted(output, args, fitted);
        }
    };
    let (table, samples) = super::read_measured(input, args.format)?;
    crate::phases::mark("read + samples");
    // A rendering-PSNR target renders the input table once as the reference.
    let reference = match &selection {
        Selection::Target(target) if target.needs_render() => {
            Some(crate::evaluation::Reference::new(
                super::table_bsdf(&table),
                &samples,
                Default::default(),
            ))
        }
        _ => None,
    };
    let fitted = select(&samples, verbose, config, selection, reference.as_ref())?;
    drop(table);
    write_fitted(output, args, fitted)
}

/// Reads `input` again for the error measures after a fit, refused if it
/// changed since `stamp` ([`file_stamp`]) was taken.
fn reread_checked(
    input: &std::path::Path,
    format: Option<super::FormatArg>,
    stamp: Option<(u64, std::time::SystemTime)>,
) -> impl FnOnce() -> Result<npf_data_loaders::Table, FitError> + Send + '_ {
    move || {
        let changed = |problem: String| FitError::Remeasure {
            source_name: input.display().to_string(),
            problem,
        };
        if file_stamp(input) != stamp {
            return Err(changed("the input changed during the fit".into()));
        }
        npf_data_loaders::Table::read(input, format.map(Into::into))
            .map_err(|e| changed(format!("reading it again: {e}")))
    }
}

/// The input's size and modification time (`None` if unreadable): what
/// tells a file changed between two reads.
fn file_stamp(path: &std::path::Path) -> Option<(u64, std::time::SystemTime)> {
    let m = std::fs::metadata(path).ok()?;
    Some((m.len(), m.modified().ok()?))
}

/// Write a fitted model to `output`.
/// Auto's candidates, their mean render PSNR and the choice (stderr).
fn print_auto(fitted: &Fitted) {
    let Some(auto) = fitted.info.selection.as_ref().and_then(|s| s.get("auto")) else {
        return;
    };
    for c in auto["candidates"].as_array().into_iter().flatten() {
        eprintln!(
            "auto: {:<28} render {:.2} dB (mean of {} scenes), log RMSE {:.4e}, {:.1} s",
            c["name"].as_str().unwrap_or("?"),
            c["render"]["mean_db"].as_f64().unwrap_or(f64::NAN),
            c["render"]["psnr_db"].as_array().map_or(0, Vec::len),
            c["log_rmse"].as_f64().unwrap_or(f64::NAN),
            c["seconds"].as_f64().unwrap_or(f64::NAN),
        );
    }
    eprintln!("auto: chose {}", auto["chosen"].as_str().unwrap_or("?"));
}

fn write_fitted(
    output: &std::path::Path,
    args: &FitArgs,
    fitted: Fitted,
) -> Result<Fitted, CliError> {
    modelfile::write(
        output,
        &ModelFile {
            model: fitted.result.model.clone(),
            fit: Some(fitted.info.clone()),
        },
        args.force,
    )?;
    crate::phases::mark("write");
    Ok(fitted)
}

enum Selection {
    Target(Target),
    Budget(usize, Target),
}

/// Model selection: fits candidates (see `selection`), keeps the chosen
/// fit, and records the choice and every trial in the fit record.
fn select(
    samples: &MeasuredSamples,
    verbose: bool,
    base: &FitConfig,
    how: Selection,
    reference: Option<&crate::evaluation::Reference>,
) -> Result<Fitted, CliError> {
    let mut kept: Vec<Fitted> = Vec::new();
    let mut try_candidate = |c: Candidate| -> Result<(Scores, f64), CliError> {
        let config = FitConfig {
            model: ModelKind::Factor,
            lobes: c.lobes,
            nodes: c.nodes,
            ..base.clone()
        };
        let f = fit(samples, &config, &mut |_, _| {})?;
        let render_psnr_db = match reference {
            Some(r) => Some(
                r.evaluate_model(config.max_theta, &f.result.model)
                    .map_err(|e| CliError::Message(e.to_string()))?
                    .0
                    .render_psnr_db,
            ),
            None => None,
        };
        if verbose {
            eprintln!(
                "  {} lobes x {} values ({} parameters): log RMSE {:.4e}, relative RMSE {:.4e}{} ({:.1} s)",
                c.lobes,
                c.nodes,
                c.params(),
                f.metrics.log_rmse,
                f.metrics.rel_cos_rmse,
                render_psnr_db.map_or(String::new(), |p| format!(", rendering PSNR {p:.2} dB")),
                f.info.seconds
            );
        }
        let out = (
            Scores {
                metrics: f.metrics,
                render_psnr_db,
            },
            f.info.seconds,
        );
        kept.push(f);
        Ok(out)
    };
    let (chosen, record) = match how {
        Selection::Target(target) => {
            if verbose {
                eprintln!(
                    "choosing the smallest model with {} {} {}",
                    target.name(),
                    target.relation(),
                    target.threshold()
                );
            }
            let (i, met, trials) = selection::smallest_meeting(target, &mut try_candidate)?;
            if !met && verbose {
                eprintln!(
                    "warning: no candidate meets {} {} {}; keeping the best ({} parameters, {:.4e})",
                    target.name(), target.relation(), target.threshold(), trials[i].params, trials[i].value
                );
            }
            let record = serde_json::json!({
                "model": "factor", "mode": "target", "target": target, "met": met,
                "chosen": trials[i], "trials": trials,
            });
            (i, record)
        }
        Selection::Budget(budget, metric) => {
            let Some((i, trials)) = selection::best_within(budget, metric, &mut try_candidate)?
            else {
                return Err(CliError::Message(format!(
                    "--budget {budget}: no candidate model has that few parameters (the smallest has {})",
                    selection::candidates()[0].params()
                )));
            };
            let record = serde_json::json!({
                "model": "factor", "mode": "budget", "budget": budget, "metric": metric.name(),
                "chosen": trials[i], "trials": trials,
            });
            (i, record)
        }
    };
    let mut fitted = kept.swap_remove(chosen);
    if verbose {
        eprintln!(
            "chose {} lobes x {} values: {} parameters",
            fitted.info.lobes,
            fitted.result.model.layout.d.len(),
            fitted.result.model.param_count()
        );
    }
    fitted.info.selection = Some(record);
    Ok(fitted)
}
