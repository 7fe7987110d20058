//! Times reading a MERL table and building its sample set, step by step.
//!
//!     cargo run --release --example prep_profile -- TABLE.binary [REPEATS] [grid]
//!
//! With `grid`, the MERL grid path: `MerlSamples` in place of the samples,
//! `FitSet::build_merl` in place of `FitSet::build`. With `check`, both
//! sets once, and whether they are the same up to order.
use npf::loaders::MerlTable;
use npf::model::Layout;
use npf::samples::{FitSet, SampleOptions};
use std::time::Instant;

/// This process's CPU time (user + system, all threads) in seconds, from
/// /proc/self/stat (10 ms resolution); wall time alone misleads on a loaded machine.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .map(|v| v.parse().unwrap_or(0.0))
        .collect();
    // Fields 14 and 15 (utime, stime) are the 12th and 13th after the name.
    (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) / 100.0
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = std::path::Path::new(&args[0]);
    let repeats: usize = args.get(1).map_or(3, |r| r.parse().expect("REPEATS"));
    let grid = args.get(2).is_some_and(|a| a == "grid");
    if args.get(2).is_some_and(|a| a == "check") {
        let table = MerlTable::read(path).expect("read");
        let (layout, so) = (Layout::default(), SampleOptions::default());
        let generic = FitSet::build(&table.samples("t"), layout, so).expect("set");
        let m = npf::loaders::MerlSamples::new(table, "t");
        let grid = FitSet::build_merl(&m, layout, so, npf::samples::GUse::Updated).expect("set");
        match npf::samples::same_up_to_order(&grid, &generic) {
            Ok(()) => println!("{}: the same set ({} samples)", path.display(), grid.len()),
            Err(e) => println!("{}: DIFFERENT: {e}", path.display()),
        }
        return;
    }
    for _ in 0..repeats {
        let (c0, t0) = (cpu_seconds(), Instant::now());
        let table = MerlTable::read(path).expect("read");
        let (c1, t1) = (cpu_seconds(), Instant::now());
        let (set, (c2, t2)) = if grid {
            let m = npf::loaders::MerlSamples::new(table, &path.display().to_string());
            let at = (cpu_seconds(), Instant::now());
            let set = FitSet::build_merl(
                &m,
                Layout::default(),
                SampleOptions::default(),
                npf::samples::GUse::Updated,
            );
            (set, at)
        } else {
            let samples = table.samples(&path.display().to_string());
            let at = (cpu_seconds(), Instant::now());
            (
                FitSet::build(&samples, Layout::default(), SampleOptions::default()),
                at,
            )
        };
        let set = set.expect("set");
        let (c3, t3) = (cpu_seconds(), Instant::now());
        println!(
            "wall (cpu) s: read {:.3} ({:.2}), samples {:.3} ({:.2}), set {:.3} ({:.2}) [{} samples], total {:.3} ({:.2})",
            (t1 - t0).as_secs_f64(),
            c1 - c0,
            (t2 - t1).as_secs_f64(),
            c2 - c1,
            (t3 - t2).as_secs_f64(),
            c3 - c2,
            set.len(),
            (t3 - t0).as_secs_f64(),
            c3 - c0
        );
    }
}
