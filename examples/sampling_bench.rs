//! Benchmark of the importance sampler (docs/sampling_benchmark.md):
//! outgoing radiance at a few pixels of a sphere under a fixed analytic
//! environment, estimated with N samples by (a) the model's sampler
//! (`NpfBxdf::sample`) and (b) cosine-weighted hemisphere sampling; RMSE
//! against a converged reference, the variance ratio, and throughput.
//!
//! cargo run --release --example sampling_bench -- FITS_DIR OUT_MD OUT_SVG [MATERIAL ...]
//!
//! FITS_DIR holds `<material>.json` model files (fit them with `npf fit`);
//! fits are never committed. Single-threaded (samples/s are per core).

use npf::sampling::NpfBxdf;
use npf_data_loaders::atomic::write_bytes_atomic;
use plotters::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;
use std::path::PathBuf;
use std::time::Instant;

type Vec3 = [f64; 3];

const NS: [usize; 6] = [16, 64, 128, 256, 1024, 4096];
/// Independent estimates per N: at least 64, and at least 2^16 samples
/// per pixel in all (rare bright paths need many runs to show up).
const MIN_RUNS: usize = 64;
const MIN_SAMPLES: usize = 1 << 16;

fn runs(n: usize) -> usize {
    MIN_RUNS.max(MIN_SAMPLES / n)
}
const REFERENCE_SAMPLES: usize = 1 << 20;
/// Screen positions (orthographic camera looking down -z at a unit sphere).
const PIXELS: [[f64; 2]; 8] = [
    [0.0, 0.0],
    [0.3, 0.2],
    [-0.5, 0.1],
    [0.6, -0.4],
    [-0.2, -0.7],
    [0.8, 0.3],
    [0.9, -0.1],
    [-0.95, 0.2],
];

fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: Vec3) -> Vec3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The environment (world frame, y up): a sky gradient, a darker ground,
/// and three disk lights (angular radius 0.15-0.3 rad, 10-100x the sky)
/// with soft edges.
fn environment(w: Vec3) -> [f64; 3] {
    let mut l = if w[1] > 0.0 {
        let k = 0.3 + 0.7 * w[1];
        [0.35 * k, 0.45 * k, 0.7 * k]
    } else {
        [0.12, 0.1, 0.08]
    };
    let lights: [(Vec3, f64, [f64; 3]); 3] = [
        (normalize([0.5, 0.7, 0.5]), 0.15, [12.0, 11.0, 10.0]),
        (normalize([-0.6, 0.3, 0.75]), 0.25, [3.0, 4.5, 7.0]),
        (normalize([0.1, 0.2, -1.0]), 0.3, [6.0, 4.0, 2.5]),
    ];
    for (d, r, c) in lights {
        let ang = dot(w, d).clamp(-1.0, 1.0).acos();
        // Soft edge over the outer 20% of the radius.
        let x = ((r - ang) / (0.2 * r)).clamp(0.0, 1.0);
        let s = x * x * (3.0 - 2.0 * x);
        for ch in 0..3 {
            l[ch] += s * c[ch];
        }
    }
    l
}

/// Shading frame of a pixel: normal n, with wo the direction to the camera.
struct Pixel {
    t: Vec3,
    b: Vec3,
    n: Vec3,
    wo: Vec3,
}

impl Pixel {
    fn new(xy: [f64; 2]) -> Self {
        let n = [
            xy[0],
            xy[1],
            (1.0 - xy[0] * xy[0] - xy[1] * xy[1]).max(0.0).sqrt(),
        ];
        let helper = if n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let t = normalize(cross(helper, n));
        let b = cross(n, t);
        let v = [0.0, 0.0, 1.0];
        let wo = normalize([dot(v, t), dot(v, b), dot(v, n)]);
        Pixel { t, b, n, wo }
    }

    fn world(&self, w: Vec3) -> Vec3 {
        std::array::from_fn(|k| w[0] * self.t[k] + w[1] * self.b[k] + w[2] * self.n[k])
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Method {
    Ours,
    Cosine,
}

/// One N-sample estimate of the outgoing radiance.
fn estimate(b: &NpfBxdf, px: &Pixel, method: Method, n: usize, rng: &mut Pcg64) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for _ in 0..n {
        let (ul, u0, u1): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
        let (wi, w) = match method {
            Method::Ours => {
                let s = b.sample(px.wo, ul, [u0, u1]);
                if s.is_lost() {
                    continue;
                }
                (s.wi, s.weight)
            }
            Method::Cosine => {
                let r = u0.sqrt();
                let (sp, cp) = (2.0 * PI * u1).sin_cos();
                let wi = [r * cp, r * sp, (1.0 - u0).max(0.0).sqrt()];
                if wi[2] <= 0.0 {
                    continue;
                }
                // f cos / (cos / pi)
                (wi, b.eval(px.wo, wi).map(|f| f * PI))
            }
        };
        let l = environment(px.world(wi));
        for c in 0..3 {
            sum[c] += w[c] * l[c];
        }
    }
    sum.map(|s| s / n as f64)
}

struct MaterialResult {
    name: String,
    table_bytes: usize,
    /// Relative RMSE per N, per method.
    ours: Vec<f64>,
    cosine: Vec<f64>,
    /// Per-sample variance ratio cosine / ours (from RMSE^2 N averaged over N).
    ratio: f64,
    ref_rel_se: f64,
    ref_mean: f64,
    /// Variance ratio cosine / D of the luminance weight alone (a uniform
    /// white environment), summed over the pixels.
    furnace_ratio: f64,
}

/// Per-sample variance of the luminance weight f cos / pdf, both methods.
fn furnace(b: &NpfBxdf, px: &Pixel, rng: &mut Pcg64) -> (f64, f64) {
    let n = 1 << 16;
    let lum = |w: [f64; 3]| 0.2126 * w[0] + 0.7152 * w[1] + 0.0722 * w[2];
    let mut var = [0.0; 2];
    for (k, method) in [Method::Ours, Method::Cosine].into_iter().enumerate() {
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let (ul, u0, u1): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
            let w = match method {
                Method::Ours => lum(b.sample(px.wo, ul, [u0, u1]).weight),
                Method::Cosine => {
                    let r = u0.sqrt();
                    let (sp, cp) = (2.0 * PI * u1).sin_cos();
                    let wi = [r * cp, r * sp, (1.0 - u0).max(0.0).sqrt()];
                    lum(b.eval(px.wo, wi)) * PI
                }
            };
            s1 += w;
            s2 += w * w;
        }
        let m = s1 / n as f64;
        var[k] = s2 / n as f64 - m * m;
    }
    (var[0], var[1])
}

fn run_material(name: &str, b: &NpfBxdf, seed: u64) -> MaterialResult {
    let pixels: Vec<Pixel> = PIXELS.iter().map(|&p| Pixel::new(p)).collect();
    // Reference: the sampler with 2^20 samples (another seed), and its
    // standard error from 64 batches.
    let mut rng = Pcg64::seed_from_u64(seed ^ 0xdead_beef);
    let mut reference = Vec::new();
    let mut ref_var = 0.0;
    for px in &pixels {
        let batches = 64;
        let per = REFERENCE_SAMPLES / batches;
        let est: Vec<[f64; 3]> = (0..batches)
            .map(|_| estimate(b, px, Method::Ours, per, &mut rng))
            .collect();
        let mean: [f64; 3] =
            std::array::from_fn(|c| est.iter().map(|e| e[c]).sum::<f64>() / batches as f64);
        for c in 0..3 {
            let v =
                est.iter().map(|e| (e[c] - mean[c]).powi(2)).sum::<f64>() / (batches - 1) as f64;
            ref_var += v / batches as f64;
        }
        reference.push(mean);
    }
    let cells = (pixels.len() * 3) as f64;
    let ref_mean = reference.iter().flatten().sum::<f64>() / cells;
    let ref_rel_se = (ref_var / cells).sqrt() / ref_mean;
    let mut rmse = |method: Method| -> Vec<f64> {
        NS.iter()
            .map(|&n| {
                let mut se = 0.0;
                for (px, r) in pixels.iter().zip(&reference) {
                    for _ in 0..runs(n) {
                        let e = estimate(b, px, method, n, &mut rng);
                        se += (0..3).map(|c| (e[c] - r[c]).powi(2)).sum::<f64>();
                    }
                }
                (se / (cells * runs(n) as f64)).sqrt() / ref_mean
            })
            .collect()
    };
    let ours = rmse(Method::Ours);
    let cosine = rmse(Method::Cosine);
    let (mut f_ours, mut f_cos) = (0.0, 0.0);
    for px in &pixels {
        let (a, c) = furnace(b, px, &mut rng);
        f_ours += a;
        f_cos += c;
    }
    // Per-sample variance: RMSE^2 N, pooled over N with weights N (the
    // number of samples behind each RMSE).
    let total: f64 = NS.iter().map(|&n| n as f64).sum();
    let var = |v: &[f64]| {
        NS.iter()
            .zip(v)
            .map(|(&n, e)| e * e * (n * n) as f64)
            .sum::<f64>()
            / total
    };
    MaterialResult {
        name: name.to_string(),
        table_bytes: b.table_bytes(),
        ratio: var(&cosine) / var(&ours),
        ours,
        cosine,
        ref_rel_se,
        ref_mean,
        furnace_ratio: f_cos / f_ours,
    }
}

struct Throughput {
    sample: f64,
    pdf: f64,
    eval: f64,
    build_ms: f64,
}

fn throughput(b: &NpfBxdf) -> Throughput {
    let n = 2_000_000;
    let mut rng = Pcg64::seed_from_u64(1);
    let wos: Vec<Vec3> = (0..256)
        .map(|_| {
            let t: f64 = rng.gen::<f64>() * 1.4;
            [t.sin(), 0.0, t.cos()]
        })
        .collect();
    let us: Vec<[f64; 3]> = (0..4096)
        .map(|_| [rng.gen(), rng.gen(), rng.gen()])
        .collect();
    let t0 = Instant::now();
    let mut acc = 0.0;
    let mut wis = Vec::with_capacity(4096);
    for i in 0..n {
        let u = us[i % us.len()];
        let s = b.sample(wos[i % wos.len()], u[0], [u[1], u[2]]);
        acc += s.pdf;
        if wis.len() < 4096 && !s.is_lost() {
            wis.push(s.wi);
        }
    }
    let sample = n as f64 / t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    for i in 0..n {
        acc += b.pdf(wos[i % wos.len()], wis[i % wis.len()]);
    }
    let pdf = n as f64 / t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    for i in 0..n {
        acc += b.eval(wos[i % wos.len()], wis[i % wis.len()])[0];
    }
    let eval = n as f64 / t2.elapsed().as_secs_f64();
    std::hint::black_box(acc);
    let t3 = Instant::now();
    let reps = 20;
    for _ in 0..reps {
        std::hint::black_box(NpfBxdf::new(b.model().clone()).unwrap());
    }
    Throughput {
        sample,
        pdf,
        eval,
        build_ms: t3.elapsed().as_secs_f64() * 1e3 / reps as f64,
    }
}

/// plotters lays text out with a real font: DejaVu Sans from the system.
const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

fn plot(results: &[MaterialResult], path: &std::path::Path) -> Result<(), String> {
    let bytes =
        std::fs::read(FONT).map_err(|e| format!("{FONT}: {e} (install fonts-dejavu-core)"))?;
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        Box::leak(bytes.into_boxed_slice()),
    )
    .map_err(|_| format!("{FONT}: not a usable font"))?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 620)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (lo, hi) = results
            .iter()
            .flat_map(|r| r.ours.iter().chain(&r.cosine))
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Relative RMSE of outgoing radiance vs samples per pixel (solid: npf sampling, dashed: cosine)",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (12f64..5000f64).log_scale(),
                (lo * 0.7..hi * 1.4).log_scale(),
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("samples per pixel N")
            .y_desc("relative RMSE")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| e.to_string())?;
        let colors = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
        for (k, r) in results.iter().enumerate() {
            let c = colors[k % colors.len()];
            let ours: Vec<(f64, f64)> = NS
                .iter()
                .map(|&n| n as f64)
                .zip(r.ours.iter().copied())
                .collect();
            let cos: Vec<(f64, f64)> = NS
                .iter()
                .map(|&n| n as f64)
                .zip(r.cosine.iter().copied())
                .collect();
            chart
                .draw_series(LineSeries::new(ours.clone(), c.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(r.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                });
            chart
                .draw_series(ours.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(DashedLineSeries::new(cos.clone(), 6, 4, c.stroke_width(2)))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(cos.iter().map(|&p| TriangleMarker::new(p, 4, c.filled())))
                .map_err(|e| e.to_string())?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerLeft)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    write_bytes_atomic(path, true, svg.as_bytes()).map_err(|e| e.to_string())
}

fn main() {
    if let Err(e) = real_main() {
        eprintln!("sampling_bench: error: {e}");
        std::process::exit(1);
    }
}

/// View angles of the per-angle table (degrees).
const VIEW_ANGLES: [f64; 3] = [0.0, 40.0, 70.0];
/// Draws per method and view angle in the per-angle table.
const ANGLE_SAMPLES: usize = 1 << 18;

/// Per-sample variances (ours, cosine) at one pixel: of the RGB estimate
/// of the outgoing radiance under the environment (summed over channels),
/// and of the luminance weight alone (white furnace); and, under the
/// environment, the variance an ideal BSDF sampler would have, whose pdf is
/// exactly proportional to lum(f) cos theta_i (the best any sampler that
/// ignores the lighting can do for all three channels at once), estimated
/// from our own draws by importance reweighting:
/// E_ideal[(f_c cos L_c / p*)^2] = E_ours[(f_c cos L_c)^2 / (p* p_ours)]
/// with p* = lum(f) cos / A, A = E_ours[lum(f cos / p_ours)] (the albedo).
fn single_sample_variances(b: &NpfBxdf, px: &Pixel, rng: &mut Pcg64) -> ([f64; 2], [f64; 2], f64) {
    let lum = |w: [f64; 3]| 0.2126 * w[0] + 0.7152 * w[1] + 0.0722 * w[2];
    let (mut env, mut white) = ([0.0; 2], [0.0; 2]);
    let mut ideal = 0.0;
    for (k, method) in [Method::Ours, Method::Cosine].into_iter().enumerate() {
        let n = ANGLE_SAMPLES;
        let (mut s1, mut s2) = ([0.0; 3], [0.0; 3]);
        let (mut f1, mut f2) = (0.0, 0.0);
        // Sums of (f_c cos L_c)^2 / (lum(f) cos p_ours) for the ideal sampler.
        let mut q = [0.0; 3];
        for _ in 0..n {
            let (ul, u0, u1): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
            let (wi, w) = match method {
                Method::Ours => {
                    let s = b.sample(px.wo, ul, [u0, u1]);
                    let lf = lum(s.f);
                    if s.pdf > 0.0 && lf > 0.0 {
                        let l = environment(px.world(s.wi));
                        for c in 0..3 {
                            q[c] += (s.f[c] * l[c]).powi(2) * s.wi[2] / (lf * s.pdf);
                        }
                    }
                    (s.wi, s.weight)
                }
                Method::Cosine => {
                    let r = u0.sqrt();
                    let (sp, cp) = (2.0 * PI * u1).sin_cos();
                    let wi = [r * cp, r * sp, (1.0 - u0).max(0.0).sqrt()];
                    (wi, b.eval(px.wo, wi).map(|f| f * PI))
                }
            };
            let l = environment(px.world(wi));
            for c in 0..3 {
                let x = w[c] * l[c];
                s1[c] += x;
                s2[c] += x * x;
            }
            let y = lum(w);
            f1 += y;
            f2 += y * y;
        }
        let nf = n as f64;
        env[k] = (0..3).map(|c| s2[c] / nf - (s1[c] / nf).powi(2)).sum();
        white[k] = f2 / nf - (f1 / nf).powi(2);
        if method == Method::Ours {
            let albedo = f1 / nf;
            ideal = (0..3)
                .map(|c| albedo * q[c] / nf - (s1[c] / nf).powi(2))
                .sum();
        }
    }
    (env, white, ideal)
}

/// `--angles FITS_DIR OUT_MD [MATERIAL ...]`: the variance ratio cosine /
/// ours at view angles 0, 40 and 70 degrees (one pixel each of the sphere,
/// azimuth 0.7 rad on screen), under the environment and in a white
/// furnace; writes a Markdown table.
fn angles_main(args: &[String]) -> Result<(), String> {
    use std::fmt::Write;
    if args.len() < 2 {
        return Err("usage: sampling_bench --angles FITS_DIR OUT_MD [MATERIAL ...]".into());
    }
    let dir = PathBuf::from(&args[0]);
    let md_path = PathBuf::from(&args[1]);
    let materials: Vec<String> = if args.len() > 2 {
        args[2..].to_vec()
    } else {
        let mut v: Vec<String> = std::fs::read_dir(&dir)
            .map_err(|e| format!("{}: {e}", dir.display()))?
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let p = e.path();
                if p.extension()? != "json" {
                    return None;
                }
                Some(p.file_stem()?.to_string_lossy().into_owned())
            })
            .collect();
        v.sort();
        v
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Generated by `cargo run --release --example sampling_bench -- --angles {}` ({} draws per method and angle; single-sample variances).\n",
        args.join(" "),
        ANGLE_SAMPLES
    );
    let mut head = "| material |".to_string();
    let mut rule = "|---|".to_string();
    for t in VIEW_ANGLES {
        let _ = write!(
            head,
            " env {t:.0} deg | ideal env {t:.0} deg | white {t:.0} deg |"
        );
        rule.push_str("---:|---:|---:|");
    }
    let _ = writeln!(s, "{head} lobe albedo share at 0 deg |\n{rule}---:|");
    for (k, name) in materials.iter().enumerate() {
        let path = dir.join(format!("{name}.json"));
        let model = npf::modelfile::read(&path)
            .map_err(|e| e.to_string())?
            .model;
        let b = NpfBxdf::new(model).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut rng = Pcg64::seed_from_u64(7000 + k as u64);
        let _ = write!(s, "| {name} |");
        for t in VIEW_ANGLES {
            let st = t.to_radians().sin();
            let px = Pixel::new([st * 0.7f64.cos(), st * 0.7f64.sin()]);
            let (env, white, ideal) = single_sample_variances(&b, &px, &mut rng);
            let _ = write!(
                s,
                " {} | {} | {} |",
                ratio(env[1] / env[0]),
                ratio(env[1] / ideal),
                ratio(white[1] / white[0])
            );
        }
        let p = b.selection_probabilities([0.0, 0.0, 1.0]);
        let _ = writeln!(s, " {:.2} |", 1.0 - p[0]);
        eprint!("{name} ");
    }
    eprintln!();
    write_bytes_atomic(&md_path, true, s.as_bytes()).map_err(|e| e.to_string())?;
    println!("{s}");
    Ok(())
}

fn real_main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--angles") {
        return angles_main(&args[1..]);
    }
    if args.len() < 3 {
        return Err("usage: sampling_bench FITS_DIR OUT_MD OUT_SVG [MATERIAL ...]".into());
    }
    let dir = PathBuf::from(&args[0]);
    let (md_path, svg_path) = (PathBuf::from(&args[1]), PathBuf::from(&args[2]));
    let materials: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        [
            "chrome",
            "black-obsidian",
            "specular-blue-phenolic",
            "gold-metallic-paint",
        ]
        .map(String::from)
        .to_vec()
    };
    let mut results = Vec::new();
    let mut speeds = Vec::new();
    for (k, name) in materials.iter().enumerate() {
        let path = dir.join(format!("{name}.json"));
        let model = npf::modelfile::read(&path)
            .map_err(|e| e.to_string())?
            .model;
        let b = NpfBxdf::new(model).map_err(|e| format!("{}: {e}", path.display()))?;
        let t = Instant::now();
        let r = run_material(name, &b, 1000 + k as u64);
        let tp = throughput(&b);
        eprintln!(
            "{name}: ratio {:.1}, ours {:?}, cosine {:?} ({:.1} s); sample {:.2} M/s, pdf {:.2} M/s",
            r.ratio,
            r.ours,
            r.cosine,
            t.elapsed().as_secs_f64(),
            tp.sample / 1e6,
            tp.pdf / 1e6
        );
        results.push(r);
        speeds.push(tp);
    }
    plot(&results, &svg_path)?;
    let md = report(&results, &speeds, &args);
    // Replace the results between the markers of an existing document
    // (its prose stays), or write a document of the results alone.
    let (begin, end) = ("<!-- results:begin -->", "<!-- results:end -->");
    let doc = match std::fs::read_to_string(&md_path) {
        Ok(old) if old.contains(begin) && old.contains(end) => {
            let a = old.find(begin).unwrap() + begin.len();
            let b = old.find(end).unwrap();
            if b < a {
                return Err(format!(
                    "{}: results markers out of order",
                    md_path.display()
                ));
            }
            format!("{}\n{md}\n{}", &old[..a], &old[b..])
        }
        _ => format!("{begin}\n{md}\n{end}\n"),
    };
    write_bytes_atomic(&md_path, true, doc.as_bytes()).map_err(|e| e.to_string())?;
    println!("{md}");
    Ok(())
}

fn ratio(r: f64) -> String {
    if r < 100.0 {
        format!("{r:.1}")
    } else {
        format!("{r:.0}")
    }
}

fn report(results: &[MaterialResult], speeds: &[Throughput], args: &[String]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "## Measured results\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release --example sampling_bench -- {}` (single thread).\n",
        args.join(" ")
    );
    let _ = writeln!(
        s,
        "{} pixels, max(64, 2^16/N) independent runs per N and method; relative RMSE = RMS error over pixels, runs and RGB channels divided by the mean reference radiance. Reference: the npf sampler with 2^20 samples per pixel (another seed).\n",
        PIXELS.len()
    );
    let mut head = "| material | method |".to_string();
    let mut rule = "|---|---|".to_string();
    for n in NS {
        let _ = write!(head, " N={n} |");
        rule.push_str("---:|");
    }
    let _ = writeln!(s, "{head}\n{rule}");
    for r in results {
        for (label, v) in [("npf sampling", &r.ours), ("cosine", &r.cosine)] {
            let _ = write!(s, "| {} | {label} |", r.name);
            for e in v.iter() {
                let _ = write!(s, " {e:.3e} |");
            }
            let _ = writeln!(s);
        }
    }
    let _ = writeln!(
        s,
        "\n| material | variance ratio cosine/npf | same, BRDF weight only | cosine N matching npf at N=128 | npf RMSE at 128 | cosine RMSE at 4096 | target (npf@128 <= cosine@4096) | reference rel. s.e. | tables (bytes) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---|---:|---:|");
    let i128 = NS.iter().position(|&n| n == 128).unwrap();
    let i4096 = NS.iter().position(|&n| n == 4096).unwrap();
    for r in results {
        let met = r.ours[i128] <= r.cosine[i4096];
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.0} | {:.3e} | {:.3e} | {} | {:.1e} | {} |",
            r.name,
            ratio(r.ratio),
            ratio(r.furnace_ratio),
            128.0 * r.ratio,
            r.ours[i128],
            r.cosine[i4096],
            if met { "met" } else { "missed" },
            r.ref_rel_se,
            r.table_bytes
        );
        let _ = r.ref_mean;
    }
    let _ = writeln!(
        s,
        "\n| material | sample (M/s/core) | pdf (M/s/core) | eval (M/s/core) | table build (ms) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|");
    for (r, t) in results.iter().zip(speeds) {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} | {:.2} | {:.1} |",
            r.name,
            t.sample / 1e6,
            t.pdf / 1e6,
            t.eval / 1e6,
            t.build_ms
        );
    }
    s
}
