//! The weighted sample set a fit runs on.
//!
//! Built once from measured samples: every valid sample with its RGB value,
//! per-channel weight and the interpolation stencils of every factor (D and F
//! cells, the Catmull-Rom control points of G at theta_i and theta_o), plus,
//! per table entry, the list of samples that touch it. The solver only reads
//! these arrays; it never recomputes geometry.
//!
//! Reciprocal pairs: the isotropic model depends on (theta_h, theta_d) and on
//! {theta_i, theta_o} as an unordered pair, so the configurations phi_d and
//! pi - phi_d (which swap theta_i and theta_o) always get the same model
//! value. Two samples with the same model value y_1, y_2 and weights w_1, w_2
//! contribute w_1 (m - y_1)^2 + w_2 (m - y_2)^2 = W (m - y)^2 + c with
//! W = w_1 + w_2, y = (w_1 y_1 + w_2 y_2) / W and c = w_1 w_2 (y_1 - y_2)^2 / W,
//! so merging them halves the work and leaves every update exactly the same;
//! c is kept in `objective_offset` so reported objectives are the true ones.
//! Only isotropic samples fitted with an isotropic layout are merged: for
//! an anisotropic model the two configurations differ in phi.
//!
//! Anisotropic layouts read the samples' azimuths too (phi_h for D, phi_i
//! and phi_o for G); their stencils are the products of a theta and a phi
//! stencil, and every tail constraint acts on the theta part, so it holds
//! in every phi column.

mod incidence;
mod merl;
mod order;
mod set;
mod source;
mod weighting;

pub use incidence::{GIncidence, GUse, Incidence};
#[doc(hidden)]
pub use merl::same_up_to_order;
pub use set::{last_free_g_node, last_free_node, FitSet, SampleError, SampleStats};
pub(crate) use source::on_data;
pub use source::{SampleData, SampleSource, SampleView};
pub(crate) use weighting::{round_to_i64, KeyMap};
pub use weighting::{SampleOptions, Weighting};
