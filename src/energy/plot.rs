//! The seed's three figures in one image: E(μ) for several α, E_avg(α) with
//! our fit and the seed's, and the white-furnace curves (single scattering,
//! compensation, sum).

use super::albedo::AlbedoTable;
use super::compensation::FurnacePoint;
use super::fit::{fit_avg, seed_fit};
use crate::charts::FONT_CANDIDATES;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::f64::consts::PI;

/// Image size in pixels.
pub const SIZE: (u32, u32) = (1500, 480);

/// Registers a TrueType font as plotters' "sans-serif" (plotters built with
/// ab_glyph has no font of its own). `explicit` wins over the usual places.
pub fn register_font(explicit: Option<&std::path::Path>) -> Result<(), String> {
    let bytes = match explicit {
        Some(p) => std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?,
        None => FONT_CANDIDATES
            .iter()
            .find_map(|p| std::fs::read(p).ok())
            .ok_or("no TrueType font found in the usual places; pass --font FILE.ttf")?,
    };
    // plotters keeps fonts for the whole run, so the bytes must live as long.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| "the font file is not a usable TrueType font".to_string())
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Draws the three panels on `root`.
pub fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    table: &AlbedoTable,
    furnace: &[FurnacePoint],
) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let panels = root.split_evenly((1, 3));
    let name = table.model.name();

    let mut c = ChartBuilder::on(&panels[0])
        .caption(format!("{name}: E(mu, alpha)"), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, 0.0..1.05)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("mu = cos theta")
        .y_desc("E")
        .draw()
        .map_err(err)?;
    for (i, &alpha) in [0.1, 0.25, 0.5, 0.75, 1.0].iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let pts = (0..=100).map(|j| {
            let mu = j as f64 / 100.0;
            (mu, table.lookup(mu, alpha))
        });
        c.draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(err)?
            .label(format!("alpha {alpha}"))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(err)?;

    let ours = fit_avg(table);
    let seed = seed_fit(table.model);
    let mut c = ChartBuilder::on(&panels[1])
        .caption(format!("{name}: E_avg(alpha)"), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, 0.0..3.3)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("alpha")
        .y_desc("E_avg (max pi)")
        .draw()
        .map_err(err)?;
    let table_pts: Vec<(f64, f64)> = (0..table.n_alpha)
        .map(|k| (table.alpha(k), table.e_avg[k]))
        .collect();
    let curves: [(&str, RGBColor, Vec<(f64, f64)>); 3] = [
        ("table", BLACK, table_pts),
        (
            "our fit",
            BLUE,
            (0..=100)
                .map(|i| (i as f64 / 100.0, ours.eval(i as f64 / 100.0)))
                .collect(),
        ),
        (
            "seed fit",
            RED,
            (0..=100)
                .map(|i| (i as f64 / 100.0, seed.eval(i as f64 / 100.0)))
                .collect(),
        ),
    ];
    for (label, color, pts) in curves {
        c.draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;

    let mut c = ChartBuilder::on(&panels[2])
        .caption(format!("{name}: white furnace"), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, 0.0..3.5)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc("alpha")
        .y_desc("integral of f cos cos")
        .draw()
        .map_err(err)?;
    let grey = RGBColor(128, 128, 128);
    let series: [(&str, RGBColor, fn(&FurnacePoint) -> f64); 3] = [
        ("single scattering", grey, |p| p.single),
        ("compensation f_ms", BLUE, |p| p.compensation),
        ("sum (pi)", RED, FurnacePoint::sum),
    ];
    for (label, color, value) in series {
        let pts = furnace.iter().map(|p| (p.alpha, value(p)));
        c.draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    }
    c.draw_series(LineSeries::new(
        [(0.0, PI), (1.0, PI)],
        BLACK.mix(0.3).stroke_width(1),
    ))
    .map_err(err)?;
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::MiddleRight)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// The figure as SVG text.
pub fn svg(table: &AlbedoTable, furnace: &[FurnacePoint]) -> Result<Vec<u8>, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        draw(&root, table, furnace)?;
    }
    Ok(out.into_bytes())
}

/// The figure as a PNG file at `path` (plotters encodes PNGs only to files).
pub fn png(
    path: &std::path::Path,
    table: &AlbedoTable,
    furnace: &[FurnacePoint],
) -> Result<(), String> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    draw(&root, table, furnace)
}
