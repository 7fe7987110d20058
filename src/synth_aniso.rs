//! Analytic anisotropic BRDFs, tabulated as UTIA tables: the data the
//! anisotropic path is developed and benchmarked on (no UTIA measurement is
//! available to the project). The isotropic counterpart is [`crate::synth`].
//!
//! A material is a Lambertian term plus a sum of lobes, each with its own
//! tangent angle (the azimuth of its x roughness axis in the shading frame):
//! anisotropic GGX (Smith G1 with the projected roughness, Schlick F),
//! Ward (the original normalisation), Ashikhmin-Shirley (its specular term;
//! its coupled diffuse is left out, the Lambertian term stands in), and a
//! Charlie sheen with Ashikhmin's visibility, which no microfacet lobe of the
//! factor model expresses exactly. [`catalogue`] is the benchmark set.

use crate::bsdf::{cosine_draw, Bsdf, BsdfSample};
use crate::microfacet::{ggx_g1_tan2, schlick};
use crate::model::{Layout, Lobe, Model};
use npf_data_loaders::geometry::{dot, Vec3};
use npf_data_loaders::UtiaTable;
use std::f64::consts::PI;

/// One specular term of an analytic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnalyticLobe {
    /// Anisotropic GGX: ks D F G1 G1 / (4 cos cos), Schlick F with f0.
    Ggx {
        /// Roughness along the tangent.
        ax: f64,
        /// Roughness along the bitangent.
        ay: f64,
        /// Tangent azimuth (radians).
        tangent: f64,
        /// Specular scale per channel.
        ks: [f64; 3],
        /// Fresnel at normal incidence per channel.
        f0: [f64; 3],
    },
    /// Ward: ks exp(-tan^2 theta_h (cos^2/ax^2 + sin^2/ay^2)) / (4 pi ax ay sqrt(cos cos)).
    Ward {
        /// Roughness along the tangent.
        ax: f64,
        /// Roughness along the bitangent.
        ay: f64,
        /// Tangent azimuth (radians).
        tangent: f64,
        /// Specular scale per channel.
        ks: [f64; 3],
    },
    /// Ashikhmin-Shirley's specular term with Schlick F (rs per channel).
    AshikhminShirley {
        /// Phong exponent along the tangent.
        nu: f64,
        /// Phong exponent along the bitangent.
        nv: f64,
        /// Tangent azimuth (radians).
        tangent: f64,
        /// Specular reflectance per channel.
        rs: [f64; 3],
    },
    /// Charlie sheen, D = (2 + 1/r) sin^(1/r) theta_h / (2 pi), with
    /// Ashikhmin's visibility 1 / (4 (cos_i + cos_o - cos_i cos_o)).
    Sheen {
        /// Sheen roughness r in (0, 1].
        r: f64,
        /// Sheen colour per channel.
        color: [f64; 3],
    },
}

/// Anisotropic GGX normal distribution of a half vector `h` whose azimuth in
/// the lobe's frame is `phi` (radians).
pub fn aniso_ggx_d(cos_h: f64, phi: f64, ax: f64, ay: f64) -> f64 {
    let c2 = cos_h * cos_h;
    if !(c2 > 0.0) {
        return 0.0;
    }
    let t2 = (1.0 - c2) / c2;
    let e = t2 * (phi.cos().powi(2) / (ax * ax) + phi.sin().powi(2) / (ay * ay));
    1.0 / (PI * ax * ay * c2 * c2 * (1.0 + e).powi(2))
}

/// Anisotropic Smith G1 of a direction with polar angle cosine `cos_t` and
/// azimuth `phi` in the lobe's frame (the roughness projected on its plane).
pub fn aniso_ggx_g1(cos_t: f64, phi: f64, ax: f64, ay: f64) -> f64 {
    if !(cos_t > 0.0) {
        return 0.0;
    }
    let a2 = (phi.cos() * ax).powi(2) + (phi.sin() * ay).powi(2);
    ggx_g1_tan2((1.0 - cos_t * cos_t).max(0.0) / (cos_t * cos_t), a2.sqrt())
}

fn azimuth(v: Vec3) -> f64 {
    v[1].atan2(v[0])
}

impl AnalyticLobe {
    /// The lobe's value per channel (1/sr) for unit directions above the horizon.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        let (ci, co) = (wi[2], wo[2]);
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = dot(s, s).sqrt();
        if !(n > 0.0) {
            return [0.0; 3];
        }
        let h = [s[0] / n, s[1] / n, s[2] / n];
        let hk = dot(h, wi).clamp(0.0, 1.0);
        match *self {
            AnalyticLobe::Ggx {
                ax,
                ay,
                tangent,
                ks,
                f0,
            } => {
                let d = aniso_ggx_d(h[2], azimuth(h) - tangent, ax, ay);
                let g = aniso_ggx_g1(ci, azimuth(wi) - tangent, ax, ay)
                    * aniso_ggx_g1(co, azimuth(wo) - tangent, ax, ay);
                std::array::from_fn(|c| ks[c] * d * schlick(f0[c], hk) * g / (4.0 * ci * co))
            }
            AnalyticLobe::Ward {
                ax,
                ay,
                tangent,
                ks,
            } => {
                let c2 = h[2] * h[2];
                let p = azimuth(h) - tangent;
                let e =
                    (1.0 - c2) / c2 * (p.cos().powi(2) / (ax * ax) + p.sin().powi(2) / (ay * ay));
                let v = (-e).exp() / (4.0 * PI * ax * ay * (ci * co).sqrt());
                ks.map(|k| k * v)
            }
            AnalyticLobe::AshikhminShirley {
                nu,
                nv,
                tangent,
                rs,
            } => {
                let p = azimuth(h) - tangent;
                let c2 = h[2] * h[2];
                let expo = if c2 < 1.0 {
                    (nu * p.cos().powi(2) + nv * p.sin().powi(2)) * (1.0 - c2).max(0.0) / (1.0 - c2)
                } else {
                    0.5 * (nu + nv)
                };
                let v = ((nu + 1.0) * (nv + 1.0)).sqrt() / (8.0 * PI) * h[2].powf(expo)
                    / (hk.max(1e-9) * ci.max(co));
                std::array::from_fn(|c| v * schlick(rs[c], hk))
            }
            AnalyticLobe::Sheen { r, color } => {
                let sin_h = (1.0 - h[2] * h[2]).max(0.0).sqrt();
                let d = (2.0 + 1.0 / r) * sin_h.powf(1.0 / r) / (2.0 * PI);
                let v = d / (4.0 * (ci + co - ci * co));
                color.map(|k| k * v)
            }
        }
    }
}

/// An analytic material: Lambertian `kd / pi` plus its lobes.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalyticBrdf {
    /// A short name (file stem of its table).
    pub name: String,
    /// Diffuse albedo per channel.
    pub kd: [f64; 3],
    /// The specular terms.
    pub lobes: Vec<AnalyticLobe>,
}

impl AnalyticBrdf {
    /// The material tabulated at every UTIA node (the raw values are its
    /// BRDF in 1/sr, the loader's colour convention).
    pub fn table(&self) -> UtiaTable {
        to_utia(self)
    }
}

/// Drawn by cosine-weighted hemisphere sampling (a reference needs no
/// better sampler); zero below the horizon.
impl Bsdf for AnalyticBrdf {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return [0.0; 3];
        }
        let mut v = self.kd.map(|k| k / PI);
        for l in &self.lobes {
            let t = l.eval(wo, wi);
            for c in 0..3 {
                v[c] += t[c];
            }
        }
        v
    }

    fn sample(&self, wo: Vec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        cosine_draw(self, wo, u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f64 {
        crate::bsdf::cosine_pdf_for(wo, wi)
    }
}

/// Any BSDF tabulated at the UTIA nodes: illumination direction `wi` from
/// (theta_i, phi_i), view `wo` from (theta_v, phi_v). All nodes are above
/// the horizon, so no cell is missing.
pub fn to_utia(bsdf: &(dyn Bsdf + Sync)) -> UtiaTable {
    use npf_data_loaders::geometry::spherical;
    UtiaTable::from_fn(|ti, pi, tv, pv| Some(bsdf.eval(spherical(tv, pv), spherical(ti, pi))))
}

fn ggx(ax: f64, ay: f64, tangent_deg: f64, ks: [f64; 3], f0: [f64; 3]) -> AnalyticLobe {
    AnalyticLobe::Ggx {
        ax,
        ay,
        tangent: tangent_deg.to_radians(),
        ks,
        f0,
    }
}

/// The benchmark set: 13 analytic materials (GGX at several alpha ratios
/// and tangent angles, Ward, Ashikhmin-Shirley, a two-lobe mixture with
/// crossed axes, a sheen, an isotropic GGX).
pub fn catalogue() -> Vec<AnalyticBrdf> {
    let m = |name: &str, kd: [f64; 3], lobes: Vec<AnalyticLobe>| AnalyticBrdf {
        name: name.into(),
        kd,
        lobes,
    };
    let gold = [0.95, 0.7, 0.35];
    let white = [0.04; 3];
    vec![
        m(
            "ggx-iso-0.25",
            [0.3, 0.2, 0.1],
            vec![ggx(0.25, 0.25, 0.0, [1.0; 3], white)],
        ),
        m(
            "ggx-0.1x0.3-t0",
            [0.05, 0.05, 0.1],
            vec![ggx(0.1, 0.3, 0.0, [1.0; 3], gold)],
        ),
        m(
            "ggx-0.1x0.3-t30",
            [0.05, 0.05, 0.1],
            vec![ggx(0.1, 0.3, 30.0, [1.0; 3], gold)],
        ),
        m(
            "ggx-0.1x0.3-t45",
            [0.05, 0.05, 0.1],
            vec![ggx(0.1, 0.3, 45.0, [1.0; 3], gold)],
        ),
        m(
            "ggx-0.12x0.48-t90",
            [0.1, 0.1, 0.1],
            vec![ggx(0.12, 0.48, 90.0, [1.0; 3], [0.9; 3])],
        ),
        m(
            "ggx-0.2x0.5-t60",
            [0.2, 0.05, 0.05],
            vec![ggx(0.2, 0.5, 60.0, [1.0; 3], white)],
        ),
        m(
            "ggx-0.3x0.6-t20",
            [0.1, 0.3, 0.1],
            vec![ggx(0.3, 0.6, 20.0, [1.0; 3], [0.5, 0.5, 0.6])],
        ),
        m(
            "ward-0.15x0.35-t0",
            [0.1, 0.1, 0.05],
            vec![AnalyticLobe::Ward {
                ax: 0.15,
                ay: 0.35,
                tangent: 0.0,
                ks: [0.6, 0.5, 0.4],
            }],
        ),
        m(
            "ward-0.12x0.3-t45",
            [0.05, 0.1, 0.2],
            vec![AnalyticLobe::Ward {
                ax: 0.12,
                ay: 0.3,
                tangent: 45f64.to_radians(),
                ks: [0.5; 3],
            }],
        ),
        m(
            "as-100x10-t0",
            [0.1, 0.05, 0.05],
            vec![AnalyticLobe::AshikhminShirley {
                nu: 100.0,
                nv: 10.0,
                tangent: 0.0,
                rs: [0.8, 0.6, 0.4],
            }],
        ),
        m(
            "as-20x200-t30",
            [0.05, 0.05, 0.05],
            vec![AnalyticLobe::AshikhminShirley {
                nu: 20.0,
                nv: 200.0,
                tangent: 30f64.to_radians(),
                rs: [0.6; 3],
            }],
        ),
        m(
            "mix-ggx-t0-t60",
            [0.05, 0.08, 0.1],
            vec![
                ggx(0.12, 0.35, 0.0, [0.7; 3], gold),
                ggx(0.4, 0.2, 60.0, [0.5; 3], white),
            ],
        ),
        m(
            "sheen-ggx-0.2x0.4",
            [0.1, 0.05, 0.15],
            vec![
                ggx(0.2, 0.4, 0.0, [1.0; 3], white),
                AnalyticLobe::Sheen {
                    r: 0.4,
                    color: [0.3, 0.3, 0.5],
                },
            ],
        ),
    ]
}

/// A known 2010-parameter model (three lobes on [`Layout::anisotropic`]):
/// D^m anisotropic GGX with tangent angles 0, 40 and 100 degrees, G^m the
/// matching anisotropic Smith G1, Schlick-shaped F per channel. Tables made
/// from it are exactly representable, so fitting them back tests the solver.
pub fn known_model() -> Model {
    let layout = Layout::anisotropic();
    let on = |grid: crate::grid::Grid, f: &dyn Fn(f64, f64) -> f64| -> Vec<f32> {
        (0..grid.len())
            .map(|k| {
                let (t, p) = grid.node(k);
                f(t, p) as f32
            })
            .collect()
    };
    let lobes = [
        (0.15, 0.4, 0.0, [0.6, 0.4, 0.3]),
        (0.35, 0.2, 40.0, [0.2, 0.3, 0.4]),
        (0.6, 0.5, 100.0, [0.05, 0.05, 0.08]),
    ]
    .into_iter()
    .map(|(ax, ay, deg, s): (f64, f64, f64, [f32; 3])| {
        let tan = deg.to_radians();
        Lobe {
            s,
            d: on(layout.d, &|t, p| aniso_ggx_d(t.cos(), p - tan, ax, ay)),
            g: on(layout.g, &|t, p| aniso_ggx_g1(t.cos(), p - tan, ax, ay)),
        }
    })
    .collect();
    let fresnel = [0.9, 0.6, 0.3].map(|f0: f64| on(layout.f, &|t, _| schlick(f0, t.cos())));
    Model {
        layout,
        diffuse: [0.04, 0.06, 0.08],
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel,
        lobes,
    }
}
