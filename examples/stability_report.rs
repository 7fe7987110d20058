//! The full stability suite: every hard case x G method (cubic, golden,
//! fixed) x lobes (1-3) x weighting, on 1/`--thin` of each table (default 4),
//! printed as a Markdown table.
//!
//!     cargo run --release --example stability_report -- [--thin K] [--sweeps N] [--case SUBSTRING] [--grazing-trust A]
//!
//! `--grazing-trust A` fits with that threshold of the data-decided grazing
//! rule (`FitConfig::grazing_trust`; 0 turns the rule off, fitting every
//! case to 85 degrees as before the rule existed).

use npf::fit::FitConfig;
use npf::samples::Weighting;
use npf::solver::GMethod;
use npf::stability::{cases, run_with, Config, Outcome};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let opt = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let thin: usize = opt("--thin").map_or(4, |v| v.parse().expect("--thin K"));
    let sweeps: usize = opt("--sweeps").map_or(50, |v| v.parse().expect("--sweeps N"));
    let filter = opt("--case");
    let base = FitConfig {
        grazing_trust: opt("--grazing-trust").map_or(FitConfig::default().grazing_trust, |v| {
            v.parse().expect("--grazing-trust A")
        }),
        ..FitConfig::default()
    };
    println!("Stability suite: 1/{thin} of each table, at most {sweeps} sweeps, errors against the clean truth within 85 degrees.\n");
    println!("| case | G method | lobes | weighting | sweeps | converged | monotone (max rise / data) | finite | non-negative | degenerate | rel. cos RMSE | log RMSE | seconds |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut all: Vec<Outcome> = Vec::new();
    for case in cases() {
        if filter
            .as_ref()
            .is_some_and(|f| !case.name.contains(f.as_str()))
        {
            continue;
        }
        let clean = case.clean();
        let data = case.data(&clean, thin, 7);
        for g_method in [GMethod::Cubic, GMethod::Golden, GMethod::Fixed] {
            for lobes in 1..=3 {
                for weighting in [
                    Weighting::Compressive,
                    Weighting::CosineL2,
                    Weighting::Uniform,
                ] {
                    let config = Config {
                        g_method,
                        lobes,
                        weighting,
                    };
                    let o = run_with(&case, &clean, &data, config, sweeps, &base);
                    all.push(o.clone());
                    if let Some(e) = &o.error {
                        println!(
                            "| {} | {g_method:?} | {lobes} | {weighting:?} | error: {e} |",
                            o.case
                        );
                        continue;
                    }
                    println!(
                        "| {} | {g_method:?} | {lobes} | {weighting:?} | {} | {} | {} ({:.0e}) | {} | {} | {} | {:.3e} | {:.3e} | {:.2} |",
                        o.case,
                        o.sweeps,
                        if o.converged { "yes" } else { "no" },
                        if o.monotone() { "yes" } else { "**no**" },
                        o.max_rise_vs_data,
                        if o.finite { "yes" } else { "**no**" },
                        if o.non_negative { "yes" } else { "**no**" },
                        o.degenerate.as_deref().unwrap_or("-"),
                        o.rel_cos_rmse,
                        o.log_rmse,
                        o.seconds
                    );
                }
            }
        }
    }
    summary(&all);
}

/// Case x G method, over the 9 runs (lobes x weighting) of each: how many
/// converged, stayed monotone, stayed finite and non-negative, degenerated,
/// and the best and median error.
fn summary(all: &[Outcome]) {
    println!("\n## Summary: case x G method (9 runs each: 1-3 lobes x 3 weightings)\n");
    println!("| case | G method | converged | monotone | finite, non-negative | degenerate lobes | best rel. cos RMSE | median rel. cos RMSE |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut keys: Vec<(String, GMethod)> = Vec::new();
    for o in all {
        let k = (o.case.clone(), o.config.g_method);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (case, method) in keys {
        let runs: Vec<&Outcome> = all
            .iter()
            .filter(|o| o.case == case && o.config.g_method == method && o.error.is_none())
            .collect();
        let n = runs.len();
        let count = |f: &dyn Fn(&Outcome) -> bool| runs.iter().filter(|o| f(o)).count();
        let mut errs: Vec<f64> = runs.iter().map(|o| o.rel_cos_rmse).collect();
        errs.sort_by(f64::total_cmp);
        let median = errs.get(n / 2).copied().unwrap_or(f64::NAN);
        println!(
            "| {case} | {method:?} | {}/{n} | {}/{n} | {}/{n} | {}/{n} | {:.3e} | {:.3e} |",
            count(&|o| o.converged),
            count(&|o| o.monotone()),
            count(&|o| o.finite && o.non_negative),
            count(&|o| o.degenerate.is_some()),
            errs.first().copied().unwrap_or(f64::NAN),
            median
        );
    }
}
