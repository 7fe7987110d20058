//! The shared-factor non-parametric microfacet model (Peng, Zheng, Lv):
//!
//! rho_C(wi, wo) = d_C + sum_m s_C^m D^m(theta_h) F_C(theta_d) G^m(theta_i) G^m(theta_o) / (cos theta_i cos theta_o)
//!
//! D^m and G^m are shared by the three channels; F_C, d_C and s_C^m are per
//! channel. Values are BRDF values in 1/sr (MERL's physical units). A model
//! stores its parameters as f32: that is what its files hold, so a model
//! written and read back is the same model, bit for bit.

use crate::interp::{Axis, Stencil};
use npf_data_loaders::geometry::{Angles, Vec3};
use serde::{Deserialize, Serialize};

/// Where the factor tables' nodes sit. The isotropic layout has 1-D tables;
/// an anisotropic layout (D, G over (theta, phi)) adds its own variant here
/// and its own stencils, and the solver, which only sees stencils, is unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// D^m(theta_h).
    pub d: Axis,
    /// F_C(theta_d).
    pub f: Axis,
    /// G^m(theta_i) and G^m(theta_o).
    pub g: Axis,
}

impl Layout {
    /// MERL-aligned layout with `n` values per factor: D on MERL's theta_h
    /// nodes, F on its theta_d nodes, G as Catmull-Rom control points.
    pub fn isotropic(n: usize) -> Self {
        Layout {
            d: Axis::SqrtAngle { n },
            f: Axis::Uniform { n },
            g: Axis::CatmullRom { n },
        }
    }

    pub fn d_stencil(&self, a: &Angles) -> Stencil {
        self.d.stencil(a.theta_h)
    }

    pub fn f_stencil(&self, a: &Angles) -> Stencil {
        self.f.stencil(a.theta_d)
    }

    pub fn g_stencil(&self, theta: f64) -> Stencil {
        self.g.stencil(theta)
    }

    /// Number of parameters of a model with `lobes` specular lobes.
    pub fn param_count(&self, lobes: usize) -> usize {
        3 + 3 * lobes + lobes * (self.d.len() + self.g.len()) + 3 * self.f.len()
    }
}

impl Default for Layout {
    fn default() -> Self {
        Layout::isotropic(90)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lobe {
    /// Per-channel scale s_C.
    pub s: [f32; 3],
    /// D(theta_h) node values.
    pub d: Vec<f32>,
    /// G(theta) control points.
    pub g: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Model {
    pub layout: Layout,
    /// Lambertian term d_C (1/sr).
    pub diffuse: [f32; 3],
    /// F_C(theta_d), one table per channel.
    pub fresnel: [Vec<f32>; 3],
    pub lobes: Vec<Lobe>,
}

impl Model {
    pub fn lobe_count(&self) -> usize {
        self.lobes.len()
    }

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
    pub fn from_params(layout: Layout, lobes: usize, p: &[f32]) -> Result<Self, String> {
        let expected = layout.param_count(lobes);
        if p.len() != expected {
            return Err(format!(
                "{} parameters for {lobes} lobes, expected {expected}",
                p.len()
            ));
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
            fresnel,
            lobes,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks table sizes and that every parameter is finite; factor tables
    /// may not be negative.
    pub fn validate(&self) -> Result<(), String> {
        let l = &self.layout;
        if l.g.len() < 2 {
            return Err("G needs at least two control points".into());
        }
        if l.d.is_empty() || l.f.is_empty() {
            return Err("empty factor table".into());
        }
        if self.lobes.is_empty() {
            return Err("a model needs at least one specular lobe".into());
        }
        for (c, f) in self.fresnel.iter().enumerate() {
            if f.len() != l.f.len() {
                return Err(format!(
                    "F channel {c} has {} values, layout says {}",
                    f.len(),
                    l.f.len()
                ));
            }
        }
        for (m, lobe) in self.lobes.iter().enumerate() {
            if lobe.d.len() != l.d.len() || lobe.g.len() != l.g.len() {
                return Err(format!(
                    "lobe {m}: D/G sizes {}/{} do not match the layout",
                    lobe.d.len(),
                    lobe.g.len()
                ));
            }
        }
        let params = self.params();
        if let Some(i) = params.iter().position(|v| !v.is_finite()) {
            return Err(format!("parameter {i} is not finite"));
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
            return Err("negative d, s, D or F value".into());
        }
        Ok(())
    }

    /// BRDF value (1/sr) per channel for a configuration; zero when either
    /// direction is at or below the horizon, never negative.
    pub fn eval_angles(&self, a: &Angles) -> [f64; 3] {
        let mut v = self.diffuse.map(f64::from);
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

    /// The specular terms s_C^m F_C D^m G^m G^m / (cos theta_i cos theta_o)
    /// of a configuration, unclamped, handed to `term(m, value)` lobe by
    /// lobe: what [`Model::eval_angles`] sums (with d_C, then clamps), and
    /// what a sampler weighs its lobes by. Returns false (calling nothing)
    /// when either direction is at or below the horizon.
    pub fn lobe_terms(&self, a: &Angles, mut term: impl FnMut(usize, [f64; 3])) -> bool {
        let (ci, co) = (a.theta_i.cos(), a.theta_o.cos());
        if ci <= 0.0 || co <= 0.0 {
            return false;
        }
        let l = &self.layout;
        let (ds, fs) = (l.d_stencil(a), l.f_stencil(a));
        let (gis, gos) = (l.g_stencil(a.theta_i), l.g_stencil(a.theta_o));
        let f = [
            fs.apply_f32(&self.fresnel[0]),
            fs.apply_f32(&self.fresnel[1]),
            fs.apply_f32(&self.fresnel[2]),
        ];
        for (m, lobe) in self.lobes.iter().enumerate() {
            let spec =
                ds.apply_f32(&lobe.d) * gis.apply_f32(&lobe.g) * gos.apply_f32(&lobe.g) / (ci * co);
            term(m, std::array::from_fn(|c| lobe.s[c] as f64 * f[c] * spec));
        }
        true
    }

    /// BRDF value for unit directions in the local shading frame (normal +z).
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        self.eval_angles(&Angles::from_directions(wi, wo))
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
        let (a, b) = (m.eval(wi, wo), m.eval(wo, wi));
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-12 * a[c]);
        }
        assert_eq!(m.eval([0.0, 1.0, -0.1], wo), [0.0; 3]);
    }
}
