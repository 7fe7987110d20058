//! Convergence study: for each MERL table, the default coarse level, then
//! full-set sweeps with no tolerance (up to `--sweeps N`), printing after
//! every full sweep its objective, relative decrease, time and the model's
//! rendering PSNR (`npf compare`'s render), so stopping rules can be judged
//! by what a fit is for without refitting.
//!
//!     cargo run --release --example sweep_study -- TABLE... [--sweeps N] [--threads N]
//!
//! Output: one CSV line per sweep: material,sweep,objective,rel,seconds,psnr,extrapolated.

use npf::bsdf::NpfBxdf;
use npf::coarse::decimate;
use npf::fit::FitConfig;
use npf::loaders::MerlTable;
use npf::model::Layout;
use npf::render::{psnr, render, RenderOptions};
use npf::samples::FitSet;
use npf::solver::{init, Executor, Factors, FitOptions, Observer, SweepReport};
use std::path::Path;

struct Study<'a> {
    name: String,
    reference: &'a npf::render::Image,
    t0: std::time::Instant,
}

impl Observer for Study<'_> {
    fn observe(&mut self, _r: &SweepReport) {}
    fn observe_factors(&mut self, r: &SweepReport, f: &Factors) {
        if let Ok(dir) = std::env::var("NPF_DUMP") {
            // Every factor table after this sweep, one line each (for diffing).
            let mut out = format!("diffuse {:?}\n", f.diffuse);
            for m in 0..f.lobes() {
                out += &format!("s{m} {:?}\nd{m} {:?}\ng{m} {:?}\n", f.s[m], f.d[m], f.g[m]);
            }
            for c in 0..3 {
                out += &format!("f{c} {:?}\n", f.f[c]);
            }
            let path = format!("{dir}/{}-{}.txt", self.name, r.sweep);
            std::fs::write(&path, out).expect("dump");
        }
        let model = f.to_model();
        let img = render(
            RenderOptions::default(),
            &NpfBxdf::new(model).expect("model"),
        );
        let p = psnr(self.reference, &img).expect("psnr");
        println!(
            "{},{},{:.17e},{:.4e},{:.3},{:.3},{}",
            self.name,
            r.sweep,
            r.objective,
            r.rel_decrease,
            self.t0.elapsed().as_secs_f64(),
            p,
            r.extrapolated as u8
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |n: &str| {
        args.iter()
            .position(|a| a == n)
            .and_then(|i| args.get(i + 1))
            .map(|v| v.parse::<usize>().expect(n))
    };
    let sweeps = get("--sweeps").unwrap_or(20);
    let threads = get("--threads").unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    let mut skip = false;
    for a in &args {
        if skip {
            skip = false;
            continue;
        }
        if a.starts_with("--") {
            skip = true;
            continue;
        }
        pool.install(|| study(Path::new(a), sweeps));
    }
}

fn study(path: &Path, sweeps: usize) {
    let name = path.file_stem().unwrap().to_string_lossy().to_string();
    let table = MerlTable::read(path).expect("table");
    let samples = table.samples(&name);
    let reference = render(RenderOptions::default(), &table);
    let cfg = FitConfig::default();
    let layout = Layout::default();
    let so = cfg.sample_options();
    let opts = cfg.fit_options();
    let t0 = std::time::Instant::now();
    let mut start = init::initial_factors(layout, opts.lobes);
    for &factor in &cfg.coarse {
        let small = FitSet::build(&decimate(&samples, factor), layout, so).expect("set");
        let r = Executor::new(
            &small,
            FitOptions {
                tol: cfg.coarse_tol,
                max_sweeps: cfg.coarse_max_sweeps,
                ..opts
            },
        )
        .start_from(start)
        .run()
        .expect("fit");
        eprintln!("{name}: coarse {} sweeps", r.history.len());
        start = r.factors;
    }
    let set = FitSet::build(&samples, layout, so).expect("set");
    let mut obs = Study {
        name,
        reference: &reference,
        t0,
    };
    let full = FitOptions {
        tol: 0.0,
        max_sweeps: sweeps,
        ..opts
    };
    Executor::new(&set, full)
        .start_from(start)
        .observe(&mut obs)
        .run()
        .expect("fit");
}
