//! The chart of fit time against rendering PSNR (docs/fit_time_psnr.svg),
//! from a CSV of measured points, so that it is regenerated, not drawn:
//!
//!     cargo run --release --example fit_time_chart -- docs/fit_time_psnr.csv docs/fit_time_psnr.svg [--force]
//!
//! CSV header `material,series,seconds,psnr_db` (any further columns are
//! ignored; `#` lines are comments): one point per material and series.
//! Series are drawn in the order they first appear, each in its own
//! colour; a material's points are joined in that order (before -> after).
//! A first comment line `# title: ...` sets the chart's title.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

const COLOURS: [&str; 6] = [
    "#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
];

struct Point {
    series: usize,
    seconds: f64,
    psnr: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let force = args.iter().any(|a| a == "--force");
    let paths: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    if paths.len() != 2 {
        eprintln!("usage: fit_time_chart POINTS.csv OUT.svg [--force]");
        std::process::exit(2);
    }
    if let Err(e) = run(Path::new(paths[0]), Path::new(paths[1]), force) {
        eprintln!("fit_time_chart: {e}");
        std::process::exit(1);
    }
}

fn run(input: &Path, out: &Path, force: bool) -> Result<(), String> {
    let text = std::fs::read_to_string(input).map_err(|e| format!("{}: {e}", input.display()))?;
    let mut title = "Fit time against rendering PSNR".to_string();
    let mut series: Vec<String> = Vec::new();
    let mut points: BTreeMap<String, Vec<Point>> = BTreeMap::new();
    let mut header = true;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if let Some(t) = line.strip_prefix("# title:") {
            title = t.trim().to_string();
            continue;
        }
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if std::mem::take(&mut header) {
            if !line.starts_with("material,series,seconds,psnr_db") {
                return Err(format!(
                    "{}: the header must start with material,series,seconds,psnr_db",
                    input.display()
                ));
            }
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let bad = |what: &str| format!("{} line {}: {what}", input.display(), i + 1);
        if f.len() < 4 {
            return Err(bad("fewer than 4 fields"));
        }
        let seconds: f64 = f[2].parse().map_err(|_| bad("seconds is not a number"))?;
        let psnr: f64 = f[3].parse().map_err(|_| bad("psnr_db is not a number"))?;
        if !(seconds.is_finite() && psnr.is_finite() && seconds >= 0.0) {
            return Err(bad("seconds or psnr_db out of range"));
        }
        let s = match series.iter().position(|x| x == f[1]) {
            Some(s) => s,
            None => {
                series.push(f[1].to_string());
                series.len() - 1
            }
        };
        points.entry(f[0].to_string()).or_default().push(Point {
            series: s,
            seconds,
            psnr,
        });
    }
    if points.is_empty() {
        return Err(format!("{}: no points", input.display()));
    }
    let svg = chart(&title, &series, &points);
    npf::loaders::atomic::write_bytes_atomic(out, force, svg.as_bytes()).map_err(|e| e.to_string())
}

/// A "nice" tick step near span/6.
fn tick(span: f64) -> f64 {
    let raw = span / 6.0;
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * p)
}

fn chart(title: &str, series: &[String], points: &BTreeMap<String, Vec<Point>>) -> String {
    let (w, h, l, r, t, b) = (900.0, 560.0, 70.0, 700.0, 40.0, 500.0);
    let all = points.values().flatten();
    let xmax = all.clone().map(|p| p.seconds).fold(0.0, f64::max) * 1.05;
    let (ymin, ymax) = all
        .map(|p| p.psnr)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let (ymin, ymax) = ((ymin - 1.0).floor(), (ymax + 1.0).ceil());
    let x = |v: f64| l + (r - l) * v / xmax;
    let y = |v: f64| b - (b - t) * (v - ymin) / (ymax - ymin);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" font-size="15">{}</text>"#,
        l,
        esc(title)
    );
    let step = tick(xmax);
    let round = |v: f64| (v * 1e6).round() / 1e6;
    let mut v = 0.0;
    while v <= xmax {
        let v_label = round(v);
        let _ = writeln!(
            s,
            r##"<line x1="{0:.1}" y1="{t}" x2="{0:.1}" y2="{b}" stroke="#ddd"/><text x="{1:.1}" y="516">{v_label}</text>"##,
            x(v),
            x(v) - 6.0
        );
        v += step;
    }
    let step = tick(ymax - ymin);
    let mut v = (ymin / step).ceil() * step;
    while v <= ymax {
        let v_label = round(v);
        let _ = writeln!(
            s,
            r##"<line x1="{l}" y1="{0:.1}" x2="{r}" y2="{0:.1}" stroke="#ddd"/><text x="40" y="{1:.1}">{v_label}</text>"##,
            y(v),
            y(v) + 4.0
        );
        v += step;
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="545">fit time (s)</text><text x="14" y="{}" transform="rotate(-90 14 {})">rendering PSNR (dB)</text>"#,
        (l + r) / 2.0 - 30.0,
        (t + b) / 2.0 + 40.0,
        (t + b) / 2.0 + 40.0
    );
    for (name, pts) in points {
        let path: Vec<String> = pts
            .iter()
            .map(|p| format!("{:.1},{:.1}", x(p.seconds), y(p.psnr)))
            .collect();
        if pts.len() > 1 {
            let _ = writeln!(
                s,
                r##"<polyline points="{}" fill="none" stroke="#999"/>"##,
                path.join(" ")
            );
        }
        for p in pts {
            let _ = writeln!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{}"/>"#,
                x(p.seconds),
                y(p.psnr),
                COLOURS[p.series % COLOURS.len()]
            );
        }
        if let Some(p) = pts.last() {
            let _ = writeln!(
                s,
                r#"<text x="{:.1}" y="{:.1}" font-size="10">{}</text>"#,
                x(p.seconds) + 6.0,
                y(p.psnr) + 3.0,
                esc(name)
            );
        }
    }
    for (i, name) in series.iter().enumerate() {
        let yy = t + 20.0 * i as f64;
        let _ = writeln!(
            s,
            r#"<circle cx="{}" cy="{yy}" r="5" fill="{}"/><text x="{}" y="{}">{}</text>"#,
            r + 20.0,
            COLOURS[i % COLOURS.len()],
            r + 32.0,
            yy + 4.0,
            esc(name)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn esc(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
