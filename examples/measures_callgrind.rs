//! The error measures after a fit, alone, for instruction counting and
//! timing (the fit itself takes seconds; this reads a table and a fitted
//! model and computes only the measures):
//!
//!     cargo build --release --example measures_callgrind
//!     valgrind --tool=callgrind '--toggle-collect=measures_callgrind::run_*' \
//!         target/release/examples/measures_callgrind TABLE MODEL.json table 1
//!
//! `table` runs `metrics::compare_model_table` (the path `npf fit` takes),
//! `samples` runs `compare_model` on `table.samples(..)` (the general
//! path); the last argument is the repetitions. Prints the measures' bits.

use std::hint::black_box;
use std::path::Path;

use npf::metrics::{compare_model, compare_model_table, MerlReference, Metrics};
use npf::model::Model;
use npf_data_loaders::{MerlSamples, MerlTable, Table};

#[inline(never)]
fn run_table(table: &Table, model: &Model) -> Metrics {
    compare_model_table(black_box(table), 85.0, model)
}

/// The reference part prepared once (outside the timing: `npf fit` makes
/// it beside the coarse level), then the model's part per repetition.
#[inline(never)]
fn run_prepared(reference: &MerlReference, table: &MerlTable, model: &Model) -> Metrics {
    reference
        .compare(black_box(table), 85.0, model)
        .expect("the prepared path applies")
}

#[inline(never)]
fn run_samples(table: &Table, model: &Model) -> Metrics {
    compare_model(&black_box(table).samples(""), 85.0, model)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 5 {
        eprintln!("usage: measures_callgrind TABLE MODEL (table|samples|prepared) REPETITIONS");
        std::process::exit(2);
    }
    let table = Table::read(Path::new(&args[1]), None).expect("the table");
    let model = npf::modelfile::read(Path::new(&args[2]))
        .expect("the model")
        .model;
    let reps: usize = args[4].parse().expect("a repetition count");
    let reference = (args[3] == "prepared").then(|| {
        let Table::Merl(merl) = &table else {
            panic!("the prepared path takes a MERL table")
        };
        let t = std::time::Instant::now();
        let samples = MerlSamples::new(merl.clone(), "");
        let r = MerlReference::prepare(&samples, 85.0);
        eprintln!("prepared in {:.4} s", t.elapsed().as_secs_f64());
        r
    });
    let run = |table: &Table, model: &Model| match (args[3].as_str(), table) {
        ("table", _) => run_table(table, model),
        ("samples", _) => run_samples(table, model),
        ("prepared", Table::Merl(merl)) => run_prepared(reference.as_ref().unwrap(), merl, model),
        (other, _) => panic!("unknown path {other}"),
    };
    let t = std::time::Instant::now();
    let mut m = run(&table, &model);
    for _ in 1..reps {
        m = run(&table, &model);
    }
    let s = t.elapsed().as_secs_f64() / reps as f64;
    println!(
        "{} samples, cos_rmse {:e} ({:016x}), rel {:e} ({:016x}), log {:e} ({:016x}), {:.4} s each",
        m.samples,
        m.cos_rmse,
        m.cos_rmse.to_bits(),
        m.rel_cos_rmse,
        m.rel_cos_rmse.to_bits(),
        m.log_rmse,
        m.log_rmse.to_bits(),
        s
    );
}
