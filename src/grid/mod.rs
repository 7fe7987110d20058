//! Factor tables on grids, and the interpolation stencils that read them.
//!
//! A factor is a table over a [`Grid`]: an elevation [`Axis`] on [0, pi/2],
//! times, for the anisotropic model, a periodic azimuth [`PhiAxis`]. Every
//! factor value the model uses is a weighted sum of a few table entries (a
//! [`Stencil`]). The solver precomputes one stencil per sample and factor
//! (a [`StencilTable`] per factor), so geometry is never recomputed during a
//! fit, and because every interpolation is linear in the table values each
//! element update stays a closed-form (or, for the squared G, a quartic)
//! least-squares problem, whatever the grid.
//!
//! `ndarray` gives the (theta, phi) matrix views for the per-column
//! operations (fills, monotone tails, smoothing); tables themselves stay
//! flat `Vec`s, the stored form of a model.

pub mod axis;
#[allow(clippy::module_inception)]
pub mod grid;
pub mod stencil;

pub use axis::{catmull_rom_stencil, Axis, PhiAxis};
pub use grid::{theta_table, Grid};
pub use stencil::{Stencil, StencilTable, Weight, MAX_SUPPORT};
