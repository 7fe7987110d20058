//! Anisotropic benchmark: fits the 2010-parameter model (`npf fit`'s
//! defaults on a UTIA table) to every material of
//! `npf::synth_aniso::catalogue()` and prints a Markdown row per material:
//! fit seconds, sweeps, numerical PSNR at the table's nodes, and three
//! rendering PSNRs of the sphere (its tangent field: see `npf::render`):
//! fit vs the analytic BRDF, the table's own quadrilinear interpolation vs
//! the analytic BRDF, and fit vs the interpolated table. Peak memory is the
//! process's (Linux VmHWM) at the end.
//!
//!     cargo run --release --example aniso_bench -- [--threads N] [--max-sweeps N] [--tol T] [--images DIR] [--only NAME] [--d-nodes N] [--d-axis A] [--g-axis A] [--gauss-newton on|off]
//!
//! `--d-axis uniform|sqrt|squared` and `--g-axis catmull-rom|uniform|closed` swap the
//! theta axis of D or G (same node counts, so still 2010 parameters):
//! the measurements behind `Layout::anisotropic()`'s choice.
//!
//! `--d-nodes N` fits a finer layout instead (an experiment, not the
//! 2010-parameter model): D on N uniform theta_h nodes 90/N degrees apart
//! times 48 phi nodes, G and F as in `Layout::anisotropic()`.
//!
//! With --images, writes DIR/NAME.png: analytic reference | fit | difference (x8).
//!
//! For the GGX materials a last column renders the analytic BRDF sampled
//! on the layout: D, G and F at their nodes, s = ks / 4, d = kd / pi (the
//! model's formula is the GGX's, so only the tables' resolution and
//! interpolation separate it from the analytic BRDF): how close the layout
//! can come by point samples alone.

use npf::bsdf::NpfBxdf;
use npf::cli::png::encode_png;
use npf::evaluation::numeric_psnr;
use npf::fit::{fit, FitConfig};
use npf::grid::{Axis, Grid};
use npf::microfacet::schlick;
use npf::model::Layout;
use npf::model::{Lobe, Model};
use npf::render::{difference_rgb8, psnr, render, RenderOptions};
use npf::samples::FitSet;
use npf::solver::{Executor, FitOptions};
use npf::synth_aniso::{aniso_ggx_d, aniso_ggx_g1, catalogue, AnalyticBrdf, AnalyticLobe};
use std::time::Instant;

fn arg<T: std::str::FromStr>(args: &[String], name: &str) -> Option<T> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(|v| {
            v.parse()
                .unwrap_or_else(|_| panic!("{name}: bad value {v}"))
        })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let threads: usize = arg(&args, "--threads").unwrap_or(0);
    let images: Option<String> = arg(&args, "--images");
    let only: Option<String> = arg(&args, "--only");
    let mut config = FitConfig {
        threads,
        ..FitConfig::default()
    };
    if let Some(s) = arg(&args, "--max-sweeps") {
        config.max_sweeps = s;
    }
    if let Some(t) = arg(&args, "--tol") {
        config.tol = t;
    }
    if let Some(g) = arg::<String>(&args, "--gauss-newton") {
        config.gauss_newton = Some(g == "on");
    }
    let d_nodes: Option<usize> = arg(&args, "--d-nodes");
    let d_axis: Option<String> = arg(&args, "--d-axis");
    let g_axis: Option<String> = arg(&args, "--g-axis");
    let axis = |name: &str, n: usize| match name {
        "uniform" => Axis::Uniform { n },
        "sqrt" => Axis::SqrtAngle { n },
        "squared" => Axis::Squared { n },
        "catmull-rom" => Axis::CatmullRom { n },
        "closed" => Axis::Closed { n },
        other => panic!("unknown axis {other} (uniform, sqrt, squared, closed, catmull-rom)"),
    };
    let mut layout = Layout::anisotropic();
    if let Some(n) = d_nodes {
        layout.d = Grid::plane(Axis::Uniform { n }, 48);
    }
    if let Some(a) = &d_axis {
        layout.d = Grid::plane(axis(a, layout.d.n_theta()), 48);
    }
    if let Some(a) = &g_axis {
        layout.g = Grid::plane(axis(a, 6), 48);
    }
    let custom = layout != Layout::anisotropic();
    let opts = RenderOptions::default();
    println!("| material | fit s | CPU s | sweeps | num. PSNR dB | render PSNR fit vs analytic | table interp. vs analytic | fit vs table interp. | analytic on the layout vs analytic |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut fit_vs_analytic = Vec::new();
    let (mut beats, mut total_secs, mut total_cpu) = (0usize, 0.0, 0.0);
    for m in catalogue() {
        if only.as_ref().is_some_and(|o| *o != m.name) {
            continue;
        }
        let table = m.table();
        let samples = table.samples(&m.name);
        let t = Instant::now();
        let cpu0 = cpu_seconds();
        let result = match custom {
            false => fit(&samples, &config, &mut |_, _| {}).expect("fit").result,
            true => {
                let set = FitSet::build(&samples, layout, config.sample_options()).expect("set");
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("pool")
                    .install(|| {
                        let opts = FitOptions {
                            gauss_newton: config.gauss_newton.unwrap_or(true),
                            ..config.fit_options()
                        };
                        Executor::new(&set, opts).run()
                    })
                    .expect("fit")
            }
        };
        let secs = t.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - cpu0;
        let bxdf = NpfBxdf::new(result.model.clone()).expect("valid model");
        let num = numeric_psnr(&samples, config.max_theta, &bxdf);
        let img_ref = render(opts, &m);
        let img_tab = render(opts, &table);
        let img_fit = render(opts, &bxdf);
        let p_fa = psnr(&img_ref, &img_fit).unwrap();
        let p_ta = psnr(&img_ref, &img_tab).unwrap();
        let p_ft = psnr(&img_tab, &img_fit).unwrap();
        let p_la = sampled_on(&m, layout).map_or("-".to_string(), |model| {
            let b = NpfBxdf::new(model).expect("valid model");
            format!("{:.2}", psnr(&img_ref, &render(opts, &b)).unwrap())
        });
        fit_vs_analytic.push((p_fa, m.name.clone()));
        beats += usize::from(p_fa >= p_ta);
        total_secs += secs;
        total_cpu += cpu;
        println!(
            "| {} | {secs:.2} | {cpu:.2} | {} | {num:.2} | {p_fa:.2} | {p_ta:.2} | {p_ft:.2} | {p_la} |",
            m.name,
            result.history.len()
        );
        if let Some(dir) = &images {
            let r = opts.res;
            let parts = [
                img_ref.to_rgb8(),
                img_fit.to_rgb8(),
                difference_rgb8(&img_ref, &img_fit, 8.0),
            ];
            let mut buf = Vec::with_capacity(3 * r * r * 3);
            for row in 0..r {
                for p in &parts {
                    buf.extend_from_slice(&p[3 * r * row..3 * r * (row + 1)]);
                }
            }
            let png = encode_png(3 * r as u32, r as u32, &buf).expect("png");
            let path = std::path::Path::new(dir).join(format!("{}.png", m.name));
            npf::loaders::atomic::write_bytes_atomic(&path, true, &png).expect("write png");
        }
    }
    fit_vs_analytic.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((worst, name)) = fit_vs_analytic.first() {
        let median = fit_vs_analytic[fit_vs_analytic.len() / 2].0;
        let mean = fit_vs_analytic.iter().map(|p| p.0).sum::<f64>() / fit_vs_analytic.len() as f64;
        println!("\nrendering PSNR (fit vs analytic): median {median:.2} dB, mean {mean:.2} dB, worst {worst:.2} dB ({name})");
        println!(
            "fit at least as close to the analytic BRDF as the table's interpolation: {beats} of {}",
            fit_vs_analytic.len()
        );
        println!("fit time: {total_secs:.1} s wall, {total_cpu:.1} s CPU in all");
    }
    let hwm = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM"))
                .map(str::to_string)
        });
    println!("peak memory: {}", hwm.unwrap_or_else(|| "n/a".into()));
}

/// A GGX material's analytic factors sampled at the layout's nodes (None
/// for other materials).
fn sampled_on(m: &AnalyticBrdf, layout: Layout) -> Option<Model> {
    let on = |grid: Grid, f: &dyn Fn(f64, f64) -> f64| -> Vec<f32> {
        (0..grid.len())
            .map(|k| {
                let (t, p) = grid.node(k);
                f(t, p) as f32
            })
            .collect()
    };
    let mut lobes = Vec::new();
    let mut f0s = Vec::new();
    for l in &m.lobes {
        let AnalyticLobe::Ggx {
            ax,
            ay,
            tangent,
            ks,
            f0,
        } = *l
        else {
            return None;
        };
        lobes.push(Lobe {
            s: ks.map(|k| (k / 4.0) as f32),
            d: on(layout.d, &|t, p| aniso_ggx_d(t.cos(), p - tangent, ax, ay)),
            g: on(layout.g, &|t, p| aniso_ggx_g1(t.cos(), p - tangent, ax, ay)),
        });
        f0s.push(f0);
    }
    // One F per channel is shared by the lobes: only single-Fresnel materials.
    if f0s.windows(2).any(|w| w[0] != w[1]) {
        return None;
    }
    let fresnel = f0s[0].map(|f0| on(layout.f, &|t, _| schlick(f0, t.cos())));
    Some(Model {
        layout,
        diffuse: m.kd.map(|k| (k / std::f64::consts::PI) as f32),
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel,
        lobes,
    })
}

/// User + system CPU seconds of this process so far (all threads; Linux
/// /proc/self/stat, 100 ticks a second), 0 where unavailable.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name; utime and stime are 14 and 15.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}
