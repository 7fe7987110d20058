//! The Bsdf interface: every implementation (factor model, GGX + Lambert,
//! measured table) draws what its pdf says and weighs by f cos / pdf.

#[path = "common/sphere_checks.rs"]
mod sphere_checks;
use sphere_checks::{grid_p_value, integrate, panel_edges, spherical, three_lobes, wo_at, Vec3};

use npf::model::Layout;
use npf::sampling::NpfBxdf;
use npf::synth::known_factor_model;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

use npf::bsdf::{Bsdf, BsdfSample};
use npf::microfacet::GgxParams;

fn ggx(alpha: f64) -> GgxParams {
    GgxParams {
        kd: [0.05, 0.08, 0.12],
        ks: [1.0, 0.9, 0.8],
        f0: [0.95, 0.64, 0.54],
        alpha,
    }
}

fn implementations() -> Vec<(&'static str, Box<dyn Bsdf + Sync>)> {
    let table = npf::synth::GgxLambert {
        kd: [0.05, 0.08, 0.12],
        f0: [0.95, 0.64, 0.54],
        alpha: 0.2,
    }
    .table();
    vec![
        ("factor", Box::new(NpfBxdf::new(three_lobes()).unwrap())),
        ("ggx-0.1", Box::new(ggx(0.1))),
        ("ggx-0.4", Box::new(ggx(0.4))),
        ("merl", Box::new(table)),
    ]
}

/// Stratified random numbers, `k` x `k` for the direction, `uc` cycled.
fn strata(k: usize) -> impl Iterator<Item = (f64, [f64; 2])> {
    (0..k * k).map(move |i| {
        let (a, b) = (i % k, i / k);
        let uc = ((i * 7919) % 1000) as f64 / 1000.0;
        (
            uc,
            [(a as f64 + 0.5) / k as f64, (b as f64 + 0.5) / k as f64],
        )
    })
}

#[test]
fn every_bsdf_sample_agrees_with_its_pdf_and_eval() {
    for (name, b) in implementations() {
        for theta_o in [0.0, 45.0, 80.0] {
            let wo = wo_at(theta_o);
            let mut drawn = 0;
            for (uc, u) in strata(64) {
                let Some(s): Option<BsdfSample> = b.sample(wo, uc, u) else {
                    continue;
                };
                drawn += 1;
                assert!(s.wi[2] > 0.0 && s.pdf > 0.0, "{name}: {s:?}");
                let n = (s.wi[0].powi(2) + s.wi[1].powi(2) + s.wi[2].powi(2)).sqrt();
                assert!((n - 1.0).abs() < 1e-12, "{name}: |wi| = {n}");
                let pdf = b.pdf(wo, s.wi);
                assert!(
                    (s.pdf - pdf).abs() <= 1e-12 * pdf,
                    "{name}: {} vs {pdf}",
                    s.pdf
                );
                assert_eq!(s.f, b.eval(wo, s.wi), "{name}");
                for c in 0..3 {
                    let w = s.f[c] * s.wi[2] / s.pdf;
                    assert!((s.weight[c] - w).abs() <= 1e-12 * w.abs(), "{name}");
                    assert!(s.f[c] >= 0.0, "{name}: negative value {s:?}");
                }
            }
            assert!(
                drawn > 64 * 64 / 2,
                "{name} at {theta_o}: only {drawn} draws"
            );
            // Outside the hemisphere: nothing, and no panic on odd numbers.
            assert!(b.sample([0.0, 0.6, -0.8], 0.5, [0.5, 0.5]).is_none());
            assert_eq!(b.pdf(wo, [0.0, 0.6, -0.8]), 0.0);
            let _ = b.sample(wo, f64::NAN, [2.0, -1.0]);
        }
    }
}

/// The pdf integrates to 1 minus the mass the sampler loses below the
/// horizon (that mass counted from stratified draws).
#[test]
fn every_bsdf_pdf_integrates_to_one_minus_its_lost_mass() {
    for (name, b) in implementations() {
        for theta_o in [0.0, 45.0, 80.0] {
            let wo = wo_at(theta_o);
            let k = 400;
            let lost = strata(k)
                .filter(|&(uc, u)| b.sample(wo, uc, u).is_none())
                .count() as f64
                / (k * k) as f64;
            // Refine around the mirror direction, where the GGX peak is.
            let th = panel_edges(0.0, PI / 2.0, 96, &[theta_o.to_radians()]);
            let ph = panel_edges(-PI, PI, 96, &[PI, -PI]);
            let total = integrate(&|wi| b.pdf(wo, wi), &th, &ph);
            eprintln!("{name:8} theta_o {theta_o:4}: integral {total:.6}, lost {lost:.6}");
            assert!(
                (total - (1.0 - lost)).abs() < 2e-3,
                "{name} at {theta_o}: {total} + {lost}"
            );
        }
    }
}

#[test]
fn chi_square_ggx_sampler_matches_its_pdf() {
    let cases: Vec<(f64, f64)> = [0.1, 0.4]
        .iter()
        .flat_map(|&a| [0.0, 45.0, 80.0].map(|t| (a, t)))
        .collect();
    let level = 1.0 - (1.0 - 0.01f64).powf(1.0 / cases.len() as f64);
    for (k, &(alpha, theta_o)) in cases.iter().enumerate() {
        let b = ggx(alpha);
        let p = grid_p_value(&b, &b, wo_at(theta_o), 300_000, 40 + k as u64);
        eprintln!("chi2 ggx alpha {alpha} theta_o {theta_o}: p = {p:.4}");
        assert!(p > level, "GGX alpha {alpha} at {theta_o} deg: p = {p:.3e}");
    }
    // And the same test rejects a slightly wrong pdf (alpha 0.3 vs 0.33).
    let p_bad = grid_p_value(&ggx(0.3), &ggx(0.33), wo_at(30.0), 300_000, 7);
    assert!(p_bad < 1e-6, "a wrong pdf passed: p = {p_bad}");
}

/// The trait's view of the factor sampler is its inherent one, with the
/// lost draws as `None`.
#[test]
fn factor_bsdf_trait_matches_the_inherent_sampler() {
    let b = NpfBxdf::new(three_lobes()).unwrap();
    for theta_o in [0.0, 60.0, 85.0] {
        let wo = wo_at(theta_o);
        for (uc, u) in strata(32) {
            let inherent = b.sample(wo, uc, u);
            let via = Bsdf::sample(&b, wo, uc, u);
            assert_eq!(via, Some(inherent).filter(|s| !s.is_lost()));
            // The flat evaluator: Model::eval's value to rounding.
            let (f, m) = (
                Bsdf::eval(&b, wo, inherent.wi),
                b.model().eval(wo, inherent.wi),
            );
            for c in 0..3 {
                assert!((f[c] - m[c]).abs() <= 1e-12 * m[c].abs(), "{f:?} {m:?}");
            }
        }
    }
}

/// The clamp the sampler used to miss: where Catmull-Rom G undershoots
/// below 0, a lobe's term is negative; the BSDF's value is `Model::eval`
/// (clamped at 0), so no value and no weight is negative.
#[test]
fn factor_bsdf_values_are_clamped_where_catmull_rom_g_undershoots() {
    let mut m = known_factor_model(Layout::default(), &[0.3]);
    m.diffuse = [0.0; 3];
    // Pairs of zero control points between ones: the spline dips below 0.
    for (k, g) in m.lobes[0].g.iter_mut().enumerate() {
        *g = if k % 3 == 0 { 1.0 } else { 0.0 };
    }
    let b = NpfBxdf::new(m.clone()).unwrap();
    let mut negative = 0;
    for i in 0..60 {
        for o in 0..60 {
            let wi = spherical(0.013 * i as f64 + 0.005, 0.4);
            let wo = spherical(0.013 * o as f64 + 0.005, 2.9);
            let a = npf::loaders::geometry::Angles::from_directions(wi, wo);
            let mut unclamped = 0.0;
            m.lobe_terms(&a, |_, t| unclamped += t[0]);
            let v = Bsdf::eval(&b, wo, wi);
            assert!(v.iter().all(|&x| x >= 0.0), "{v:?}");
            if unclamped < 0.0 {
                negative += 1;
                assert_eq!(v[0], 0.0);
            }
        }
    }
    assert!(negative > 0, "the test model never undershoots");
    for (uc, u) in strata(32) {
        if let Some(s) = Bsdf::sample(&b, wo_at(40.0), uc, u) {
            assert!(s.weight.iter().all(|&w| w >= 0.0), "{s:?}");
        }
    }
}

// ------------------------------------------------------ white-furnace variance

/// Per-sample variance of the luminance weight lum(f) cos / pdf at wo, of
/// npf's draw and of cosine sampling (same random numbers).
fn white_furnace_variances(b: &NpfBxdf, wo: Vec3, n: usize, seed: u64) -> (f64, f64) {
    let lum = |f: [f64; 3]| 0.2126 * f[0] + 0.7152 * f[1] + 0.0722 * f[2];
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut a, mut c) = ([0.0; 2], [0.0; 2]);
    for _ in 0..n {
        let (ul, u): (f64, [f64; 2]) = (rng.gen(), [rng.gen(), rng.gen()]);
        let w = lum(b.sample(wo, ul, u).weight);
        a[0] += w;
        a[1] += w * w;
        let wi = npf::bsdf::cosine_hemisphere(u);
        let w = if wi[2] > 0.0 {
            lum(b.eval(wo, wi)) * PI
        } else {
            0.0
        };
        c[0] += w;
        c[1] += w * w;
    }
    let var = |s: [f64; 2]| s[1] / n as f64 - (s[0] / n as f64).powi(2);
    (var(a), var(c))
}

#[test]
fn near_lambertian_draws_are_no_worse_than_cosine_sampling() {
    // A diffuse term with a broad lobe that carries most of the albedo:
    // the lobe's visible-normal draw follows D while f there is shaped by
    // G, F and 1 / (cos i cos o), so albedo-proportional selection alone
    // can lose to plain cosine sampling; the selection's defensive cosine
    // share must keep the white-furnace variance at or below cosine's.
    for (alpha, diffuse) in [(0.5, 0.2), (0.8, 0.05), (0.3, 0.5)] {
        let mut m = known_factor_model(Layout::default(), &[alpha]);
        m.diffuse = [diffuse; 3];
        let b = NpfBxdf::new(m).unwrap();
        for (k, theta) in [0.0, 40.0, 70.0].into_iter().enumerate() {
            let (npf, cosine) = white_furnace_variances(&b, wo_at(theta), 200_000, 40 + k as u64);
            eprintln!("alpha {alpha} diffuse {diffuse} theta_o {theta}: npf {npf:.4e} cosine {cosine:.4e}");
            // 5% for the estimates' own noise at 200k draws.
            assert!(
                npf <= 1.05 * cosine,
                "alpha {alpha} diffuse {diffuse} at {theta} deg: npf {npf:.4e} > cosine {cosine:.4e}"
            );
        }
    }
}
