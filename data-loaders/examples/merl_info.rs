//! Reads MERL files and prints timings and counts.
//!
//! `cargo run --release -p npf-data-loaders --example merl_info -- FILE.binary...`

use std::path::Path;
use std::time::Instant;

use npf_data_loaders::MerlTable;

fn main() {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: merl_info FILE.binary...");
        std::process::exit(2);
    }
    let mut failed = false;
    for p in &paths {
        let path = Path::new(p);
        let t0 = Instant::now();
        let table = match MerlTable::read(path) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("{e}");
                failed = true;
                continue;
            }
        };
        let t_read = t0.elapsed();
        let t1 = Instant::now();
        let s = table.samples(p);
        let t_samples = t1.elapsed();
        let mut max = [0.0f64; 3];
        for m in &s.samples {
            for (mx, v) in max.iter_mut().zip(m.rgb) {
                *mx = mx.max(v);
            }
        }
        println!(
            "{p}: read {:.1} ms, samples {:.1} ms; {} valid cells, {} samples, {} missing; max rgb {:.4} {:.4} {:.4}",
            t_read.as_secs_f64() * 1e3,
            t_samples.as_secs_f64() * 1e3,
            table.valid_cells(),
            s.samples.len(),
            s.missing,
            max[0],
            max[1],
            max[2],
        );
    }
    if failed {
        std::process::exit(1);
    }
}
