//! Model selection on every MERL table in a folder: for each target, the
//! smallest candidate (1-3 lobes x 30/45/90 values per table) that meets
//! it, what `npf fit --target` would choose. Candidates are fitted lazily
//! and shared between targets, so a material costs as many fits as its
//! strictest target needs.
//!
//!     cargo run --release --example selection_bench -- DATA_DIR psnr=35 psnr=45 log-rmse=0.01

use npf::evaluation::Reference;
use npf::loaders::MerlTable;
use npf::metrics::compare_model;
use npf::samples::{FitSet, SampleOptions};
use npf::selection::{smallest_meeting, Candidate, Scores, Target};
use npf::solver::{Executor, FitOptions};
use std::collections::HashMap;
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(dir) = args.first() else {
        eprintln!("usage: selection_bench DATA_DIR TARGET...");
        std::process::exit(2);
    };
    let targets: Vec<Target> = args[1..]
        .iter()
        .map(|t| t.parse().unwrap_or_else(|e| panic!("{e}")))
        .collect();
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("read DATA_DIR")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "binary"))
        .collect();
    files.sort();
    print!("| material |");
    for t in &targets {
        print!(
            " {} {} {}: chosen (params) | reached |",
            t.name(),
            t.relation(),
            t.threshold()
        );
    }
    println!(" fits | seconds |");
    println!("|---|{}---|---|", "---|---|".repeat(targets.len()));
    for f in files {
        let name = f.file_stem().unwrap().to_string_lossy().to_string();
        let table = MerlTable::read(&f).expect("read table");
        let samples = table.samples(&name);
        let reference = targets
            .iter()
            .any(|t| t.needs_render())
            .then(|| Reference::new(&table, &samples, Default::default()));
        let mut memo: HashMap<(usize, usize), (Scores, f64)> = HashMap::new();
        let t0 = std::time::Instant::now();
        print!("| {name} |");
        for &target in &targets {
            let fit = |c: Candidate| -> Result<(Scores, f64), String> {
                if let Some(r) = memo.get(&(c.lobes, c.nodes)) {
                    return Ok(*r);
                }
                let set = FitSet::build(&samples, c.layout(), SampleOptions::default())
                    .map_err(|e| e.to_string())?;
                let opts = FitOptions {
                    lobes: c.lobes,
                    ..Default::default()
                };
                let res = Executor::new(&set, opts).run().map_err(|e| e.to_string())?;
                let scores = Scores {
                    metrics: compare_model(&samples, 85.0, &res.model),
                    render_psnr_db: match &reference {
                        Some(r) => Some(
                            r.evaluate_model(85.0, &res.model)
                                .map_err(|e| e.to_string())?
                                .0
                                .render_psnr_db,
                        ),
                        None => None,
                    },
                };
                memo.insert((c.lobes, c.nodes), (scores, res.seconds));
                Ok((scores, res.seconds))
            };
            let (i, met, trials) = smallest_meeting(target, fit).expect("fit");
            let c = trials[i].candidate;
            let value = if target.needs_render() {
                format!("{:.2}", trials[i].value)
            } else {
                format!("{:.3e}", trials[i].value)
            };
            print!(
                " {}{} lobes x {} ({}) | {value} |",
                if met { "" } else { "not met; best: " },
                c.lobes,
                c.nodes,
                trials[i].params,
            );
        }
        println!(" {} | {:.0} |", memo.len(), t0.elapsed().as_secs_f64());
    }
}
