//! Models back to MERL tables, so any MERL-capable tool can use a fit.

use crate::model::Model;
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::MerlTable;

/// The model evaluated at every cell's lower-edge node (the convention of
/// MERL's reader and of `nbrdf2merl.py`); cells whose node lies at or below
/// the horizon are missing (-1).
pub fn to_merl(model: &Model) -> MerlTable {
    MerlTable::from_fn(|th, td, pd| {
        let a = Angles::from_half_diff(th, 0.0, td, pd);
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| model.eval_angles(&a))
    })
}
