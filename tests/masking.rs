//! Height-correlated masking and the compensation option: a G2 model is
//! fitted back from its own table (and better than the separable form
//! can), the objective never rises in the G2 pass, model files carry both
//! options, the shader exports refuse them, and a compensated fit with
//! F = 1 passes the white furnace.

use npf::bsdf::{albedo, NpfBxdf};
use npf::energy::coupled::{compensation, specular_albedo};
use npf::fit::{fit, FitConfig};
use npf::loaders::MeasuredSamples;
use npf::metrics::compare_model;
use npf::model::{Layout, Masking, Model};
use npf::modelfile::{self, ModelFile};
use npf::samples::{FitSet, SampleOptions};
use npf::solver::{FitOptions, FitResult};
use npf::synth::known_factor_model;

#[path = "common/monotone.rs"]
mod monotone;
use monotone::assert_stages_monotone;
#[path = "common/synthetic_fit.rs"]
mod synthetic_fit;
use synthetic_fit::{fit_one_lobe, samples};

/// A one-lobe known model with height-correlated masking (its G is GGX's
/// Smith G1, at most 1).
fn g2_truth() -> Model {
    // Rough (Smith G1 of alpha 0.9): G2 then differs from the product.
    let mut m = known_factor_model(Layout::default(), &[0.6]);
    m.masking = Masking::HeightCorrelated;
    m
}

fn fit_from(
    s: &MeasuredSamples,
    masking: Masking,
    sweeps: usize,
    trace: bool,
    start: Option<&Model>,
) -> FitResult {
    let opts = FitOptions {
        masking,
        ..Default::default()
    };
    fit_one_lobe(s, opts, sweeps, trace, start)
}

fn fit_with(s: &MeasuredSamples, masking: Masking, sweeps: usize, trace: bool) -> FitResult {
    fit_from(s, masking, sweeps, trace, None)
}

#[test]
fn height_correlated_truth_is_recovered_and_its_g_is_a_g1() {
    // Started from the true D, F and s with G scaled by 0.8: for the
    // separable form a pure gauge, for G2 a different model (G2 is not
    // homogeneous in G), so the G2 pass must move G back. Measured: G2 fit
    // relative cos-RMSE 1.0e-3 after 40 sweeps, the separable form 7.3e-3.
    let truth = g2_truth();
    let s = samples(&truth, 5);
    let mut start = truth.clone();
    start.lobes[0].g.iter_mut().for_each(|v| *v *= 0.8);
    let own = fit_from(&s, Masking::HeightCorrelated, 40, false, Some(&start));
    let sep = fit_from(&s, Masking::Separable, 40, false, Some(&start));
    let (a, b) = (
        compare_model(&s, 85.0, &own.model),
        compare_model(&s, 85.0, &sep.model),
    );
    eprintln!(
        "G2 truth: own {} sweeps rel {:.3e}, separable {} sweeps rel {:.3e}",
        own.history.len(),
        a.rel_cos_rmse,
        sep.history.len(),
        b.rel_cos_rmse
    );
    // G2 is nearly homogeneous in G where G is near 1, so G's level is
    // only weakly identified (traded with s); what must hold is that G
    // stays a G1.
    let g = &own.model.lobes[0].g;
    assert_eq!(own.model.masking, Masking::HeightCorrelated);
    assert!(a.rel_cos_rmse < 2e-3, "{a:?}");
    assert!(a.rel_cos_rmse < 0.3 * b.rel_cos_rmse, "{a:?} vs {b:?}");
    assert!(g.iter().all(|&v| (0.0..=1.0 + 1e-3).contains(&v)), "{g:?}");
}

#[test]
fn objective_never_rises_in_the_height_correlated_g_pass() {
    let s = samples(&g2_truth(), 11);
    let res = fit_with(&s, Masking::HeightCorrelated, 8, true);
    assert_stages_monotone(&res, "height-correlated");
    assert!(res.objective < 0.5 * res.initial_objective);
    assert!(res.history.iter().any(|r| r.g_passes[0].accepted > 0));
}

#[test]
fn model_files_carry_masking_and_compensation() {
    let mut m = g2_truth();
    m.compensation = Some(compensation(&m));
    let dir = tempfile::tempdir().unwrap();
    for name in ["m.json", "m.npfb"] {
        let p = dir.path().join(name);
        let file = ModelFile {
            model: m.clone(),
            fit: None,
        };
        modelfile::write(&p, &file, false).unwrap();
        let back = modelfile::read(&p).unwrap().model;
        assert_eq!(back, m, "{name}");
    }
    // A separable, uncompensated model writes no new field: its JSON is
    // what older versions wrote and read.
    let plain = known_factor_model(Layout::default(), &[0.35]);
    let p = dir.path().join("plain.json");
    let file = ModelFile {
        model: plain,
        fit: None,
    };
    modelfile::write(&p, &file, false).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    let model_part = &text[text.find("\"model\"").unwrap()..];
    assert!(!model_part.contains("\"masking\"") && !model_part.contains("\"compensation\""));
    // Evaluation reads both: G2 lies above the separable product, and the
    // compensation term adds energy.
    let wo = [0.3f64, 0.0, (1.0f64 - 0.09).sqrt()];
    let wi = [-0.6f64, 0.1, (1.0f64 - 0.37).sqrt()];
    let mut sep = m.clone();
    sep.masking = Masking::Separable;
    sep.compensation = None;
    let mut g2 = m.clone();
    g2.compensation = None;
    let (a, b, c) = (sep.eval(wo, wi), g2.eval(wo, wi), m.eval(wo, wi));
    assert!(b[0] > a[0] && c[2] > b[2], "{a:?} {b:?} {c:?}");
}

#[test]
fn shader_exports_refuse_what_they_cannot_express() {
    let m = g2_truth();
    let e = npf::export::shader::glsl(&m).unwrap_err().to_string();
    assert!(e.contains("height-correlated"), "{e}");
    let mut c = known_factor_model(Layout::default(), &[0.35]);
    c.compensation = Some(compensation(&c));
    let e = npf::export::shader::c_header(&c).unwrap_err().to_string();
    assert!(e.contains("compensation"), "{e}");
}

/// `compensate: true` on a fit of a white (F = 1, d = 0) table: with the
/// fitted F set to 1 and d to 0, and the term recomputed for that F, the
/// compensated model's albedo (Model::eval through the sampler's BSDF) is 1
/// within 1e-3 at every theta_o up to 85 degrees.
#[test]
fn white_furnace_of_a_compensate_fit_is_one_within_1e_3() {
    let mut truth = known_factor_model(Layout::default(), &[0.35]);
    truth.diffuse = [0.0; 3];
    for f in truth.fresnel.iter_mut() {
        f.iter_mut().for_each(|v| *v = 1.0);
    }
    // At most 80 % single scattering (a lobe reflecting more than it
    // receives leaves nothing to compensate).
    let e = specular_albedo(&truth);
    let most = e.iter().flatten().cloned().fold(0.0, f64::max);
    for v in truth.lobes[0].s.iter_mut() {
        *v *= (0.8 / most) as f32;
    }
    let s = samples(&truth, 9);
    let config = FitConfig {
        lobes: 1,
        max_sweeps: 20,
        threads: 1,
        compensate: true,
        ..FitConfig::default()
    };
    let fitted = fit(&s, &config, &mut |_, _| {}).unwrap();
    assert!(fitted.result.model.compensation.is_some());
    let mut m = fitted.result.model;
    m.diffuse = [0.0; 3];
    for f in m.fresnel.iter_mut() {
        f.iter_mut().for_each(|v| *v = 1.0);
    }
    m.compensation = Some(compensation(&m));
    let b = NpfBxdf::new(m).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..=17 {
        let theta = (5.0 * k as f64).to_radians();
        let a = albedo(theta, &b);
        for v in a {
            worst = worst.max((v - 1.0).abs());
        }
    }
    eprintln!("compensated fit: worst |albedo - 1| = {worst:.2e}");
    assert!(worst < 1e-3, "worst |albedo - 1| = {worst}");
}

/// The grazing taper: weights past it fall linearly to 0 at the horizon
/// (the same samples are kept), and a bad start angle is refused.
#[test]
fn grazing_taper_weights_fall_linearly_past_its_start() {
    let truth = known_factor_model(Layout::default(), &[0.35]);
    let s = samples(&truth, 7);
    let plain = SampleOptions {
        max_theta_deg: 89.0,
        ..Default::default()
    };
    let taper = SampleOptions {
        taper_from_deg: Some(80.0),
        ..plain
    };
    let (a, b) = (
        FitSet::build(&s, Layout::default(), plain).unwrap(),
        FitSet::build(&s, Layout::default(), taper).unwrap(),
    );
    assert_eq!(a.len(), b.len());
    let mut tapered = 0;
    for j in 0..a.len() {
        let theta = (b.dirs[j][0].max(b.dirs[j][1]) as f64).to_degrees();
        let want = if theta > 80.0 {
            (90.0 - theta) / 10.0
        } else {
            1.0
        };
        for c in 0..3 {
            let ratio = b.w[j][c] / a.w[j][c];
            assert!(
                (ratio - want).abs() < 1e-5,
                "theta {theta}: {ratio} vs {want}"
            );
        }
        tapered += (theta > 80.0) as usize;
    }
    assert!(tapered > 0);
    let bad = SampleOptions {
        taper_from_deg: Some(90.0),
        ..plain
    };
    assert!(FitSet::build(&s, Layout::default(), bad).is_err());
}
