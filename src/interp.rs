//! Factor-table axes and the interpolation stencils that read them.
//!
//! Every factor value the model uses is a weighted sum of at most four table
//! entries (a [`Stencil`]). The solver precomputes one stencil per sample and
//! factor, so geometry is never recomputed during a fit, and because every
//! interpolation is linear in the table values each element update stays a
//! closed-form (or, for the squared G, a quartic) least-squares problem.

use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;

/// Up to four (index, weight) pairs; unused entries have weight 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stencil {
    pub idx: [u32; 4],
    pub w: [f64; 4],
}

impl Stencil {
    pub fn single(i: usize) -> Self {
        Stencil {
            idx: [i as u32, 0, 0, 0],
            w: [1.0, 0.0, 0.0, 0.0],
        }
    }

    #[inline]
    pub fn apply(&self, values: &[f64]) -> f64 {
        self.idx
            .iter()
            .zip(&self.w)
            .map(|(&i, &w)| {
                if w != 0.0 {
                    w * values[i as usize]
                } else {
                    0.0
                }
            })
            .sum()
    }

    #[inline]
    pub fn apply_f32(&self, values: &[f32]) -> f64 {
        self.idx
            .iter()
            .zip(&self.w)
            .map(|(&i, &w)| {
                if w != 0.0 {
                    w * values[i as usize] as f64
                } else {
                    0.0
                }
            })
            .sum()
    }

    /// The non-zero entries.
    pub fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.idx
            .iter()
            .zip(&self.w)
            .filter(|(_, &w)| w != 0.0)
            .map(|(&i, &w)| (i as usize, w))
    }
}

/// How the nodes of a 1-D factor table sit on an angle in [0, pi/2], and how
/// values between them are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Axis {
    /// MERL's theta_h axis: node k at theta = (k/n)^2 * pi/2, k = 0..n-1
    /// (dense near the specular peak); linear in sqrt(theta) between nodes,
    /// constant past the last node.
    SqrtAngle { n: usize },
    /// Node k at theta = k/n * pi/2, k = 0..n-1 (MERL's 1-degree theta_d
    /// cells for n = 90); linear between nodes, constant past the last node.
    Uniform { n: usize },
    /// n Catmull-Rom control points spanning [0, pi/2] inclusively,
    /// theta_k = k/(n-1) * pi/2, with pbrt's end conditions.
    CatmullRom { n: usize },
}

impl Axis {
    pub fn len(&self) -> usize {
        match *self {
            Axis::SqrtAngle { n } | Axis::Uniform { n } | Axis::CatmullRom { n } => n,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The angle (radians) of node k.
    pub fn node(&self, k: usize) -> f64 {
        self.angle_at(k as f64)
    }

    /// Angle at continuous node coordinate p.
    pub fn angle_at(&self, p: f64) -> f64 {
        match *self {
            Axis::SqrtAngle { n } => (p / n as f64).powi(2) * FRAC_PI_2,
            Axis::Uniform { n } => p / n as f64 * FRAC_PI_2,
            Axis::CatmullRom { n } => p / (n - 1) as f64 * FRAC_PI_2,
        }
    }

    /// Continuous node coordinate of an angle, clamped to [0, pi/2].
    pub fn coord(&self, theta: f64) -> f64 {
        let x = (theta / FRAC_PI_2).clamp(0.0, 1.0);
        match *self {
            Axis::SqrtAngle { n } => x.sqrt() * n as f64,
            Axis::Uniform { n } => x * n as f64,
            Axis::CatmullRom { n } => x * (n - 1) as f64,
        }
    }

    /// The coordinate at which the axis reaches pi/2.
    fn coord_end(&self) -> f64 {
        self.coord(FRAC_PI_2)
    }

    pub fn stencil(&self, theta: f64) -> Stencil {
        match *self {
            Axis::SqrtAngle { n } | Axis::Uniform { n } => linear_stencil(self.coord(theta), n),
            Axis::CatmullRom { n } => catmull_rom_stencil(self.coord(theta), n),
        }
    }

    pub fn eval(&self, values: &[f64], theta: f64) -> f64 {
        self.stencil(theta).apply(values)
    }

    /// Weights q_k such that sum_k q_k v_k = integral over [0, pi/2] of
    /// g(theta) times the interpolated table, by composite Gauss-Legendre
    /// quadrature on each unit of node coordinate (interpolants are
    /// polynomial there, so this is exact up to g's smoothness).
    pub fn quadrature_weights(&self, g: impl Fn(f64) -> f64) -> Vec<f64> {
        const GL_X: [f64; 4] = [
            -0.861_136_311_594_052_6,
            -0.339_981_043_584_856_3,
            0.339_981_043_584_856_3,
            0.861_136_311_594_052_6,
        ];
        const GL_W: [f64; 4] = [
            0.347_854_845_137_453_9,
            0.652_145_154_862_546_1,
            0.652_145_154_862_546_1,
            0.347_854_845_137_453_9,
        ];
        let mut q = vec![0.0; self.len()];
        let end = self.coord_end();
        // Sub-steps per node interval: the sqrt map is steep near 0.
        let sub = 16;
        let steps = (end.ceil() as usize) * sub;
        let h = end / steps as f64;
        for s in 0..steps {
            let (a, b) = (s as f64 * h, (s + 1) as f64 * h);
            for (x, w) in GL_X.iter().zip(GL_W) {
                let p = 0.5 * (a + b) + 0.5 * (b - a) * x;
                let dp = 1e-6 * (1.0 + p);
                let theta = self.angle_at(p);
                let jac = (self.angle_at(p + dp) - self.angle_at(p - dp)) / (2.0 * dp);
                let weight = 0.5 * (b - a) * w * jac * g(theta);
                for (k, wk) in self.stencil(theta).entries() {
                    q[k] += weight * wk;
                }
            }
        }
        q
    }
}

/// Snap to a node when a coordinate is within rounding of it, so samples on
/// the grid (MERL's theta_h and theta_d) touch exactly one cell.
const SNAP: f64 = 1e-7;

fn linear_stencil(p: f64, n: usize) -> Stencil {
    if n == 1 {
        return Stencil::single(0);
    }
    let last = (n - 1) as f64;
    if p >= last - SNAP {
        return Stencil::single(n - 1);
    }
    let i = p.floor() as usize;
    let t = p - i as f64;
    if t < SNAP {
        return Stencil::single(i);
    }
    if t > 1.0 - SNAP {
        return Stencil::single(i + 1);
    }
    Stencil {
        idx: [i as u32, i as u32 + 1, 0, 0],
        w: [1.0 - t, t, 0.0, 0.0],
    }
}

/// pbrt-v3's CatmullRomWeights on uniform nodes 0..n-1 (coordinate p):
/// interior tangents are centred differences, the end intervals use the chord.
pub fn catmull_rom_stencil(p: f64, n: usize) -> Stencil {
    assert!(n >= 2, "a Catmull-Rom axis needs two nodes");
    let i = (p.floor() as usize).min(n - 2);
    let t = (p - i as f64).clamp(0.0, 1.0);
    let (t2, t3) = (t * t, t * t * t);
    let mut w = [0.0, 2.0 * t3 - 3.0 * t2 + 1.0, -2.0 * t3 + 3.0 * t2, 0.0];
    let h10 = t3 - 2.0 * t2 + t;
    let h11 = t3 - t2;
    if i > 0 {
        // Uniform spacing: delta / (x_{i+1} - x_{i-1}) = 1/2.
        let a = 0.5 * h10;
        w[0] = -a;
        w[2] += a;
    } else {
        w[1] -= h10;
        w[2] += h10;
    }
    if i + 2 < n {
        let b = 0.5 * h11;
        w[1] -= b;
        w[3] = b;
    } else {
        w[1] -= h11;
        w[2] += h11;
    }
    let mut st = Stencil::default();
    for (k, &wk) in w.iter().enumerate() {
        let j = i as isize - 1 + k as isize;
        if wk != 0.0 && j >= 0 && (j as usize) < n {
            st.idx[k] = j as u32;
            st.w[k] = wk;
        }
    }
    st
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catmull_rom_reproduces_linear_functions_and_nodes() {
        let n = 12;
        let values: Vec<f64> = (0..n).map(|k| 0.3 + 0.7 * k as f64).collect();
        for s in 0..=200 {
            let p = s as f64 / 200.0 * (n - 1) as f64;
            let st = catmull_rom_stencil(p, n);
            let sum: f64 = st.w.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12);
            assert!((st.apply(&values) - (0.3 + 0.7 * p)).abs() < 1e-12);
        }
        let bumpy: Vec<f64> = (0..n).map(|k| ((k * k) % 7) as f64).collect();
        for k in 0..n {
            assert!((catmull_rom_stencil(k as f64, n).apply(&bumpy) - bumpy[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn merl_nodes_touch_one_cell() {
        let axis = Axis::SqrtAngle { n: 90 };
        for k in 0..90 {
            let st = axis.stencil(axis.node(k));
            assert_eq!(st.entries().collect::<Vec<_>>(), vec![(k, 1.0)]);
        }
    }

    #[test]
    fn quadrature_weights_integrate_interpolated_tables() {
        // A constant table integrates cos*sin over [0, pi/2] to 1/2 on every axis.
        for axis in [
            Axis::SqrtAngle { n: 90 },
            Axis::Uniform { n: 45 },
            Axis::CatmullRom { n: 30 },
        ] {
            let q = axis.quadrature_weights(|t| t.cos() * t.sin());
            let total: f64 = q.iter().sum();
            assert!((total - 0.5).abs() < 1e-9, "{axis:?}: {total}");
        }
    }
}
