//! The compressive weighting's data-relative floor and its pooled weights
//! near the mirror direction (issue 16: tables whose exact zeros and
//! phi_d-varying peaks the default floor and own-value weights followed).

use npf::fit::FitConfig;
use npf::model::Layout;
use npf::reconstruct::to_merl;
use npf::samples::{FitSet, SampleOptions};
use npf::solver::{Executor, Factors, FitOptions};
use npf::synth::known_factor_model;

/// The floor a fit uses is the larger of `epsilon` and the fraction times
/// the median of rho cos theta_i (channel mean) inside the cut-off.
#[test]
fn floor_is_the_larger_of_epsilon_and_a_fraction_of_the_median() {
    let truth = known_factor_model(Layout::default(), &[0.3]);
    let s = to_merl(&truth).samples("synthetic");
    let cut = 85f64.to_radians();
    let mut v: Vec<f64> = s
        .samples
        .iter()
        .filter(|x| x.angles.theta_i <= cut && x.angles.theta_o <= cut)
        .map(|x| x.rgb.iter().sum::<f64>() / 3.0 * x.angles.theta_i.cos())
        .collect();
    v.sort_by(f64::total_cmp);
    let median = v[v.len() / 2];
    let c = FitConfig {
        epsilon_median: 0.5,
        ..Default::default()
    };
    // The relative branch is the one exercised.
    assert!(0.5 * median > c.epsilon, "median {median}");
    assert_eq!(c.epsilon_for(&s), 0.5 * median);
    let off = FitConfig {
        epsilon_median: 0.0,
        ..c.clone()
    };
    assert_eq!(off.epsilon_for(&s), c.epsilon);
    let high = FitConfig {
        epsilon: 1e2,
        ..c.clone()
    };
    assert_eq!(high.epsilon_for(&s), 1e2);
    // Out of range is refused before any work.
    let bad = FitConfig {
        epsilon_median: -1.0,
        ..c
    };
    assert!(bad.validate().is_err());
}

/// A peak that varies along phi_d (which an isotropic model cannot follow
/// at theta_h = 0) by a factor 1 + 0.8 cos 2 phi_d of mean 1: with weights
/// from each sample's own value the fit's peak falls to about a third of
/// the mean (sum 1/y over sum 1/y^2), with pooled weights it stays at it.
#[test]
fn pooled_weights_keep_a_phi_d_varying_peak_at_its_mean() {
    let truth = known_factor_model(Layout::default(), &[0.05]);
    let mut s = to_merl(&truth).samples("synthetic");
    let limit = 1.6f64.to_radians();
    for x in &mut s.samples {
        if x.angles.theta_h < limit {
            let f = 1.0 + 0.8 * (2.0 * x.angles.phi_d).cos();
            x.rgb = x.rgb.map(|v| v * f);
        }
    }
    let peak_ratio = |pool: Option<f64>| {
        let so = SampleOptions {
            pool_scale_below_deg: pool,
            ..Default::default()
        };
        let model = fit_one_lobe(&s, so, &truth);
        // The mirror direction at 30 degrees (theta_h = 0).
        let t = 30f64.to_radians();
        let (wi, wo) = ([t.sin(), 0.0, t.cos()], [-t.sin(), 0.0, t.cos()]);
        let (m, r) = (model.eval(wo, wi), truth.eval(wo, wi));
        (0..3).map(|c| m[c] / r[c]).sum::<f64>() / 3.0
    };
    let pooled = peak_ratio(Some(1.6));
    let own = peak_ratio(None);
    assert!((pooled - 1.0).abs() < 0.1, "pooled peak ratio {pooled}");
    assert!(own < 0.6, "own-value peak ratio {own}");
}

/// Clamped data (the lowest cells of a known model set to exactly 0, as a
/// resampling that clamps negative values leaves them): the data-dependent
/// rule notices the zeros and raises the floor, and the fit then stays
/// closer to the unclamped truth than one whose floor lets the zeros
/// dominate. On the unclamped table the rule leaves the floor alone.
#[test]
fn clamped_zeros_raise_the_floor_and_keep_the_fit_near_the_truth() {
    use npf::fit::{FitConfig, CLAMPED_ZERO_FRACTION};
    use npf::metrics::compare_model;
    let truth = known_factor_model(Layout::default(), &[0.2]);
    let clean = to_merl(&truth).samples("synthetic");
    let config = FitConfig::default();
    assert!(config.epsilon_median_untrusted > 0.0);
    let rule = config.floor_rule(&clean);
    assert_eq!(rule.zero_fraction, 0.0);
    assert!(!rule.clamped && !rule.untrusted);
    assert_eq!(rule.epsilon, config.epsilon);

    // Zero the 2 % of cells with the lowest rho cos theta_i (channel mean)
    // inside the cut-off.
    let cut = 85f64.to_radians();
    let level = |x: &npf_data_loaders::MeasuredSample| {
        x.rgb.iter().sum::<f64>() / 3.0 * x.angles.theta_i.cos()
    };
    let mut v: Vec<f64> = clean
        .samples
        .iter()
        .filter(|x| x.angles.theta_i <= cut && x.angles.theta_o <= cut)
        .map(level)
        .collect();
    v.sort_by(f64::total_cmp);
    let below = v[v.len() / 50];
    let mut clamped = clean.clone();
    for x in &mut clamped.samples {
        if level(x) < below {
            x.rgb = [0.0; 3];
        }
    }
    let rule = config.floor_rule(&clamped);
    assert!(
        rule.clamped && rule.untrusted,
        "zero fraction {}",
        rule.zero_fraction
    );
    assert!(rule.zero_fraction >= CLAMPED_ZERO_FRACTION);
    assert!(
        rule.epsilon > 10.0 * config.epsilon,
        "floor {}",
        rule.epsilon
    );
    assert_eq!(rule.epsilon, config.epsilon_median_untrusted * rule.median);

    // Fit the clamped table from the truth with the rule's floor and with
    // the rule off; score both against the unclamped truth.
    let error = |c: &FitConfig| {
        let model = fit_one_lobe(&clamped, c.sample_options_for(&clamped), &truth);
        compare_model(&clean, 85.0, &model).log_rmse
    };
    let with_rule = error(&config);
    let without = error(&FitConfig {
        epsilon_median_untrusted: 0.0,
        ..config.clone()
    });
    assert!(
        with_rule < 0.5 * without,
        "log RMSE against the truth: rule {with_rule:e}, no rule {without:e}"
    );
}

/// The grazing rule reads the data's reciprocity: on a table made from a
/// (reciprocal) known model it fits to 89 degrees with the taper, which
/// recovers the grazing band (85-89 degrees) better than the 85 degree
/// cut-off's extrapolation; when the grazing cells disagree with their
/// reciprocal partners it keeps the cut-off, and that fit stays nearer
/// the truth inside 85 degrees than one forced to follow those cells.
#[test]
fn grazing_trust_follows_the_reciprocity_of_the_grazing_cells() {
    use npf::fit::{FitConfig, GRAZING_MAX_THETA, GRAZING_TAPER_FROM};
    use npf::metrics::compare_model;
    let truth = known_factor_model(Layout::default(), &[0.3]);
    let clean = to_merl(&truth).samples("synthetic");
    let on = FitConfig {
        grazing_trust: 0.2,
        ..Default::default()
    };
    let off = FitConfig {
        grazing_trust: 0.0,
        ..on.clone()
    };
    let forced = FitConfig {
        max_theta: GRAZING_MAX_THETA,
        taper_from: Some(GRAZING_TAPER_FROM),
        ..off.clone()
    };
    let (asymmetry, cells) = on.grazing_asymmetry(&clean);
    assert!(cells > 1000, "cells {cells}");
    assert!(asymmetry < 1e-3, "asymmetry {asymmetry}");
    let floor = on.floor_rule(&clean);
    assert!(!floor.untrusted);
    assert_eq!(floor.epsilon, on.epsilon);
    let rule = on.grazing_rule(&floor);
    assert!(rule.trusted);
    assert_eq!(rule.max_theta_deg, GRAZING_MAX_THETA);
    assert_eq!(rule.taper_from_deg, Some(GRAZING_TAPER_FROM));
    // A cut-off the user chose is kept on trusted data: the rule replaces
    // only the default one.
    let chosen = FitConfig {
        max_theta: 80.0,
        ..on.clone()
    };
    let kept = chosen.grazing_rule(&chosen.floor_rule(&clean));
    assert!(!kept.trusted);
    assert_eq!(kept.max_theta_deg, 80.0);
    assert_eq!(kept.taper_from_deg, None);
    assert_eq!(chosen.sample_options_for(&clean).max_theta_deg, 80.0);
    // Clamped data are never trusted at grazing angles.
    let clamped = npf::fit::FloorRule {
        clamped: true,
        untrusted: true,
        ..floor
    };
    assert!(!on.grazing_rule(&clamped).trusted);
    // Untrusted isotropic data get every row's weights pooled; trusted
    // data and anisotropic data keep the peak-only pooling.
    let pool =
        |f: &npf::fit::FloorRule, iso: bool| on.sample_options_with(f, iso).pool_scale_below_deg;
    assert_eq!(pool(&clamped, true), on.pool_scale_below_untrusted);
    assert_eq!(pool(&clamped, false), on.pool_scale_below);
    assert_eq!(pool(&floor, true), on.pool_scale_below);
    assert!(on.pool_scale_below_untrusted > on.pool_scale_below);

    let start = init_model(&truth);
    let fit = |data: &npf_data_loaders::MeasuredSamples, c: &FitConfig| {
        fit_one_lobe(data, c.sample_options_for(data), &start)
    };
    // Scored up to 89 degrees: the cut-off fit extrapolates past 85.
    let trusted = compare_model(&clean, 89.0, &fit(&clean, &on)).log_rmse;
    let cut = compare_model(&clean, 89.0, &fit(&clean, &off)).log_rmse;
    assert!(
        trusted < cut,
        "log RMSE to 89 deg: trusted {trusted:e}, cut-off {cut:e}"
    );

    // Grazing cells whose value depends on which direction is the grazing
    // one (a cell three times its partner): not reciprocal, not trusted.
    let (lo, hi) = (85f64.to_radians(), 89f64.to_radians());
    let mut skewed = clean.clone();
    for x in &mut skewed.samples {
        let a = x.angles;
        if a.theta_o > a.theta_i && a.theta_o > lo && a.theta_o <= hi {
            x.rgb = x.rgb.map(|v| 3.0 * v);
        }
    }
    let floor = on.floor_rule(&skewed);
    assert!(
        floor.grazing_asymmetry > 0.2,
        "asymmetry {}",
        floor.grazing_asymmetry
    );
    assert!(floor.untrusted && !floor.clamped);
    // Untrusted data get the raised floor.
    assert_eq!(floor.epsilon, on.epsilon_median_untrusted * floor.median);
    let rule = on.grazing_rule(&floor);
    assert!(!rule.trusted);
    assert_eq!(rule.max_theta_deg, on.max_theta);
    // The cut-off against following the cells, at the same floor.
    let same_floor = |c: &FitConfig| FitConfig {
        epsilon_median_untrusted: 0.0,
        ..c.clone()
    };
    let kept = compare_model(&clean, 85.0, &fit(&skewed, &same_floor(&on))).log_rmse;
    let followed = compare_model(&clean, 85.0, &fit(&skewed, &same_floor(&forced))).log_rmse;
    assert!(
        kept < followed,
        "log RMSE to 85 deg: rule {kept:e}, forced {followed:e}"
    );
}

/// A start near, not at, the truth (G scaled down), so that fits with
/// different cut-offs end at different points.
fn init_model(truth: &npf::model::Model) -> npf::model::Model {
    let mut m = truth.clone();
    for l in &mut m.lobes {
        for g in &mut l.g {
            *g *= 0.8;
        }
    }
    m
}

/// Eight sweeps of a one-lobe fit of `data` from `start`; the objective
/// must not rise.
fn fit_one_lobe(
    data: &npf_data_loaders::MeasuredSamples,
    options: SampleOptions,
    start: &npf::model::Model,
) -> npf::model::Model {
    let set = FitSet::build(data, Layout::default(), options).unwrap();
    let res = Executor::new(
        &set,
        FitOptions {
            lobes: 1,
            max_sweeps: 8,
            ..Default::default()
        },
    )
    .start_from(Factors::from_model(start))
    .run()
    .unwrap();
    assert!(res.objective <= res.initial_objective);
    res.model
}

/// The floor rule (parallel passes) is a plain serial count and median of
/// rho cos theta_i over the cut-off, on records and on a MERL grid
/// (`npf fit` calls it on `MerlSamples` itself, not through `SampleData`),
/// for 1 and 3 threads, on clean and clamped data and with the median off.
#[test]
fn the_floor_rule_is_the_serial_rule_on_records_and_grid_for_any_thread_count() {
    use npf_data_loaders::{MeasuredSamples, MerlSamples, MerlTable};
    let truth = known_factor_model(Layout::default(), &[0.25]);
    let clean = to_merl(&truth);
    // A clamped copy: the cells of a band of theta_h rows set to exactly 0.
    let mut raw = clean.raw().to_vec();
    for (i, v) in raw.iter_mut().enumerate() {
        let i_th = (i % MerlTable::CELLS) / (90 * 180);
        if (30..34).contains(&i_th) {
            *v = 0.0;
        }
    }
    let clamped = MerlTable::from_raw(raw);
    let two_pass = |c: &FitConfig, s: &MeasuredSamples| {
        let cut = c.max_theta.to_radians();
        let inside: Vec<_> = s
            .samples
            .iter()
            .filter(|x| x.angles.theta_i <= cut && x.angles.theta_o <= cut)
            .collect();
        let zeros = (0..3)
            .map(|ch| inside.iter().filter(|x| x.rgb[ch] == 0.0).count() as f64)
            .map(|z| z / inside.len() as f64)
            .fold(0.0, f64::max);
        let mut v: Vec<f64> = inside
            .iter()
            .map(|x| x.rgb.iter().sum::<f64>() / 3.0 * x.angles.theta_i.cos().max(0.0))
            .collect();
        v.sort_by(f64::total_cmp);
        (zeros, v[v.len() / 2])
    };
    let configs = [
        FitConfig::default(),
        FitConfig {
            epsilon_median: 0.5,
            ..Default::default()
        },
        FitConfig {
            epsilon_median: 0.0,
            epsilon_median_untrusted: 0.0,
            ..Default::default()
        },
    ];
    let mut untrusted_seen = false;
    for table in [&clean, &clamped] {
        let records = table.samples("t");
        let grid = MerlSamples::new(table.clone(), "t");
        for c in &configs {
            let (zero_fraction, median) = two_pass(c, &records);
            let asymmetry = c.grazing_asymmetry(&records).0;
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                for rule in [
                    pool.install(|| c.floor_rule(&records)),
                    pool.install(|| c.floor_rule(&grid)),
                ] {
                    assert_eq!(rule.zero_fraction, zero_fraction);
                    assert_eq!(rule.grazing_asymmetry.to_bits(), asymmetry.to_bits());
                    untrusted_seen |= rule.untrusted;
                    if rule.median_fraction > 0.0 {
                        assert_eq!(rule.median, median, "{threads} threads");
                        let want = c
                            .epsilon
                            .max(rule.median_fraction * median)
                            .min(npf::fit::MAX_EPSILON);
                        assert_eq!(rule.epsilon, want);
                    } else {
                        assert_eq!((rule.median, rule.epsilon), (0.0, c.epsilon));
                    }
                }
            }
        }
    }
    assert!(untrusted_seen, "the clamped table takes the other branch");
}
