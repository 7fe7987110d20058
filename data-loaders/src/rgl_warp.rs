//! The piecewise-bilinear 2-D warp of RGL `.bsdf` files (Mitsuba 3's
//! `Marginal2D<…, Continuous=true>`, pbrt-v4's `PiecewiseLinear2D`;
//! `../shared/docs/RGL_FORMAT.md` section 5), both ways: the forward map
//! places a writer's sample nodes, the inverse is what a reader evaluates
//! with. A table conditioned on parameters (the file's `phi_i`, `theta_i`)
//! holds one slice per parameter node; each slice is normalised on its own
//! and a query blends the 2^d neighbouring slices' values linearly, as the
//! renderers do, so the warp at a parameter between nodes is the warp of
//! the blended density.

/// Solves integral_0^t lerp(a, b, tau) d tau = target for t in [0, 1].
#[inline]
fn linear_segment(a: f64, b: f64, target: f64) -> f64 {
    let t = if (a - b).abs() <= 1e-4 * (a + b) {
        2.0 * target / (a + b)
    } else {
        (a - (a * a + 2.0 * target * (b - a)).max(0.0).sqrt()) / (a - b)
    };
    if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Index of the last of the first `n - 1` entries that is <= x.
fn interval(n: usize, x: f64, at: impl Fn(usize) -> f64) -> usize {
    let (mut lo, mut hi) = (0usize, n - 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if at(mid) <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A parameter axis of a conditioned table: its nodes, increasing.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamAxis(pub Vec<f64>);

impl ParamAxis {
    /// (lower node index, weight of the next node) for `p`: the interval
    /// holding p, clamped to the first or last one, the weight clamped to
    /// [0, 1]; a single node has weight 0 on a next that does not exist.
    pub fn weight(&self, p: f64) -> (usize, f64) {
        let n = self.0.len();
        if n < 2 {
            return (0, 0.0);
        }
        let i = interval(n, p, |k| self.0[k]);
        let (a, b) = (self.0[i], self.0[i + 1]);
        let t = ((p - a) / (b - a)).clamp(0.0, 1.0);
        (i, if t.is_finite() { t } else { 0.0 })
    }
}

/// Where a query blends slices: (slice index, weight) pairs, at most 2^d.
pub type Blend = Vec<(usize, f64)>;

/// The blend of `axes` (outermost first) at `params`: each slice index is
/// row-major over the axes' nodes.
pub fn blend(axes: &[ParamAxis], params: &[f64]) -> Blend {
    let mut out: Blend = vec![(0, 1.0)];
    for (axis, &p) in axes.iter().zip(params) {
        let n = axis.0.len();
        let (i, t) = axis.weight(p);
        let mut next = Vec::with_capacity(out.len() * 2);
        for &(s, w) in &out {
            next.push((s * n + i, w * (1.0 - t)));
            if t > 0.0 {
                next.push((s * n + i + 1, w * t));
            }
        }
        out = next;
    }
    out
}

/// The warp of a stack of (H x W) slices: per slice the normalised
/// density, the conditional CDFs of its rows and its marginal CDF.
#[derive(Clone, Debug)]
pub struct Warp2D {
    w: usize,
    h: usize,
    /// Normalised density values, slice-major then row-major.
    f: Vec<f64>,
    /// Conditional CDFs, same layout.
    cond: Vec<f64>,
    /// Marginal CDFs (H per slice).
    marg: Vec<f64>,
}

/// Why a slice cannot be warped.
#[derive(Clone, Debug, PartialEq)]
pub enum WarpError {
    /// H or W below 2, or the values do not fill the slices.
    Shape,
    /// Slice `slice` integrates to zero, or to no finite number.
    Integral {
        /// The slice's index.
        slice: usize,
    },
}

impl Warp2D {
    /// The warp of `values`: `values.len() / (h * w)` slices, each
    /// non-negative with a positive integral.
    pub fn new(values: &[f64], h: usize, w: usize) -> Result<Self, WarpError> {
        if h < 2 || w < 2 || values.is_empty() || values.len() % (h * w) != 0 {
            return Err(WarpError::Shape);
        }
        let slices = values.len() / (h * w);
        let mut f = vec![0.0; values.len()];
        let mut cond = vec![0.0; values.len()];
        let mut marg = vec![0.0; slices * h];
        for s in 0..slices {
            let table = &values[s * h * w..(s + 1) * h * w];
            let c = &mut cond[s * h * w..(s + 1) * h * w];
            for j in 0..h {
                for k in 1..w {
                    c[j * w + k] = c[j * w + k - 1]
                        + (table[j * w + k - 1] + table[j * w + k]) / (2.0 * (w - 1) as f64);
                }
            }
            let m = &mut marg[s * h..(s + 1) * h];
            for j in 1..h {
                m[j] =
                    m[j - 1] + (c[(j - 1) * w + w - 1] + c[j * w + w - 1]) / (2.0 * (h - 1) as f64);
            }
            let total = m[h - 1];
            if !(total > 0.0 && total.is_finite()) {
                return Err(WarpError::Integral { slice: s });
            }
            m.iter_mut().for_each(|v| *v /= total);
            c.iter_mut().for_each(|v| *v /= total);
            for (o, v) in f[s * h * w..(s + 1) * h * w].iter_mut().zip(table) {
                *o = v / total;
            }
        }
        Ok(Warp2D {
            w,
            h,
            f,
            cond,
            marg,
        })
    }

    /// Number of slices.
    pub fn slices(&self) -> usize {
        self.marg.len() / self.h
    }

    fn blended(v: &[f64], stride: usize, blend: &[(usize, f64)], i: usize) -> f64 {
        blend.iter().map(|&(s, w)| w * v[s * stride + i]).sum()
    }

    /// Maps a point s of the unit square to u (x the last axis), with the
    /// density of u, under the slices blended by `blend`.
    pub fn sample(&self, s: [f64; 2], blend: &[(usize, f64)]) -> ([f64; 2], f64) {
        let (w, h) = (self.w, self.h);
        let f = |i: usize| Self::blended(&self.f, h * w, blend, i);
        let cond = |i: usize| Self::blended(&self.cond, h * w, blend, i);
        let marg = |j: usize| Self::blended(&self.marg, h, blend, j);
        let row = |j: usize| cond(j * w + w - 1);
        let sy = s[1].clamp(0.0, 1.0);
        let j = interval(h, sy, marg);
        let (r0, r1) = (row(j), row(j + 1));
        let ty = linear_segment(r0, r1, (sy - marg(j)) * (h - 1) as f64);
        let uy = (j as f64 + ty) / (h - 1) as f64;
        let c = |k: usize| cond(j * w + k) * (1.0 - ty) + cond((j + 1) * w + k) * ty;
        let target = s[0].clamp(0.0, 1.0) * (r0 * (1.0 - ty) + r1 * ty);
        let k = interval(w, target, c);
        let fv = |k: usize| f(j * w + k) * (1.0 - ty) + f((j + 1) * w + k) * ty;
        let (c0, c1) = (fv(k), fv(k + 1));
        let tx = linear_segment(c0, c1, (target - c(k)) * (w - 1) as f64);
        let ux = (k as f64 + tx) / (w - 1) as f64;
        ([ux, uy], c0 * (1.0 - tx) + c1 * tx)
    }

    /// The inverse of [`Self::sample`]: the point s that maps to u, with
    /// the density at u. u is clamped to the unit square.
    pub fn invert(&self, u: [f64; 2], blend: &[(usize, f64)]) -> ([f64; 2], f64) {
        let (w, h) = (self.w, self.h);
        let f = |i: usize| Self::blended(&self.f, h * w, blend, i);
        let cond = |i: usize| Self::blended(&self.cond, h * w, blend, i);
        let marg = |j: usize| Self::blended(&self.marg, h, blend, j);
        let cell = |x: f64, n: usize| {
            let x = x.clamp(0.0, 1.0) * (n - 1) as f64;
            let i = (x.floor() as usize).min(n - 2);
            (i, x - i as f64)
        };
        let (j, ty) = cell(u[1], h);
        let (k, tx) = cell(u[0], w);
        let (r0, r1) = (cond(j * w + w - 1), cond((j + 1) * w + w - 1));
        let lerp_y = |a: f64, b: f64| a * (1.0 - ty) + b * ty;
        let c0 = lerp_y(f(j * w + k), f((j + 1) * w + k));
        let c1 = lerp_y(f(j * w + k + 1), f((j + 1) * w + k + 1));
        let r = lerp_y(r0, r1);
        let ck = lerp_y(cond(j * w + k), cond((j + 1) * w + k));
        let x_part = ck + tx * (c0 + 0.5 * tx * (c1 - c0)) / (w - 1) as f64;
        let sx = if r > 0.0 { x_part / r } else { 0.0 };
        let sy = marg(j) + ty * (r0 + 0.5 * ty * (r1 - r0)) / (h - 1) as f64;
        (
            [sx.clamp(0.0, 1.0), sy.clamp(0.0, 1.0)],
            c0 * (1.0 - tx) + c1 * tx,
        )
    }
}

/// A stack of (H x W) tables on the unit square (nodes j / (H - 1),
/// k / (W - 1)), read bilinearly with x clamped and y wrapped into [0, 1)
/// as the renderers read `ndf`, `sigma` and `rgb`, slices blended.
#[derive(Clone, Debug)]
pub struct Bilinear {
    /// Rows per slice.
    pub h: usize,
    /// Columns.
    pub w: usize,
    /// Values, slice-major then row-major.
    pub v: Vec<f64>,
}

impl Bilinear {
    /// The value at (x, y) of the slices blended by `blend`.
    pub fn at(&self, x: f64, y: f64, blend: &[(usize, f64)]) -> f64 {
        let (h, w) = (self.h, self.w);
        let x = x.clamp(0.0, 1.0) * (w - 1) as f64;
        let y = (y - y.floor()).clamp(0.0, 1.0) * (h - 1) as f64;
        let (k, j) = (
            (x.floor() as usize).min(w - 2),
            (y.floor() as usize).min(h - 2),
        );
        let (tx, ty) = (x - k as f64, y - j as f64);
        blend
            .iter()
            .map(|&(s, wt)| {
                let v = &self.v[s * h * w..];
                let row = |j: usize| v[j * w + k] * (1.0 - tx) + v[j * w + k + 1] * tx;
                wt * (row(j) * (1.0 - ty) + row(j + 1) * ty)
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bumpy(h: usize, w: usize, phase: f64) -> Vec<f64> {
        (0..h * w)
            .map(|i| {
                let (j, k) = ((i / w) as f64, (i % w) as f64);
                0.05 + (1.0 + (0.7 * k + phase).sin()) * (1.0 + (0.4 * j).cos())
                    + if i == 7 { 3.0 } else { 0.0 }
            })
            .collect()
    }

    #[test]
    fn invert_undoes_sample_on_one_slice_and_between_slices() {
        let (h, w) = (7, 9);
        let mut v = bumpy(h, w, 0.0);
        v.extend(bumpy(h, w, 1.3));
        let warp = Warp2D::new(&v, h, w).unwrap();
        let axes = [ParamAxis(vec![0.2, 0.6])];
        for p in [0.0, 0.35, 0.6, 1.0] {
            let b = blend(&axes, &[p]);
            for a in 0..23 {
                for c in 0..19 {
                    let s = [(a as f64 + 0.3) / 23.0, (c as f64 + 0.6) / 19.0];
                    let (u, pdf) = warp.sample(s, &b);
                    let (back, pdf2) = warp.invert(u, &b);
                    assert!(
                        (back[0] - s[0]).abs() < 1e-9 && (back[1] - s[1]).abs() < 1e-9,
                        "{s:?} -> {u:?} -> {back:?}"
                    );
                    assert!((pdf - pdf2).abs() < 1e-9 * pdf.max(1.0));
                }
            }
        }
    }

    /// The midpoints of an n x n grid on the unit square.
    fn midpoints(n: usize) -> impl Iterator<Item = [f64; 2]> {
        let m = move |a: usize| (a as f64 + 0.5) / n as f64;
        (0..n).flat_map(move |a| (0..n).map(move |c| [m(a), m(c)]))
    }

    #[test]
    fn the_density_integrates_to_one() {
        let (h, w) = (5, 6);
        let warp = Warp2D::new(&bumpy(h, w, 0.4), h, w).unwrap();
        let b = blend(&[], &[]);
        let n = 400;
        let sum: f64 = midpoints(n)
            .map(|u| warp.invert(u, &b).1 / (n * n) as f64)
            .sum();
        assert!((sum - 1.0).abs() < 1e-4, "{sum}");
    }

    #[test]
    fn warp_pushes_uniform_points_to_the_density() {
        // Density rising along x: the warped mean of x is its mean under
        // the (normalised bilinear) density, 2/3 for f = x.
        let (h, w) = (2, 9);
        let t: Vec<f64> = (0..h * w)
            .map(|i| (i % w) as f64 / (w - 1) as f64)
            .collect();
        let warp = Warp2D::new(&t, h, w).unwrap();
        let b = blend(&[], &[]);
        let n = 200;
        let mut mean = 0.0;
        for s in midpoints(n) {
            let (u, p) = warp.sample(s, &b);
            assert!((p - 2.0 * u[0]).abs() < 1e-9);
            mean += u[0];
        }
        mean /= (n * n) as f64;
        assert!((mean - 2.0 / 3.0).abs() < 1e-4, "{mean}");
    }

    #[test]
    fn a_constant_table_warps_to_the_identity() {
        let warp = Warp2D::new(&[2.0; 12], 3, 4).unwrap();
        let b = blend(&[], &[]);
        for u in [[0.0, 0.0], [0.3, 0.8], [1.0, 1.0], [0.5, 0.25]] {
            let (s, pdf) = warp.invert(u, &b);
            assert!(
                (s[0] - u[0]).abs() < 1e-12
                    && (s[1] - u[1]).abs() < 1e-12
                    && (pdf - 1.0).abs() < 1e-12
            );
            let (back, _) = warp.sample(s, &b);
            assert!((back[0] - u[0]).abs() < 1e-12 && (back[1] - u[1]).abs() < 1e-12);
        }
    }

    #[test]
    fn bad_slices_are_refused() {
        assert_eq!(Warp2D::new(&[1.0; 5], 2, 2).unwrap_err(), WarpError::Shape);
        let mut v = vec![1.0; 8];
        v[4..].iter_mut().for_each(|x| *x = 0.0);
        assert_eq!(
            Warp2D::new(&v, 2, 2).unwrap_err(),
            WarpError::Integral { slice: 1 }
        );
        assert!(Warp2D::new(&[f64::NAN, 1.0, 1.0, 1.0], 2, 2).is_err());
    }

    #[test]
    fn blends_weigh_neighbouring_nodes() {
        let axes = [ParamAxis(vec![0.0]), ParamAxis(vec![0.0, 1.0, 2.0])];
        assert_eq!(blend(&axes, &[5.0, 1.25]), vec![(1, 0.75), (2, 0.25)]);
        assert_eq!(blend(&axes, &[0.0, 9.0]), vec![(1, 0.0), (2, 1.0)]);
    }
}
