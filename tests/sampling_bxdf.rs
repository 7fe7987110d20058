//! The importance sampler against its own pdf, on synthetic models only:
//! normalisation (with the mass lost below the horizon), chi-square
//! goodness of fit of `sample` against `pdf` (as Mitsuba's and pbrt's
//! sampler tests), and the Monte Carlo weight `sample` returns.

use npf::model::{Layout, Model};
use npf::sampling::{Component, NpfBxdf, PHI_CELLS};
use npf::synth::known_factor_model;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

#[path = "common/sphere_checks.rs"]
mod sphere_checks;
use sphere_checks::{
    gamma_q, grid_p_value, integrate, panel_edges, pooled_p_value, spherical, three_lobes, wo_at,
    Vec3, GL_W, GL_X,
};

fn specular() -> Model {
    known_factor_model(Layout::default(), &[0.02])
}

fn glossy() -> Model {
    known_factor_model(Layout::default(), &[0.2])
}

fn diffuse_only() -> Model {
    let mut m = known_factor_model(Layout::default(), &[0.2]);
    m.lobes[0].s = [0.0; 3];
    m
}

/// One lobe of the three-lobe model alone (no diffuse term): the mixture is
/// then that single component.
fn lobe_only(alpha: f64) -> Model {
    let mut m = known_factor_model(Layout::default(), &[alpha]);
    m.diffuse = [0.0; 3];
    m
}

/// The glossy model with a separable diffuse factor whose P falls to 0 at
/// the horizon (Ashikhmin-Shirley's shape): its diffuse share follows the
/// view angle.
fn separable_diffuse() -> Model {
    let mut m = glossy();
    let p = npf::synth::ashikhmin_shirley_p(npf::model::SEPARABLE_NODES);
    m.diffuse_form = npf::model::DiffuseForm::Separable { p };
    m
}

fn models() -> Vec<(&'static str, NpfBxdf)> {
    vec![
        ("specular", NpfBxdf::new(specular()).unwrap()),
        ("glossy", NpfBxdf::new(glossy()).unwrap()),
        ("three-lobes", NpfBxdf::new(three_lobes()).unwrap()),
        ("diffuse", NpfBxdf::new(diffuse_only()).unwrap()),
        (
            "separable diffuse",
            NpfBxdf::new(separable_diffuse()).unwrap(),
        ),
    ]
}

/// Directions as functions of the half vector of (wi, wo): wo has azimuth
/// 0, h = (theta_h, phi_h) with phi_h in (-pi, pi], wi = 2 (wo.h) h - wo. For
/// wi above the horizon this is a bijection, so a partition of (theta_h,
/// phi_h) is a partition of the hemisphere of wi; the pdf's own cells are
/// circles of constant theta_h there, so quadrature panels can follow them.
fn wi_of(wo: Vec3, theta_h: f64, phi_h: f64) -> Vec3 {
    let h = spherical(theta_h, phi_h);
    let k = 2.0 * (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]);
    [k * h[0] - wo[0], k * h[1] - wo[1], k * h[2] - wo[2]]
}

/// Solid angle of wi per d theta_h d phi_h, by central differences of the
/// map (independent of the Jacobian the sampler uses).
fn jacobian(wo: Vec3, theta_h: f64, phi_h: f64) -> f64 {
    let d = 1e-6;
    let a = wi_of(wo, theta_h + d, phi_h);
    let b = wi_of(wo, theta_h - d, phi_h);
    let c = wi_of(wo, theta_h, phi_h + d);
    let e = wi_of(wo, theta_h, phi_h - d);
    let u = [
        (a[0] - b[0]) / (2.0 * d),
        (a[1] - b[1]) / (2.0 * d),
        (a[2] - b[2]) / (2.0 * d),
    ];
    let v = [
        (c[0] - e[0]) / (2.0 * d),
        (c[1] - e[1]) / (2.0 * d),
        (c[2] - e[2]) / (2.0 * d),
    ];
    let x = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// Half-width of the arc of phi_h (around wo's azimuth) whose wi is above
/// the horizon: wi_z = 2 (wo.h) cos theta_h - cos theta_o > 0.
fn visible_half_arc(wo: Vec3, theta_h: f64) -> f64 {
    let (co, so) = (wo[2], (wo[0] * wo[0] + wo[1] * wo[1]).sqrt());
    let (sh, ch) = theta_h.sin_cos();
    // 2 (so sh cos phi + co ch) ch > co  <=>  cos phi > c.
    let rhs = co / (2.0 * ch) - co * ch;
    let k = so * sh;
    if k <= 0.0 {
        return if rhs < 0.0 { PI } else { 0.0 };
    }
    let c = rhs / k;
    if c >= 1.0 {
        0.0
    } else if c <= -1.0 {
        PI
    } else {
        c.acos()
    }
}

/// Cell edges in theta_h: the sampler's own table edges (where its pdf
/// jumps), or a uniform grid for a model without lobes.
fn theta_h_edges(b: &NpfBxdf) -> Vec<f64> {
    match (0..b.model().lobes.len()).find_map(|m| b.lobe_distribution(m)) {
        Some(d) => d.edges().iter().map(|t| t.sqrt().min(1.0).asin()).collect(),
        None => (0..=180).map(|k| k as f64 / 180.0 * PI / 2.0).collect(),
    }
}

/// Integral of pdf(wo, wi) over the wi above the horizon whose half vector
/// lies in theta_h in [edges[0], edges[last]] (one panel per edge interval),
/// phi_h in [p0, p1] (wo at azimuth 0).
fn integrate_pdf_h(b: &NpfBxdf, wo: Vec3, edges: &[f64], p0: f64, p1: f64) -> f64 {
    let rot = wo[1].atan2(wo[0]);
    let wo0 = [(wo[0] * wo[0] + wo[1] * wo[1]).sqrt(), 0.0, wo[2]];
    let mut sum = 0.0;
    for w in edges.windows(2) {
        for (xt, wt) in GL_X.iter().zip(GL_W) {
            let th = 0.5 * (w[0] + w[1]) + 0.5 * (w[1] - w[0]) * xt;
            let arc = visible_half_arc(wo0, th);
            let (lo, hi) = (p0.max(-arc), p1.min(arc));
            if hi <= lo {
                continue;
            }
            // Panels break where the sampler's azimuth cells do (its pdf
            // jumps there), three per piece.
            let mut breaks = vec![lo];
            let cell = PI / PHI_CELLS as f64;
            for k in -(PHI_CELLS as i64)..=(PHI_CELLS as i64) {
                let x = k as f64 * cell;
                if x > lo && x < hi {
                    breaks.push(x);
                }
            }
            breaks.push(hi);
            let pieces: Vec<(f64, f64)> = breaks
                .windows(2)
                .flat_map(|w| {
                    let step = (w[1] - w[0]) / 3.0;
                    (0..3).map(move |k| (w[0] + k as f64 * step, w[0] + (k + 1) as f64 * step))
                })
                .collect();
            let mut inner = 0.0;
            for (a, c) in pieces {
                for (xp, wp) in GL_X.iter().zip(GL_W) {
                    let ph = 0.5 * (a + c) + 0.5 * (c - a) * xp;
                    let wi = wi_of(wo0, th, ph);
                    // Rotate back to wo's azimuth (the model is isotropic,
                    // but the sampler is asked about the real wo).
                    let (s, cr) = rot.sin_cos();
                    let wi = [cr * wi[0] - s * wi[1], s * wi[0] + cr * wi[1], wi[2]];
                    inner += 0.5 * (c - a) * wp * b.pdf(wo, wi) * jacobian(wo0, th, ph);
                }
            }
            sum += 0.5 * (w[1] - w[0]) * wt * inner;
        }
    }
    sum
}

#[test]
fn pdf_integrates_to_one_minus_the_mass_lost_below_the_horizon() {
    let mut rng = Pcg64::seed_from_u64(7);
    for (name, b) in models() {
        let edges = theta_h_edges(&b);
        for theta_o in [0.0f64, 30.0, 60.0, 80.0, 89.0] {
            // An azimuth other than 0, to exercise the isotropy.
            let t = theta_o.to_radians();
            let wo = spherical(t, 0.7);
            let up = integrate_pdf_h(&b, wo, &edges, -PI, PI);
            let lost = b.lost_mass(wo);
            assert!(
                (up + lost - 1.0).abs() < 1e-3,
                "{name} at {theta_o} deg: integral {up:.6} + lost {lost:.6} = {:.6}",
                up + lost
            );
            // The reported loss is what sample does.
            let n = 200_000;
            let drawn_lost = (0..n)
                .filter(|_| b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]).is_lost())
                .count() as f64
                / n as f64;
            let sigma = (lost * (1.0 - lost) / n as f64).sqrt();
            assert!(
                (drawn_lost - lost).abs() < 5.0 * sigma + 2e-4,
                "{name} at {theta_o} deg: drew {drawn_lost:.5} below the horizon, tables say {lost:.5}"
            );
            eprintln!(
                "{name:12} theta_o {theta_o:4}: pdf integral {up:.7}, lost {lost:.7}, sum {:.7}, drawn lost {drawn_lost:.6}",
                up + lost
            );
        }
    }
}

#[test]
fn pdf_integrates_to_one_on_a_plain_direction_grid() {
    // Independent of the half-vector map, for the smoother models: composite
    // Gauss-Legendre over (theta_i, phi_i), refined around the mirror direction.
    for (name, b) in models()
        .into_iter()
        .filter(|(n, _)| *n == "glossy" || *n == "diffuse")
    {
        for theta_o in [0.0f64, 50.0, 85.0] {
            let wo = wo_at(theta_o);
            let to = theta_o.to_radians();
            let thetas = panel_edges(0.0, PI / 2.0, 96, &[to, 0.0]);
            let phis = panel_edges(0.0, 2.0 * PI, 96, &[PI]);
            let up = integrate(&|wi| b.pdf(wo, wi), &thetas, &phis);
            let lost = b.lost_mass(wo);
            assert!(
                (up + lost - 1.0).abs() < 1e-3,
                "{name} at {theta_o}: {up} + {lost}"
            );
        }
    }
}

#[test]
fn sample_returns_the_pdf_and_the_weight_of_what_it_draws() {
    let mut rng = Pcg64::seed_from_u64(3);
    for (name, b) in models() {
        let mut seen_lobe = false;
        for k in 0..20_000 {
            let theta = rng.gen::<f64>() * 0.5 * PI * 0.999;
            let wo = spherical(theta, rng.gen::<f64>() * 2.0 * PI);
            let s = b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]);
            let norm = (s.wi[0].powi(2) + s.wi[1].powi(2) + s.wi[2].powi(2)).sqrt();
            assert!((norm - 1.0).abs() < 1e-9, "{name}: |wi| = {norm}");
            if s.is_lost() {
                assert!(
                    s.wi[2] <= 0.0 || b.pdf(wo, s.wi) == 0.0,
                    "{name}: lost draw above the horizon"
                );
                assert_eq!(s.weight, [0.0; 3]);
                assert_eq!(s.f, [0.0; 3]);
                continue;
            }
            if matches!(s.component, Component::Lobe(_)) {
                seen_lobe = true;
            }
            let pdf = b.pdf(wo, s.wi);
            assert!(
                pdf > 0.0 && (s.pdf - pdf).abs() <= 1e-12 * pdf,
                "{name} #{k}: {} vs {pdf}",
                s.pdf
            );
            let f = b.eval(wo, s.wi);
            let m = b.model().eval(wo, s.wi);
            for c in 0..3 {
                let expect = f[c] * s.wi[2] / pdf;
                assert!(
                    (s.weight[c] - expect).abs() <= 1e-12 * expect.abs() + 1e-300,
                    "{name}: weight"
                );
                assert!(
                    (f[c] - m[c]).abs() <= 1e-6 * m[c].abs() + 1e-12,
                    "{name}: eval {f:?} vs model {m:?}"
                );
            }
        }
        assert_eq!(seen_lobe, name != "diffuse", "{name}: lobe draws");
        // Below the horizon: zero value, zero pdf, lost draws.
        let wo = wo_at(30.0);
        assert_eq!(b.pdf(wo, [0.0, 0.6, -0.8]), 0.0);
        assert_eq!(b.eval(wo, [0.0, 0.6, -0.8]), [0.0; 3]);
        assert_eq!(b.pdf([0.0, 0.6, -0.8], wo), 0.0);
        assert!(b.sample([0.0, 0.6, -0.8], 0.5, [0.5, 0.5]).is_lost());
        assert!(b.sample([1.0, 0.0, 0.0], 0.5, [0.5, 0.5]).is_lost());
        // Odd random numbers never panic.
        for u in [0.0, 1.0, f64::NAN, -1.0, 2.0] {
            let _ = b.sample(wo, u, [u, u]);
        }
        let p: f64 = b.selection_probabilities(wo).iter().sum();
        assert!((p - 1.0).abs() < 1e-12, "{name}: selection sums to {p}");
    }
}

#[test]
fn mean_weight_is_the_directional_albedo() {
    // Against a deterministic quadrature of f cos over the hemisphere.
    for (b, theta_o) in [(glossy(), 40.0), (separable_diffuse(), 70.0)] {
        mean_weight_is_the_albedo_at(NpfBxdf::new(b).unwrap(), theta_o);
    }
}

fn mean_weight_is_the_albedo_at(b: NpfBxdf, theta_o: f64) {
    let wo = wo_at(theta_o);
    let thetas = panel_edges(0.0, PI / 2.0, 96, &[theta_o.to_radians()]);
    let phis = panel_edges(0.0, 2.0 * PI, 96, &[PI]);
    let mut rng = Pcg64::seed_from_u64(11);
    let n = 400_000;
    for c in 0..3 {
        let albedo = integrate(&|wi| b.eval(wo, wi)[c] * wi[2], &thetas, &phis);
        let mut rng_c = Pcg64::seed_from_u64(11 + c as u64);
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let w = b.sample(wo, rng_c.gen(), [rng_c.gen(), rng_c.gen()]).weight[c];
            s1 += w;
            s2 += w * w;
        }
        let mean = s1 / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - albedo).abs() < 5.0 * se + 1e-4,
            "channel {c}: {mean} +- {se} vs {albedo}"
        );
    }
    let _ = rng.gen::<f64>();
}

/// Chi-square goodness of fit of `sample` against `pdf` for one view.
/// The grid covers the sphere of wi through the half vector of (wi, wo)
/// (see [`wi_of`]) and adapts to the distribution: theta_h bands at
/// quantiles of a pilot sample, snapped to the sampler's table edges (so
/// the pdf is smooth inside each cell and the quadrature is accurate), and
/// PHI_CELLS uniform cells in phi_h; one extra cell holds the draws lost
/// below the horizon (expected: `lost_mass`). Expected counts integrate
/// `pdf` with a numerical Jacobian; cells expecting fewer than 5 are pooled
/// (as Mitsuba's and pbrt's tests). Returns the p-value.
fn chi2_p_value(b: &NpfBxdf, wo: Vec3, n: usize, seed: u64) -> f64 {
    const BANDS: usize = 24;
    const PHI_CELLS: usize = 24;
    let mut rng = Pcg64::seed_from_u64(seed);
    let draw = |rng: &mut Pcg64| b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]);
    let rot = wo[1].atan2(wo[0]);
    // (theta_h, phi_h relative to wo's azimuth) of a drawn wi.
    let half_angles = |wi: Vec3| {
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let th = (s[0] * s[0] + s[1] * s[1]).sqrt().atan2(s[2]);
        let _ = n;
        let mut ph = s[1].atan2(s[0]) - rot;
        if ph > PI {
            ph -= 2.0 * PI;
        }
        if ph <= -PI {
            ph += 2.0 * PI;
        }
        (th, ph)
    };
    let table = theta_h_edges(b);
    let mut pilot: Vec<f64> = (0..50_000)
        .map(|_| draw(&mut rng))
        .filter(|s| !s.is_lost())
        .map(|s| half_angles(s.wi).0)
        .collect();
    pilot.sort_by(f64::total_cmp);
    // Band edges: indices into the table edges.
    let mut bands = vec![0usize];
    for k in 1..BANDS {
        let q = pilot[k * pilot.len() / BANDS];
        let i = table.partition_point(|&e| e <= q).min(table.len() - 1);
        if i > *bands.last().unwrap() {
            bands.push(i);
        }
    }
    if *bands.last().unwrap() < table.len() - 1 {
        bands.push(table.len() - 1);
    }
    let phi_edge = |j: usize| -PI + 2.0 * PI * j as f64 / PHI_CELLS as f64;
    let mut expected = Vec::new();
    for w in bands.windows(2) {
        let edges = &table[w[0]..=w[1]];
        for j in 0..PHI_CELLS {
            expected.push(n as f64 * integrate_pdf_h(b, wo, edges, phi_edge(j), phi_edge(j + 1)));
        }
    }
    expected.push(n as f64 * b.lost_mass(wo));
    let mut observed = vec![0.0; expected.len()];
    let lost_cell = expected.len() - 1;
    for _ in 0..n {
        let s = draw(&mut rng);
        if s.is_lost() {
            observed[lost_cell] += 1.0;
            continue;
        }
        let (th, ph) = half_angles(s.wi);
        let i = table.partition_point(|&e| e <= th);
        let band = bands.partition_point(|&e| e < i).clamp(1, bands.len() - 1) - 1;
        let j = (((ph + PI) / (2.0 * PI) * PHI_CELLS as f64) as usize).min(PHI_CELLS - 1);
        observed[band * PHI_CELLS + j] += 1.0;
    }
    for (e, o) in expected.iter().zip(&observed) {
        assert!(!(*e == 0.0 && *o > 0.0), "draws in a cell of zero pdf");
    }
    let total_e: f64 = expected.iter().sum();
    assert!(
        (total_e / n as f64 - 1.0).abs() < 1e-3,
        "expected counts sum to {total_e} of {n}"
    );
    pooled_p_value(&expected, &observed)
}

#[test]
fn chi_square_sample_matches_pdf() {
    let views = [0.0, 45.0, 85.0];
    let all = models();
    let tests = all.len() * views.len();
    // Sidak-corrected per-test level for a 1% family-wise level.
    let alpha = 1.0 - (1.0 - 0.01f64).powf(1.0 / tests as f64);
    let mut failures = Vec::new();
    for (i, (name, b)) in all.iter().enumerate() {
        for (j, &theta_o) in views.iter().enumerate() {
            let p = chi2_p_value(b, wo_at(theta_o), 400_000, 100 + (i * 10 + j) as u64);
            eprintln!("chi2 {name:12} theta_o {theta_o:4}: p = {p:.4}");
            if p.is_nan() || p <= alpha {
                failures.push(format!(
                    "{name} at {theta_o} deg: p = {p:.3e} < {alpha:.3e}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn chi_square_each_component_matches_its_pdf() {
    // Each lobe component alone (its view table at the nearest view node,
    // between nodes too: 40 and 70 degrees are off the 5.93-degree grid);
    // the diffuse component alone is the "diffuse" model above.
    let views = [0.0, 40.0, 70.0, 87.0];
    let lobes = [0.02, 0.15, 0.5];
    let tests = lobes.len() * views.len();
    let alpha = 1.0 - (1.0 - 0.01f64).powf(1.0 / tests as f64);
    let mut failures = Vec::new();
    for (i, &a) in lobes.iter().enumerate() {
        let b = NpfBxdf::new(lobe_only(a)).unwrap();
        assert_eq!(b.selection_probabilities(wo_at(10.0))[0], 0.0);
        for (j, &theta_o) in views.iter().enumerate() {
            let p = chi2_p_value(&b, wo_at(theta_o), 200_000, 300 + (i * 10 + j) as u64);
            eprintln!("chi2 lobe {a:5} theta_o {theta_o:4}: p = {p:.4}");
            if p.is_nan() || p <= alpha {
                failures.push(format!(
                    "lobe {a} at {theta_o} deg: p = {p:.3e} < {alpha:.3e}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn isotropic_eval_matches_the_full_angle_map() {
    // Model::eval skips the azimuths for isotropic tables; the value must be
    // eval_angles at the full Rusinkiewicz angles, to rounding.
    let m = three_lobes();
    let mut rng = Pcg64::seed_from_u64(11);
    let mut worst = 0.0f64;
    for _ in 0..20_000 {
        let wo = spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI);
        let wi = if rng.gen::<bool>() {
            // Near the mirror direction, where the specular lobe is.
            let r = [-wo[0], -wo[1], wo[2]];
            let d = [
                rng.gen::<f64>() - 0.5,
                rng.gen::<f64>() - 0.5,
                rng.gen::<f64>() - 0.5,
            ];
            let e = 0.02 * rng.gen::<f64>();
            let v = [r[0] + e * d[0], r[1] + e * d[1], r[2] + e * d[2]];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / n, v[1] / n, v[2] / n]
        } else {
            spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI)
        };
        if wi[2] <= 0.0 {
            continue;
        }
        let fast = m.eval(wo, wi);
        let full = m.eval_angles(&npf_data_loaders::geometry::Angles::from_directions(wi, wo));
        for c in 0..3 {
            let rel = (fast[c] - full[c]).abs() / full[c].abs().max(1e-300);
            worst = worst.max(if full[c] == 0.0 { fast[c].abs() } else { rel });
        }
    }
    eprintln!("fast vs full angle map: largest relative difference {worst:e}");
    assert!(worst < 1e-9, "largest relative difference {worst:e}");
}

/// Random pairs, half of them near the mirror direction (where the
/// specular lobes are), both above the horizon.
fn test_pairs(seed: u64, n: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let wo = spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI);
        let wi = if rng.gen::<bool>() {
            let r = [-wo[0], -wo[1], wo[2]];
            let e = 0.02 * rng.gen::<f64>().powi(3);
            let v: Vec<f64> = (0..3)
                .map(|c| r[c] + e * (rng.gen::<f64>() - 0.5))
                .collect();
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / n, v[1] / n, v[2] / n]
        } else {
            spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI)
        };
        if wi[2] > 0.0 {
            out.push((wo, wi));
        }
    }
    out
}

#[test]
fn the_flat_evaluator_matches_model_eval() {
    // NpfBxdf::eval runs a flattened copy of the model (fused lobes, inline
    // stencils and arccosine); it must give Model::eval's value.
    for (name, b) in models() {
        let mut worst = 0.0f64;
        for (wo, wi) in test_pairs(21, 50_000) {
            let (fast, model) = (b.eval(wo, wi), b.model().eval(wo, wi));
            for c in 0..3 {
                let d = (fast[c] - model[c]).abs();
                worst = worst.max(if model[c] == 0.0 { d } else { d / model[c] });
            }
        }
        eprintln!("{name}: flat eval vs Model::eval, largest relative difference {worst:e}");
        assert!(worst < 1e-9, "{name}: {worst:e}");
    }
}

#[test]
fn the_fused_pdf_matches_the_per_lobe_tables() {
    // pdf reads one fused row of densities after a guide-table search and
    // an azimuth test by comparisons; pdf_reference reads each lobe's table
    // after a binary search and atan2.
    for (name, b) in models() {
        let mut pairs = test_pairs(22, 30_000);
        // And the sampler's own draws, which sit where the tables have mass.
        let mut rng = Pcg64::seed_from_u64(23);
        for _ in 0..30_000 {
            let wo = spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI);
            let s = b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]);
            if !s.is_lost() {
                pairs.push((wo, s.wi));
            }
        }
        let mut worst = 0.0f64;
        for (wo, wi) in pairs {
            let (fast, reference) = (b.pdf(wo, wi), b.pdf_reference(wo, wi));
            let d = (fast - reference).abs();
            worst = worst.max(if reference == 0.0 { d } else { d / reference });
        }
        eprintln!("{name}: fused pdf vs per-lobe tables, largest relative difference {worst:e}");
        assert!(worst < 1e-12, "{name}: {worst:e}");
    }
}

#[test]
fn models_with_more_lobes_than_the_selection_row_sample_their_pdf() {
    // A draw computes the selection shares of the diffuse term and four
    // lobes once; lobes past those are interpolated where used. Six lobes
    // exercise both: sample's pdf is pdf's, which is pdf_reference's.
    let mut m = known_factor_model(Layout::default(), &[0.02, 0.05, 0.1, 0.2, 0.4, 0.8]);
    m.diffuse = [0.1, 0.2, 0.3];
    let b = NpfBxdf::new(m).unwrap();
    let mut rng = Pcg64::seed_from_u64(31);
    let mut drawn = [0usize; 7];
    for k in 0..20_000 {
        let wo = spherical(rng.gen::<f64>() * 1.55, rng.gen::<f64>() * 2.0 * PI);
        let s = b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]);
        let p: f64 = b.selection_probabilities(wo).iter().sum();
        assert!((p - 1.0).abs() < 1e-12, "selection sums to {p}");
        if s.is_lost() {
            continue;
        }
        drawn[match s.component {
            Component::Diffuse => 0,
            Component::Lobe(m) => 1 + m,
        }] += 1;
        let (pdf, reference) = (b.pdf(wo, s.wi), b.pdf_reference(wo, s.wi));
        assert!(
            pdf > 0.0 && (s.pdf - pdf).abs() <= 1e-12 * pdf,
            "#{k}: sample's pdf {} vs pdf {pdf}",
            s.pdf
        );
        assert!(
            (pdf - reference).abs() <= 1e-12 * reference,
            "#{k}: pdf {pdf} vs reference {reference}"
        );
    }
    // Every component is drawn (each has at least a 1% share).
    assert!(
        drawn.iter().all(|&n| n > 50),
        "draws per component {drawn:?}"
    );
}

#[test]
fn chi_square_detects_a_wrong_pdf() {
    // The same test must reject a sampler whose pdf is off: compare the
    // glossy model's draws with the three-lobe model's pdf.
    let wo = wo_at(30.0);
    let good = NpfBxdf::new(glossy()).unwrap();
    let p_good = chi2_p_value(&good, wo, 100_000, 5);
    assert!(p_good > 1e-3, "{p_good}");
    // A model that differs only a little: alpha 0.2 vs 0.22.
    let other = NpfBxdf::new(known_factor_model(Layout::default(), &[0.22])).unwrap();
    let p_bad = grid_p_value(&good, &other, wo, 200_000, 9);
    assert!(p_bad < 1e-6, "a wrong pdf passed: p = {p_bad}");
}

#[test]
fn chi_square_helper_is_calibrated() {
    // Q(k/2, x/2) for known chi-square quantiles.
    assert!((gamma_q(0.5, 3.841_458_820_694_124 / 2.0) - 0.05).abs() < 1e-9);
    assert!((gamma_q(5.0, 23.209_251_158_954_36 / 2.0) - 0.01).abs() < 1e-9);
    assert!((gamma_q(50.0, 124.342_113_404_3 / 2.0) - 0.05).abs() < 1e-8);
}
