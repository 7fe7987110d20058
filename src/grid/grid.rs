//! A factor's grid: an elevation axis, optionally times a periodic azimuth.
//!
//! The table of a 2-D grid is row-major theta x phi (entry kt * n_phi + kp),
//! so a phi column is a strided view and a theta row is contiguous. Tails,
//! monotone parts and fills are defined along theta and applied to every phi
//! column; a 1-D grid is the one-column case, so the isotropic model runs
//! exactly the 1-D arithmetic.

use super::axis::{Axis, PhiAxis};
use super::stencil::Stencil;
use ndarray::{ArrayViewMut1, ArrayViewMut2, Axis as NdAxis};
use serde::{Deserialize, Serialize};

/// The nodes of one factor table: theta axis x optional periodic phi axis.
///
/// Its JSON form is the theta axis's (`{"kind": "sqrt_angle", "n": 90}`),
/// plus `"phi": {"n": 48}` when 2-D, so 1-D files read as before.
#[derive(Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    /// The elevation axis.
    #[serde(flatten)]
    pub theta: Axis,
    /// The azimuth axis of a 2-D table (`None`: the table is 1-D).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phi: Option<PhiAxis>,
}

/// A 1-D grid prints as its axis (`SqrtAngle { n: 90 }`), a 2-D one as
/// `CatmullRom { n: 6 } x PhiAxis { n: 48 }`.
impl std::fmt::Debug for Grid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.phi {
            None => write!(f, "{:?}", self.theta),
            Some(p) => write!(f, "{:?} x {:?}", self.theta, p),
        }
    }
}

impl From<Axis> for Grid {
    fn from(theta: Axis) -> Self {
        Grid::line(theta)
    }
}

impl Grid {
    /// A 1-D table on `theta`.
    pub fn line(theta: Axis) -> Self {
        Grid { theta, phi: None }
    }

    /// A 2-D table on `theta` x `n_phi` periodic azimuth nodes.
    pub fn plane(theta: Axis, n_phi: usize) -> Self {
        Grid {
            theta,
            phi: Some(PhiAxis { n: n_phi }),
        }
    }

    /// Whether the table depends on theta only.
    pub fn is_1d(&self) -> bool {
        self.phi.is_none()
    }

    /// Number of phi columns (1 for a 1-D table).
    pub fn n_phi(&self) -> usize {
        self.phi.map_or(1, |p| p.n)
    }

    /// Number of theta rows.
    pub fn n_theta(&self) -> usize {
        self.theta.len()
    }

    /// Number of table entries.
    pub fn len(&self) -> usize {
        self.theta.len() * self.n_phi()
    }

    /// Whether the table has no entries (never true of a valid layout).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Slots of this grid's stencils (the product of its axes' supports).
    pub fn stencil_width(&self) -> usize {
        self.theta.stencil_width() * if self.is_1d() { 1 } else { 2 }
    }

    /// The theta index of a flat entry.
    pub fn theta_index(&self, k: usize) -> usize {
        k / self.n_phi()
    }

    /// (theta, phi) of a flat entry's node (phi 0 for a 1-D table).
    pub fn node(&self, k: usize) -> (f64, f64) {
        let np = self.n_phi();
        let phi = self.phi.map_or(0.0, |p| p.node(k % np));
        (self.theta.node(k / np), phi)
    }

    /// The stencil of a direction (phi is ignored by a 1-D table).
    pub fn stencil(&self, theta: f64, phi: f64) -> Stencil {
        self.extend(self.theta.stencil(theta), phi)
    }

    /// A theta stencil (possibly folded, see `samples`) extended over phi:
    /// unchanged for a 1-D table, the tensor product with the phi stencil
    /// otherwise, except on the pole row of a Catmull-Rom or closed (G) axis (theta
    /// node 0 at theta = 0): that is one direction whatever phi, so it is
    /// one value, the row's first entry (its other entries are never read).
    /// Without this the 48 pole values of G differ, fitted only through
    /// their theta neighbours, and the model is discontinuous where the
    /// view or light meets the normal (a star at the centre of the sphere).
    /// D's pole row (theta_h = 0) keeps its 48 values: the discontinuity is
    /// then inside the highlight, and the per-azimuth values are what lets
    /// a 15-degree D axis follow a narrow anisotropic peak (tying them
    /// costs 4 dB of rendering PSNR on ggx-0.1x0.3-t0, docs/anisotropic.md).
    pub fn extend(&self, theta_stencil: Stencil, phi: f64) -> Stencil {
        match self.phi {
            None => theta_stencil,
            Some(p) => {
                let ps = p.stencil(phi);
                let mut out = Stencil::empty(0);
                for (i, w) in theta_stencil.entries() {
                    if i == 0 && self.theta.pole_tied() {
                        out.push(0, w);
                    } else {
                        for (j, wj) in ps.entries() {
                            out.push(i * p.n + j, w * wj);
                        }
                    }
                }
                out
            }
        }
    }

    /// The interpolated value of a table at a direction.
    pub fn eval(&self, values: &[f64], theta: f64, phi: f64) -> f64 {
        self.stencil(theta, phi).apply(values)
    }

    /// The table as a (theta, phi) matrix view, for column operations.
    pub fn view_mut<'a>(&self, table: &'a mut [f64]) -> ArrayViewMut2<'a, f64> {
        ArrayViewMut2::from_shape((self.n_theta(), self.n_phi()), table)
            .expect("table size matches its grid")
    }

    /// Apply `f` to every phi column (the theta profile at one azimuth).
    pub fn for_each_column(&self, table: &mut [f64], mut f: impl FnMut(ArrayViewMut1<f64>)) {
        let mut v = self.view_mut(table);
        for col in v.axis_iter_mut(NdAxis(1)) {
            f(col);
        }
    }
}

/// A table of f(theta) on a grid's nodes (the same profile in every phi column).
pub fn theta_table(grid: Grid, f: &dyn Fn(f64) -> f64) -> Vec<f64> {
    (0..grid.len())
        .map(|k| f(grid.theta.node(grid.theta_index(k))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_d_grids_serialise_as_their_axis() {
        let g = Grid::line(Axis::SqrtAngle { n: 90 });
        let j = serde_json::to_string(&g).unwrap();
        assert_eq!(j, r#"{"kind":"sqrt_angle","n":90}"#);
        assert_eq!(serde_json::from_str::<Grid>(&j).unwrap(), g);
        let p = Grid::plane(Axis::CatmullRom { n: 6 }, 48);
        let j = serde_json::to_string(&p).unwrap();
        assert_eq!(j, r#"{"kind":"catmull_rom","n":6,"phi":{"n":48}}"#);
        assert_eq!(serde_json::from_str::<Grid>(&j).unwrap(), p);
    }

    #[test]
    fn two_d_stencils_interpolate_bilinear_products() {
        let g = Grid::plane(Axis::Uniform { n: 6 }, 48);
        assert_eq!(g.len(), 288);
        assert_eq!(g.stencil_width(), 4);
        // f(theta, phi) = a(theta) + b(phi) with both parts linear between
        // nodes is reproduced exactly between nodes.
        let table: Vec<f64> = (0..g.len())
            .map(|k| {
                let (t, p) = g.node(k);
                2.0 * t + p.cos()
            })
            .collect();
        let (t, p) = (0.3, 1.0);
        let st = g.stencil(t, p);
        assert_eq!(st.entries().count(), 4);
        let sum: f64 = st.entries().map(|(_, w)| w).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        let phi = PhiAxis { n: 48 };
        let pc = phi
            .stencil(p)
            .apply(&(0..48).map(|k| phi.node(k).cos()).collect::<Vec<_>>());
        assert!((st.apply(&table) - (2.0 * t + pc)).abs() < 1e-12);
        let cr = Grid::plane(Axis::CatmullRom { n: 6 }, 48);
        assert_eq!(cr.stencil_width(), 8);
        assert_eq!(cr.stencil(0.7, 2.0).entries().count(), 8);
    }
}
