//! The shared-factor non-parametric microfacet model (Peng, Zheng, Lv):
//!
//! rho_C(wi, wo) = d_C b_C(wi, wo) + sum_m s_C^m D^m(theta_h) F_C(theta_d) G^m(theta_i) G^m(theta_o) / (cos theta_i cos theta_o)
//!
//! (optionally with the height-correlated G2 of the two G values in place
//! of their product, [`Masking`], and Kulla-Conty's multiple-scattering
//! term added, [`Compensation`]).
//!
//! D^m and G^m are shared by the three channels; F_C, d_C and s_C^m are per
//! channel. b_C is the diffuse form's directional factor ([`DiffuseForm`]):
//! 1 for the paper's Lambertian term. Values are BRDF values in 1/sr (MERL's physical units). A model
//! stores its parameters as f32: that is what its files hold, so a model
//! written and read back is the same model, bit for bit.

use crate::grid::axis::catmull_rom_weights;
use crate::grid::{Axis, Grid, Stencil};
use npf_data_loaders::geometry::{Angles, Vec3};
use serde::{Deserialize, Serialize};

/// Where the factor tables' nodes sit: one [`Grid`] per factor. The
/// isotropic layout has 1-D tables; the anisotropic one puts D on
/// (theta_h, phi_h) and G on (theta, phi) of each direction. The solver
/// only sees stencils, so it fits either unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// D^m(theta_h[, phi_h]).
    pub d: Grid,
    /// F_C(theta_d[, phi_d]) (1-D in both built-in layouts).
    pub f: Grid,
    /// G^m(theta[, phi]) of each direction.
    pub g: Grid,
}

/// Why a model (or its layout) is not valid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// A factor table's grid has too few nodes.
    #[error("{factor} grid needs at least {min} theta nodes, has {n}")]
    TooFewNodes {
        /// "D", "F" or "G".
        factor: &'static str,
        /// The least allowed.
        min: usize,
        /// What the layout has.
        n: usize,
    },
    /// A periodic phi axis without nodes.
    #[error("{factor} grid has an empty phi axis")]
    EmptyPhi {
        /// "D", "F" or "G".
        factor: &'static str,
    },
    /// A grid larger than model files can describe.
    #[error("{factor} grid has {n} nodes on an axis, at most 65535 are allowed")]
    TooManyNodes {
        /// "D", "F" or "G".
        factor: &'static str,
        /// The axis length.
        n: usize,
    },
    /// The lobe count is outside 1 to 255 (or does not match the parameters).
    #[error("a model needs 1 to 255 specular lobes, got {0}")]
    Lobes(usize),
    /// A parameter vector of the wrong length.
    #[error("{got} parameters for {lobes} lobes, expected {expected}")]
    ParamCount {
        /// Parameters given.
        got: usize,
        /// Lobes asked for.
        lobes: usize,
        /// Parameters the layout needs.
        expected: usize,
    },
    /// A table whose length does not match the layout.
    #[error("{table} has {got} values, the layout says {expected}")]
    TableSize {
        /// Which table ("F channel 1", "lobe 0 D", ...).
        table: String,
        /// Its length.
        got: usize,
        /// The layout's size.
        expected: usize,
    },
    /// A NaN or infinite parameter.
    #[error("parameter {0} is not finite")]
    NotFinite(usize),
    /// A negative d, s, D or F value.
    #[error("negative d, s, D or F value")]
    Negative,
    /// The diffuse form's data are not valid.
    #[error("diffuse form: {0}")]
    DiffuseForm(String),
}

impl Layout {
    /// MERL-aligned layout with `n` values per factor: D on MERL's theta_h
    /// nodes, F on its theta_d nodes, G as Catmull-Rom control points.
    /// 822 parameters for 3 lobes at n = 90.
    pub fn isotropic(n: usize) -> Self {
        Layout {
            d: Grid::line(Axis::SqrtAngle { n }),
            f: Grid::line(Axis::Uniform { n }),
            g: Grid::line(Axis::CatmullRom { n }),
        }
    }

    /// The anisotropic layout of the paper (section 2.2), aligned with UTIA's
    /// 6 x 48 (theta, phi) grid: D on (theta_h, phi_h), 6 linear theta nodes
    /// 15 degrees apart times 48 periodic phi nodes (bilinear); G on
    /// (theta, phi) of each direction, 6 Catmull-Rom control points over
    /// [0, 90] degrees times 48 linear phi nodes (so G reaches 0 at the
    /// horizon as in the isotropic model); F on 90 theta_d nodes.
    /// 3 + 9 + 6 * 48 * 3 * 2 + 90 * 3 = 2010 parameters for 3 lobes.
    pub fn anisotropic() -> Self {
        Layout {
            d: Grid::plane(Axis::Uniform { n: 6 }, 48),
            f: Grid::line(Axis::Uniform { n: 90 }),
            g: Grid::plane(Axis::CatmullRom { n: 6 }, 48),
        }
    }

    /// Whether every table is 1-D (the model depends on theta_h, theta_d and
    /// the unordered pair {theta_i, theta_o} only).
    pub fn is_isotropic(&self) -> bool {
        self.d.is_1d() && self.f.is_1d() && self.g.is_1d()
    }

    /// The D stencil of a configuration.
    pub fn d_stencil(&self, a: &Angles) -> Stencil {
        self.d.stencil(a.theta_h, a.phi_h)
    }

    /// The F stencil of a configuration.
    pub fn f_stencil(&self, a: &Angles) -> Stencil {
        self.f.stencil(a.theta_d, a.phi_d)
    }

    /// The G stencil of one direction.
    pub fn g_stencil(&self, theta: f64, phi: f64) -> Stencil {
        self.g.stencil(theta, phi)
    }

    /// Number of parameters of a model with `lobes` specular lobes.
    pub fn param_count(&self, lobes: usize) -> usize {
        3 + 3 * lobes + lobes * (self.d.len() + self.g.len()) + 3 * self.f.len()
    }

    /// Checks the grids' sizes: G needs two theta nodes (Catmull-Rom), D and
    /// F one; phi axes at least one node; every axis at most 65535 nodes.
    pub fn validate(&self) -> Result<(), ModelError> {
        for (factor, grid, min) in [("D", self.d, 1), ("F", self.f, 1), ("G", self.g, 2)] {
            let n = grid.n_theta();
            if n < min {
                return Err(ModelError::TooFewNodes { factor, min, n });
            }
            if grid.phi.is_some_and(|p| p.n == 0) {
                return Err(ModelError::EmptyPhi { factor });
            }
            if n > u16::MAX as usize || grid.n_phi() > u16::MAX as usize {
                return Err(ModelError::TooManyNodes {
                    factor,
                    n: n.max(grid.n_phi()),
                });
            }
        }
        Ok(())
    }
}

impl Default for Layout {
    fn default() -> Self {
        Layout::isotropic(90)
    }
}

/// One specular lobe: its per-channel scale and its shared D and G tables.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lobe {
    /// Per-channel scale s_C.
    pub s: [f32; 3],
    /// D node values on the layout's D grid (row-major theta x phi when 2-D).
    pub d: Vec<f32>,
    /// G control points on the layout's G grid (row-major theta x phi when 2-D).
    pub g: Vec<f32>,
}

/// Nodes of an energy-coupled diffuse form's albedo tables: theta_k =
/// k / (n - 1) * pi / 2, linear between nodes.
pub const ALBEDO_NODES: usize = 32;

/// How the diffuse term depends on the directions: d_C b_C(wi, wo).
///
/// Every form is reciprocal and has no free parameter the AWLS sweep
/// updates (Oren-Nayar's sigma and the albedo tables are refreshed between
/// sweeps, each refresh kept only when the objective falls), so the model
/// keeps its parameter count.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "form", rename_all = "kebab-case")]
pub enum DiffuseForm {
    /// b = 1: the paper's Lambertian term (d_C in 1/sr).
    #[default]
    Lambert,
    /// Kelemen / Kulla-Conty coupling to the energy the specular lobes
    /// leave: b_C = (1 - E_C(theta_i)) (1 - E_C(theta_o)) / (1 - Eavg_C),
    /// E_C the directional albedo (integral of f cos) of the specular lobes
    /// alone, clamped to [0, 1], and Eavg_C = 2 int E_C(mu) mu dmu. Its
    /// albedo is then pi d_C (1 - E_C(theta_o)): with pi d_C = 1 the whole
    /// model has albedo 1 at every angle. (The (pi - E_avg)
    /// denominator is the same with E_avg scaled by pi and d_C by 1/pi.)
    EnergyCoupled {
        /// E_C on [`ALBEDO_NODES`] uniform theta nodes, per channel.
        albedo: [Vec<f32>; 3],
        /// Eavg_C.
        average: [f32; 3],
    },
    /// Oren-Nayar's qualitative rough-diffuse factor: b = A + B max(0,
    /// cos(phi_i - phi_o)) sin(alpha) tan(beta), alpha = max(theta_i,
    /// theta_o), beta = min, A = 1 - sigma^2 / (2 (sigma^2 + 0.33)), B =
    /// 0.45 sigma^2 / (sigma^2 + 0.09); sigma (radians) shared by the
    /// channels.
    OrenNayar {
        /// Facet slope deviation (radians).
        sigma: f32,
    },
    /// A reciprocal separable factor b = P(theta_i) P(theta_o), one table P
    /// shared by the channels, linear between uniform nodes spanning [0,
    /// pi/2] inclusively (Lambert when P = 1). It represents
    /// Ashikhmin-Shirley-type coupled diffuse, whose factor is (1 - (1 -
    /// cos/2)^5) at each direction, exactly. Fitted inside AWLS (its nodes
    /// by the cubic rule of the G update); the fit keeps 2 int P(mu) mu dmu
    /// = 1, so pi d_C P(theta_o) is the term's directional albedo.
    Separable {
        /// P on [`SEPARABLE_NODES`] (or as many as the file holds, >= 2)
        /// uniform theta nodes.
        p: Vec<f32>,
    },
}

/// Nodes of the separable diffuse factor's table P (6 degrees apart).
pub const SEPARABLE_NODES: usize = 16;

impl DiffuseForm {
    /// Whether this is the Lambertian form.
    pub fn is_lambert(&self) -> bool {
        *self == DiffuseForm::Lambert
    }

    /// The form's short name (as the CLI and reports spell it).
    pub fn name(&self) -> &'static str {
        match self {
            DiffuseForm::Lambert => "lambert",
            DiffuseForm::EnergyCoupled { .. } => "energy-coupled",
            DiffuseForm::OrenNayar { .. } => "oren-nayar",
            DiffuseForm::Separable { .. } => "separable",
        }
    }

    /// The values the form adds to the model's parameters (P's nodes for
    /// the separable form; the others have none the sweep updates).
    pub fn param_count(&self) -> usize {
        match self {
            DiffuseForm::Separable { p } => p.len(),
            _ => 0,
        }
    }

    /// b_C for elevations theta_i, theta_o (radians, above the horizon) and
    /// the cosine of the azimuth difference.
    #[inline]
    pub fn factor(&self, theta_i: f64, theta_o: f64, cos_dphi: f64) -> [f64; 3] {
        match self {
            DiffuseForm::Lambert => [1.0; 3],
            DiffuseForm::EnergyCoupled { albedo, average } => std::array::from_fn(|c| {
                let t = &albedo[c];
                let (ei, eo) = (table_at(t, theta_i), table_at(t, theta_o));
                (1.0 - ei) * (1.0 - eo) / (1.0 - average[c] as f64).max(1e-3)
            }),
            DiffuseForm::OrenNayar { sigma } => {
                [oren_nayar(*sigma as f64, theta_i, theta_o, cos_dphi); 3]
            }
            DiffuseForm::Separable { p } => [table_at(p, theta_i) * table_at(p, theta_o); 3],
        }
    }

    /// True when [`DiffuseForm::factor`] reads its azimuth argument.
    pub(crate) fn reads_azimuth(&self) -> bool {
        matches!(self, DiffuseForm::OrenNayar { .. })
    }

    fn validate(&self) -> Result<(), ModelError> {
        match self {
            DiffuseForm::Lambert => Ok(()),
            DiffuseForm::EnergyCoupled { albedo, average } => {
                for (c, t) in albedo.iter().enumerate() {
                    if t.len() < 2 {
                        return Err(ModelError::TableSize {
                            table: format!("diffuse albedo channel {c}"),
                            got: t.len(),
                            expected: ALBEDO_NODES,
                        });
                    }
                }
                let ok = |v: f32| v.is_finite() && (0.0..=1.0).contains(&v);
                if albedo.iter().flatten().chain(average).all(|&v| ok(v)) {
                    Ok(())
                } else {
                    Err(ModelError::DiffuseForm(
                        "energy-coupled albedo values must lie in [0, 1]".into(),
                    ))
                }
            }
            DiffuseForm::OrenNayar { sigma } => {
                if sigma.is_finite() && *sigma >= 0.0 {
                    Ok(())
                } else {
                    Err(ModelError::DiffuseForm(format!(
                        "Oren-Nayar sigma must be finite and >= 0, got {sigma}"
                    )))
                }
            }
            DiffuseForm::Separable { p } => {
                if p.len() < 2 {
                    return Err(ModelError::TableSize {
                        table: "separable diffuse P".into(),
                        got: p.len(),
                        expected: SEPARABLE_NODES,
                    });
                }
                if p.iter().all(|v| v.is_finite() && *v >= 0.0) {
                    Ok(())
                } else {
                    Err(ModelError::DiffuseForm(
                        "separable P values must be finite and >= 0".into(),
                    ))
                }
            }
        }
    }
}

/// 2 int_0^1 P(mu) mu dmu = int_0^{pi/2} P(theta) sin(2 theta) dtheta for
/// P linear between uniform nodes over [0, pi/2], exactly (per interval,
/// the integrals of sin(2t) and t sin(2t) in closed form).
pub fn separable_mean(p: &[f32]) -> f64 {
    let h = std::f64::consts::FRAC_PI_2 / (p.len() - 1) as f64;
    // int sin 2t = -cos(2t)/2; int t sin 2t = -t cos(2t)/2 + sin(2t)/4.
    let i0 = |t: f64| -0.5 * (2.0 * t).cos();
    let i1 = |t: f64| -0.5 * t * (2.0 * t).cos() + 0.25 * (2.0 * t).sin();
    let mut sum = 0.0;
    for k in 0..p.len() - 1 {
        let (a, b) = (k as f64 * h, (k + 1) as f64 * h);
        // P = p_k + (p_{k+1} - p_k) (t - a) / h on [a, b].
        let slope = (p[k + 1] as f64 - p[k] as f64) / h;
        let base = p[k] as f64 - slope * a;
        sum += base * (i0(b) - i0(a)) + slope * (i1(b) - i1(a));
    }
    sum
}

/// Linear interpolation of a table on uniform theta nodes over [0, pi/2].
#[inline]
pub(crate) fn table_at(t: &[f32], theta: f64) -> f64 {
    let x = (theta / std::f64::consts::FRAC_PI_2).clamp(0.0, 1.0) * (t.len() - 1) as f64;
    let k = (x as usize).min(t.len() - 2);
    let u = x - k as f64;
    t[k] as f64 * (1.0 - u) + t[k + 1] as f64 * u
}

/// Oren-Nayar's qualitative factor (see [`DiffuseForm::OrenNayar`]).
#[inline]
pub fn oren_nayar(sigma: f64, theta_i: f64, theta_o: f64, cos_dphi: f64) -> f64 {
    let s2 = sigma * sigma;
    let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
    let b = 0.45 * s2 / (s2 + 0.09);
    let (alpha, beta) = (theta_i.max(theta_o), theta_i.min(theta_o));
    a + b * cos_dphi.max(0.0) * alpha.sin() * beta.tan()
}

/// How a lobe's masking-shadowing combines its tabulated G of the two
/// directions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Masking {
    /// G(theta_i) G(theta_o): the paper's separable (uncorrelated) form.
    #[default]
    Separable,
    /// Height-correlated Smith: G2 = 1 / (1 + Lambda(theta_i) +
    /// Lambda(theta_o)) with Lambda = 1 / G - 1 from the tabulated G taken
    /// as G1 (clamped to [0, 1]), i.e. G2 = Gi Go / (Gi + Go - Gi Go).
    /// G's scale is then no longer traded with s: G is a true G1 <= 1.
    HeightCorrelated,
}

impl Masking {
    /// Whether this is the separable form (what older files hold).
    pub fn is_separable(&self) -> bool {
        *self == Masking::Separable
    }

    /// The short name (as the CLI spells it).
    pub fn name(&self) -> &'static str {
        match self {
            Masking::Separable => "separable",
            Masking::HeightCorrelated => "height-correlated",
        }
    }

    /// The lobe's masking-shadowing from its G values at the two directions.
    #[inline]
    pub fn product(self, gi: f64, go: f64) -> f64 {
        match self {
            Masking::Separable => gi * go,
            Masking::HeightCorrelated => height_correlated(gi, go),
        }
    }
}

/// G2 = 1 / (1 + Lambda_i + Lambda_o) with Lambda = 1 / G1 - 1, G1 clamped
/// to [0, 1]; 0 when either G1 is 0 (the horizon).
#[inline]
pub fn height_correlated(gi: f64, go: f64) -> f64 {
    let (a, b) = (gi.clamp(0.0, 1.0), go.clamp(0.0, 1.0));
    if a <= 0.0 || b <= 0.0 {
        0.0
    } else {
        a * b / (a + b - a * b)
    }
}

/// Kulla-Conty's multiple-scattering term of a model's own lobes (seed
/// `001`; [`crate::energy::coupled::multiple_scattering`]): f_ms,C =
/// scale_C (1 - E_C(theta_i)) (1 - E_C(theta_o)) / (1 - Eavg_C), E_C the
/// lobes' directional albedo with F = 1, clamped to [0, 1]. Added to the
/// model's value when present; with F = 1 and no diffuse term the
/// compensated model then reflects all it receives (white furnace).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Compensation {
    /// E_C on uniform theta nodes over [0, pi/2] (linear between), per channel.
    pub albedo: [Vec<f32>; 3],
    /// Eavg_C = 2 int E_C(mu) mu dmu.
    pub average: [f32; 3],
    /// Per-channel scale: Kulla-Conty's colour factor over pi.
    pub scale: [f32; 3],
}

impl Compensation {
    /// f_ms per channel at elevations theta_i, theta_o (radians).
    #[inline]
    pub fn value(&self, theta_i: f64, theta_o: f64) -> [f64; 3] {
        std::array::from_fn(|c| {
            let t = &self.albedo[c];
            let (ei, eo) = (table_at(t, theta_i), table_at(t, theta_o));
            self.scale[c] as f64 * (1.0 - ei) * (1.0 - eo)
                / (1.0 - self.average[c] as f64).max(1e-3)
        })
    }

    /// f_ms's directional albedo at theta_o: pi scale (1 - E(theta_o))
    /// (the integral of (1 - E) cos over the hemisphere is pi (1 - Eavg),
    /// which cancels the denominator).
    pub fn albedo_at(&self, theta_o: f64) -> [f64; 3] {
        std::array::from_fn(|c| {
            std::f64::consts::PI * self.scale[c] as f64 * (1.0 - table_at(&self.albedo[c], theta_o))
        })
    }

    fn validate(&self) -> Result<(), ModelError> {
        let ok = |v: f32| v.is_finite() && (0.0..=1.0).contains(&v);
        if self.albedo.iter().any(|t| t.len() < 2)
            || !self
                .albedo
                .iter()
                .flatten()
                .chain(&self.average)
                .all(|&v| ok(v))
            || !self.scale.iter().all(|v| v.is_finite() && *v >= 0.0)
        {
            return Err(ModelError::DiffuseForm(
                "compensation tables need >= 2 nodes with values in [0, 1] and a non-negative scale"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// A fitted model: layout, diffuse term, Fresnel tables and lobes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Where every table's nodes sit.
    pub layout: Layout,
    /// Diffuse scale d_C (1/sr); the term is d_C times the form's factor.
    pub diffuse: [f32; 3],
    /// The diffuse term's directional form (absent in older files and not
    /// written for Lambertian models, whose JSON is what it always was).
    #[serde(default, skip_serializing_if = "DiffuseForm::is_lambert")]
    pub diffuse_form: DiffuseForm,
    /// How each lobe combines G at the two directions (absent: separable).
    #[serde(default, skip_serializing_if = "Masking::is_separable")]
    pub masking: Masking,
    /// Kulla-Conty multiple scattering added to the value (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compensation: Option<Compensation>,
    /// F_C(theta_d), one table per channel.
    pub fresnel: [Vec<f32>; 3],
    /// The specular lobes.
    pub lobes: Vec<Lobe>,
}

/// G's interpolation at one elevation ([`Model::eval_half_diff`]): on a
/// Catmull-Rom axis the interval and weights [`catmull_rom_stencil`]
/// would put in its slots, without building the stencil.
///
/// [`catmull_rom_stencil`]: crate::grid::catmull_rom_stencil
enum GAt {
    CatmullRom { i: usize, w: [f64; 4], n: usize },
    Stencil(Stencil),
}

impl GAt {
    /// [`Stencil::apply_f32`] of the stencil: the slots in order, zero
    /// weights and nodes off the axis skipped, so the same bits.
    #[inline(always)]
    fn apply_f32(&self, values: &[f32]) -> f64 {
        match self {
            GAt::CatmullRom { i, w, n } => {
                let mut s = 0.0;
                for (k, &wk) in w.iter().enumerate() {
                    let j = (*i + k).wrapping_sub(1);
                    if wk != 0.0 && j < *n {
                        s += wk * values[j] as f64;
                    }
                }
                s
            }
            GAt::Stencil(st) => st.apply_f32(values),
        }
    }
}

impl Model {
    /// Number of specular lobes.
    pub fn lobe_count(&self) -> usize {
        self.lobes.len()
    }

    /// Number of parameters ([`Layout::param_count`]).
    pub fn param_count(&self) -> usize {
        self.layout.param_count(self.lobes.len())
    }

    /// All parameters in file order: d (3), then per lobe s (3), then per lobe
    /// D, then per lobe G, then F_R, F_G, F_B.
    pub fn params(&self) -> Vec<f32> {
        let mut p = Vec::with_capacity(self.param_count());
        p.extend(self.diffuse);
        for l in &self.lobes {
            p.extend(l.s);
        }
        for l in &self.lobes {
            p.extend(&l.d);
        }
        for l in &self.lobes {
            p.extend(&l.g);
        }
        for f in &self.fresnel {
            p.extend(f);
        }
        p
    }

    /// Inverse of [`Model::params`].
    pub fn from_params(layout: Layout, lobes: usize, p: &[f32]) -> Result<Self, ModelError> {
        layout.validate()?;
        let expected = layout.param_count(lobes);
        if p.len() != expected {
            return Err(ModelError::ParamCount {
                got: p.len(),
                lobes,
                expected,
            });
        }
        let (nd, ng, nf) = (layout.d.len(), layout.g.len(), layout.f.len());
        let mut it = p.iter().copied();
        let mut take = |n: usize| -> Vec<f32> { it.by_ref().take(n).collect() };
        let three = |v: Vec<f32>| [v[0], v[1], v[2]];
        let diffuse = three(take(3));
        let s: Vec<[f32; 3]> = (0..lobes).map(|_| three(take(3))).collect();
        let d: Vec<Vec<f32>> = (0..lobes).map(|_| take(nd)).collect();
        let g: Vec<Vec<f32>> = (0..lobes).map(|_| take(ng)).collect();
        let fresnel = [take(nf), take(nf), take(nf)];
        let lobes = s
            .into_iter()
            .zip(d)
            .zip(g)
            .map(|((s, d), g)| Lobe { s, d, g })
            .collect();
        let m = Model {
            layout,
            diffuse,
            diffuse_form: DiffuseForm::Lambert,
            masking: Masking::Separable,
            compensation: None,
            fresnel,
            lobes,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks table sizes and that every parameter is finite; factor tables
    /// may not be negative.
    pub fn validate(&self) -> Result<(), ModelError> {
        let l = &self.layout;
        l.validate()?;
        if self.lobes.is_empty() || self.lobes.len() > u8::MAX as usize {
            return Err(ModelError::Lobes(self.lobes.len()));
        }
        let size = |table: String, got: usize, expected: usize| {
            if got == expected {
                Ok(())
            } else {
                Err(ModelError::TableSize {
                    table,
                    got,
                    expected,
                })
            }
        };
        for (c, f) in self.fresnel.iter().enumerate() {
            size(format!("F channel {c}"), f.len(), l.f.len())?;
        }
        for (m, lobe) in self.lobes.iter().enumerate() {
            size(format!("lobe {m} D"), lobe.d.len(), l.d.len())?;
            size(format!("lobe {m} G"), lobe.g.len(), l.g.len())?;
        }
        self.diffuse_form.validate()?;
        if let Some(c) = &self.compensation {
            c.validate()?;
        }
        let params = self.params();
        if let Some(i) = params.iter().position(|v| !v.is_finite()) {
            return Err(ModelError::NotFinite(i));
        }
        if self
            .diffuse
            .iter()
            .chain(self.fresnel.iter().flatten())
            .any(|&v| v < 0.0)
            || self
                .lobes
                .iter()
                .any(|l| l.s.iter().chain(&l.d).any(|&v| v < 0.0))
        {
            return Err(ModelError::Negative);
        }
        Ok(())
    }

    /// BRDF value (1/sr) per channel for a configuration; zero when either
    /// direction is at or below the horizon, never negative.
    pub fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        let mut v = self.diffuse_term(a.theta_i, a.theta_o, (a.phi_i - a.phi_o).cos());
        if !self.lobe_terms(a, |_, t| {
            for c in 0..3 {
                v[c] += t[c];
            }
        }) {
            return [0.0; 3];
        }
        // Catmull-Rom G can undershoot below 0 between non-negative control
        // points; a BRDF is never negative. Wherever the fitted (unclamped)
        // value is >= 0 this changes nothing, elsewhere it only moves the
        // value towards any measurement.
        v.map(|x| x.max(0.0))
    }

    /// The diffuse term d_C b_C at elevations theta_i, theta_o and azimuth
    /// difference cosine `cos_dphi` (only Oren-Nayar reads it), plus the
    /// multiple-scattering term when the model is compensated (both are
    /// smooth, cosine-sampled parts of the value).
    #[inline]
    pub fn diffuse_term(&self, theta_i: f64, theta_o: f64, cos_dphi: f64) -> [f64; 3] {
        let d = self.diffuse.map(f64::from);
        let v = if let DiffuseForm::Lambert = self.diffuse_form {
            d
        } else {
            let b = self.diffuse_form.factor(theta_i, theta_o, cos_dphi);
            std::array::from_fn(|c| d[c] * b[c])
        };
        match &self.compensation {
            None => v,
            Some(k) => {
                let ms = k.value(theta_i, theta_o);
                std::array::from_fn(|c| v[c] + ms[c])
            }
        }
    }

    /// The diffuse term's directional albedo (integral of d_C b_C cos
    /// theta_i) at view angle theta_o: exact for the Lambertian, separable and
    /// energy-coupled forms, Oren-Nayar's A term only (a lower bound) for
    /// that form; plus the multiple-scattering term's albedo when the model
    /// is compensated. Samplers weigh their diffuse component by it.
    pub fn diffuse_albedo(&self, theta_o: f64) -> [f64; 3] {
        let a = self.diffuse_form_albedo(theta_o);
        match &self.compensation {
            None => a,
            Some(k) => {
                let ms = k.albedo_at(theta_o);
                std::array::from_fn(|c| a[c] + ms[c])
            }
        }
    }

    fn diffuse_form_albedo(&self, theta_o: f64) -> [f64; 3] {
        let d = self.diffuse.map(|v| std::f64::consts::PI * v as f64);
        match &self.diffuse_form {
            DiffuseForm::Lambert => d,
            DiffuseForm::EnergyCoupled { albedo, .. } => {
                std::array::from_fn(|c| d[c] * (1.0 - table_at(&albedo[c], theta_o)))
            }
            DiffuseForm::OrenNayar { sigma } => {
                let s2 = (*sigma as f64).powi(2);
                d.map(|v| v * (1.0 - 0.5 * s2 / (s2 + 0.33)))
            }
            DiffuseForm::Separable { p } => {
                let k = table_at(p, theta_o) * separable_mean(p);
                d.map(|v| v * k)
            }
        }
    }

    /// The specular terms s_C^m F_C D^m G^m G^m / (cos theta_i cos theta_o)
    /// of a configuration, unclamped, handed to `term(m, value)` lobe by
    /// lobe: what [`Model::eval_angles`] sums (with d_C, then clamps), and
    /// what a sampler weighs its lobes by. Returns false (calling nothing)
    /// when either direction is at or below the horizon.
    pub fn lobe_terms(&self, a: &Angles, term: impl FnMut(usize, [f64; 3])) -> bool {
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if ci <= 0.0 || co <= 0.0 {
            return false;
        }
        self.terms_with_cosines(a, ci, co, term);
        true
    }

    /// [`Model::lobe_terms`] with the cosines of theta_i and theta_o given
    /// (both positive).
    #[inline]
    fn terms_with_cosines(&self, a: &Angles, ci: f64, co: f64, term: impl FnMut(usize, [f64; 3])) {
        let l = &self.layout;
        let (ds, fs) = (l.d_stencil(a), l.f_stencil(a));
        let f = [
            fs.apply_f32(&self.fresnel[0]),
            fs.apply_f32(&self.fresnel[1]),
            fs.apply_f32(&self.fresnel[2]),
        ];
        let (gis, gos) = (
            l.g_stencil(a.theta_i, a.phi_i),
            l.g_stencil(a.theta_o, a.phi_o),
        );
        self.terms_with_factors(
            (|g: &[f32]| gis.apply_f32(g), |g: &[f32]| gos.apply_f32(g)),
            ci * co,
            f,
            |m| ds.apply_f32(&self.lobes[m].d),
            term,
        );
    }

    /// The lobe terms from G at the two directions (of a lobe's G
    /// values), cos theta_i cos theta_o, the F values and each lobe's D value.
    #[inline(always)]
    fn terms_with_factors(
        &self,
        (gi, go): (impl Fn(&[f32]) -> f64, impl Fn(&[f32]) -> f64),
        cos_product: f64,
        f: [f64; 3],
        d: impl Fn(usize) -> f64,
        mut term: impl FnMut(usize, [f64; 3]),
    ) {
        let masking = self.masking;
        for (m, lobe) in self.lobes.iter().enumerate() {
            let g = masking.product(gi(&lobe.g), go(&lobe.g));
            let spec = d(m) * g / cos_product;
            term(m, std::array::from_fn(|c| lobe.s[c] as f64 * f[c] * spec));
        }
    }

    /// An isotropic model's F values and each lobe's D value at (theta_h,
    /// theta_d) (phi_h, phi_d are not read): what every cell of a table row
    /// of that theta_h and theta_d shares, for [`Model::eval_half_diff`].
    ///
    /// # Panics
    /// If `d` is not one value per lobe.
    pub(crate) fn half_diff_factors(&self, theta_h: f64, theta_d: f64, d: &mut [f64]) -> [f64; 3] {
        debug_assert!(self.layout.is_isotropic());
        let (ds, fs) = (
            self.layout.d.stencil(theta_h, 0.0),
            self.layout.f.stencil(theta_d, 0.0),
        );
        for (d, lobe) in d.iter_mut().zip(&self.lobes) {
            *d = ds.apply_f32(&lobe.d);
        }
        std::array::from_fn(|c| fs.apply_f32(&self.fresnel[c]))
    }

    /// G's interpolation at elevation `theta` on a 1-D G grid.
    #[inline(always)]
    fn g_at(&self, theta: f64) -> GAt {
        let axis = self.layout.g.theta;
        match axis {
            Axis::CatmullRom { n } => {
                let (i, w) = catmull_rom_weights(axis.coord(theta), n);
                GAt::CatmullRom { i, w, n }
            }
            _ => GAt::Stencil(self.layout.g.stencil(theta, 0.0)),
        }
    }

    /// [`Model::eval_angles`] of an isotropic model from its row factors
    /// ([`Model::half_diff_factors`] at the configuration's theta_h and
    /// theta_d), theta_i, theta_o, their cosines (`theta.cos()`) and the
    /// azimuth difference's cosine (read by the Oren-Nayar form only): the
    /// same arithmetic, so the same bits.
    #[inline]
    pub(crate) fn eval_half_diff(
        &self,
        (f, d): ([f64; 3], &[f64]),
        (theta_i, theta_o): (f64, f64),
        (ci, co): (f64, f64),
        cos_dphi: f64,
    ) -> [f64; 3] {
        let mut v = self.diffuse_term(theta_i, theta_o, cos_dphi);
        if ci <= 0.0 || co <= 0.0 {
            return [0.0; 3];
        }
        let (gi, go) = (self.g_at(theta_i), self.g_at(theta_o));
        self.terms_with_factors(
            (|g: &[f32]| gi.apply_f32(g), |g: &[f32]| go.apply_f32(g)),
            ci * co,
            f,
            |m| d[m],
            |_, t| {
                for c in 0..3 {
                    v[c] += t[c];
                }
            },
        );
        v.map(|x| x.max(0.0))
    }

    /// BRDF value for unit directions in the local shading frame (normal
    /// +z), pbrt's argument order: outgoing (view) direction first. The
    /// model is reciprocal, so the order changes no value.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        if !self.layout.is_isotropic() {
            return self.eval_angles(&Angles::from_directions(wi, wo));
        }
        // Isotropic tables read only the four elevations, so skip the
        // azimuths and rotations of the full Rusinkiewicz map: theta_h from
        // h = (wi + wo) / |wi + wo|, cos theta_d = wi.h, and the cosines of
        // theta_i and theta_o are the z components (the same angles to
        // rounding; tests/sampling_bxdf.rs compares both paths).
        // h.z = s.z / |s| exactly as the full map computes it: near the
        // mirror direction acos amplifies any rounding of h.z.
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let acos = |c: f64| c.clamp(-1.0, 1.0).acos();
        let a = Angles {
            theta_h: acos(s[2] / n),
            phi_h: 0.0,
            theta_d: acos((wi[0] * s[0] + wi[1] * s[1] + wi[2] * s[2]) / n),
            phi_d: 0.0,
            theta_i: acos(wi[2]),
            phi_i: 0.0,
            theta_o: acos(wo[2]),
            phi_o: 0.0,
        };
        let cos_dphi = {
            let (xi, xo) = (wi[0].hypot(wi[1]), wo[0].hypot(wo[1]));
            if xi > 0.0 && xo > 0.0 {
                (wi[0] * wo[0] + wi[1] * wo[1]) / (xi * xo)
            } else {
                1.0
            }
        };
        let mut v = self.diffuse_term(a.theta_i, a.theta_o, cos_dphi);
        self.terms_with_cosines(&a, wi[2].min(1.0), wo[2].min(1.0), |_, t| {
            for c in 0..3 {
                v[c] += t[c];
            }
        });
        v.map(|x| x.max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn toy(lobes: usize) -> Model {
        let layout = Layout::isotropic(90);
        let n = 90;
        Model {
            layout,
            diffuse: [0.1, 0.2, 0.3],
            diffuse_form: Default::default(),
            masking: Default::default(),
            compensation: None,
            fresnel: [vec![1.0; n], vec![0.5; n], vec![0.25; n]],
            lobes: (0..lobes)
                .map(|m| Lobe {
                    s: [1.0, 2.0, 3.0],
                    d: vec![m as f32 + 1.0; n],
                    g: vec![0.9; n],
                })
                .collect(),
        }
    }

    #[test]
    fn parameter_counts_match_the_paper() {
        assert_eq!(toy(3).param_count(), 822);
        assert_eq!(toy(3).params().len(), 822);
        assert_eq!(Layout::isotropic(90).param_count(1), 3 + 3 + 90 * 5);
    }

    #[test]
    fn params_round_trip() {
        let m = toy(2);
        let back = Model::from_params(m.layout, 2, &m.params()).unwrap();
        assert_eq!(m, back);
    }

    #[test]
    fn below_horizon_is_zero_and_reciprocal_above() {
        let m = toy(3);
        let wi = [0.3, 0.1, (1.0f64 - 0.1).sqrt()];
        let wo = [-0.5, 0.2, (1.0f64 - 0.29).sqrt()];
        let (a, b) = (m.eval(wo, wi), m.eval(wi, wo));
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-12 * a[c]);
        }
        assert_eq!(m.eval(wo, [0.0, 1.0, -0.1]), [0.0; 3]);
    }

    #[test]
    fn anisotropic_layout_has_2010_parameters_and_depends_on_phi() {
        let layout = Layout::anisotropic();
        assert!(!layout.is_isotropic() && Layout::default().is_isotropic());
        assert_eq!(layout.param_count(3), 2010);
        let (nd, ng, nf) = (layout.d.len(), layout.g.len(), layout.f.len());
        let mut m = Model {
            layout,
            diffuse: [0.1; 3],
            diffuse_form: Default::default(),
            masking: Default::default(),
            compensation: None,
            fresnel: [vec![1.0; nf], vec![1.0; nf], vec![1.0; nf]],
            lobes: vec![Lobe {
                s: [1.0; 3],
                d: (0..nd).map(|k| 1.0 + (k % 48) as f32).collect(),
                g: vec![0.9; ng],
            }],
        };
        assert!(m.validate().is_ok());
        let back = Model::from_params(layout, 1, &m.params()).unwrap();
        assert_eq!(back, m);
        let wi = [0.3, 0.1, (1.0f64 - 0.1).sqrt()];
        let wo = [-0.5, 0.2, (1.0f64 - 0.29).sqrt()];
        let rot = |v: [f64; 3], a: f64| {
            [
                v[0] * a.cos() - v[1] * a.sin(),
                v[0] * a.sin() + v[1] * a.cos(),
                v[2],
            ]
        };
        let (a, b) = (m.eval(wo, wi), m.eval(rot(wo, 1.0), rot(wi, 1.0)));
        assert!((a[0] - b[0]).abs() > 1e-3 * a[0], "{a:?} {b:?}");
        let (x, y) = (m.eval(wo, wi), m.eval(wi, wo));
        assert!((x[0] - y[0]).abs() < 1e-12 * x[0]);
        m.lobes[0].g.pop();
        assert!(matches!(m.validate(), Err(ModelError::TableSize { .. })));
    }
}
