//! A flat copy of an isotropic model for fast evaluation ([`FlatEval`]):
//! the same interpolation and arithmetic as [`Model::eval`], with the
//! tables as f64 rows holding every lobe side by side (one stencil serves
//! all lobes), stencils built inline, no allocation, and an inlined
//! `acos` ([`acos`]) in place of the C library's.
//!
//! It exists for throughput (renderers call eval and pdf billions of
//! times); `Model::eval` stays the model's definition, and
//! `tests/sampling_bxdf.rs` checks the two agree to 1e-9 relative.

use crate::grid::axis::{catmull_rom_weights, linear_weights};
use crate::grid::Axis;
use crate::model::Model;
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::FRAC_PI_2;

/// Lobes the flat evaluator holds side by side (models with more fall back
/// to [`Model::eval`]).
pub const FLAT_LOBES: usize = 4;

/// Rows of zeros before each table, so every stencil reads four rows from
/// its base without bounds cases (a Catmull-Rom stencil starts one node
/// before its interval).
const PAD_BEFORE: usize = 1;
/// Rows of zeros after each table (a linear stencil at the last node reads
/// three rows past it, with weight 0).
const PAD_AFTER: usize = 3;

/// One factor's table on its axis: `rows[PAD_BEFORE + k][lane]` is node k
/// of lane `lane` (a lobe for D and G, a channel for F).
#[derive(Clone, Debug)]
struct FlatTable {
    axis: Axis,
    rows: Vec<[f64; FLAT_LOBES]>,
}

impl FlatTable {
    fn new(axis: Axis, lanes: &[&[f32]]) -> Self {
        let n = axis.len();
        let mut rows = vec![[0.0; FLAT_LOBES]; PAD_BEFORE + n + PAD_AFTER];
        for (lane, values) in lanes.iter().enumerate() {
            for (k, &v) in values.iter().enumerate() {
                rows[PAD_BEFORE + k][lane] = v as f64;
            }
        }
        FlatTable { axis, rows }
    }

    /// The interpolated value of every lane at angle theta: exactly
    /// `axis.stencil(theta).apply_f32(lane)` (the same weights, summed in
    /// the same slot order; unused slots have weight 0 on finite values).
    #[inline(always)]
    fn eval(&self, theta: f64) -> [f64; FLAT_LOBES] {
        let (base, w) = stencil(self.axis, theta);
        let r = &self.rows[base..base + 4];
        let mut out = [0.0; FLAT_LOBES];
        for (l, o) in out.iter_mut().enumerate() {
            *o = w[0] * r[0][l] + w[1] * r[1][l] + w[2] * r[2][l] + w[3] * r[3][l];
        }
        out
    }
}

/// The stencil of `axis` at theta as (first padded row, four weights):
/// the same nodes and weights as `Axis::stencil` (`grid::axis`).
#[inline(always)]
fn stencil(axis: Axis, theta: f64) -> (usize, [f64; 4]) {
    let x = (theta / FRAC_PI_2).clamp(0.0, 1.0);
    match axis {
        Axis::SqrtAngle { n } => linear(x.sqrt() * n as f64, n),
        Axis::Uniform { n } => linear(x * n as f64, n),
        Axis::Squared { n } => linear(axis.coord(theta), n),
        Axis::CatmullRom { n } => catmull_rom(x * (n - 1) as f64, n),
    }
}

/// `grid::axis`'s linear stencil, as (base, weights).
#[inline(always)]
fn linear(p: f64, n: usize) -> (usize, [f64; 4]) {
    let (i, w0, w1) = linear_weights(p, n);
    (PAD_BEFORE + i, [w0, w1, 0.0, 0.0])
}

/// `grid::axis`'s Catmull-Rom stencil, as (base, weights): slot k is node
/// i - 1 + k (the padding row before node 0 for k = 0 at i = 0).
#[inline(always)]
fn catmull_rom(p: f64, n: usize) -> (usize, [f64; 4]) {
    let (i, w) = catmull_rom_weights(p, n);
    (PAD_BEFORE + i - 1, w)
}

/// An isotropic model with at most [`FLAT_LOBES`] lobes, flattened for
/// [`FlatEval::eval`].
#[derive(Clone, Debug)]
pub struct FlatEval {
    lobes: usize,
    diffuse: [f64; 3],
    /// s[m][c] as f64.
    s: [[f64; 3]; FLAT_LOBES],
    d: FlatTable,
    g: FlatTable,
    f: FlatTable,
}

impl FlatEval {
    /// The flat copy of a (valid) model, or `None` when it is anisotropic,
    /// has more than [`FLAT_LOBES`] lobes, a non-Lambertian diffuse form,
    /// height-correlated masking or a compensation term.
    pub fn new(model: &Model) -> Option<Self> {
        let l = &model.layout;
        // Only the paper's plain form is flattened; the options go through Model::eval.
        let lambert = matches!(model.diffuse_form, crate::model::DiffuseForm::Lambert)
            && model.masking.is_separable()
            && model.compensation.is_none();
        if !lambert || !l.is_isotropic() || model.lobes.is_empty() || model.lobes.len() > FLAT_LOBES
        {
            return None;
        }
        if l.g.theta.len() < 2 {
            return None;
        }
        let d: Vec<&[f32]> = model.lobes.iter().map(|b| b.d.as_slice()).collect();
        let g: Vec<&[f32]> = model.lobes.iter().map(|b| b.g.as_slice()).collect();
        let f: Vec<&[f32]> = model.fresnel.iter().map(|v| v.as_slice()).collect();
        let mut s = [[0.0; 3]; FLAT_LOBES];
        for (m, lobe) in model.lobes.iter().enumerate() {
            s[m] = lobe.s.map(f64::from);
        }
        Some(FlatEval {
            lobes: model.lobes.len(),
            diffuse: model.diffuse.map(f64::from),
            s,
            d: FlatTable::new(l.d.theta, &d),
            g: FlatTable::new(l.g.theta, &g),
            f: FlatTable::new(l.f.theta, &f),
        })
    }

    /// Heap bytes of the flat tables.
    pub fn table_bytes(&self) -> usize {
        8 * FLAT_LOBES * (self.d.rows.len() + self.g.rows.len() + self.f.rows.len())
    }

    /// [`Model::eval`] of the model this was built from: the same angles
    /// (theta_h from `h.z = s.z / |s|`, cos theta_d = wi.h, the z
    /// components), stencils, products and sums in the same order; only
    /// [`acos`] differs from the C library's, by at most an ulp or so.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        self.eval_body(wo, wi)
    }

    #[inline(always)]
    fn eval_body(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        if !(wi[2] > 0.0 && wo[2] > 0.0) {
            return [0.0; 3];
        }
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let [theta_h, theta_d, theta_i, theta_o] = acos4(
            [
                s[2] / n,
                (wi[0] * s[0] + wi[1] * s[1] + wi[2] * s[2]) / n,
                wi[2],
                wo[2],
            ]
            .map(|c| c.clamp(0.0, 1.0)),
        );
        let (ci, co) = (wi[2].min(1.0), wo[2].min(1.0));
        let d = self.d.eval(theta_h);
        let gi = self.g.eval(theta_i);
        let go = self.g.eval(theta_o);
        let f = self.f.eval(theta_d);
        let mut v = self.diffuse;
        let inv_cc = 1.0 / (ci * co);
        for m in 0..self.lobes {
            let spec = d[m] * gi[m] * go[m] * inv_cc;
            for c in 0..3 {
                v[c] += self.s[m][c] * f[c] * spec;
            }
        }
        v.map(|x| x.max(0.0))
    }
}

const PIO2_HI: f64 = 1.570_796_326_794_896_558_00e+00;
const PIO2_LO: f64 = 6.123_233_995_736_766_035_87e-17;
const PS0: f64 = 1.666_666_666_666_666_574_15e-01;
const PS1: f64 = -3.255_658_186_224_009_154_05e-01;
const PS2: f64 = 2.012_125_321_348_629_258_81e-01;
const PS3: f64 = -4.005_553_450_067_941_140_27e-02;
const PS4: f64 = 7.915_349_942_898_145_321_76e-04;
const PS5: f64 = 3.479_331_075_960_211_675_70e-05;
const QS1: f64 = -2.403_394_911_734_414_218_78e+00;
const QS2: f64 = 2.020_945_760_233_505_694_71e+00;
const QS3: f64 = -6.882_839_716_054_532_930_30e-01;
const QS4: f64 = 7.703_815_055_590_193_527_91e-02;

/// (asin(x) - x) / x^3 as a rational function of z = x^2 (fdlibm's, for
/// x^2 <= 1/4).
#[inline(always)]
fn asin_r(z: f64) -> f64 {
    let p = z * (PS0 + z * (PS1 + z * (PS2 + z * (PS3 + z * (PS4 + z * PS5)))));
    let q = 1.0 + z * (QS1 + z * (QS2 + z * (QS3 + z * QS4)));
    p / q
}

/// arccos by fdlibm's algorithm (Sun's e_acos.c, as musl has it): error
/// below one ulp, so within an ulp or two of the C library's (tested
/// against `f64::acos`), but inlined and a few times cheaper. NaN for
/// |x| > 1 or NaN.
#[inline(always)]
pub fn acos(x: f64) -> f64 {
    let ax = x.abs();
    if !(ax < 1.0) {
        return if x == 1.0 {
            0.0
        } else if x == -1.0 {
            2.0 * PIO2_HI
        } else {
            f64::NAN
        };
    }
    if ax < 0.5 {
        if ax <= f64::from_bits(0x3c60_0000_0000_0000) {
            return PIO2_HI;
        }
        return PIO2_HI - (x - (PIO2_LO - x * asin_r(x * x)));
    }
    if x < 0.0 {
        let z = (1.0 + x) * 0.5;
        let s = z.sqrt();
        let w = asin_r(z) * s - PIO2_LO;
        return 2.0 * (PIO2_HI - (s + w));
    }
    let z = (1.0 - x) * 0.5;
    let s = z.sqrt();
    // s split into a high part with a 32-bit-zero tail, for exactness.
    let df = f64::from_bits(s.to_bits() & 0xffff_ffff_0000_0000);
    let c = (z - df * df) / (s + df);
    let w = asin_r(z) * s + c;
    2.0 * (df + w)
}

/// [`acos`] of four values in [0, 1] at once, without branches (so the
/// lanes vectorise): the same rational approximation, without fdlibm's
/// extra-precision split of the square root (one division less; error a
/// few ulps, tested). Inputs outside [0, 1] must be clamped by the caller.
#[inline(always)]
pub fn acos4(x: [f64; 4]) -> [f64; 4] {
    let mut z = [0.0; 4];
    let mut a = [0.0; 4];
    for k in 0..4 {
        let small = x[k] < 0.5;
        let zl = (1.0 - x[k]) * 0.5;
        z[k] = if small { x[k] * x[k] } else { zl };
        a[k] = if small { x[k] } else { zl.sqrt() };
    }
    let mut out = [0.0; 4];
    for k in 0..4 {
        let w = a[k] * asin_r(z[k]);
        out[k] = if x[k] < 0.5 {
            PIO2_HI - (a[k] - (PIO2_LO - w))
        } else {
            2.0 * (a[k] + w)
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;

    #[test]
    fn acos_is_within_two_ulps_of_the_c_library() {
        let mut worst = 0u64;
        let n = 200_000;
        for k in 0..=n {
            let base = -1.0 + 2.0 * k as f64 / n as f64;
            for x in [base, 1.0 - (k as f64 * 1e-5).powi(3), base * 1e-9] {
                let (a, b) = (acos(x), x.acos());
                let ulps = (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs();
                worst = worst.max(ulps);
            }
        }
        assert!(worst <= 2, "worst {worst} ulps");
        let mut worst4 = 0u64;
        for k in 0..=n {
            let x = k as f64 / n as f64;
            let xs = [
                x,
                (1.0 - (k as f64 * 1e-5).powi(3)).max(0.0),
                x * 1e-9,
                0.5 + x * 1e-6,
            ];
            let a = acos4(xs);
            for (j, &x) in xs.iter().enumerate() {
                let ulps = (a[j].to_bits() as i64 - x.acos().to_bits() as i64).unsigned_abs();
                worst4 = worst4.max(ulps);
            }
        }
        assert!(worst4 <= 4, "acos4: worst {worst4} ulps");
        assert_eq!(
            acos4([1.0, 0.0, 0.5, 1.0]),
            [0.0, PIO2_HI, 0.5f64.acos(), 0.0]
        );
        assert_eq!(acos(1.0), 0.0);
        assert!(acos(1.5).is_nan() && acos(f64::NAN).is_nan());
    }

    #[test]
    fn stencils_match_the_grid_axes() {
        for axis in [
            Axis::SqrtAngle { n: 90 },
            Axis::Uniform { n: 90 },
            Axis::CatmullRom { n: 90 },
            Axis::CatmullRom { n: 2 },
            Axis::Uniform { n: 1 },
        ] {
            let values: Vec<f32> = (0..axis.len()).map(|k| 1.0 + (k * k % 7) as f32).collect();
            let t = FlatTable::new(axis, &[&values]);
            for k in 0..=4000 {
                let theta = k as f64 / 4000.0 * FRAC_PI_2 * 1.01;
                let a = t.eval(theta)[0];
                let b = axis.stencil(theta).apply_f32(&values);
                assert!(
                    (a - b).abs() <= 1e-14 * b.abs().max(1.0),
                    "{axis:?} {theta}"
                );
            }
            // Nodes themselves (the snapped cases).
            for k in 0..axis.len() {
                let theta = axis.node(k);
                assert_eq!(t.eval(theta)[0], axis.stencil(theta).apply_f32(&values));
            }
        }
    }

    #[test]
    fn flat_eval_matches_the_model() {
        let m = known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]);
        let f = FlatEval::new(&m).unwrap();
        let mut worst = 0.0f64;
        for k in 0..20_000 {
            let a = k as f64 * 0.618_033_988_749_895;
            let wo = npf_data_loaders::geometry::spherical((a * 7.1).fract() * 1.55, a * 3.0);
            let wi = npf_data_loaders::geometry::spherical((a * 5.3).fract() * 1.55, a * 1.3);
            let (x, y) = (f.eval(wo, wi), m.eval(wo, wi));
            for c in 0..3 {
                worst = worst.max((x[c] - y[c]).abs() / y[c].abs().max(1e-300));
            }
        }
        assert!(worst <= 1e-9, "worst relative difference {worst}");
    }
}
