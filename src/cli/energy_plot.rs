//! The seed's three figures in one image: E(μ) for several α, E_avg(α) with
//! our fit and the seed's, and the white-furnace curves (single scattering,
//! compensation, sum).

use super::fonts::ensure_font;
use crate::energy::albedo::AlbedoTable;
use crate::energy::compensation::FurnacePoint;
use crate::energy::fit::{fit_avg, seed_fit};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::f64::consts::PI;

/// Image size in pixels.
pub const SIZE: (u32, u32) = (1500, 480);

/// Registers a TrueType font as plotters' "sans-serif" (plotters built with
/// ab_glyph has no font of its own). `explicit` wins over the usual places
/// (`fonts::ensure_font`).
pub fn register_font(explicit: Option<&std::path::Path>) -> Result<(), String> {
    let Some(p) = explicit else {
        return if ensure_font() {
            Ok(())
        } else {
            Err("no TrueType font found in the usual places; pass --font FILE.ttf".into())
        };
    };
    // A regular file of at most 64 MiB (a FIFO would block, a device never end).
    let bytes = npf_data_loaders::sniff::read_bounded(p, 64 << 20, "a TrueType font")
        .map_err(|e| e.to_string())?;
    // plotters keeps fonts for the whole run, so the bytes must live as long.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| format!("{}: not a usable TrueType font", p.display()))
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One panel: caption, alpha or mu on [0, 1] along x, the given y range.
fn panel<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: String,
    y_max: f64,
    x_desc: &str,
    y_desc: &str,
) -> Result<Chart<'a, DB>, String> {
    let mut c = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, 0.0..y_max)
        .map_err(err)?;
    c.configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .draw()
        .map_err(err)?;
    Ok(c)
}

/// A labelled 2-px curve.
fn curve<'a, DB: DrawingBackend + 'a>(
    c: &mut Chart<'a, DB>,
    label: String,
    color: RGBAColor,
    pts: impl IntoIterator<Item = (f64, f64)>,
) -> Result<(), String> {
    c.draw_series(LineSeries::new(pts, color.stroke_width(2)))
        .map_err(err)?
        .label(label)
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
    Ok(())
}

fn legend<'a, DB: DrawingBackend + 'a>(
    c: &mut Chart<'a, DB>,
    position: SeriesLabelPosition,
) -> Result<(), String> {
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(position)
        .draw()
        .map_err(err)
}

/// Points of `f` on 101 even steps over [0, 1].
fn sampled(f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    (0..=100)
        .map(|i| {
            let x = i as f64 / 100.0;
            (x, f(x))
        })
        .collect()
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

    let mut c = panel(
        &panels[0],
        format!("{name}: E(mu, alpha)"),
        1.05,
        "mu = cos theta",
        "E",
    )?;
    for (i, &alpha) in [0.1, 0.25, 0.5, 0.75, 1.0].iter().enumerate() {
        let pts = sampled(|mu| table.lookup(mu, alpha));
        curve(
            &mut c,
            format!("alpha {alpha}"),
            Palette99::pick(i).to_rgba(),
            pts,
        )?;
    }
    legend(&mut c, SeriesLabelPosition::LowerRight)?;

    let ours = fit_avg(table);
    let seed = seed_fit(table.model);
    let mut c = panel(
        &panels[1],
        format!("{name}: E_avg(alpha)"),
        3.3,
        "alpha",
        "E_avg (max pi)",
    )?;
    let table_pts: Vec<(f64, f64)> = (0..table.n_alpha)
        .map(|k| (table.alpha(k), table.e_avg[k]))
        .collect();
    curve(&mut c, "table".into(), BLACK.to_rgba(), table_pts)?;
    curve(
        &mut c,
        "our fit".into(),
        BLUE.to_rgba(),
        sampled(|a| ours.eval(a)),
    )?;
    curve(
        &mut c,
        "seed fit".into(),
        RED.to_rgba(),
        sampled(|a| seed.eval(a)),
    )?;
    legend(&mut c, SeriesLabelPosition::MiddleRight)?;

    let mut c = panel(
        &panels[2],
        format!("{name}: white furnace"),
        3.5,
        "alpha",
        "integral of f cos cos",
    )?;
    type Series = (&'static str, RGBColor, fn(&FurnacePoint) -> f64);
    let series: [Series; 3] = [
        ("single scattering", RGBColor(128, 128, 128), |p| p.single),
        ("compensation f_ms", BLUE, |p| p.compensation),
        ("sum (pi)", RED, FurnacePoint::sum),
    ];
    for (label, color, value) in series {
        let pts = furnace.iter().map(|p| (p.alpha, value(p)));
        curve(&mut c, label.into(), color.to_rgba(), pts)?;
    }
    c.draw_series(LineSeries::new(
        [(0.0, PI), (1.0, PI)],
        BLACK.mix(0.3).stroke_width(1),
    ))
    .map_err(err)?;
    legend(&mut c, SeriesLabelPosition::MiddleRight)?;
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
