//! `npf view`: the page opens in headless Chromium without a JavaScript or
//! WebGL error, and the sphere its WebGL code renders (the exported GLSL
//! evaluator, summed one direction a pass) matches npf's own CPU render of
//! the same view (`npf::render::render_scene`), on isotropic, separable
//! and anisotropic models, with and without a reference table.
//!
//! Chromium is Debian's `chromium` (tests/run-all.sh installs it); without
//! it the tests skip loudly, or fail when NPF_REQUIRE_TOOLS is set.

use npf::bsdf::NpfBxdf;
use npf::model::{DiffuseForm, Layout, Model};
use npf::modelfile::{self, ModelFile};
use npf::render::{render_scene, EnvQuadrature, RenderOptions};
use npf::synth::known_factor_model;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The browser: $NPF_CHROMIUM, else `chromium` on the PATH.
fn chromium() -> Option<PathBuf> {
    let exe =
        std::env::var_os("NPF_CHROMIUM").map_or_else(|| PathBuf::from("chromium"), PathBuf::from);
    let ok = Command::new(&exe)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(exe);
    }
    if std::env::var_os("NPF_REQUIRE_TOOLS").is_some() {
        panic!("`chromium` is missing and NPF_REQUIRE_TOOLS is set");
    }
    eprintln!("\n*** SKIPPING the npf view tests: `chromium` not found (Debian: chromium) ***\n");
    None
}

/// Runs headless Chromium on `url` with `args`, killed after a minute.
fn run_chromium(exe: &Path, profile: &Path, args: &[String], url: &str) -> Output {
    // The flags a sandboxed, offline machine needs (no GPU: SwiftShader's
    // software WebGL; no network; a fresh profile).
    let mut cmd = Command::new(exe);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
    ])
    .arg(format!("--user-data-dir={}", profile.display()))
    .args(args)
    .arg(url)
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    let child = cmd.spawn().expect("chromium starts");
    let id = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(Duration::from_secs(60)) {
        Ok(out) => out.expect("chromium's output"),
        Err(_) => {
            let _ = Command::new("kill").arg("-9").arg(id.to_string()).status();
            panic!("chromium did not finish {url} within 60 s");
        }
    }
}

fn npf(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_npf"))
        .args(args)
        .output()
        .expect("npf runs");
    assert!(
        out.status.success(),
        "npf {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn file_url(path: &Path) -> String {
    format!("file://{}", path.canonicalize().unwrap().display())
}

/// The page's DOM after its load: `data-status` must be "ok" and the error
/// log empty.
fn check_dom(exe: &Path, profile: &Path, url: &str) {
    let out = run_chromium(exe, profile, &["--dump-dom".into()], url);
    let dom = String::from_utf8_lossy(&out.stdout);
    assert!(
        dom.contains("data-status=\"ok\""),
        "{url}: the page did not report ok: {}",
        dom.split("<pre id=\"log\">")
            .nth(1)
            .unwrap_or(&dom[..dom.len().min(400)])
            .chars()
            .take(600)
            .collect::<String>()
    );
    assert!(
        dom.contains("<pre id=\"log\"></pre>"),
        "{url}: the page logged errors"
    );
}

/// Decodes a screenshot (8-bit RGB or RGBA PNG) into rows of RGB.
fn decode_png(path: &Path) -> (usize, usize, Vec<[u8; 3]>) {
    let dec = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let ch = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("unexpected screenshot colour type {other:?}"),
    };
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    let (w, h) = (info.width as usize, info.height as usize);
    let px = (0..w * h)
        .map(|k| {
            let o = (k / w) * info.line_size + (k % w) * ch;
            [buf[o], buf[o + 1], buf[o + 2]]
        })
        .collect();
    (w, h, px)
}

/// How the WebGL sphere differs from the CPU render, in 8-bit levels.
#[derive(Debug)]
struct Difference {
    pixels: usize,
    mean: f64,
    max: u8,
    over_2: usize,
}

/// Screenshot of the page's sphere (`#shot`) against npf's CPU render of
/// the same scene, resolution and environment strata. Pixels within 1e-3
/// of the rim (r^2 in float and double may fall on either side) are left
/// out; everything else is compared, background included.
fn compare_sphere(exe: &Path, dir: &Path, page: &Path, model: &Model, scene: usize) -> Difference {
    let (res, nt) = (96usize, 6usize);
    let url = format!("{}#shot&res={res}&nt={nt}&scene={scene}", file_url(page));
    let profile = tempfile::tempdir().unwrap();
    check_dom(exe, profile.path(), &url);
    let shot = dir.join(format!("shot-{scene}.png"));
    let t = Instant::now();
    run_chromium(
        exe,
        profile.path(),
        &[
            // larger than the canvas: the headless window's viewport is
            // smaller than its size
            format!("--window-size={},{}", res + 200, res + 200),
            format!("--screenshot={}", shot.display()),
        ],
        &url,
    );
    eprintln!(
        "screenshot of scene {scene} in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let (w, h, px) = decode_png(&shot);
    assert!(
        w >= res && h >= res,
        "screenshot {w}x{h} smaller than the sphere"
    );
    let scenes = npf::cli::view::scenes();
    let opts = RenderOptions {
        res,
        n_theta: nt,
        env: EnvQuadrature::Sphere,
    };
    let cpu = render_scene(
        opts,
        &scenes[scene].1,
        &NpfBxdf::new(model.clone()).unwrap(),
    )
    .to_rgb8();
    let mut d = Difference {
        pixels: 0,
        mean: 0.0,
        max: 0,
        over_2: 0,
    };
    for j in 0..res {
        for i in 0..res {
            let x = 2.0 * (i as f64 + 0.5) / res as f64 - 1.0;
            let y = 1.0 - 2.0 * (j as f64 + 0.5) / res as f64;
            if ((x * x + y * y) - 1.0).abs() < 1e-3 {
                continue;
            }
            let gpu = px[j * w + i];
            for c in 0..3 {
                let e = gpu[c].abs_diff(cpu[3 * (j * res + i) + c]);
                d.mean += f64::from(e);
                d.max = d.max.max(e);
                d.over_2 += usize::from(e > 2);
                d.pixels += 1;
            }
        }
    }
    d.mean /= d.pixels as f64;
    d
}

fn write_model(dir: &Path, name: &str, model: Model) -> PathBuf {
    let path = dir.join(name);
    modelfile::write(&path, &ModelFile { model, fit: None }, false).unwrap();
    path
}

/// The stated tolerance, in 8-bit display levels: a mean under 0.1 and no
/// value more than 2 off (GLSL computes in float, npf in double; measured:
/// means 0.002-0.003, no value more than 1 off).
fn assert_close(what: &str, d: &Difference) {
    eprintln!("{what}: {d:?}");
    assert!(d.mean < 0.1, "{what}: mean difference {:.3} levels", d.mean);
    assert_eq!(
        d.over_2, 0,
        "{what}: {} of {} values more than 2 levels off",
        d.over_2, d.pixels
    );
    assert!(d.max <= 2, "{what}: a value {} levels off", d.max);
}

#[test]
fn isotropic_sphere_matches_the_cpu_render() {
    let Some(exe) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let model = known_factor_model(Layout::default(), &[0.1, 0.35]);
    let path = write_model(dir.path(), "iso.json", model.clone());
    let page = dir.path().join("iso.html");
    npf(&["view", path.to_str().unwrap(), "-o", page.to_str().unwrap()]);
    // the whole page, as a user opens it
    check_dom(&exe, tempfile::tempdir().unwrap().path(), &file_url(&page));
    for scene in [0, 1] {
        let d = compare_sphere(&exe, dir.path(), &page, &model, scene);
        assert_close(&format!("isotropic, scene {scene}"), &d);
    }
}

#[test]
fn separable_and_anisotropic_spheres_match_the_cpu_render() {
    let Some(exe) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut sep = known_factor_model(Layout::default(), &[0.2]);
    sep.diffuse = [0.12, 0.08, 0.05];
    sep.diffuse_form = DiffuseForm::Separable {
        p: npf::synth::ashikhmin_shirley_p(16),
    };
    sep.validate().unwrap();
    let aniso = npf::synth_aniso::known_model();
    for (name, model) in [("separable", sep), ("anisotropic", aniso)] {
        let path = write_model(dir.path(), &format!("{name}.npfb"), model.clone());
        let page = dir.path().join(format!("{name}.html"));
        npf(&["view", path.to_str().unwrap(), "-o", page.to_str().unwrap()]);
        let d = compare_sphere(&exe, dir.path(), &page, &model, 0);
        assert_close(name, &d);
    }
}

#[test]
fn a_reference_table_is_shown_beside_the_fit() {
    let Some(exe) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    // A MERL table of an analytic BRDF, and the model it was made from.
    let model = known_factor_model(Layout::default(), &[0.15, 0.4]);
    let table = dir.path().join("ref.binary");
    let path = write_model(dir.path(), "m.json", model);
    npf(&[
        "reconstruct",
        path.to_str().unwrap(),
        "-o",
        table.to_str().unwrap(),
    ]);
    let page = dir.path().join("ref.html");
    npf(&[
        "view",
        path.to_str().unwrap(),
        "--reference",
        table.to_str().unwrap(),
        "-o",
        page.to_str().unwrap(),
    ]);
    let html = std::fs::read_to_string(&page).unwrap();
    // three images (reference, fit, difference) and the measures
    assert!(
        html.matches("data:image/png;base64,").count() >= 4,
        "the renders are embedded"
    );
    // the page's data: every scene of the menu rendered for table and fit,
    // close (the table is the model's own reconstruction; MERL's reader
    // holds each bin's value, so not identical)
    let data = html
        .split("<script id=\"npf-data\" type=\"application/json\">")
        .nth(1)
        .and_then(|t| t.split("</script>").next())
        .expect("the page's data block");
    let data: serde_json::Value = serde_json::from_str(&data.replace("<\\/", "</")).unwrap();
    let scenes = data["reference"]["scenes"]
        .as_array()
        .expect("per-scene renders");
    assert_eq!(scenes.len(), npf::cli::view::scenes().len());
    for (k, s) in scenes.iter().enumerate() {
        let db = s["psnr_db"].as_f64().unwrap();
        eprintln!("scene {k}: rendering PSNR {db:.2} dB");
        assert!(
            db > 35.0,
            "scene {k}: the fit renders {db} dB from its own table"
        );
    }
    assert!(
        data["reference"]["evaluation"]["render_psnr_db"]
            .as_f64()
            .unwrap()
            > 35.0
    );
    // nothing fetched: the one URL is the SVG namespace's name
    let urls = html.matches("http://").count() + html.matches("https://").count();
    let namespace = html.matches("http://www.w3.org/2000/svg").count();
    assert_eq!(
        urls, namespace,
        "the page names no address but the SVG namespace"
    );
    check_dom(&exe, tempfile::tempdir().unwrap().path(), &file_url(&page));
}

#[test]
fn bad_invocations_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = write_model(
        dir.path(),
        "m.json",
        known_factor_model(Layout::default(), &[0.3]),
    );
    let m = model.to_str().unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_npf"))
            .args(args)
            .output()
            .unwrap()
    };
    // not .html
    let out = run(&["view", m, "-o", dir.path().join("p.txt").to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains(".html"));
    // the model as output
    let out = run(&["view", m, "-o", m]);
    assert!(!out.status.success());
    // an existing page without --force
    let page = dir.path().join("p.html");
    std::fs::write(&page, "keep").unwrap();
    let out = run(&["view", m, "-o", page.to_str().unwrap()]);
    assert!(!out.status.success());
    assert_eq!(std::fs::read_to_string(&page).unwrap(), "keep");
    // a truncated reference names the file
    let bad = dir.path().join("bad.binary");
    std::fs::write(&bad, [0u8; 100]).unwrap();
    let out = run(&[
        "view",
        m,
        "--reference",
        bad.to_str().unwrap(),
        "-o",
        dir.path().join("q.html").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.binary"));
    assert!(!dir.path().join("q.html").exists());
}
