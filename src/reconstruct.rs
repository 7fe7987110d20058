//! Models back to measured tables (MERL for isotropic models, UTIA for
//! either), so any MERL- or UTIA-capable tool can use a fit.

use crate::model::Model;
use npf_data_loaders::geometry::Angles;
use npf_data_loaders::{MerlTable, UtiaTable};

/// The model evaluated at every cell's lower-edge node (the convention of
/// MERL's reader and of `nbrdf2merl.py`); cells whose node lies at or below
/// the horizon are missing (-1).
pub fn to_merl(model: &Model) -> MerlTable {
    MerlTable::from_fn(|th, td, pd| {
        let a = Angles::from_half_diff(th, 0.0, td, pd);
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| model.eval_angles(&a))
    })
}

/// The model evaluated at every UTIA node (illumination (theta_i, phi_i),
/// view (theta_v, phi_v); all above the horizon, so no cell is missing).
/// The tangent is the table's phi = 0.
pub fn to_utia(model: &Model) -> UtiaTable {
    use npf_data_loaders::geometry::spherical;
    UtiaTable::from_fn(|ti, pi, tv, pv| Some(model.eval(spherical(tv, pv), spherical(ti, pi))))
}
