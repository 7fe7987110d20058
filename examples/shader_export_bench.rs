//! Sizes and generation times of the shader and C exports for 3-lobe
//! isotropic (822 parameters) and anisotropic (2010 parameters) models,
//! and, when `cc` is present, the C header's throughput (eval, pdf,
//! sample per second, one core, `cc -O2`). BENCHMARKS.md quotes it:
//!
//!     cargo run --release --example shader_export_bench

use npf::export::shader;
use npf::model::{Layout, Model};
use std::process::Command;
use std::time::Instant;

const C_BENCH: &str = r#"
#define _POSIX_C_SOURCE 199309L
#include "model.h"
#include <stdio.h>
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
int main(void) {
    enum { N = 2000000 };
    static double dirs[64][3];
    for (int k = 0; k < 64; k++) {
        double th = 1.5 * (k % 8) / 8.0, ph = 0.8 * k;
        dirs[k][0] = sin(th) * cos(ph); dirs[k][1] = sin(th) * sin(ph); dirs[k][2] = cos(th);
    }
    double sink = 0.0, f[3], wi[3], pdf, u[2];
    double t0 = now();
    for (int k = 0; k < N; k++) { npf_eval(dirs[k & 63], dirs[(k * 7 + 3) & 63], f); sink += f[1]; }
    double t1 = now();
    for (int k = 0; k < N; k++) sink += npf_pdf(dirs[k & 63], dirs[(k * 7 + 3) & 63]);
    double t2 = now();
    for (int k = 0; k < N; k++) {
        u[0] = (k % 1000) / 1000.0; u[1] = (k % 997) / 997.0;
        npf_sample(dirs[k & 63], (k % 991) / 991.0, u, wi, f, &pdf); sink += pdf;
    }
    double t3 = now();
    printf("%.2f %.2f %.2f %g\n", N / (t1 - t0) / 1e6, N / (t2 - t1) / 1e6, N / (t3 - t2) / 1e6, sink);
    return 0;
}
"#;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Model::eval calls per second on the C benchmark's direction pairs.
fn rust_evals_per_second(model: &Model) -> f64 {
    let dirs: Vec<[f64; 3]> = (0..64)
        .map(|k| npf::loaders::geometry::spherical(1.5 * (k % 8) as f64 / 8.0, 0.8 * k as f64))
        .collect();
    let n = 2_000_000;
    let t = Instant::now();
    let mut sink = 0.0;
    for k in 0..n {
        sink += model.eval(dirs[k & 63], dirs[(k * 7 + 3) & 63])[1];
    }
    std::hint::black_box(sink);
    n as f64 / t.elapsed().as_secs_f64()
}

fn main() {
    let alphas = [0.05, 0.2, 0.5];
    let iso = npf::synth::known_factor_model(Layout::default(), &alphas);
    let aniso = {
        let layout = Layout::anisotropic();
        let iso = npf::synth::known_factor_model(Layout::default(), &alphas);
        let ggx =
            |grid: npf::grid::Grid, f: &dyn Fn(f64) -> f64| npf::microfacet::tabulate(grid, f);
        Model {
            layout,
            diffuse: iso.diffuse,
            diffuse_form: Default::default(),
            masking: Default::default(),
            compensation: None,
            fresnel: iso.fresnel.clone(),
            lobes: alphas
                .iter()
                .zip(&iso.lobes)
                .map(|(&a, l)| npf::model::Lobe {
                    s: l.s,
                    d: ggx(layout.d, &|t| npf::microfacet::ggx_d(t, a)),
                    g: ggx(layout.g, &|t| npf::microfacet::ggx_g1(t, a)),
                })
                .collect(),
        }
    };
    println!("| model | params | format | bytes | generation (ms, median of 5) |");
    println!("|---|---|---|---|---|");
    type Export = fn(&Model) -> Result<String, shader::ShaderError>;
    let formats: [(&str, Export); 3] = [
        (".brdf", shader::brdf_explorer),
        (".glsl", shader::glsl),
        (".h", shader::c_header),
    ];
    for (name, model) in [
        ("isotropic, 3 lobes", &iso),
        ("anisotropic, 3 lobes", &aniso),
    ] {
        for (ext, f) in formats {
            let mut times = Vec::new();
            let mut bytes = 0;
            for _ in 0..5 {
                let t = Instant::now();
                bytes = f(model).unwrap().len();
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            println!(
                "| {name} | {} | {ext} | {bytes} | {:.1} |",
                model.param_count(),
                median(times)
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    println!("\nC header, cc -O2, one core (M calls/s; median of 5 runs), next to");
    println!("npf's own Model::eval on the same direction pairs in the same run:\n");
    println!("| model | Rust Model::eval | C eval | C pdf | C sample (incl. eval and pdf) |");
    println!("|---|---|---|---|---|");
    for (name, model) in [
        ("isotropic, 3 lobes", &iso),
        ("anisotropic, 3 lobes", &aniso),
    ] {
        std::fs::write(dir.path().join("model.h"), shader::c_header(model).unwrap()).unwrap();
        std::fs::write(dir.path().join("bench.c"), C_BENCH).unwrap();
        let exe = dir.path().join("bench");
        let ok = Command::new("cc")
            .args(["-std=c99", "-O2", "-o"])
            .arg(&exe)
            .arg(dir.path().join("bench.c"))
            .arg("-lm")
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            println!("(cc not available or failed: no C throughput)");
            return;
        }
        let runs: Vec<Vec<f64>> = (0..5)
            .map(|_| {
                let out = Command::new(&exe).output().unwrap();
                String::from_utf8_lossy(&out.stdout)
                    .split_whitespace()
                    .take(3)
                    .map(|v| v.parse().unwrap())
                    .collect()
            })
            .collect();
        let col = |i: usize| median(runs.iter().map(|r| r[i]).collect());
        let rust = median((0..5).map(|_| rust_evals_per_second(model) / 1e6).collect());
        println!(
            "| {name} | {rust:.1} | {:.1} | {:.1} | {:.1} |",
            col(0),
            col(1),
            col(2)
        );
    }
}
