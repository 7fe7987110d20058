//! `npf view MODEL [--reference TABLE] -o page.html`: one self-contained
//! HTML page to look at a fit (docs/view.md). No network, no server: the
//! model's exported GLSL evaluator renders a sphere in WebGL 2 (the scene
//! of [`crate::render`], a draggable key light, an exposure), and the page
//! draws the BRDF in the incidence plane and the factor tables from data
//! npf evaluates here. With a reference table the page shows npf's own
//! renders of the table and of the fit, their difference and the error
//! measures of `npf compare`.
//!
//! The page's pixels are npf's: `tests/view.rs` opens it in headless
//! Chromium and compares the WebGL sphere with [`crate::render`]'s.

use super::png::encode_png;
use super::{check_outputs, CliError, CliResult, FormatArg};
use crate::bsdf::{Bsdf, NpfBxdf};
use crate::evaluation::Reference;
use crate::model::{DiffuseForm, Model};
use crate::modelfile;
use crate::render::{
    difference_rgb8, psnr, render_scenes, EnvQuadrature, Image, RenderOptions, Scene,
};
use base64::Engine;
use clap::Args;
use npf_data_loaders::atomic::write_bytes_atomic;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// `npf view`'s arguments.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Model file (.json or .npfb).
    pub model: PathBuf,
    /// Measured table (MERL .binary or UTIA .bin) to show beside the fit:
    /// its render, the difference image and the error measures.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Read the reference as this format instead of detecting it.
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Output page (.html).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Print nothing on success.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The CPU renders' settings (those of `npf compare`).
pub const CPU_RENDER: RenderOptions = RenderOptions {
    res: 128,
    n_theta: 24,
    env: EnvQuadrature::Sphere,
};

/// Incidence angles of the plane plots (degrees).
pub const PLOT_THETA_I: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

/// Gain of the difference image (that of `npf compare --images`).
const DIFF_GAIN: f64 = super::compare::DIFF_GAIN;

/// The scenes the page offers: the first is [`Scene::standard`], the
/// others keep its lights or environment alone.
pub fn scenes() -> Vec<(&'static str, Scene)> {
    let standard = Scene::standard();
    let key = Scene {
        lights: standard.lights[..1].to_vec(),
        environment_gain: 0.0,
    };
    let lights = Scene {
        lights: standard.lights.clone(),
        environment_gain: 0.0,
    };
    let env = Scene {
        lights: Vec::new(),
        environment_gain: 1.0,
    };
    vec![
        ("environment and three lights", standard),
        ("key light", key),
        ("three lights", lights),
        ("environment", env),
    ]
}

/// Run `npf view`.
pub fn run(args: ViewArgs) -> CliResult {
    let ext = args.output.extension().and_then(|e| e.to_str());
    if !matches!(ext, Some(e) if e.eq_ignore_ascii_case("html") || e.eq_ignore_ascii_case("htm")) {
        return Err(CliError::Message(format!(
            "{}: the page must be an .html file",
            args.output.display()
        )));
    }
    let mut inputs: Vec<&Path> = vec![&args.model];
    if let Some(r) = &args.reference {
        inputs.push(r);
    }
    check_outputs(&[args.output.as_path()], &inputs, args.force)?;
    let file = modelfile::read(&args.model)?;
    let reference = match &args.reference {
        Some(path) => Some((path, super::read_measured(path, args.format)?)),
        None => None,
    };
    let model_err =
        |e: &dyn std::fmt::Display| CliError::Message(format!("{}: {e}", args.model.display()));
    let bsdf = NpfBxdf::new(file.model.clone()).map_err(|e| model_err(&e))?;
    let mut page = PageData::new(&args.model, &file, &bsdf)?;
    if let Some((path, (table, samples))) = &reference {
        let table_bsdf = super::table_bsdf(table);
        let r = Reference::new(table_bsdf, samples, CPU_RENDER);
        let (eval, _) = r
            .evaluate(file.fit.as_ref().map_or(85.0, |f| f.max_theta_deg), &bsdf)
            .map_err(|e| model_err(&e))?;
        // Every scene of the page's menu, table and fit (one environment
        // integral per pixel for all of them); the first is compare's.
        let list: Vec<Scene> = scenes().into_iter().map(|(_, s)| s).collect();
        let refs = render_scenes(CPU_RENDER, &list, table_bsdf);
        let fits = render_scenes(CPU_RENDER, &list, &bsdf);
        let per_scene = refs
            .iter()
            .zip(&fits)
            .map(|(a, b)| {
                Ok(json!({
                    "image": png_uri(a)?,
                    "fit_image": png_uri(b)?,
                    "difference": diff_uri(a, b)?,
                    "psnr_db": psnr(a, b).map_err(|e| model_err(&e))?,
                }))
            })
            .collect::<Result<Vec<Value>, CliError>>()?;
        page.reference = Some(json!({
            "name": path.display().to_string(),
            "scenes": per_scene,
            "difference_gain": DIFF_GAIN,
            "evaluation": eval,
        }));
        page.polar_reference = Some(plane_values(table_bsdf, &page.planes));
    }
    let html = page.html()?;
    write_bytes_atomic(&args.output, args.force, html.as_bytes())?;
    if !args.quiet {
        println!(
            "wrote {} ({:.1} KiB){}",
            args.output.display(),
            html.len() as f64 / 1024.0,
            if page.glsl.is_none() {
                " without the WebGL sphere (see the page)"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// What the page embeds.
struct PageData {
    title: String,
    summary: Vec<(String, String)>,
    fit_info: Option<Value>,
    glsl: Option<String>,
    glsl_missing: Option<String>,
    cpu_image: String,
    planes: Vec<f64>,
    polar: Value,
    polar_reference: Option<Value>,
    factors: Value,
    reference: Option<Value>,
}

impl PageData {
    fn new(path: &Path, file: &modelfile::ModelFile, bsdf: &NpfBxdf) -> Result<Self, CliError> {
        let model = &file.model;
        let (glsl, glsl_missing) =
            match crate::export::shader::glsl_eval_with(model, &Default::default()) {
                Ok(g) => (Some(g), None),
                Err(e) => (None, Some(e.to_string())),
            };
        let iso = model.layout.is_isotropic();
        let planes = if iso { vec![0.0] } else { vec![0.0, 90.0] };
        let cpu = crate::render::render(CPU_RENDER, bsdf);
        Ok(PageData {
            title: path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into(),
            ),
            summary: summary(model),
            fit_info: file.fit.as_ref().map(|f| json!(f)),
            glsl,
            glsl_missing,
            cpu_image: png_uri(&cpu)?,
            polar: plane_values(bsdf, &planes),
            planes,
            polar_reference: None,
            factors: factors(model),
            reference: None,
        })
    }

    fn html(&self) -> Result<String, CliError> {
        let scenes: Vec<Value> = scenes()
            .into_iter()
            .map(|(name, s)| {
                json!({
                    "name": name,
                    "lights": s.lights.iter().map(|(w, e)| json!({"dir": w, "e": e})).collect::<Vec<_>>(),
                    "environment": s.environment_gain,
                })
            })
            .collect();
        let data = json!({
            "title": self.title,
            "npf_version": env!("CARGO_PKG_VERSION"),
            "summary": self.summary,
            "fit": self.fit_info,
            "glsl": self.glsl,
            "glsl_missing": self.glsl_missing,
            "cpu": {"image": self.cpu_image, "res": CPU_RENDER.res, "n_theta": CPU_RENDER.n_theta},
            "scenes": scenes,
            "plane": {"theta_i": PLOT_THETA_I, "theta_o": plot_theta_o(), "phi": self.planes, "fit": self.polar, "reference": self.polar_reference},
            "factors": self.factors,
            "reference": self.reference,
        });
        // `</` never appears inside the script: a string holding it cannot
        // end the element early.
        let text = serde_json::to_string(&data)
            .map_err(|e| CliError::Message(e.to_string()))?
            .replace("</", "<\\/");
        Ok(fill(
            TEMPLATE,
            &[
                ("{{TITLE}}", &html_escape(&self.title)),
                ("{{SCRIPT}}", SCRIPT),
                ("{{DATA}}", &text),
            ],
        ))
    }
}

/// The template with each marker replaced, in one pass over the template
/// only (a value that holds a marker stays as it is).
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let mut out =
        String::with_capacity(template.len() + values.iter().map(|v| v.1.len()).sum::<usize>());
    let mut rest = template;
    while let Some((at, (marker, value))) = values
        .iter()
        .filter_map(|v| rest.find(v.0).map(|at| (at, *v)))
        .min_by_key(|(at, _)| *at)
    {
        out.push_str(&rest[..at]);
        out.push_str(value);
        rest = &rest[at + marker.len()..];
    }
    out.push_str(rest);
    out
}

const TEMPLATE: &str = include_str!("view/page.html");
const SCRIPT: &str = include_str!("view/page.js");

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn png_uri(image: &Image) -> Result<String, CliError> {
    rgb_uri(image.res, &image.to_rgb8())
}

fn diff_uri(a: &Image, b: &Image) -> Result<String, CliError> {
    rgb_uri(a.res, &difference_rgb8(a, b, DIFF_GAIN))
}

fn rgb_uri(res: usize, rgb: &[u8]) -> Result<String, CliError> {
    let png = encode_png(res as u32, res as u32, rgb).map_err(CliError::Message)?;
    Ok(format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(png)
    ))
}

/// The model's description: layout, lobes, parameters, forms.
fn summary(model: &Model) -> Vec<(String, String)> {
    let l = &model.layout;
    let mut rows = vec![
        (
            "layout".to_string(),
            format!(
                "{} (D {:?}, F {:?}, G {:?})",
                if l.is_isotropic() {
                    "isotropic"
                } else {
                    "anisotropic"
                },
                l.d,
                l.f,
                l.g
            ),
        ),
        ("lobes".into(), model.lobe_count().to_string()),
        ("parameters".into(), model.param_count().to_string()),
        ("diffuse form".into(), model.diffuse_form.name().to_string()),
        ("masking".into(), model.masking.name().to_string()),
        (
            "energy compensation".into(),
            if model.compensation.is_some() {
                "Kulla-Conty".into()
            } else {
                "none".into()
            },
        ),
        (
            "diffuse d (1/sr)".into(),
            format!(
                "{:.4} {:.4} {:.4}",
                model.diffuse[0], model.diffuse[1], model.diffuse[2]
            ),
        ),
    ];
    for (m, lobe) in model.lobes.iter().enumerate() {
        rows.push((
            format!("lobe {} scale s", m + 1),
            format!("{:.4e} {:.4e} {:.4e}", lobe.s[0], lobe.s[1], lobe.s[2]),
        ));
    }
    rows
}

/// theta_o of the plane plots (degrees): every half degree from -89.5 to
/// 89.5 (negative: the side opposite the light, where the mirror
/// direction is).
fn plot_theta_o() -> Vec<f64> {
    (-179..=179).map(|k| 0.5 * k as f64).collect()
}

/// f(wo, wi) (RGB, 1/sr, as f32) in each plane of azimuth `planes`
/// (degrees) for every [`PLOT_THETA_I`] and [`plot_theta_o`].
fn plane_values(bsdf: &(dyn Bsdf + Sync), planes: &[f64]) -> Value {
    let dir = |theta: f64, phi: f64| {
        let (t, p) = (theta.to_radians(), phi.to_radians());
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    };
    let per_plane: Vec<Value> = planes
        .iter()
        .map(|&phi| {
            let per_theta: Vec<Value> = PLOT_THETA_I
                .iter()
                .map(|&ti| {
                    let wi = dir(ti, phi);
                    let v: Vec<[f32; 3]> = plot_theta_o()
                        .into_iter()
                        .map(|to| bsdf.eval(dir(to, phi), wi))
                        .map(|v| v.map(|x| if x.is_finite() { x as f32 } else { 0.0 }))
                        .collect();
                    json!(v)
                })
                .collect();
            json!(per_theta)
        })
        .collect();
    json!(per_plane)
}

/// The factor tables as curves (their interpolation, as `Model::eval`
/// reads it) and nodes, in degrees.
fn factors(model: &Model) -> Value {
    let l = &model.layout;
    let phis: Vec<f64> = if l.is_isotropic() {
        vec![0.0]
    } else {
        vec![0.0, 45.0, 90.0, 135.0]
    };
    // D's peak sits in the first degrees: sample it as its sqrt axis does.
    let d_x: Vec<f64> = (0..=240)
        .map(|k| 90.0 * (k as f64 / 240.0).powi(2))
        .collect();
    let lin_x: Vec<f64> = (0..=180).map(|k| k as f64 * 0.5).collect();
    let curve = |grid: &crate::grid::Grid, values: &[f32], xs: &[f64], phi: f64| -> Vec<f64> {
        let v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
        xs.iter()
            .map(|&x| grid.eval(&v, x.to_radians(), phi.to_radians()))
            .collect()
    };
    let nodes = |grid: &crate::grid::Grid| -> Vec<f64> {
        (0..grid.n_theta())
            .map(|k| grid.node(k * grid.n_phi()).0.to_degrees())
            .collect()
    };
    let lobes = |grid: &crate::grid::Grid, xs: &[f64], tables: Vec<&[f32]>| {
        tables
            .iter()
            .map(|t| {
                phis.iter()
                    .map(|&p| curve(grid, t, xs, p))
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    let d_tables = model.lobes.iter().map(|lb| lb.d.as_slice()).collect();
    let g_tables = model.lobes.iter().map(|lb| lb.g.as_slice()).collect();
    let f: Vec<Vec<f64>> = (0..3)
        .map(|c| curve(&l.f, &model.fresnel[c], &lin_x, 0.0))
        .collect();
    let p = match &model.diffuse_form {
        DiffuseForm::Separable { p } => {
            let n = p.len().max(2) - 1;
            Some(json!({
                "x": (0..p.len()).map(|k| 90.0 * k as f64 / n as f64).collect::<Vec<_>>(),
                "p": p,
            }))
        }
        _ => None,
    };
    json!({
        "phi": phis,
        "d": {"x": d_x, "lobes": lobes(&l.d, &d_x, d_tables), "nodes": nodes(&l.d)},
        "g": {"x": lin_x, "lobes": lobes(&l.g, &lin_x, g_tables), "nodes": nodes(&l.g)},
        "f": {"x": lin_x, "channels": f, "nodes": nodes(&l.f)},
        "p": p,
        "diffuse": model.diffuse,
        "s": model.lobes.iter().map(|lb| lb.s).collect::<Vec<_>>(),
    })
}
