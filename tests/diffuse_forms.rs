//! The non-Lambertian diffuse forms: each recovers its own synthetic ground
//! truth, the objective never rises with the between-sweep refreshes, and
//! model files carry the form (old Lambertian files still load).

use npf::energy::coupled::{energy_coupled_form, specular_albedo};
use npf::loaders::MeasuredSamples;
use npf::metrics::compare_model;
use npf::model::{separable_mean, DiffuseForm, Layout, Model, SEPARABLE_NODES};
use npf::modelfile::{self, ModelFile};
use npf::solver::{DiffuseKind, FitOptions, FitResult};
use npf::synth::known_factor_model;

#[path = "common/monotone.rs"]
mod monotone;
use monotone::assert_stages_monotone;
#[path = "common/synthetic_fit.rs"]
mod synthetic_fit;
use synthetic_fit::{fit_one_lobe, samples};

/// One rough lobe scaled to reflect at most 40 % at normal incidence (a
/// lobe reflecting more than it receives has no energy left to couple),
/// plus a diffuse term of the given form.
fn truth(form: impl Fn(&Model) -> DiffuseForm) -> Model {
    let mut m = known_factor_model(Layout::default(), &[0.25]);
    m.diffuse = [0.0; 3];
    let e = specular_albedo(&m);
    let top = (0..3).map(|c| e[c][0]).fold(0.0, f64::max);
    for v in m.lobes[0].s.iter_mut() {
        *v *= (0.4 / top) as f32;
    }
    m.diffuse = [0.12, 0.18, 0.06];
    m.diffuse_form = form(&m);
    m
}

fn fit(s: &MeasuredSamples, diffuse: DiffuseKind, sweeps: usize, trace: bool) -> FitResult {
    fit_from(s, diffuse, sweeps, trace, None)
}

fn fit_from(
    s: &MeasuredSamples,
    diffuse: DiffuseKind,
    sweeps: usize,
    trace: bool,
    start: Option<&Model>,
) -> FitResult {
    let opts = FitOptions {
        diffuse,
        ..Default::default()
    };
    fit_one_lobe(s, opts, sweeps, trace, start)
}

/// Fits the truth with its own form and with Lambert, both started from the
/// true lobes with no diffuse term (a rough lobe and a diffuse term trade
/// energy along a flat valley, so a cold start separates them only after
/// many sweeps): its own form must reach a small error, well below
/// Lambert's, with the true d.
fn recovers(truth: &Model, kind: DiffuseKind, bound: f64) -> FitResult {
    let s = samples(truth, 5);
    let mut start = truth.clone();
    start.diffuse = [0.0; 3];
    start.diffuse_form = DiffuseForm::Lambert;
    let own = fit_from(&s, kind, 40, false, Some(&start));
    let lambert = fit_from(&s, DiffuseKind::Lambert, 40, false, Some(&start));
    let (a, b) = (
        compare_model(&s, 85.0, &own.model),
        compare_model(&s, 85.0, &lambert.model),
    );
    eprintln!(
        "{kind:?}: own {} sweeps rel {:.3e}, lambert rel {:.3e}; form {:?}, d {:?}",
        own.history.len(),
        a.rel_cos_rmse,
        b.rel_cos_rmse,
        own.model.diffuse_form.name(),
        own.model.diffuse
    );
    assert!(a.rel_cos_rmse < bound, "{a:?}");
    assert!(a.rel_cos_rmse < 0.3 * b.rel_cos_rmse, "{a:?} vs {b:?}");
    for c in 0..3 {
        let (got, want) = (own.model.diffuse[c], truth.diffuse[c]);
        assert!((got - want).abs() < 0.02 * want, "d_{c}: {got} vs {want}");
    }
    assert_eq!(own.model.diffuse_form.name(), truth.diffuse_form.name());
    own
}

#[test]
fn energy_coupled_truth_is_recovered() {
    let t = truth(energy_coupled_form);
    recovers(&t, DiffuseKind::EnergyCoupled, 1e-3);
}

#[test]
fn oren_nayar_truth_is_recovered() {
    let t = truth(|_| DiffuseForm::OrenNayar { sigma: 0.4 });
    let res = recovers(&t, DiffuseKind::OrenNayar, 1e-3);
    let DiffuseForm::OrenNayar { sigma } = res.model.diffuse_form else {
        unreachable!()
    };
    assert!((sigma - 0.4).abs() < 0.04, "sigma {sigma}");
}

/// Ashikhmin-Shirley's coupled diffuse factor at each direction, 1 - (1 -
/// cos theta / 2)^5, on P's nodes, in the form's gauge (2 int P mu dmu = 1).
fn ashikhmin_shirley_p() -> Vec<f32> {
    let p = npf::synth::ashikhmin_shirley_p(SEPARABLE_NODES);
    let mean = separable_mean(&p);
    p.iter().map(|&v| (v as f64 / mean) as f32).collect()
}

#[test]
fn separable_truth_is_recovered() {
    // Ashikhmin-Shirley-type coupled diffuse: P falls to 0 at the horizon.
    let want = ashikhmin_shirley_p();
    let t = truth(|_| DiffuseForm::Separable { p: want.clone() });
    let res = recovers(&t, DiffuseKind::Separable, 1e-3);
    let DiffuseForm::Separable { p } = &res.model.diffuse_form else {
        unreachable!()
    };
    // The samples reach 85 degrees: the nodes up to there are read, the
    // horizon node (90) only by the interval before it.
    for k in 0..SEPARABLE_NODES - 1 {
        let (got, want) = (p[k] as f64, want[k] as f64);
        assert!(
            (got - want).abs() <= 0.01 * want,
            "P node {k}: {got} vs {want}"
        );
    }
}

#[test]
fn separable_p_is_recovered_from_a_cold_start() {
    // No truth in the start: the default initialisation, P = 1. The rough
    // lobe and P then trade energy along a flat valley near grazing: after
    // 150 sweeps nodes 0-72 degrees were measured within 0.7 %, 78 degrees
    // 1.2 % off, and 84 degrees (read only by the few, cosine-weighted
    // samples between 78 and 85 degrees) 3.3 %, which is left unchecked.
    let want = ashikhmin_shirley_p();
    let t = truth(|_| DiffuseForm::Separable { p: want.clone() });
    let s = samples(&t, 5);
    let res = fit(&s, DiffuseKind::Separable, 150, false);
    let DiffuseForm::Separable { p } = &res.model.diffuse_form else {
        unreachable!()
    };
    let e = compare_model(&s, 85.0, &res.model);
    eprintln!(
        "cold start: {} sweeps, rel {:.3e}, P {p:?}",
        res.history.len(),
        e.rel_cos_rmse
    );
    assert!(e.rel_cos_rmse < 2e-3, "{e:?}");
    for k in 0..SEPARABLE_NODES - 2 {
        let (got, want) = (p[k] as f64, want[k] as f64);
        assert!(
            (got - want).abs() <= 0.02 * want,
            "P node {k}: {got} vs {want}"
        );
    }
}

#[test]
fn objective_never_rises_with_diffuse_refreshes() {
    let t = truth(energy_coupled_form);
    let s = samples(&t, 11);
    for kind in [
        DiffuseKind::EnergyCoupled,
        DiffuseKind::OrenNayar,
        DiffuseKind::Separable,
    ] {
        let res = fit(&s, kind, 8, true);
        assert_stages_monotone(&res, &format!("{kind:?}"));
        assert!(res.objective < res.initial_objective);
    }
}

#[test]
fn energy_coupled_albedo_is_pi_d_times_what_the_lobes_leave() {
    // The coupled term's albedo is pi d (1 - E(theta_o)): with pi d = 1 the
    // model's albedo is 1 wherever the lobes reflect at most everything.
    let mut m = truth(energy_coupled_form);
    m.diffuse = [1.0 / std::f32::consts::PI; 3];
    for k in 0..8 {
        let theta = (k as f64 * 10.0).to_radians();
        let a = npf::bsdf::albedo(theta, &npf::bsdf::NpfBxdf::new(m.clone()).unwrap());
        for c in 0..3 {
            assert!((a[c] - 1.0).abs() < 1e-2, "theta {theta}: {a:?}");
        }
    }
}

#[test]
fn model_files_carry_the_diffuse_form() {
    let dir = tempfile::tempdir().unwrap();
    for form in [
        DiffuseForm::Lambert,
        energy_coupled_form(&truth(|_| DiffuseForm::Lambert)),
        DiffuseForm::OrenNayar { sigma: 0.3 },
        DiffuseForm::Separable {
            p: ashikhmin_shirley_p(),
        },
    ] {
        let m = truth(|_| form.clone());
        for ext in ["json", "npfb"] {
            let p = dir.path().join(format!("m-{}.{ext}", form.name()));
            let file = ModelFile {
                model: m.clone(),
                fit: None,
            };
            modelfile::write(&p, &file, false).unwrap();
            assert_eq!(
                modelfile::read(&p).unwrap().model,
                m,
                "{ext} {}",
                form.name()
            );
        }
    }
    // A Lambertian model writes what earlier versions wrote: no form in the
    // binary header, no trailer; JSON without the key reads as Lambert.
    let m = truth(|_| DiffuseForm::Lambert);
    let bytes = modelfile::to_binary(&m);
    assert_eq!(&bytes[6..8], &[0, 0]);
    assert_eq!(bytes.len(), 23 + 4 * m.param_count());
    let mut j: serde_json::Value = serde_json::from_str(&modelfile::to_json(&ModelFile {
        model: m.clone(),
        fit: None,
    }))
    .unwrap();
    j["model"].as_object_mut().unwrap().remove("diffuse_form");
    let back = modelfile::from_json(&j.to_string(), std::path::Path::new("old.json")).unwrap();
    assert_eq!(back.model, m);
}
