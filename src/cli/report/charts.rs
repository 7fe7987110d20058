//! The report's charts (plotters), each written as SVG and PNG.

use super::convergence::Convergence;
use super::markdown::median;
use super::rows::Row;
use crate::cli::{CliError, CliResult};
use crate::model::Model;
use npf_data_loaders::atomic::write_bytes_atomic;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

type R = Result<(), String>;

fn e<T: std::fmt::Debug>(x: T) -> String {
    format!("{x:?}")
}

/// Draw with the same function into an SVG and a PNG next to `stem`.
fn save_both(
    stem: &Path,
    size: (u32, u32),
    svg: impl Fn(DrawingArea<SVGBackend, Shift>) -> R,
    png: impl Fn(DrawingArea<BitMapBackend, Shift>) -> R,
) -> CliResult {
    let fail = |what: &str, m: String| CliError::Message(format!("{}.{what}: {m}", stem.display()));
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(|x| fail("svg", e(x)))?;
        svg(root.clone()).map_err(|m| fail("svg", m))?;
        root.present().map_err(|x| fail("svg", e(x)))?;
    }
    write_bytes_atomic(&stem.with_extension("svg"), true, text.as_bytes())?;
    let mut buf = vec![0u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(|x| fail("png", e(x)))?;
        png(root.clone()).map_err(|m| fail("png", m))?;
        root.present().map_err(|x| fail("png", e(x)))?;
    }
    let bytes = crate::cli::png::encode_png(size.0, size.1, &buf).map_err(|m| fail("png", m))?;
    write_bytes_atomic(&stem.with_extension("png"), true, &bytes)?;
    Ok(())
}

fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    C[i % C.len()]
}

fn draw_speed<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, rows: &[Row], names: &[&str]) -> R {
    let pts: Vec<(usize, f64, f64)> = rows
        .iter()
        .filter_map(|r| {
            let k = names.iter().position(|n| *n == r.config)?;
            let p = r.eval.as_ref()?.render_psnr_db;
            (p.is_finite() && r.seconds > 0.0 && r.seconds.is_finite()).then_some((k, r.seconds, p))
        })
        .collect();
    if pts.is_empty() {
        return Ok(());
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(_, x, y) in &pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Fit time vs rendering PSNR (one point per material; large: median)",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((x0 / 1.3..x1 * 1.3).log_scale(), (y0 - 2.0)..(y1 + 2.0))
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("fit seconds (one thread, log scale)")
        .y_desc("rendering PSNR (dB)")
        .draw()
        .map_err(e)?;
    for (k, name) in names.iter().enumerate() {
        let mine: Vec<(f64, f64)> = pts
            .iter()
            .filter(|p| p.0 == k)
            .map(|p| (p.1, p.2))
            .collect();
        if mine.is_empty() {
            continue;
        }
        let c = color(k);
        chart
            .draw_series(
                mine.iter()
                    .map(|&(x, y)| Circle::new((x, y), 3, c.mix(0.55).filled())),
            )
            .map_err(e)?
            .label(*name)
            .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
        let mut xs: Vec<f64> = mine.iter().map(|p| p.0).collect();
        let mut ys: Vec<f64> = mine.iter().map(|p| p.1).collect();
        let (mx, my) = (median(&mut xs), median(&mut ys));
        chart
            .draw_series([
                Circle::new((mx, my), 9, c.filled()),
                Circle::new((mx, my), 9, BLACK.stroke_width(2)),
            ])
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// The speed-vs-accuracy chart (`speed-accuracy.{svg,png}` in `out`): median fit seconds against median rendering PSNR per configuration.
pub fn speed_accuracy(out: &Path, rows: &[Row], names: &[&str]) -> CliResult {
    save_both(
        &out.join("speed-accuracy"),
        (960, 640),
        |r| draw_speed(r, rows, names),
        |r| draw_speed(r, rows, names),
    )
}

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    xlabel: &str,
    series: &[(String, Vec<(f64, f64)>)],
    log_y: bool,
) -> R {
    let mut pts = series
        .iter()
        .flat_map(|s| s.1.iter())
        .filter(|p| p.1.is_finite());
    let Some(&(fx, fy)) = pts.next() else {
        return Ok(());
    };
    let (mut x0, mut x1, mut y0, mut y1) = (fx, fx, fy, fy);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let mut b = ChartBuilder::on(area);
    b.caption(title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(32)
        .y_label_area_size(60);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(xlabel)
                .y_label_formatter(&|v| {
                    if log_y {
                        format!("{v:.1e}")
                    } else {
                        format!("{v:.3}")
                    }
                })
                .draw()
                .map_err(e)?;
            for (k, (name, s)) in series.iter().enumerate() {
                let c = color(k);
                let data: Vec<(f64, f64)> = s
                    .iter()
                    .copied()
                    .filter(|p| p.1.is_finite() && (!log_y || p.1 > 0.0))
                    .collect();
                chart
                    .draw_series(LineSeries::new(data.clone(), c.stroke_width(2)))
                    .map_err(e)?
                    .label(name.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                    });
                if data.len() < 20 {
                    chart
                        .draw_series(data.iter().map(|&p| Circle::new(p, 3, c.filled())))
                        .map_err(e)?;
                }
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(e)?;
        }};
    }
    if log_y {
        let lo = series
            .iter()
            .flat_map(|s| s.1.iter())
            .map(|p| p.1)
            .filter(|v| *v > 0.0 && v.is_finite())
            .fold(f64::MAX, f64::min);
        let lo = if lo == f64::MAX {
            1e-6
        } else {
            lo.max(y1 * 1e-8)
        };
        body!(b
            .build_cartesian_2d(x0..x1, (lo / 1.5..y1.max(lo) * 1.5).log_scale())
            .map_err(e)?);
    } else {
        let pad = ((y1 - y0) * 0.05).max(0.1);
        body!(b
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
            .map_err(e)?);
    }
    Ok(())
}

fn draw_factors<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, title: &str, m: &Model) -> R {
    let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let areas = root.split_evenly((1, 3));
    let l = &m.layout;
    let per_channel = m.lobes.len() == 3
        && m.lobes
            .iter()
            .enumerate()
            .all(|(k, lobe)| (0..3).all(|c| (c == k) || lobe.s[c] == 0.0));
    let name = |k: usize| {
        if per_channel {
            ["R", "G", "B"][k].to_string()
        } else {
            format!("lobe {k}")
        }
    };
    // One curve per table: (node angle in degrees, value).
    let curve = |axis: crate::grid::Axis, t: &[f32]| -> Vec<(f64, f64)> {
        t.iter()
            .enumerate()
            .map(|(i, &v)| (axis.node(i).to_degrees(), v as f64))
            .collect()
    };
    type Series = Vec<(String, Vec<(f64, f64)>)>;
    let d: Series = (m.lobes.iter().enumerate())
        .map(|(k, lobe)| (name(k), curve(l.d.theta, &lobe.d)))
        .collect();
    let f: Series = (m.fresnel.iter().enumerate())
        .map(|(c, t)| (["F_R", "F_G", "F_B"][c].to_string(), curve(l.f.theta, t)))
        .collect();
    let g: Series = (m.lobes.iter().enumerate())
        .map(|(k, lobe)| (name(k), curve(l.g.theta, &lobe.g)))
        .collect();
    panel(&areas[0], "D(theta_h) (log)", "theta_h (deg)", &d, true)?;
    panel(
        &areas[1],
        "F(theta_d) per channel",
        "theta_d (deg)",
        &f,
        false,
    )?;
    panel(
        &areas[2],
        "G(theta) control points",
        "theta (deg)",
        &g,
        false,
    )?;
    Ok(())
}

/// The factor plot of one model (`stem.{svg,png}`): D, F per channel and G per lobe.
pub fn factor_plot(stem: &Path, material: &str, config: &str, model: &Model) -> CliResult {
    let title = format!("{material}: {config} factors");
    save_both(
        stem,
        (1350, 420),
        |r| draw_factors(r, &title, model),
        |r| draw_factors(r, &title, model),
    )
}

fn draw_convergence<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    material: &str,
    runs: &[(String, Convergence)],
) -> R {
    let root = root
        .titled(&format!("Convergence on {material}"), ("sans-serif", 20))
        .map_err(e)?;
    let areas = root.split_evenly((2, 2));
    let rel = |c: &Convergence, v: f64| {
        if c.initial_objective > 0.0 {
            v / c.initial_objective
        } else {
            v
        }
    };
    let obj_sweeps: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(n, c)| {
            (
                n.clone(),
                c.history
                    .iter()
                    .map(|h| (h.0 as f64, rel(c, h.1)))
                    .collect(),
            )
        })
        .collect();
    let obj_secs: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(n, c)| {
            (
                n.clone(),
                c.history.iter().map(|h| (h.2, rel(c, h.1))).collect(),
            )
        })
        .collect();
    let psnr_sweeps: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(n, c)| {
            (
                n.clone(),
                c.checkpoints
                    .iter()
                    .map(|k| (k.sweeps as f64, k.render_psnr_db))
                    .collect(),
            )
        })
        .collect();
    let psnr_secs: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(n, c)| {
            (
                n.clone(),
                c.checkpoints
                    .iter()
                    .map(|k| (k.seconds, k.render_psnr_db))
                    .collect(),
            )
        })
        .collect();
    panel(
        &areas[0],
        "objective / initial vs sweeps",
        "sweeps",
        &obj_sweeps,
        true,
    )?;
    panel(
        &areas[1],
        "objective / initial vs seconds",
        "seconds",
        &obj_secs,
        true,
    )?;
    panel(
        &areas[2],
        "rendering PSNR (dB) vs sweeps",
        "sweeps",
        &psnr_sweeps,
        false,
    )?;
    panel(
        &areas[3],
        "rendering PSNR (dB) vs seconds",
        "seconds",
        &psnr_secs,
        false,
    )?;
    Ok(())
}

/// The convergence chart (`convergence.{svg,png}` in `out`): objective and rendering PSNR against sweeps and seconds.
pub fn convergence(out: &Path, material: &str, runs: &[(String, Convergence)]) -> CliResult {
    save_both(
        &out.join("convergence"),
        (1200, 860),
        |r| draw_convergence(r, material, runs),
        |r| draw_convergence(r, material, runs),
    )
}
