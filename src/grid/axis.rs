//! One angle axis of a factor table: the elevation axes on [0, pi/2]
//! ([`Axis`]) and the periodic azimuth axis on [0, 2 pi) ([`PhiAxis`]), each
//! with its 1-D interpolation stencil.

use super::stencil::Stencil;
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, TAU};

/// How the nodes of a 1-D factor table sit on an angle in [0, pi/2], and how
/// values between them are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Axis {
    /// MERL's theta_h axis: node k at theta = (k/n)^2 * pi/2, k = 0..n-1
    /// (dense near the specular peak); linear in sqrt(theta) between nodes,
    /// constant past the last node.
    SqrtAngle {
        /// Number of nodes.
        n: usize,
    },
    /// Node k at theta = k/n * pi/2, k = 0..n-1 (MERL's 1-degree theta_d
    /// cells for n = 90); linear between nodes, constant past the last node.
    Uniform {
        /// Number of nodes.
        n: usize,
    },
    /// Uniform's span with squared spacing: node k at theta =
    /// (k/(n-1))^2 * (n-1)/n * pi/2, k = 0..n-1 (for n = 6: 0, 3, 12, 27,
    /// 48, 75 degrees, UTIA's theta_h range, dense near the specular peak);
    /// linear in sqrt(theta) between nodes, constant past the last node.
    Squared {
        /// Number of nodes.
        n: usize,
    },
    /// n nodes spanning [0, pi/2] inclusively (the Catmull-Rom axis's
    /// nodes), linear between them: a G axis whose last node is the
    /// horizon, so the tail tie can take it to 0 there.
    Closed {
        /// Number of nodes.
        n: usize,
    },
    /// n Catmull-Rom control points spanning [0, pi/2] inclusively,
    /// theta_k = k/(n-1) * pi/2, with pbrt's end conditions.
    CatmullRom {
        /// Number of control points.
        n: usize,
    },
}

impl Axis {
    /// Number of nodes.
    pub fn len(&self) -> usize {
        match *self {
            Axis::SqrtAngle { n }
            | Axis::Uniform { n }
            | Axis::Squared { n }
            | Axis::Closed { n }
            | Axis::CatmullRom { n } => n,
        }
    }

    /// Whether the axis has no nodes (never true of a valid layout).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Slots of this axis's stencils: 2 for the linear axes, 4 for Catmull-Rom.
    pub fn stencil_width(&self) -> usize {
        match self {
            Axis::SqrtAngle { .. }
            | Axis::Uniform { .. }
            | Axis::Squared { .. }
            | Axis::Closed { .. } => 2,
            Axis::CatmullRom { .. } => 4,
        }
    }

    /// Whether a 2-D table on this axis holds one value on its pole row
    /// (`Grid::extend`): the G axes, whose node 0 is one direction.
    pub fn pole_tied(&self) -> bool {
        matches!(self, Axis::CatmullRom { .. } | Axis::Closed { .. })
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
            Axis::Squared { n } => squared_span(n) * (p / squared_last(n)).powi(2) * FRAC_PI_2,
            Axis::CatmullRom { n } | Axis::Closed { n } => p / (n - 1) as f64 * FRAC_PI_2,
        }
    }

    /// Continuous node coordinate of an angle, clamped to [0, pi/2].
    pub fn coord(&self, theta: f64) -> f64 {
        let x = (theta / FRAC_PI_2).clamp(0.0, 1.0);
        match *self {
            Axis::SqrtAngle { n } => x.sqrt() * n as f64,
            Axis::Uniform { n } => x * n as f64,
            Axis::Squared { n } => (x / squared_span(n)).sqrt() * squared_last(n),
            Axis::CatmullRom { n } | Axis::Closed { n } => x * (n - 1) as f64,
        }
    }

    /// The coordinate at which the axis reaches pi/2.
    fn coord_end(&self) -> f64 {
        self.coord(FRAC_PI_2)
    }

    /// The interpolation stencil of an angle.
    pub fn stencil(&self, theta: f64) -> Stencil {
        match *self {
            Axis::SqrtAngle { n }
            | Axis::Uniform { n }
            | Axis::Squared { n }
            | Axis::Closed { n } => linear_stencil(self.coord(theta), n),
            Axis::CatmullRom { n } => catmull_rom_stencil(self.coord(theta), n),
        }
    }

    /// The interpolated table value at an angle.
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

/// The last node of a [`Axis::Squared`] axis as a fraction of pi/2
/// (Uniform's last node, (n-1)/n; 1 for a single node).
fn squared_span(n: usize) -> f64 {
    if n > 1 {
        (n - 1) as f64 / n as f64
    } else {
        1.0
    }
}

/// The coordinate of a [`Axis::Squared`] axis's last node (at least 1, so a
/// single-node axis maps every angle to node 0).
fn squared_last(n: usize) -> f64 {
    (n.max(2) - 1) as f64
}

/// Snap to a node when a coordinate is within rounding of it, so samples on
/// the grid (MERL's theta_h and theta_d) touch exactly one cell.
pub(crate) const SNAP: f64 = 1e-7;

fn linear_stencil(p: f64, n: usize) -> Stencil {
    match linear_weights(p, n) {
        (i, _, 0.0) => Stencil::single(i),
        (i, w0, w1) => Stencil::pair(i, w0, i + 1, w1),
    }
}

/// The linear stencil at coordinate p on n nodes as (i, w_i, w_{i+1}):
/// w_{i+1} = 0 (node i + 1 is then not read and may not exist) when p is
/// within [`SNAP`] of node i, or past the last node.
#[inline(always)]
pub(crate) fn linear_weights(p: f64, n: usize) -> (usize, f64, f64) {
    if n == 1 {
        return (0, 1.0, 0.0);
    }
    // 32-bit conversions (grids have far fewer than 2^31 nodes): the same
    // values as through usize, in fewer instructions on x86-64.
    let last = (n - 1) as u32 as f64;
    if p >= last - SNAP {
        return (n - 1, 1.0, 0.0);
    }
    // Truncation is floor here (and for p < 0 both give 0), without a libm
    // call on baseline x86-64.
    let i = (p as i32).max(0);
    let t = p - i as f64;
    let i = i as usize;
    if t < SNAP {
        return (i, 1.0, 0.0);
    }
    if t > 1.0 - SNAP {
        return (i + 1, 1.0, 0.0);
    }
    (i, 1.0 - t, t)
}

/// pbrt-v3's CatmullRomWeights on uniform nodes 0..n-1 (coordinate p):
/// interior tangents are centred differences, the end intervals use the chord.
pub fn catmull_rom_stencil(p: f64, n: usize) -> Stencil {
    let (i, w) = catmull_rom_weights(p, n);
    // Slot k stays slot k (an unused slot keeps weight 0): the order in
    // which sums read the slots is part of the fit's arithmetic.
    let mut st = Stencil::empty(4);
    for (k, &wk) in w.iter().enumerate() {
        let j = i as isize - 1 + k as isize;
        if wk != 0.0 && j >= 0 && (j as usize) < n {
            st.set(k, j as usize, wk);
        }
    }
    st
}

/// [`catmull_rom_stencil`]'s interval i and weights: slot k is node
/// i - 1 + k (slot 0 has weight 0 at i = 0, slot 3 at i = n - 2).
#[inline(always)]
pub(crate) fn catmull_rom_weights(p: f64, n: usize) -> (usize, [f64; 4]) {
    assert!(n >= 2, "a Catmull-Rom axis needs two nodes");
    let i = (p as usize).min(n - 2);
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
    (i, w)
}

/// The periodic azimuth axis of a 2-D factor table: `n` nodes at
/// phi_k = 2 pi k / n over [0, 2 pi), linear between nodes, wrapping from
/// the last node to the first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PhiAxis {
    /// Number of nodes.
    pub n: usize,
}

impl PhiAxis {
    /// The angle (radians) of node k.
    pub fn node(&self, k: usize) -> f64 {
        k as f64 / self.n as f64 * TAU
    }

    /// The two-slot linear stencil of an azimuth (any real angle; it wraps).
    pub fn stencil(&self, phi: f64) -> Stencil {
        let n = self.n;
        if n == 1 {
            return Stencil::single(0);
        }
        let p = (phi.rem_euclid(TAU) / TAU * n as f64).clamp(0.0, n as f64);
        let i = (p.floor() as usize).min(n - 1);
        let t = p - i as f64;
        if t < SNAP {
            return Stencil::single(i % n);
        }
        if t > 1.0 - SNAP {
            return Stencil::single((i + 1) % n);
        }
        Stencil::pair(i, 1.0 - t, (i + 1) % n, t)
    }

    /// Weights q_k with sum_k q_k v_k = integral over [0, 2 pi) of the
    /// interpolated table (exact: each node's hat function has area 2 pi / n).
    pub fn quadrature_weights(&self) -> Vec<f64> {
        vec![TAU / self.n as f64; self.n]
    }
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
            let sum: f64 = st.entries().map(|(_, w)| w).sum();
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
    fn squared_axis_spans_uniforms_range_with_squared_spacing() {
        let axis = Axis::Squared { n: 6 };
        let deg: Vec<f64> = (0..6).map(|k| axis.node(k).to_degrees()).collect();
        for (d, want) in deg.iter().zip([0.0, 3.0, 12.0, 27.0, 48.0, 75.0]) {
            assert!((d - want).abs() < 1e-9, "{deg:?}");
        }
        for k in 0..6 {
            let st = axis.stencil(axis.node(k));
            assert_eq!(st.entries().collect::<Vec<_>>(), vec![(k, 1.0)]);
        }
        // Linear in sqrt(theta) between nodes; constant past the last one.
        let values: Vec<f64> = (0..6).map(|k| axis.node(k).sqrt()).collect();
        for t in [0.01f64, 0.3, 0.7, 1.2] {
            assert!((axis.eval(&values, t) - t.sqrt()).abs() < 1e-12);
        }
        assert_eq!(axis.eval(&values, 1.5), values[5]);
    }

    #[test]
    fn closed_axis_spans_the_horizon_linearly() {
        let axis = Axis::Closed { n: 6 };
        assert_eq!(axis.node(5), FRAC_PI_2);
        assert!((axis.node(1) - 18f64.to_radians()).abs() < 1e-15);
        // Linear between nodes, the last node read at the horizon.
        let values = [1.0, 0.9, 0.8, 0.6, 0.4, 0.0];
        let t = 81f64.to_radians();
        assert!((axis.eval(&values, t) - 0.2).abs() < 1e-12);
        assert_eq!(axis.eval(&values, FRAC_PI_2), 0.0);
        assert!(axis.pole_tied() && !Axis::Uniform { n: 6 }.pole_tied());
    }

    #[test]
    fn phi_axis_wraps_and_reproduces_nodes() {
        let axis = PhiAxis { n: 48 };
        for k in 0..48 {
            let st = axis.stencil(axis.node(k));
            assert_eq!(st.entries().collect::<Vec<_>>(), vec![(k, 1.0)]);
            let st = axis.stencil(axis.node(k) - TAU);
            assert_eq!(st.entries().collect::<Vec<_>>(), vec![(k, 1.0)]);
        }
        // Half way between the last node and 2 pi: the last node and node 0.
        let st = axis.stencil(TAU * (47.5 / 48.0));
        let e: Vec<_> = st.entries().collect();
        assert_eq!(e.len(), 2);
        assert_eq!((e[0].0, e[1].0), (47, 0));
        assert!((e[0].1 - 0.5).abs() < 1e-12 && (e[1].1 - 0.5).abs() < 1e-12);
        let q: f64 = axis.quadrature_weights().iter().sum();
        assert!((q - TAU).abs() < 1e-12);
    }

    #[test]
    fn quadrature_weights_integrate_interpolated_tables() {
        // A constant table integrates cos*sin over [0, pi/2] to 1/2 on every axis.
        for axis in [
            Axis::SqrtAngle { n: 90 },
            Axis::Uniform { n: 45 },
            Axis::Squared { n: 6 },
            Axis::Closed { n: 6 },
            Axis::CatmullRom { n: 30 },
        ] {
            let q = axis.quadrature_weights(|t| t.cos() * t.sin());
            let total: f64 = q.iter().sum();
            assert!((total - 0.5).abs() < 1e-9, "{axis:?}: {total}");
        }
    }
}
