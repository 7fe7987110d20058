//! A flat copy of an isotropic model for fast evaluation ([`FlatEval`]):
//! the same interpolation as [`Model::eval`] (equal to rounding), with the
//! tables as f64 rows holding every lobe side by side (one stencil serves
//! all lobes), the arithmetic in SSE2 lane pairs ([`F64x2`]), stencils
//! built inline, no allocation, and a branch-free arccosine ([`acos2`])
//! in place of the C library's.
//!
//! It exists for throughput (renderers call eval and pdf billions of
//! times); `Model::eval` stays the model's definition, and
//! `tests/sampling_bxdf.rs` checks the two agree to 1e-9 relative.

// fdlibm's coefficients are kept digit for digit as published (each rounds
// to the f64 it names), so they can be checked against the source.
#![allow(clippy::excessive_precision)]

use super::f64x2::{floor_index, F64x2};
use super::lanes::{F64x2x2, Lanes, Lanes4};
use crate::grid::axis::{linear_weights, SNAP};
use crate::grid::Axis;
use crate::model::Model;
use npf_data_loaders::geometry::Vec3;
use std::f64::consts::FRAC_2_PI;

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
    /// The axis's coordinate per unit x = theta / (pi/2): n, or n - 1 on a
    /// Catmull-Rom axis (as f64 once, not per call).
    scale: f64,
    rows: Vec<[f64; FLAT_LOBES]>,
    /// On a Catmull-Rom axis, per interval i the power-basis coefficients
    /// `cubic[i][p][lane]` of the spline in t = p - i: the stencil's
    /// weights are cubics in t, so the value is a cubic too, evaluated by
    /// Horner's rule instead of weights times four rows.
    cubic: Vec<[[f64; FLAT_LOBES]; 4]>,
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
        let cubic = match axis {
            Axis::CatmullRom { n } if n >= 2 => (0..n - 1)
                .map(|i| {
                    let w = catmull_rom_power_basis(i, n);
                    let mut c = [[0.0; FLAT_LOBES]; 4];
                    for (p, cp) in c.iter_mut().enumerate() {
                        for (lane, v) in cp.iter_mut().enumerate() {
                            // Slot k is node i - 1 + k (padded row PAD_BEFORE + i - 1 + k).
                            *v = (0..4)
                                .map(|k| w[k][p] * rows[PAD_BEFORE + i - 1 + k][lane])
                                .sum();
                        }
                    }
                    c
                })
                .collect(),
            _ => Vec::new(),
        };
        let scale = match axis {
            Axis::CatmullRom { n } => (n - 1) as f64,
            _ => n as f64,
        };
        FlatTable {
            axis,
            scale,
            rows,
            cubic,
        }
    }

    /// The interpolated value of every lane at angle theta, as lanes
    /// (0, 1) and (2, 3), given x = clamp(theta / (pi/2), 0, 1):
    /// `axis.stencil(theta).apply_f32(lane)` (a linear stencil's weights
    /// and slot order exactly, its two zero-weight slots skipped; the
    /// Catmull-Rom spline in its power basis, equal up to rounding).
    #[inline(always)]
    fn eval(&self, theta: f64, x: f64) -> [F64x2; 2] {
        self.eval_v::<F64x2x2>(theta, x).0
    }

    /// [`FlatTable::eval`] in any four-lane type (lane l = row lane l; the
    /// same operations, so the same values).
    #[inline(always)]
    fn eval_v<V: Lanes4>(&self, theta: f64, x: f64) -> V {
        let p = match self.axis {
            Axis::SqrtAngle { .. } => x.sqrt() * self.scale,
            Axis::Uniform { .. } | Axis::CatmullRom { .. } => x * self.scale,
            Axis::Squared { .. } | Axis::Closed { .. } => self.axis.coord(theta),
        };
        self.eval_at(p)
    }

    /// The axis coordinates of [`FlatTable::eval_v`] for four angles at
    /// once (x their `theta / (pi/2)`, clamped, in lanes): the same
    /// operations lane by lane.
    #[inline(always)]
    fn coords<V: Lanes4>(&self, theta: &[f64; 4], x: V) -> V {
        match self.axis {
            Axis::SqrtAngle { .. } => x.sqrt() * V::splat(self.scale),
            Axis::Uniform { .. } | Axis::CatmullRom { .. } => x * V::splat(self.scale),
            Axis::Squared { .. } | Axis::Closed { .. } => {
                V::load(&theta.map(|t| self.axis.coord(t)))
            }
        }
    }

    /// The stencils [`FlatTable::eval_at`] builds, for four coordinates at
    /// once in lanes (p never NaN: the coordinates of clamped x): the
    /// same index and weights per lane, so [`FlatTable::eval_stencil`]
    /// gives `eval_at`'s values bit for bit. A linear axis's
    /// (first padded row, w0, w1), `grid::axis::linear_weights`' snapping
    /// included; a Catmull-Rom axis's (interval, t, unused).
    #[inline(always)]
    fn stencils<V: Lanes4>(&self, p: V) -> Stencils4 {
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        match self.axis {
            Axis::CatmullRom { .. } => {
                let i = p.floor_index().min(V::splat((self.cubic.len() - 1) as f64));
                // clamp(0, 1) (p - i is never -0 or NaN here).
                let t = (p - i).max(zero).min(one);
                Stencils4 {
                    at: i.to_u32(),
                    w0: t.to_array(),
                    w1: [0.0; 4],
                }
            }
            Axis::SqrtAngle { n }
            | Axis::Uniform { n }
            | Axis::Squared { n }
            | Axis::Closed { n } => {
                if n == 1 {
                    return Stencils4 {
                        at: [PAD_BEFORE as u32; 4],
                        w0: [1.0; 4],
                        w1: [0.0; 4],
                    };
                }
                let last = (n - 1) as u32 as f64;
                let i = p.floor_index();
                let t = p - i;
                let (snap, top) = (V::splat(SNAP), V::splat(1.0 - SNAP));
                // Within SNAP of node i: it alone; of node i + 1: that alone.
                let w0 = t.lt_select(snap, one, top.lt_select(t, one, one - t));
                let w1 = t.lt_select(snap, zero, top.lt_select(t, zero, t));
                let at = top.lt_select(t, i + one, i);
                // At or past last - SNAP: the last node alone.
                let end = V::splat(last - SNAP);
                let w0 = p.lt_select(end, w0, one);
                let w1 = p.lt_select(end, w1, zero);
                let at = p.lt_select(end, at, V::splat(last)) + V::splat(PAD_BEFORE as f64);
                Stencils4 {
                    at: at.to_u32(),
                    w0: w0.to_array(),
                    w1: w1.to_array(),
                }
            }
        }
    }

    /// Every lane's value at lane k of [`FlatTable::stencils`].
    #[inline(always)]
    fn eval_stencil<V: Lanes4>(&self, s: &Stencils4, k: usize) -> V {
        let at = s.at[k] as usize;
        match self.axis {
            Axis::CatmullRom { .. } => {
                let t = V::splat(s.w0[k]);
                let c = &self.cubic[at];
                ((V::load(&c[3]) * t + V::load(&c[2])) * t + V::load(&c[1])) * t + V::load(&c[0])
            }
            _ => self.lerp((at, s.w0[k], s.w1[k])),
        }
    }

    /// Every lane's value at axis coordinate p (see [`FlatTable::coords`]).
    #[inline(always)]
    fn eval_at<V: Lanes4>(&self, p: f64) -> V {
        match self.axis {
            Axis::SqrtAngle { n }
            | Axis::Uniform { n }
            | Axis::Squared { n }
            | Axis::Closed { n } => self.lerp(linear(p, n)),
            Axis::CatmullRom { .. } => {
                // floor, at most n - 2 (the last interval; x <= 1).
                let i = floor_index(p).min(self.cubic.len() - 1);
                let t = V::splat((p - i as u32 as f64).clamp(0.0, 1.0));
                // Horner's rule on the power-basis coefficients.
                let c = &self.cubic[i];
                ((V::load(&c[3]) * t + V::load(&c[2])) * t + V::load(&c[1])) * t + V::load(&c[0])
            }
        }
    }

    /// A two-node stencil (base row, weights) applied to every lane.
    #[inline(always)]
    fn lerp<V: Lanes4>(&self, (base, w0, w1): (usize, f64, f64)) -> V {
        let r = &self.rows[base..base + 2];
        V::splat(w0) * V::load(&r[0]) + V::splat(w1) * V::load(&r[1])
    }

    /// The interpolated value of every lane at angle theta (the scalar form
    /// of [`FlatTable::eval`], for tests).
    #[cfg(test)]
    fn eval_lanes(&self, theta: f64) -> [f64; FLAT_LOBES] {
        let x = (theta / std::f64::consts::FRAC_PI_2).clamp(0.0, 1.0);
        let [a, b] = self.eval(theta, x);
        [a.lo(), a.hi(), b.lo(), b.hi()]
    }
}

/// Four lanes' stencils on one table (see [`FlatTable::stencils`]).
#[derive(Clone, Copy, Debug)]
struct Stencils4 {
    at: [u32; 4],
    w0: [f64; 4],
    w1: [f64; 4],
}

/// The Catmull-Rom weights of `grid::axis` on interval i of n nodes as
/// polynomials in t: `w[k][p]` is the coefficient of t^p in slot k's
/// weight (the same case analysis: centred tangents inside, the chord at
/// the ends).
fn catmull_rom_power_basis(i: usize, n: usize) -> [[f64; 4]; 4] {
    // 2t^3 - 3t^2 + 1, -2t^3 + 3t^2, t^3 - 2t^2 + t, t^3 - t^2.
    let (p1, p2, h10, h11) = (
        [1.0, 0.0, -3.0, 2.0],
        [0.0, 0.0, 3.0, -2.0],
        [0.0, 1.0, -2.0, 1.0],
        [0.0, 0.0, -1.0, 1.0],
    );
    let mut w = [[0.0; 4], p1, p2, [0.0; 4]];
    for p in 0..4 {
        if i > 0 {
            w[0][p] = -0.5 * h10[p];
            w[2][p] += 0.5 * h10[p];
        } else {
            w[1][p] -= h10[p];
            w[2][p] += h10[p];
        }
        if i + 2 < n {
            w[1][p] -= 0.5 * h11[p];
            w[3][p] = 0.5 * h11[p];
        } else {
            w[1][p] -= h11[p];
            w[2][p] += h11[p];
        }
    }
    w
}

/// `grid::axis`'s linear stencil, as (first padded row, weights).
#[inline(always)]
fn linear(p: f64, n: usize) -> (usize, f64, f64) {
    let (i, w0, w1) = linear_weights(p, n);
    (PAD_BEFORE + i, w0, w1)
}

/// An isotropic model with at most [`FLAT_LOBES`] lobes, flattened for
/// [`FlatEval::eval`].
#[derive(Clone, Debug)]
pub struct FlatEval {
    diffuse: [f64; 3],
    /// s[m][c] as f64.
    s: [[f64; 3]; FLAT_LOBES],
    /// s[m][0] and s[m][1] as lanes.
    s01: [F64x2; FLAT_LOBES],
    /// s[m] as four lanes (channels, then 0), for [`FlatEval::eval4`].
    s4: [[f64; 4]; FLAT_LOBES],
    /// The diffuse albedo as four lanes (channels, then 0).
    diffuse4: [f64; 4],
    d: FlatTable,
    g: FlatTable,
    f: FlatTable,
    /// A separable diffuse form's P nodes (uniform in theta over [0, pi/2]).
    p: Option<Vec<f64>>,
}

impl FlatEval {
    /// The flat copy of a (valid) model, or `None` when it is anisotropic,
    /// has more than [`FLAT_LOBES`] lobes, a non-Lambertian diffuse form,
    /// height-correlated masking or a compensation term.
    pub fn new(model: &Model) -> Option<Self> {
        let l = &model.layout;
        // Only the paper's plain form is flattened; the options go through Model::eval.
        let p = match &model.diffuse_form {
            crate::model::DiffuseForm::Lambert => None,
            crate::model::DiffuseForm::Separable { p } if p.len() >= 2 => {
                Some(p.iter().map(|&v| v as f64).collect())
            }
            _ => return None,
        };
        let lambert = model.masking.is_separable() && model.compensation.is_none();
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
            diffuse: model.diffuse.map(f64::from),
            s,
            s01: s.map(|v| F64x2::new(v[0], v[1])),
            s4: s.map(|v| [v[0], v[1], v[2], 0.0]),
            diffuse4: {
                let d = model.diffuse.map(f64::from);
                [d[0], d[1], d[2], 0.0]
            },
            d: FlatTable::new(l.d.theta, &d),
            g: FlatTable::new(l.g.theta, &g),
            f: FlatTable::new(l.f.theta, &f),
            p,
        })
    }

    /// Whether the diffuse term is Lambertian (no separable P).
    pub(crate) fn is_lambert(&self) -> bool {
        self.p.is_none()
    }

    /// The diffuse albedo times P(theta_i) P(theta_o) at the axis
    /// coordinates x = theta / (pi/2) (the model's linear reading of P).
    #[inline(always)]
    fn diffuse_at(&self, xi: f64, xo: f64) -> [f64; 3] {
        let Some(p) = &self.p else {
            return self.diffuse;
        };
        let at = |x: f64| {
            let y = x * (p.len() - 1) as f64;
            let k = (y as usize).min(p.len() - 2);
            let u = y - k as f64;
            p[k] * (1.0 - u) + p[k + 1] * u
        };
        let pp = at(xi) * at(xo);
        self.diffuse.map(|d| d * pp)
    }

    /// Heap bytes of the flat tables.
    pub fn table_bytes(&self) -> usize {
        let t = [&self.d, &self.g, &self.f];
        t.iter()
            .map(|t| 8 * FLAT_LOBES * (t.rows.len() + 4 * t.cubic.len()))
            .sum()
    }

    /// [`Model::eval`] of the model this was built from, to rounding: the
    /// same angles (theta_h from `h.z = s.z / |s|`, cos theta_d = wi.h,
    /// the z components) and interpolation; the arccosines, the axis
    /// coordinate (a product with 2/pi), the Catmull-Rom G (its power
    /// basis) and the order of products and of the lobe sum differ by ulps
    /// (about 1e-14 relative measured, 1e-9 tested).
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
        let (zero, one) = (F64x2::splat(0.0), F64x2::splat(1.0));
        // Lanes (h, d) and (i, o): cosines, angles, and x = theta / (pi/2).
        let c_hd = F64x2::new(s[2], wi[0] * s[0] + wi[1] * s[1] + wi[2] * s[2]) / F64x2::splat(n);
        let c_io = F64x2::new(wi[2], wo[2]);
        let t_hd = acos2(c_hd.max(zero).min(one));
        let t_io = acos2(c_io.max(zero).min(one));
        // x = theta / (pi/2) by a product with 2/pi: an ulp from the axes'
        // quotient (so a stencil moves by an ulp of its coordinate), and a
        // division less on the dependency chain that bounds eval's time.
        let to_x = F64x2::splat(FRAC_2_PI);
        let x_hd = (t_hd * to_x).max(zero).min(one);
        let x_io = (t_io * to_x).max(zero).min(one);
        let (ci, co) = (wi[2].min(1.0), wo[2].min(1.0));
        let d = self.d.eval(t_hd.lo(), x_hd.lo());
        let f = self.f.eval(t_hd.hi(), x_hd.hi());
        let gi = self.g.eval(t_io.lo(), x_io.lo());
        let go = self.g.eval(t_io.hi(), x_io.hi());
        // D comes last (its chain has the most square roots and
        // divisions): the G products and 1/(ci co) are formed before it.
        let inv_cc = F64x2::splat(1.0 / (ci * co));
        let spec = [0, 1].map(|h| d[h] * (gi[h] * go[h] * inv_cc));
        let spec = [spec[0].lo(), spec[0].hi(), spec[1].lo(), spec[1].hi()];
        // Channels (0, 1) in one pair of lanes, channel 2 alone; the lobe
        // terms summed pairwise (a shorter chain than one by one). Lanes
        // past the model's lobes have s = 0 and zero rows, so add exact
        // zeros (for finite spec, i.e. unless ci co underflows).
        let f2 = f[1].lo();
        let t01: [F64x2; FLAT_LOBES] =
            std::array::from_fn(|m| self.s01[m] * f[0] * F64x2::splat(spec[m]));
        let t2: [f64; FLAT_LOBES] = std::array::from_fn(|m| self.s[m][2] * f2 * spec[m]);
        let dif = self.diffuse_at(x_io.lo(), x_io.hi());
        let v01 = F64x2::new(dif[0], dif[1]) + ((t01[0] + t01[1]) + (t01[2] + t01[3]));
        let v2 = dif[2] + ((t2[0] + t2[1]) + (t2[2] + t2[3]));
        let v01 = v01.max(zero);
        [v01.lo(), v01.hi(), v2.max(0.0)]
    }
}

impl FlatEval {
    /// [`FlatEval::eval`] of four direction pairs at once, with exactly
    /// its values (bit for bit, tested): the angles of the four pairs in
    /// four lanes (one arccosine chain serves four directions, and the
    /// four pairs' chains are independent, so their latencies overlap),
    /// then each pair's tables and lobe sum with the four lobes (or
    /// channels) in four lanes. The per-lane operations and their order
    /// are those of `eval`; only the grouping into lanes differs. `V` is
    /// [`F64x2x2`] (SSE2 pairs) or, inside an AVX2 function, AVX lanes.
    // No closures below: a closure is compiled as its own function,
    // without the AVX2 target feature of the caller, and its AVX lanes
    // would then be calls instead of instructions.
    #[inline(always)]
    pub(crate) fn eval4<V: Lanes4>(&self, wo: [Vec3; 4], wi: [Vec3; 4]) -> [[f64; 3]; 4] {
        self.eval4_view::<V>(wo, wi, None)
    }

    /// [`FlatEval::eval4`] given, optionally, the views' angles `theta_o`
    /// (lane k `acos_lanes` of wo[k]'s z clamped to [0, 1], as a batch
    /// draw has them): the same values, one arccosine chain less.
    #[inline(always)]
    pub(crate) fn eval4_view<V: Lanes4>(
        &self,
        wo: [Vec3; 4],
        wi: [Vec3; 4],
        theta_o: Option<V>,
    ) -> [[f64; 3]; 4] {
        // Written out: `[0, 1, 2, 3].map(..)` compiled to an out-of-line
        // call (with a vzeroupper) in the AVX2 kernel.
        let valid = [
            wi[0][2] > 0.0 && wo[0][2] > 0.0,
            wi[1][2] > 0.0 && wo[1][2] > 0.0,
            wi[2][2] > 0.0 && wo[2][2] > 0.0,
            wi[3][2] > 0.0 && wo[3][2] > 0.0,
        ];
        let (ox, oy, oz) = (
            column::<V>(&wo, &valid, 0),
            column::<V>(&wo, &valid, 1),
            column::<V>(&wo, &valid, 2),
        );
        let (ix, iy, iz) = (
            column::<V>(&wi, &valid, 0),
            column::<V>(&wi, &valid, 1),
            column::<V>(&wi, &valid, 2),
        );
        let (s0, s1, s2) = (ix + ox, iy + oy, iz + oz);
        let n = (s0 * s0 + s1 * s1 + s2 * s2).sqrt();
        let one = V::splat(1.0);
        let c_h = s2 / n;
        let c_d = (ix * s0 + iy * s1 + iz * s2) / n;
        let ((t_h, x_h), (t_d, x_d)) = (angle_and_x(c_h), angle_and_x(c_d));
        // A valid lane's wo.z is in (0, inf), where clamping to [0, 1]
        // equals `column`'s value clamped: the same angle (invalid lanes'
        // results are discarded).
        let (t_i, x_i) = angle_and_x(iz);
        let (t_o, x_o) = match theta_o {
            Some(t) => angle_x_of(t),
            None => angle_and_x(oz),
        };
        // The axis coordinates in lanes too (D's square root among them).
        // The stencils in lanes too (`eval_at`'s, lane by lane).
        let (s_h, s_d) = (
            self.d.stencils(self.d.coords(&t_h, x_h)),
            self.f.stencils(self.f.coords(&t_d, x_d)),
        );
        let (s_i, s_o) = (
            self.g.stencils(self.g.coords(&t_i, x_i)),
            self.g.stencils(self.g.coords(&t_o, x_o)),
        );
        let inv_cc = (one / (iz.min(one) * oz.min(one))).to_array();
        let (xi, xo) = (x_i.to_array(), x_o.to_array());
        let mut out = [[0.0; 3]; 4];
        for k in 0..4 {
            if !valid[k] {
                continue;
            }
            let d: V = self.d.eval_stencil(&s_h, k);
            let f: V = self.f.eval_stencil(&s_d, k);
            let gi: V = self.g.eval_stencil(&s_i, k);
            let go: V = self.g.eval_stencil(&s_o, k);
            let spec = (d * (gi * go * V::splat(inv_cc[k]))).to_array();
            // Channels in lanes, the lobe terms summed pairwise (eval's
            // order).
            let s = &self.s4;
            let t0 = V::load(&s[0]) * f * V::splat(spec[0]);
            let t1 = V::load(&s[1]) * f * V::splat(spec[1]);
            let t2 = V::load(&s[2]) * f * V::splat(spec[2]);
            let t3 = V::load(&s[3]) * f * V::splat(spec[3]);
            let dif = if self.p.is_some() {
                let d = self.diffuse_at(xi[k], xo[k]);
                V::load(&[d[0], d[1], d[2], 0.0])
            } else {
                V::load(&self.diffuse4)
            };
            let v = dif + ((t0 + t1) + (t2 + t3));
            let v = v.max(V::splat(0.0)).to_array();
            out[k] = [v[0], v[1], v[2]];
        }
        out
    }

    /// [`FlatEval::eval`] of every pair (wo[j], wi[j]) (components as
    /// slices) into `out[c][j]`, four pairs at a time: AVX2 lanes where the
    /// CPU has them (detected at run time), SSE2 pairs otherwise; the same
    /// values either way. Every slice must have the length of `wo[0]`.
    pub(crate) fn eval_slices(&self, wo: [&[f64]; 3], wi: [&[f64]; 3], out: [&mut [f64]; 3]) {
        let n = wo[0].len();
        assert!(
            wo.iter().chain(&wi).all(|v| v.len() == n) && out.iter().all(|v| v.len() == n),
            "eval_slices: slices of different lengths"
        );
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            #[target_feature(enable = "avx2")]
            fn run(f: &FlatEval, wo: [&[f64]; 3], wi: [&[f64]; 3], out: [&mut [f64]; 3]) {
                f.eval_slices_in::<super::lanes::avx::F64x4>(wo, wi, out)
            }
            // SAFETY: AVX2 was detected just above.
            return unsafe { run(self, wo, wi, out) };
        }
        self.eval_slices_in::<F64x2x2>(wo, wi, out)
    }

    /// [`FlatEval::eval_slices`] in lane type V (slices of one length).
    #[inline(always)]
    fn eval_slices_in<V: Lanes4>(&self, wo: [&[f64]; 3], wi: [&[f64]; 3], out: [&mut [f64]; 3]) {
        let n = wo[0].len();
        let [o0, o1, o2] = out;
        let mut k = 0;
        while k < n {
            // The last group repeats its final pair in its unused slots.
            let at = |v: [&[f64]; 3], j: usize| {
                let j = (k + j).min(n - 1);
                [v[0][j], v[1][j], v[2][j]]
            };
            let o = [at(wo, 0), at(wo, 1), at(wo, 2), at(wo, 3)];
            let i = [at(wi, 0), at(wi, 1), at(wi, 2), at(wi, 3)];
            let f = self.eval4::<V>(o, i);
            for (j, v) in f.iter().enumerate().take(n - k) {
                o0[k + j] = v[0];
                o1[k + j] = v[1];
                o2[k + j] = v[2];
            }
            k += 4;
        }
    }
}

/// Component c of four directions as lanes, the normal in place of the
/// invalid ones (so that their arithmetic stays finite and their table
/// rows in bounds; their results are replaced by 0).
#[inline(always)]
fn column<V: Lanes4>(v: &[Vec3; 4], valid: &[bool; 4], c: usize) -> V {
    let normal = [0.0, 0.0, 1.0][c];
    let at = |k: usize| if valid[k] { v[k][c] } else { normal };
    V::load(&[at(0), at(1), at(2), at(3)])
}

/// The angle of each lane's cosine (clamped to [0, 1]) and x = angle /
/// (pi/2) clamped to [0, 1], as `FlatEval::eval` computes them.
#[inline(always)]
fn angle_and_x<V: Lanes4>(c: V) -> ([f64; 4], V) {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    angle_x_of(acos_lanes(c.max(zero).min(one)))
}

/// Angles t and their x = t / (pi/2) clamped to [0, 1].
#[inline(always)]
fn angle_x_of<V: Lanes4>(t: V) -> ([f64; 4], V) {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    (t.to_array(), (t * V::splat(FRAC_2_PI)).max(zero).min(one))
}

// fdlibm's high part of pi/2 is the f64 nearest pi/2.
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
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

/// [`asin_r`] lane by lane.
#[inline(always)]
fn asin_r_lanes<V: Lanes>(z: V) -> V {
    let c = V::splat;
    let p = z * (c(PS0) + z * (c(PS1) + z * (c(PS2) + z * (c(PS3) + z * (c(PS4) + z * c(PS5))))));
    let q = c(1.0) + z * (c(QS1) + z * (c(QS2) + z * (c(QS3) + z * c(QS4))));
    p / q
}

/// [`acos`] of two values in [0, 1] at once, without branches (see
/// [`acos_lanes`]).
#[inline(always)]
pub(crate) fn acos2(x: F64x2) -> F64x2 {
    acos_lanes(x)
}

/// [`acos`] lane by lane for values in [0, 1], without branches: the same
/// rational approximation, without fdlibm's extra-precision split of the
/// square root (one division less; error a few ulps, tested). Inputs
/// outside [0, 1] must be clamped by the caller.
#[inline(always)]
pub(crate) fn acos_lanes<V: Lanes>(x: V) -> V {
    let half = V::splat(0.5);
    let zl = (V::splat(1.0) - x) * half;
    let z = x.lt_select(half, x * x, zl);
    let a = x.lt_select(half, x, zl.sqrt());
    let w = a * asin_r_lanes(z);
    let small = V::splat(PIO2_HI) - (a - (V::splat(PIO2_LO) - w));
    let large = V::splat(2.0) * (a + w);
    x.lt_select(half, small, large)
}

/// [`acos`] of four values in [0, 1] at once (two [`acos2`]s): inputs
/// outside [0, 1] must be clamped by the caller.
#[cfg(test)]
fn acos4(x: [f64; 4]) -> [f64; 4] {
    let a = acos2(F64x2::new(x[0], x[1]));
    let b = acos2(F64x2::new(x[2], x[3]));
    [a.lo(), a.hi(), b.lo(), b.hi()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;
    use std::f64::consts::FRAC_PI_2;

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
                let a = t.eval_lanes(theta)[0];
                let b = axis.stencil(theta).apply_f32(&values);
                assert!(
                    (a - b).abs() <= 1e-14 * b.abs().max(1.0),
                    "{axis:?} {theta}"
                );
            }
            // Nodes themselves: the linear stencils' snapped cases exactly,
            // the power-basis cubic to rounding.
            for k in 0..axis.len() {
                let theta = axis.node(k);
                let (a, b) = (
                    t.eval_lanes(theta)[0],
                    axis.stencil(theta).apply_f32(&values),
                );
                if matches!(axis, Axis::CatmullRom { .. }) {
                    assert!((a - b).abs() <= 2e-15 * b.abs(), "{axis:?} node {k}");
                } else {
                    assert_eq!(a, b, "{axis:?} node {k}");
                }
            }
        }
    }

    /// Coordinates at, near and between nodes (inside and outside SNAP)
    /// and at and past the last node.
    fn stencil_coordinates(n: usize) -> Vec<f64> {
        let last = (n - 1) as f64;
        let mut p = vec![0.0, 1e-9, 0.3, last, last - 1e-8, last - 1e-6, last + 0.5];
        for k in 0..n {
            let k = k as f64;
            p.extend([
                k,
                k + 5e-8,
                k - 5e-8,
                k + 2e-7,
                k - 2e-7,
                k + 0.5,
                k + 0.999,
            ]);
        }
        p.retain(|&x| (0.0..=last + 0.5).contains(&x));
        p
    }

    fn check_stencils<V: Lanes4>(t: &FlatTable, p: &[f64]) {
        for q in p.chunks(4) {
            let q: Vec<f64> = (0..4).map(|k| q[k.min(q.len() - 1)]).collect();
            let s = t.stencils(V::load(&[q[0], q[1], q[2], q[3]]));
            for (k, &x) in q.iter().enumerate() {
                let (a, b) = (t.eval_stencil::<V>(&s, k), t.eval_at::<V>(x));
                let bits = |v: V| v.to_array().map(f64::to_bits);
                assert_eq!(bits(a), bits(b), "{:?} p = {x}", t.axis);
            }
        }
    }

    #[test]
    fn lane_stencils_are_the_per_call_ones_bit_for_bit() {
        for axis in [
            Axis::SqrtAngle { n: 90 },
            Axis::Uniform { n: 30 },
            Axis::Squared { n: 12 },
            Axis::Closed { n: 7 },
            Axis::CatmullRom { n: 90 },
            Axis::CatmullRom { n: 2 },
            Axis::Uniform { n: 1 },
        ] {
            let values: Vec<f32> = (0..axis.len()).map(|k| 1.0 + (k * k % 7) as f32).collect();
            let t = FlatTable::new(axis, &[&values, &values]);
            let p = stencil_coordinates(axis.len());
            check_stencils::<F64x2x2>(&t, &p);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                #[target_feature(enable = "avx2")]
                fn avx(t: &FlatTable, p: &[f64]) {
                    check_stencils::<crate::bsdf::lanes::avx::F64x4>(t, p)
                }
                // SAFETY: AVX2 was detected.
                unsafe { avx(&t, &p) };
            }
        }
    }

    fn separable(mut m: crate::model::Model) -> crate::model::Model {
        let n = crate::model::SEPARABLE_NODES;
        m.diffuse = [0.3, 0.2, 0.1];
        m.diffuse_form = crate::model::DiffuseForm::Separable {
            p: crate::synth::ashikhmin_shirley_p(n),
        };
        m
    }

    #[test]
    fn flat_eval_matches_the_model() {
        let plain = known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]);
        for m in [plain.clone(), separable(plain)] {
            flat_matches(&m);
        }
    }

    fn flat_matches(m: &crate::model::Model) {
        let f = FlatEval::new(m).unwrap();
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

    /// Pairs for the batch tests: random directions over the whole sphere
    /// (so some below the horizon), near-normal and grazing ones.
    fn batch_pairs(n: usize) -> Vec<(Vec3, Vec3)> {
        let dir = |a: f64, b: f64| {
            let z = 2.0 * a - 1.0;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let p = b * std::f64::consts::TAU;
            [r * p.cos(), r * p.sin(), z]
        };
        (0..n)
            .map(|k| {
                let a = k as f64 * 0.618_033_988_749_895;
                match k % 7 {
                    0 => ([0.0, 0.0, 1.0], dir(0.999 + 0.001 * a.fract(), a * 3.1)),
                    1 => (
                        dir(1e-4 * a.fract(), a),
                        dir(0.5 + 0.5 * (a * 2.3).fract(), a),
                    ),
                    _ => (
                        dir((a * 7.1).fract(), (a * 3.7).fract()),
                        dir((a * 5.3).fract(), (a * 1.3).fract()),
                    ),
                }
            })
            .collect()
    }

    fn check_eval4<V: Lanes4>(f: &FlatEval, pairs: &[(Vec3, Vec3)]) {
        for len in [0, 1, 3, 4, 5, pairs.len()] {
            let col = |w: usize, c: usize| -> Vec<f64> {
                pairs[..len]
                    .iter()
                    .map(|p| if w == 0 { p.0[c] } else { p.1[c] })
                    .collect()
            };
            let (wo, wi) = ([0, 1, 2].map(|c| col(0, c)), [0, 1, 2].map(|c| col(1, c)));
            let mut out = [
                vec![f64::NAN; len],
                vec![f64::NAN; len],
                vec![f64::NAN; len],
            ];
            let [a, b, c] = &mut out;
            f.eval_slices_in::<V>(
                [&wo[0], &wo[1], &wo[2]],
                [&wi[0], &wi[1], &wi[2]],
                [a, b, c],
            );
            for (k, &(wo, wi)) in pairs[..len].iter().enumerate() {
                let e = f.eval(wo, wi);
                let got = [out[0][k], out[1][k], out[2][k]];
                assert_eq!(got.map(f64::to_bits), e.map(f64::to_bits), "{wo:?} {wi:?}");
            }
        }
    }

    #[test]
    fn four_pairs_at_once_equal_one_at_a_time_bit_for_bit() {
        let pairs = batch_pairs(5003);
        let mut squared = Layout::isotropic(45);
        squared.d = crate::grid::Grid::line(Axis::Squared { n: 45 });
        squared.f = crate::grid::Grid::line(Axis::Closed { n: 30 });
        let models = [
            known_factor_model(Layout::default(), &[0.02, 0.15, 0.5]),
            known_factor_model(Layout::default(), &[0.05, 0.1, 0.3, 0.7]),
            known_factor_model(Layout::isotropic(12), &[0.3]),
            known_factor_model(squared, &[0.1, 0.4]),
            separable(known_factor_model(Layout::default(), &[0.02, 0.15, 0.5])),
        ];
        for m in &models {
            let f = FlatEval::new(m).unwrap();
            check_eval4::<F64x2x2>(&f, &pairs);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                #[target_feature(enable = "avx2")]
                fn avx(f: &FlatEval, pairs: &[(Vec3, Vec3)]) {
                    check_eval4::<crate::bsdf::lanes::avx::F64x4>(f, pairs)
                }
                // SAFETY: AVX2 was detected.
                unsafe { avx(&f, &pairs) };
            }
        }
    }
}
