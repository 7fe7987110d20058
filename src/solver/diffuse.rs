//! Refreshing the diffuse form between sweeps.
//!
//! The diffuse factor b_C(wi, wo) of the energy-coupled and Oren-Nayar
//! forms depends on the specular lobes (E) or on a shape parameter (sigma)
//! that no closed-form update handles. It is held fixed during a sweep, so
//! every element update stays exact; after the sweep's d, s solve a new
//! factor is tried (with d, s re-solved for it) and kept only if the
//! objective falls, otherwise the previous factor, d and s come back. The
//! objective therefore never rises. The separable form's table P is
//! updated in the same place by its own element rule ([`super::separable`]).

use super::state::State;
use super::updates::{recompute_residuals, update_diffuse_and_scales};
use super::{DiffuseKind, MAX_LOBES};
use crate::energy::coupled::energy_coupled_form;
use crate::model::{DiffuseForm, SEPARABLE_NODES};
use crate::samples::{FitSet, GIncidence};

/// Oren-Nayar sigma never leaves [0, SIGMA_MAX] (radians).
const SIGMA_MAX: f64 = 1.5;

/// The start's diffuse form, taken unconditionally (before the fit's
/// initial objective is recorded, so monotonicity is unaffected): a
/// Lambertian start would let the lobes absorb the diffuse term's shape,
/// after which no single refresh pays off and the form is never used.
/// Energy-coupled starts from the start lobes' albedo, Oren-Nayar from sigma
/// = 0.3, separable from `carried` (a coarser level's P) if that is
/// separable, else from P = 1 (Lambert). d and s are re-solved for it.
pub(crate) fn start(
    set: &FitSet,
    st: &mut State,
    mask: &[[bool; 3]; MAX_LOBES],
    kind: DiffuseKind,
    carried: Option<&DiffuseForm>,
) {
    let form = match kind {
        DiffuseKind::Lambert => return,
        DiffuseKind::EnergyCoupled => energy_coupled_form(&st.to_model()),
        DiffuseKind::OrenNayar => DiffuseForm::OrenNayar { sigma: 0.3 },
        DiffuseKind::Separable => match carried {
            Some(f @ DiffuseForm::Separable { .. }) => f.clone(),
            _ => DiffuseForm::Separable {
                p: vec![1.0; SEPARABLE_NODES],
            },
        },
    };
    st.set_diffuse_form(set, form);
    update_diffuse_and_scales(set, st, mask);
}

/// Try a refreshed diffuse form of `kind`; returns whether one was kept.
/// `p_inc` is P's incidence ([`super::separable::incidence`]), needed by
/// the separable form only.
pub(crate) fn refresh(
    set: &FitSet,
    st: &mut State,
    mask: &[[bool; 3]; MAX_LOBES],
    kind: DiffuseKind,
    p_inc: Option<&GIncidence>,
) -> bool {
    match kind {
        DiffuseKind::Lambert => false,
        DiffuseKind::Separable => {
            match p_inc.and_then(|inc| super::separable::next_p(set, st, inc)) {
                Some(p) => try_form(set, st, mask, DiffuseForm::Separable { p }),
                None => false,
            }
        }
        DiffuseKind::EnergyCoupled => {
            let form = energy_coupled_form(&st.to_model());
            try_form(set, st, mask, form)
        }
        DiffuseKind::OrenNayar => {
            let current = match st.diffuse_form {
                DiffuseForm::OrenNayar { sigma } => sigma as f64,
                _ => 0.0,
            };
            // A coarse start, then multiplicative steps either way.
            let candidates: Vec<f64> = if current == 0.0 {
                vec![0.15, 0.3, 0.6]
            } else {
                vec![
                    current * 1.25,
                    current / 1.25,
                    current * 1.05,
                    current / 1.05,
                ]
            };
            let mut kept = false;
            for sigma in candidates {
                let form = DiffuseForm::OrenNayar {
                    sigma: sigma.min(SIGMA_MAX) as f32,
                };
                kept |= try_form(set, st, mask, form);
            }
            kept
        }
    }
}

/// Switch to `form`, re-solve d and s, and keep it only if the objective
/// falls.
fn try_form(
    set: &FitSet,
    st: &mut State,
    mask: &[[bool; 3]; MAX_LOBES],
    form: DiffuseForm,
) -> bool {
    if form == st.diffuse_form {
        return false;
    }
    let before = st.objective(set);
    let (diffuse, s) = (st.factors.diffuse, st.factors.s.clone());
    let (basis, old) = (st.basis.take(), st.diffuse_form.clone());
    st.set_diffuse_form(set, form);
    update_diffuse_and_scales(set, st, mask);
    if st.objective(set) < before {
        return true;
    }
    st.factors.diffuse = diffuse;
    st.factors.s = s;
    st.basis = basis;
    st.diffuse_form = old;
    recompute_residuals(set, st);
    false
}
