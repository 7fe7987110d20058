//! A deterministic sphere renderer for comparing a BRDF model with its
//! measured table (see `docs/evaluation.md` for the definitions).
//!
//! Scene (world frame: +y up, the camera looks down -z from +z):
//! - an orthographic view of a unit sphere filling a `res` x `res` image;
//!   pixel (i, j) has centre x = (2 (i + 1/2) / res - 1), y = 1 - 2 (j + 1/2)
//!   / res; pixels with x^2 + y^2 >= 1 are background (black, and not part
//!   of any error);
//! - a smooth environment: L(w) = sky (0.55 + 0.45 w_y) + ground (0.5 - 0.5
//!   w_y)^2, sky = (0.40, 0.50, 0.70), ground = (0.30, 0.22, 0.15) (1/sr
//!   scaled radiance; linear in w_y plus a quadratic bounce term, so it has
//!   no edges);
//! - three directional (delta) lights, irradiance E at normal incidence:
//!   key from (-0.5, 0.6, 0.62) with E = (3.0, 2.85, 2.6), fill from
//!   (0.7, 0.2, 0.7) with E = (0.6, 0.7, 0.9), rim from (0.15, 0.4, -0.9)
//!   with E = (2.0, 2.0, 2.0) (directions normalised).
//!
//! Radiance at a pixel: L_o = sum_lights f(wo, wi) E cos theta_i + sum_k
//! f(wo, w_k) L(w_k) cos theta_k dOmega_k over a fixed midpoint grid on the
//! sphere of directions: `n_theta` strata uniform in w_y (equal area) times
//! `2 n_theta` in azimuth, each of solid angle 4 pi / (2 n_theta^2). Only
//! directions above the pixel's tangent plane count. The quadrature is the
//! same for the table and the model, and has no randomness. The grid reads
//! a sharp peak at isolated points; [`EnvQuadrature::HalfVector`]
//! integrates per pixel over half vectors instead, and converges on it.
//!
//! Display values: P = srgb(L / (1 + L)) per channel (Reinhard, then the
//! sRGB transfer curve), in [0, 1). Rendering PSNR = 10 log10(1 / MSE) over
//! the sphere's pixels and the three channels of P, in dB (infinite for
//! identical images).

use crate::bsdf::Bsdf;
use npf_data_loaders::geometry::{dot, normalize, Vec3};
use rayon::prelude::*;

/// Render settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width and height in pixels.
    pub res: usize,
    /// Environment quadrature: strata in w_y (azimuth gets twice as many),
    /// or with [`EnvQuadrature::HalfVector`] strata in sqrt(theta_h)
    /// (the same: twice as many in azimuth).
    pub n_theta: usize,
    /// How the environment integral is sampled.
    pub env: EnvQuadrature,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            res: 128,
            n_theta: 24,
            env: EnvQuadrature::Sphere,
        }
    }
}

/// The environment integral's quadrature.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EnvQuadrature {
    /// One midpoint grid over the sphere of directions, the same for every
    /// pixel. Cheap, but a peak narrower than its spacing (about 7 deg at
    /// 24 strata) is read at isolated points: the highlight of a sharp
    /// material is a pattern of dots, and the score depends on the peak's
    /// value at those points rather than on the light it reflects.
    #[default]
    Sphere,
    /// Per pixel, a midpoint grid over half vectors around the normal,
    /// uniform in sqrt(theta_h / 90 deg) as MERL's table is, with twice
    /// as many azimuth strata; each reflects the view into one
    /// incident direction with Jacobian 4 (wo . h). Dense where a specular
    /// peak is, so sharp highlights converge (the environment is smooth).
    HalfVector,
}

/// A linear-radiance RGB image; `mask` marks the sphere's pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width and height in pixels.
    pub res: usize,
    /// Linear radiance per pixel, row-major.
    pub rgb: Vec<[f64; 3]>,
    /// True for the sphere's pixels (the others are background).
    pub mask: Vec<bool>,
}

/// Why images could not be compared or encoded.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The two images have different resolutions.
    #[error("images of {0} and {1} pixels square cannot be compared")]
    SizeMismatch(usize, usize),
    /// The reference image has no sphere pixel.
    #[error("no sphere pixels")]
    Empty,
}

const SKY: [f64; 3] = [0.40, 0.50, 0.70];
const GROUND: [f64; 3] = [0.30, 0.22, 0.15];

/// The environment radiance in world direction `w`.
pub fn environment(w: Vec3) -> [f64; 3] {
    let a = 0.55 + 0.45 * w[1];
    let b = (0.5 - 0.5 * w[1]).powi(2);
    std::array::from_fn(|c| SKY[c] * a + GROUND[c] * b)
}

/// The directional lights: (direction towards the light, irradiance).
pub fn lights() -> [(Vec3, [f64; 3]); 3] {
    [
        (normalize([-0.5, 0.6, 0.62]), [3.0, 2.85, 2.6]),
        (normalize([0.7, 0.2, 0.7]), [0.6, 0.7, 0.9]),
        (normalize([0.15, 0.4, -0.9]), [2.0, 2.0, 2.0]),
    ]
}

/// The environment quadrature: (direction, L(w) dOmega).
pub fn quadrature(n_theta: usize) -> Vec<(Vec3, [f64; 3])> {
    let n_theta = n_theta.max(1);
    let n_phi = 2 * n_theta;
    let d_omega = 4.0 * std::f64::consts::PI / (n_theta * n_phi) as f64;
    let mut out = Vec::with_capacity(n_theta * n_phi);
    for a in 0..n_theta {
        let y = 1.0 - 2.0 * (a as f64 + 0.5) / n_theta as f64;
        let r = (1.0 - y * y).max(0.0).sqrt();
        for b in 0..n_phi {
            let phi = 2.0 * std::f64::consts::PI * (b as f64 + 0.5) / n_phi as f64;
            let w = [r * phi.cos(), y, r * phi.sin()];
            out.push((w, environment(w).map(|l| l * d_omega)));
        }
    }
    out
}

/// Half vectors of the local hemisphere with their solid angles d omega_h:
/// `n` strata uniform in u = sqrt(theta_h / 90 deg), `2 n` in azimuth, each
/// read at its midpoint and weighted by its exact solid angle. At n = 90 the
/// strata are MERL's theta_h cells, so a table (constant across a cell) is
/// integrated exactly in theta_h. A fitted model's peak varies inside the
/// first cells (under 1.1 deg), so those strata are split eight ways.
fn half_vectors(n: usize) -> Vec<(Vec3, f64)> {
    const SPLIT: usize = 8;
    let n = n.max(1);
    let m = 2 * n;
    let half_pi = std::f64::consts::FRAC_PI_2;
    let d_phi = 2.0 * std::f64::consts::PI / m as f64;
    let theta_at = |u: f64| half_pi * u * u;
    let mut rows = Vec::new();
    for a in 0..n {
        let split = if 9 * a < n { SPLIT } else { 1 };
        for k in 0..split {
            let u = |x: f64| (a as f64 + (k as f64 + x) / split as f64) / n as f64;
            rows.push((theta_at(u(0.0)), theta_at(u(0.5)), theta_at(u(1.0))));
        }
    }
    let mut out = Vec::with_capacity(rows.len() * m);
    for (lo, theta, hi) in rows {
        // cos lo - cos hi without cancellation for tiny strata
        let d_omega = 2.0 * (0.5 * (hi + lo)).sin() * (0.5 * (hi - lo)).sin() * d_phi;
        for k in 0..m {
            let phi = d_phi * (k as f64 + 0.5);
            let h = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            out.push((h, d_omega));
        }
    }
    out
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// What lights the sphere: directional lights and the environment's gain
/// (the environment's shape is fixed, [`environment`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// (direction towards the light, irradiance at normal incidence).
    pub lights: Vec<(Vec3, [f64; 3])>,
    /// The environment radiance is multiplied by this (0: no environment).
    pub environment_gain: f64,
}

impl Scene {
    /// The standard scene of the module notes: the environment and the
    /// three [`lights`].
    pub fn standard() -> Self {
        Scene {
            lights: lights().to_vec(),
            environment_gain: 1.0,
        }
    }
}

/// Render the sphere with any BSDF (evaluated in the local shading frame,
/// normal +z, as `bsdf.eval(wo, wi)`) in the [`Scene::standard`] scene.
pub fn render(opts: RenderOptions, bsdf: &(dyn Bsdf + Sync)) -> Image {
    render_scene(opts, &Scene::standard(), bsdf)
}

/// [`render`] in another scene.
pub fn render_scene(opts: RenderOptions, scene: &Scene, bsdf: &(dyn Bsdf + Sync)) -> Image {
    let res = opts.res.max(1);
    let env = Environment::new(opts, scene.environment_gain);
    let lights = &scene.lights;
    let px: Vec<([f64; 3], bool)> = (0..res * res)
        .into_par_iter()
        .map(|p| {
            let Some(frame) = Frame::at(p, res) else {
                return ([0.0; 3], false);
            };
            let mut l = [0.0; 3];
            for (w, e) in lights {
                frame.add(bsdf, &mut l, *w, e);
            }
            env.add(&frame, bsdf, &mut l);
            (l, true)
        })
        .collect();
    image(res, px)
}

/// [`render_scene`] for several scenes at once: the environment's
/// integral (nearly all of a render's evaluations) is the same in every
/// scene up to its gain, so it is taken once per pixel. Each image equals
/// its [`render_scene`] up to rounding (the sums are grouped differently).
pub fn render_scenes(
    opts: RenderOptions,
    scenes: &[Scene],
    bsdf: &(dyn Bsdf + Sync),
) -> Vec<Image> {
    let res = opts.res.max(1);
    let any_env = scenes.iter().any(|s| s.environment_gain != 0.0);
    let env = Environment::new(opts, if any_env { 1.0 } else { 0.0 });
    let px: Vec<Option<Vec<[f64; 3]>>> = (0..res * res)
        .into_par_iter()
        .map(|p| {
            let frame = Frame::at(p, res)?;
            let mut e = [0.0; 3];
            env.add(&frame, bsdf, &mut e);
            let per_scene = scenes
                .iter()
                .map(|s| {
                    let mut l = [0.0; 3];
                    for (w, irr) in &s.lights {
                        frame.add(bsdf, &mut l, *w, irr);
                    }
                    std::array::from_fn(|c| l[c] + s.environment_gain * e[c])
                })
                .collect();
            Some(per_scene)
        })
        .collect();
    (0..scenes.len())
        .map(|k| {
            let scene_px = px
                .iter()
                .map(|v| v.as_ref().map_or(([0.0; 3], false), |l| (l[k], true)))
                .collect();
            image(res, scene_px)
        })
        .collect()
}

fn image(res: usize, px: Vec<([f64; 3], bool)>) -> Image {
    Image {
        res,
        rgb: px.iter().map(|p| p.0).collect(),
        mask: px.iter().map(|p| p.1).collect(),
    }
}

/// A sphere pixel's shading frame (world-frame normal, tangent and
/// bitangent) and its view direction in that frame.
struct Frame {
    n: Vec3,
    t: Vec3,
    b: Vec3,
    wo: Vec3,
}

impl Frame {
    /// Pixel `p` of a `res` x `res` image; `None` off the sphere.
    fn at(p: usize, res: usize) -> Option<Frame> {
        let (i, j) = (p % res, p / res);
        let x = 2.0 * (i as f64 + 0.5) / res as f64 - 1.0;
        let y = 1.0 - 2.0 * (j as f64 + 0.5) / res as f64;
        let r2 = x * x + y * y;
        if r2 >= 1.0 {
            return None;
        }
        let n = [x, y, (1.0 - r2).sqrt()];
        let t = {
            let c = cross([0.0, 1.0, 0.0], n);
            if dot(c, c) < 1e-12 {
                [1.0, 0.0, 0.0]
            } else {
                normalize(c)
            }
        };
        let b = cross(n, t);
        let mut f = Frame {
            n,
            t,
            b,
            wo: [0.0; 3],
        };
        f.wo = f.local([0.0, 0.0, 1.0]);
        Some(f)
    }

    fn local(&self, v: Vec3) -> Vec3 {
        [dot(v, self.t), dot(v, self.b), dot(v, self.n)]
    }

    /// Adds f(wo, wi) e cos theta_i for light from world direction `wi_world`.
    fn add(&self, bsdf: &(dyn Bsdf + Sync), l: &mut [f64; 3], wi_world: Vec3, e: &[f64; 3]) {
        let wi = self.local(wi_world);
        if wi[2] <= 0.0 || self.wo[2] <= 0.0 {
            return;
        }
        let v = bsdf.eval(self.wo, wi);
        for c in 0..3 {
            l[c] += v[c] * e[c] * wi[2];
        }
    }
}

/// The environment's quadrature for a gain (empty at gain 0).
struct Environment {
    kind: EnvQuadrature,
    gain: f64,
    quad: Vec<(Vec3, [f64; 3])>,
    half: Vec<(Vec3, f64)>,
}

impl Environment {
    fn new(opts: RenderOptions, gain: f64) -> Self {
        let quad = match opts.env {
            // A gain of 1 multiplies exactly: the standard scene's bits stay.
            EnvQuadrature::Sphere if gain != 0.0 => quadrature(opts.n_theta)
                .into_iter()
                .map(|(w, e)| (w, e.map(|v| v * gain)))
                .collect(),
            _ => Vec::new(),
        };
        let half = match opts.env {
            EnvQuadrature::HalfVector if gain != 0.0 => half_vectors(opts.n_theta),
            _ => Vec::new(),
        };
        Environment {
            kind: opts.env,
            gain,
            quad,
            half,
        }
    }

    /// Adds the environment's reflected radiance at `frame` to `l`.
    fn add(&self, frame: &Frame, bsdf: &(dyn Bsdf + Sync), l: &mut [f64; 3]) {
        let (wo, gain) = (frame.wo, self.gain);
        match self.kind {
            EnvQuadrature::Sphere => {
                for (w, e) in &self.quad {
                    frame.add(bsdf, l, *w, e);
                }
            }
            EnvQuadrature::HalfVector => {
                for (h, dh) in &self.half {
                    let Some((wi, c)) = crate::bsdf::reflect_up(wo, *h) else {
                        continue;
                    };
                    // back to the world frame: wi = x t + y b + z n
                    let world = std::array::from_fn(|k| {
                        wi[0] * frame.t[k] + wi[1] * frame.b[k] + wi[2] * frame.n[k]
                    });
                    let e = environment(world).map(|v| v * gain * 4.0 * c * dh);
                    let v = bsdf.eval(wo, wi);
                    for ch in 0..3 {
                        l[ch] += v[ch] * e[ch] * wi[2];
                    }
                }
            }
        }
    }
}

fn srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The display value of a linear radiance: sRGB(L / (1 + L)), in [0, 1).
pub fn display(l: f64) -> f64 {
    let l = if l.is_finite() { l.max(0.0) } else { 0.0 };
    srgb(l / (1.0 + l))
}

impl Image {
    /// Display values, row-major RGB.
    pub fn display(&self) -> Vec<[f64; 3]> {
        self.rgb.iter().map(|p| p.map(display)).collect()
    }

    /// 8-bit sRGB bytes, row-major RGB.
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.display()
            .iter()
            .flat_map(|p| p.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8))
            .collect()
    }
}

/// Rendering PSNR in dB of `test` against `reference` (see the module
/// notes); `f64::INFINITY` for identical display values. Errors on images of
/// different sizes.
pub fn psnr(reference: &Image, test: &Image) -> Result<f64, RenderError> {
    if reference.res != test.res {
        return Err(RenderError::SizeMismatch(reference.res, test.res));
    }
    let (a, b) = (reference.display(), test.display());
    let mut sum = 0.0;
    let mut n = 0usize;
    for k in 0..a.len() {
        if !reference.mask[k] {
            continue;
        }
        for c in 0..3 {
            sum += (a[k][c] - b[k][c]).powi(2);
        }
        n += 3;
    }
    if n == 0 {
        return Err(RenderError::Empty);
    }
    let mse = sum / n as f64;
    Ok(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    })
}

/// The difference image: |P_ref - P_test| x `gain` per channel, as 8-bit RGB.
pub fn difference_rgb8(reference: &Image, test: &Image, gain: f64) -> Vec<u8> {
    let (a, b) = (reference.display(), test.display());
    a.iter()
        .zip(&b)
        .flat_map(|(p, q)| {
            std::array::from_fn::<u8, 3, _>(|c| {
                ((p[c] - q[c]).abs() * gain * 255.0)
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
        })
        .collect()
}
