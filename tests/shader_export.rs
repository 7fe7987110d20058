//! The shader and C exports (src/export/shader): the generated GLSL and
//! BRDF Explorer shader compile with glslangValidator; the C header
//! compiles with `cc -std=c99 -Wall -Werror`, its eval matches
//! `Model::eval` to 1e-5 relative, and its sampler is consistent with its
//! pdf and unbiased for the model's albedo.
//!
//! A missing tool skips its test with a loud message, or fails it when
//! NPF_REQUIRE_TOOLS is set (tests/run-all.sh sets it and installs them).

use npf::bsdf::half_vector_quadrature;
use npf::export::shader::{self, ShaderError, ShaderOptions};
use npf::loaders::geometry::{spherical, Vec3};
use npf::model::{Layout, Lobe, Model};
use npf::synth::known_factor_model;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Whether a tool runs; without it, fail under NPF_REQUIRE_TOOLS, else skip loudly.
fn have(tool: &str, test: &str) -> bool {
    let ok = Command::new(tool)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        if std::env::var_os("NPF_REQUIRE_TOOLS").is_some() {
            panic!("{test}: `{tool}` is missing and NPF_REQUIRE_TOOLS is set");
        }
        eprintln!("\n*** SKIPPING {test}: `{tool}` not found (Debian: glslang-tools / gcc) ***\n");
    }
    ok
}

/// Two GGX-shaped lobes on the MERL-aligned layout.
fn isotropic() -> Model {
    known_factor_model(Layout::default(), &[0.1, 0.35])
}

/// One lobe whose G drops to 0 right after a peak, so Catmull-Rom
/// undershoots below zero near the horizon and the >= 0 clamp acts.
fn undershooting() -> Model {
    let mut m = known_factor_model(Layout::default(), &[0.3]);
    m.diffuse = [0.0; 3];
    let n = m.lobes[0].g.len();
    for k in n - 12..n {
        m.lobes[0].g[k] = if k < n - 8 { 1.5 } else { 0.0 };
    }
    m
}

/// A model's diffuse term made separable, P rising from 0.4 at normal
/// incidence to a peak and falling to 0 at the horizon (not a shape a
/// constant could pass for).
fn separable(mut m: Model) -> Model {
    let n = 11;
    let p = (0..n)
        .map(|k| {
            let t = k as f32 / (n - 1) as f32;
            0.4 + 3.0 * t * (1.0 - t) - 0.4 * t * t
        })
        .collect();
    m.diffuse = [0.12, 0.08, 0.05];
    m.diffuse_form = npf::model::DiffuseForm::Separable { p };
    m.validate().unwrap();
    m
}

/// The anisotropic layout with D and G varying in phi.
fn anisotropic() -> Model {
    anisotropic_on(Layout::anisotropic())
}

/// The anisotropic layout with D on the squared theta_h axis.
fn squared_d() -> Model {
    let mut layout = Layout::anisotropic();
    layout.d.theta = npf::grid::Axis::Squared { n: 6 };
    anisotropic_on(layout)
}

fn anisotropic_on(layout: Layout) -> Model {
    let iso = known_factor_model(Layout::isotropic(90), &[0.2, 0.5]);
    let (d, g) = (layout.d, layout.g);
    let lobes = (0..2)
        .map(|m| Lobe {
            s: iso.lobes[m].s,
            d: (0..d.len())
                .map(|k| {
                    let (t, p) = d.node(k);
                    let a = 0.2 + 0.3 * m as f64 + 0.1 * (2.0 * p).cos();
                    npf::microfacet::ggx_d(t, a) as f32
                })
                .collect(),
            g: (0..g.len())
                .map(|k| {
                    let (t, p) = g.node(k);
                    (npf::microfacet::ggx_g1(t, 0.4) * (1.0 + 0.2 * p.sin())) as f32
                })
                .collect(),
        })
        .collect();
    let m = Model {
        layout,
        diffuse: [0.04, 0.05, 0.06],
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel: iso.fresnel.clone(),
        lobes,
    };
    m.validate().unwrap();
    m
}

fn dir(r: &mut Pcg64) -> Vec3 {
    // Uniform on the hemisphere, plus some exactly at the normal.
    if r.gen::<f64>() < 0.02 {
        return [0.0, 0.0, 1.0];
    }
    let z: f64 = r.gen_range(1e-3..1.0);
    spherical(z.acos(), r.gen_range(-3.2..3.2))
}

/// Random pairs: half uniform, half near the mirror direction (theta <= 89 deg).
fn pairs(n: usize, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut r = Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let wo = dir(&mut r);
            let wi = if k % 2 == 0 {
                dir(&mut r)
            } else {
                let (t, p) = npf::loaders::geometry::angles_of(wo);
                let t = (t + r.gen_range(-0.02..0.02)).clamp(0.0, 1.55);
                spherical(t, p + std::f64::consts::PI + r.gen_range(-0.02..0.02))
            };
            (wo, wi)
        })
        .collect()
}

const C_PROGRAM: &str = r#"
#include "model.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static unsigned long long state = 0x9e3779b97f4a7c15ULL;
static double rnd(void) {
    state += 0x9e3779b97f4a7c15ULL;
    unsigned long long z = state;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

int main(int argc, char **argv) {
    if (argc >= 2 && strcmp(argv[1], "eval") == 0) {
        double wo[3], wi[3], f[3];
        while (scanf("%lf %lf %lf %lf %lf %lf", &wo[0], &wo[1], &wo[2], &wi[0], &wi[1], &wi[2]) == 6) {
            npf_eval(wo, wi, f);
            printf("%.17g %.17g %.17g\n", f[0], f[1], f[2]);
        }
        return 0;
    }
    if (argc == 4 && strcmp(argv[1], "sample") == 0) {
        double theta = atof(argv[2]);
        long n = atol(argv[3]);
        double wo[3] = { sin(theta), 0.0, cos(theta) };
        double mean[3] = { 0, 0, 0 };
        long lost = 0, mismatched = 0;
        for (long k = 0; k < n; k++) {
            double u[2] = { rnd(), rnd() }, wi[3], f[3], pdf, g[3];
            int ok = npf_sample(wo, rnd(), u, wi, f, &pdf);
            if (!ok) {
                if (pdf != 0.0 || f[0] != 0.0) mismatched++;
                lost++;
                continue;
            }
            double len = sqrt(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2]);
            npf_eval(wo, wi, g);
            if (pdf != npf_pdf(wo, wi) || !(pdf > 0.0) || fabs(len - 1.0) > 1e-9 || g[0] != f[0]) mismatched++;
            for (int c = 0; c < 3; c++) mean[c] += f[c] * wi[2] / pdf;
        }
        /* The integral of pdf over the upper hemisphere, by a midpoint grid
           over the half vector (theta_h = pi/2 u^2), wi the reflection of wo. */
        int nu = 600, nphi = 1200;
        double integral = 0.0;
        for (int a = 0; a < nu; a++) {
            double uu = (a + 0.5) / nu, th = 1.5707963267948966 * uu * uu;
            double wt = sin(th) * 3.141592653589793 * uu / nu * (6.283185307179586 / nphi);
            for (int b = 0; b < nphi; b++) {
                double ph = (b + 0.5) * 6.283185307179586 / nphi;
                double h[3] = { sin(th) * cos(ph), sin(th) * sin(ph), cos(th) };
                double oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                if (oh <= 0.0) continue;
                double wi[3] = { 2 * oh * h[0] - wo[0], 2 * oh * h[1] - wo[1], 2 * oh * h[2] - wo[2] };
                if (wi[2] <= 0.0) continue;
                integral += npf_pdf(wo, wi) * 4.0 * oh * wt;
            }
        }
        printf("%.10g %.10g %.10g %.10g %ld %.10g\n", mean[0] / n, mean[1] / n, mean[2] / n,
               (double)lost / n, mismatched, integral);
        return 0;
    }
    fprintf(stderr, "usage: %s eval < pairs | sample THETA N\n", argv[0]);
    return 2;
}
"#;

/// Compiles the header of `model` with the test program; the binary's path.
fn compile_c(model: &Model, dir: &Path) -> PathBuf {
    std::fs::write(dir.join("model.h"), shader::c_header(model).unwrap()).unwrap();
    std::fs::write(dir.join("main.c"), C_PROGRAM).unwrap();
    let exe = dir.join("main");
    let out = Command::new("cc")
        .args([
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-pedantic",
            "-Werror",
            "-O2",
            "-o",
        ])
        .arg(&exe)
        .arg(dir.join("main.c"))
        .arg("-lm")
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cc failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    exe
}

fn run(exe: &Path, args: &[&str], input: &str) -> String {
    // Input through a file: a pipe written before the output is read
    // would deadlock once both pipe buffers fill.
    let path = exe.with_extension("in");
    std::fs::write(&path, input).unwrap();
    let out = Command::new(exe)
        .args(args)
        .stdin(std::fs::File::open(&path).unwrap())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn c_header_eval_matches_model_eval() {
    if !have("cc", "c_header_eval_matches_model_eval") {
        return;
    }
    for (name, model) in [
        ("isotropic", isotropic()),
        ("undershooting", undershooting()),
        ("anisotropic", anisotropic()),
        ("squared D", squared_d()),
        ("separable diffuse", separable(isotropic())),
        ("anisotropic, separable diffuse", separable(anisotropic())),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let exe = compile_c(&model, dir.path());
        let pairs = pairs(4000, 7);
        let input: String = pairs
            .iter()
            .map(|(o, i)| {
                format!(
                    "{:?} {:?} {:?} {:?} {:?} {:?}\n",
                    o[0], o[1], o[2], i[0], i[1], i[2]
                )
            })
            .collect();
        let out = run(&exe, &["eval"], &input);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), pairs.len());
        let (mut worst, mut zeros, mut positive) = (0.0f64, 0, 0);
        for ((wo, wi), line) in pairs.iter().zip(lines) {
            let c: Vec<f64> = line.split(' ').map(|v| v.parse().unwrap()).collect();
            let r = model.eval(*wo, *wi);
            for ch in 0..3 {
                let err = (c[ch] - r[ch]).abs() / r[ch].abs().max(1e-12);
                worst = worst.max(err);
                assert!(
                    err <= 1e-5,
                    "{name}: channel {ch} at wo {wo:?} wi {wi:?}: C {} vs Model::eval {}",
                    c[ch],
                    r[ch]
                );
                if r[ch] == 0.0 {
                    zeros += 1;
                } else {
                    positive += 1;
                }
            }
        }
        eprintln!(
            "{name}: worst relative error {worst:.2e} over {} pairs",
            pairs.len()
        );
        assert!(
            positive > 3 * pairs.len() / 2,
            "{name}: most values are positive"
        );
        if name == "undershooting" {
            assert!(zeros > 0, "the clamp acts somewhere");
        }
    }
}

#[test]
fn c_header_sampler_matches_its_pdf_and_is_unbiased() {
    if !have("cc", "c_header_sampler_matches_its_pdf_and_is_unbiased") {
        return;
    }
    for (name, model) in [
        ("isotropic", isotropic()),
        ("anisotropic", anisotropic()),
        ("separable diffuse", separable(isotropic())),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let exe = compile_c(&model, dir.path());
        for theta_deg in [0.0f64, 40.0, 70.0] {
            let theta = theta_deg.to_radians();
            let out = run(&exe, &["sample", &theta.to_string(), "200000"], "");
            let v: Vec<f64> = out.split_whitespace().map(|x| x.parse().unwrap()).collect();
            let (mean, lost, mismatched, integral) = (&v[0..3], v[3], v[4], v[5]);
            assert_eq!(
                mismatched, 0.0,
                "{name}: sample's pdf or f differs from pdf/eval"
            );
            // The pdf integrates to 1 minus the mass that leaves the hemisphere.
            assert!(
                (integral - (1.0 - lost)).abs() < 0.01,
                "{name} at {theta_deg} deg: integral of pdf {integral}, 1 - lost {}",
                1.0 - lost
            );
            // The mean weight is the directional albedo npf integrates.
            let albedo = half_vector_quadrature(theta, 160, 320, 3, |wo, wi, w, acc| {
                let f = model.eval(wo, wi);
                for c in 0..3 {
                    acc[c] += f[c] * w;
                }
            });
            for c in 0..3 {
                let rel = (mean[c] - albedo[c]).abs() / albedo[c];
                assert!(
                    rel < 0.02,
                    "{name} at {theta_deg} deg, channel {c}: mean weight {} vs albedo {}",
                    mean[c],
                    albedo[c]
                );
            }
            eprintln!(
                "{name} {theta_deg} deg: albedo {:.4} mean weight {:.4}, lost {lost:.4}, pdf integral {integral:.4}",
                albedo[1], mean[1]
            );
        }
    }
}

/// Validates a fragment shader with glslangValidator.
fn validate_glsl(source: &str, dir: &Path, name: &str) {
    let path = dir.join(format!("{name}.frag"));
    std::fs::write(&path, source).unwrap();
    let out = Command::new("glslangValidator")
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{name}: glslangValidator failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn glsl_functions_compile() {
    if !have("glslangValidator", "glsl_functions_compile") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, model) in [
        ("isotropic", isotropic()),
        ("anisotropic", anisotropic()),
        ("separable", separable(anisotropic())),
    ] {
        let code = shader::glsl(&model).unwrap();
        assert!(code.lines().all(|l| !l.trim_start().starts_with('#')));
        let frag = format!(
            "#version 410\n{code}
uniform vec3 wo; uniform vec3 wi; uniform vec3 u;
out vec4 color;
void main() {{
    vec3 d; vec3 f; float p;
    bool ok = npf_sample(wo, u.x, u.yz, d, f, p);
    color = vec4(npf_eval(wo, wi) + f + d, npf_pdf(wo, wi) + (ok ? p : 0.0));
}}
"
        );
        validate_glsl(&frag, dir.path(), name);
    }
}

/// The parameters and shader of a `.brdf` file, checked against BRDF
/// Explorer's reader: `analytic` first, only float/bool/color parameter
/// lines, no line starting with '#'.
fn parse_brdf(text: &str) -> (Vec<(String, String)>, String) {
    let mut lines = text.lines();
    assert_eq!(lines.next().map(str::trim), Some("analytic"));
    let (mut params, mut shader, mut section) = (Vec::new(), String::new(), None::<String>);
    for line in lines {
        let t = line.trim();
        assert!(!t.starts_with('#'), "BRDF Explorer drops '#' lines: {line}");
        if let Some(s) = t.strip_prefix("::begin ") {
            assert!(section.is_none(), "nested section");
            section = Some(s.trim().to_string());
        } else if let Some(s) = t.strip_prefix("::end ") {
            assert_eq!(section.as_deref(), Some(s.trim()));
            section = None;
        } else {
            match section.as_deref() {
                Some("parameters") if !t.is_empty() => {
                    let w: Vec<&str> = t.split_whitespace().collect();
                    let count = match w[0] {
                        "float" => 5,
                        "bool" => 3,
                        "color" => 5,
                        other => panic!("unknown parameter type {other}"),
                    };
                    assert_eq!(w.len(), count, "{t}");
                    assert!(w[2..].iter().all(|v| v.parse::<f32>().is_ok()), "{t}");
                    params.push((w[0].to_string(), w[1].to_string()));
                }
                Some("shader") => {
                    shader += line;
                    shader.push('\n');
                }
                Some("parameters") | None => {}
                Some(other) => panic!("unexpected section {other}"),
            }
        }
    }
    assert!(section.is_none(), "unterminated section");
    (params, shader)
}

#[test]
fn brdf_explorer_file_follows_the_format_and_compiles() {
    let tools = have(
        "glslangValidator",
        "brdf_explorer_file_follows_the_format_and_compiles",
    );
    let dir = tempfile::tempdir().unwrap();
    for (name, model) in [("isotropic", isotropic()), ("anisotropic", anisotropic())] {
        let text = shader::brdf_explorer(&model).unwrap();
        let (params, code) = parse_brdf(&text);
        assert!(code.contains("vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)"));
        assert_eq!(
            params.len(),
            2 + model.lobe_count(),
            "exposure, diffuse, one switch per lobe"
        );
        if !tools {
            continue;
        }
        // BRDF Explorer's templates: #version 410, its own uniforms (exposure
        // among them), then the parameters as uniforms, then the shader.
        let uniforms: String = params
            .iter()
            .map(|(t, n)| {
                let ty = if t == "color" { "vec3" } else { t.as_str() };
                format!("uniform {ty} {n};\n")
            })
            .collect();
        let frag = format!(
            "#version 410
uniform float exposure; uniform float gamma; uniform float brightness;
{uniforms}{code}
uniform vec3 L; uniform vec3 V;
out vec4 color;
void main() {{
    color = vec4(BRDF(L, V, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)), exposure);
}}
"
        );
        validate_glsl(&frag, dir.path(), &format!("brdf_explorer_{name}"));
    }
}

#[test]
fn bad_models_and_prefixes_are_errors() {
    let mut m = isotropic();
    m.lobes[0].d[3] = f32::NAN;
    assert!(matches!(
        shader::glsl(&m),
        Err(ShaderError::InvalidModel(_))
    ));
    m.lobes[0].d[3] = -1.0;
    assert!(matches!(
        shader::c_header(&m),
        Err(ShaderError::InvalidModel(_))
    ));
    // A form with no shader code is refused by name.
    let mut oren = isotropic();
    oren.diffuse_form = npf::model::DiffuseForm::OrenNayar { sigma: 0.3 };
    assert!(matches!(
        shader::glsl(&oren),
        Err(ShaderError::DiffuseForm("oren-nayar"))
    ));
    for bad in ["", "9a", "a b", "gl_x", "a__b", "x_", "é"] {
        let o = ShaderOptions { prefix: bad.into() };
        assert!(
            matches!(
                shader::brdf_explorer_with(&isotropic(), &o),
                Err(ShaderError::BadPrefix(_))
            ),
            "{bad:?}"
        );
    }
    let o = ShaderOptions {
        prefix: "gold".into(),
    };
    let h = shader::c_header_with(&isotropic(), &o).unwrap();
    assert!(h.contains("gold_eval(") && !h.contains("npf_eval") && !h.contains("npf_D["));
}
