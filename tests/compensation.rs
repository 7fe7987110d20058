//! White furnace of an energy-compensated fitted model: with F = 1 and no
//! diffuse term, the model plus its Kulla-Conty term from its own lobes
//! reflects everything it receives. Convention: albedo 1, i.e. the integral
//! of f cos theta_i over the incident hemisphere is 1 at every theta_o (the
//! hemispherical double integral of f cos cos is then pi).

use npf::bsdf::{albedo, Bsdf, Compensated, NpfBxdf};
use npf::energy::coupled::specular_albedo;
use npf::model::{Layout, Model};
use npf::reconstruct::to_merl;
use npf::samples::{FitSet, SampleOptions};
use npf::solver::{Executor, FitOptions};
use npf::synth::known_factor_model;

/// A factor model with F = 1 and d = 0 whose lobes reflect at most `top`.
fn white(alphas: &[f64], top: f64) -> Model {
    let mut m = known_factor_model(Layout::default(), alphas);
    m.diffuse = [0.0; 3];
    for f in m.fresnel.iter_mut() {
        f.iter_mut().for_each(|v| *v = 1.0);
    }
    let e = specular_albedo(&m);
    let most = e.iter().flatten().cloned().fold(0.0, f64::max);
    for l in m.lobes.iter_mut() {
        for v in l.s.iter_mut() {
            *v *= (top / most) as f32;
        }
    }
    m
}

fn furnace(m: Model) -> f64 {
    let comp = Compensated::new(m.clone()).unwrap();
    let plain = NpfBxdf::new(m).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..=17 {
        let theta = (5.0 * k as f64).to_radians();
        let (a, b) = (albedo(theta, &comp), albedo(theta, &plain));
        for c in 0..3 {
            eprintln!(
                "theta {:>2} c{c}: single {:.5} compensated {:.5}",
                5 * k,
                b[c],
                a[c]
            );
            worst = worst.max((a[c] - 1.0).abs());
        }
    }
    worst
}

#[test]
fn white_furnace_of_a_compensated_known_model_is_one_within_1e_3() {
    let worst = furnace(white(&[0.3, 0.6], 0.8));
    assert!(worst < 1e-3, "worst |albedo - 1| = {worst}");
}

#[test]
fn white_furnace_of_a_compensated_fit_is_one_within_1e_3() {
    // Fit the white model's table, then set the fit's F to 1 and drop its
    // diffuse term: the compensated fit must pass the same furnace.
    let truth = white(&[0.35], 0.7);
    let mut s = to_merl(&truth).samples("white");
    s.samples = s.samples.into_iter().step_by(9).collect();
    let set = FitSet::build(&s, Layout::default(), SampleOptions::default()).unwrap();
    let fit = Executor::new(
        &set,
        FitOptions {
            lobes: 1,
            max_sweeps: 20,
            ..Default::default()
        },
    )
    .run()
    .unwrap();
    let mut m = fit.model;
    m.diffuse = [0.0; 3];
    for f in m.fresnel.iter_mut() {
        f.iter_mut().for_each(|v| *v = 1.0);
    }
    let worst = furnace(m);
    assert!(worst < 1e-3, "worst |albedo - 1| = {worst}");
}

#[test]
fn compensated_sampler_pdf_matches_its_draws() {
    let comp = Compensated::new(white(&[0.3], 0.8)).unwrap();
    let wo = [0.5f64.sin(), 0.0, 0.5f64.cos()];
    let mut n = 0;
    for i in 0..64 {
        for j in 0..64 {
            let u = [(i as f64 + 0.5) / 64.0, (j as f64 + 0.5) / 64.0];
            if let Some(s) = comp.sample(wo, ((i * 64 + j) as f64 * 0.618).fract(), u) {
                assert!((s.pdf - comp.pdf(wo, s.wi)).abs() <= 1e-9 * s.pdf);
                let f = comp.eval(wo, s.wi);
                assert_eq!(f, s.f);
                n += 1;
            }
        }
    }
    assert!(n > 3000);
}
