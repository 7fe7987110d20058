//! End-to-end fits of tables npf synthesises itself: known factors are
//! recovered, the objective never rises, and the thread count does not
//! change a single bit.

use npf::loaders::{MeasuredSamples, MerlTable};
use npf::metrics::compare_model;
use npf::model::Layout;
use npf::reconstruct::to_merl;
use npf::samples::{FitSet, SampleOptions, Weighting};
use npf::solver::{Executor, FitOptions, FitResult, GMethod};
use npf::synth::{known_factor_model, GgxLambert};

#[path = "common/monotone.rs"]
mod monotone;
use monotone::assert_stages_monotone;

fn fit(samples: &MeasuredSamples, opts: FitOptions) -> FitResult {
    fit_with(samples, SampleOptions::default(), opts)
}

fn fit_with(samples: &MeasuredSamples, so: SampleOptions, opts: FitOptions) -> FitResult {
    let set = FitSet::build(samples, Layout::default(), so).unwrap();
    Executor::new(&set, opts).run().unwrap()
}

/// Every `keep`-th valid sample: a down-sampled grid for the cheaper tests.
fn thinned(table: &MerlTable, keep: usize) -> MeasuredSamples {
    let mut s = table.samples("synthetic");
    s.samples = s.samples.into_iter().step_by(keep).collect();
    s
}

/// The error measured is cosine-weighted, so the fit minimises exactly that
/// (the cosine-L2 weighting); the compressive default converges to the same
/// exact solution, only more slowly in this metric.
#[test]
fn known_three_lobe_model_is_fitted_back_below_1e_3() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let samples = to_merl(&truth).samples("known-3-lobe");
    let res = fit_with(
        &samples,
        SampleOptions {
            weighting: Weighting::CosineL2,
            ..Default::default()
        },
        FitOptions {
            max_sweeps: 150,
            tol: 1e-9,
            ..Default::default()
        },
    );
    let m = compare_model(&samples, 85.0, &res.model);
    eprintln!("known 3-lobe: {} sweeps, {m:?}", res.history.len());
    assert!(m.rel_cos_rmse < 1e-3, "{m:?}");
    assert!(res.model.validate().is_ok());
}

/// A copper-like GGX + Lambert BRDF.
fn metal_ggx() -> GgxLambert {
    GgxLambert {
        kd: [0.05, 0.08, 0.12],
        f0: [0.95, 0.64, 0.54],
        alpha: 0.15,
    }
}

/// The documented GGX + Lambert error (docs/fitting.md): an analytic BRDF is
/// not exactly a factor model, so the bound is looser than for known factors.
#[test]
fn ggx_lambert_is_fitted_to_its_documented_error() {
    let brdf = metal_ggx();
    let samples = brdf.table().samples("ggx-lambert");
    let res = fit(&samples, FitOptions::default());
    let m = compare_model(&samples, 85.0, &res.model);
    eprintln!("GGX+Lambert: {} sweeps, {m:?}", res.history.len());
    assert!(m.rel_cos_rmse < 3e-3, "{m:?}");
    assert!(m.log_rmse < 1.5e-3, "{m:?}");
}

#[test]
fn objective_never_rises_between_stages_or_within_g_updates() {
    let truth = known_factor_model(Layout::default(), &[0.03, 0.3, 0.6]);
    let samples = thinned(&to_merl(&truth), 7);
    for method in [GMethod::Cubic, GMethod::Golden] {
        let res = fit(
            &samples,
            FitOptions {
                max_sweeps: 12,
                tol: 0.0,
                trace_stages: true,
                smooth_g: Some(1.0),
                g_method: method,
                ..Default::default()
            },
        );
        let mut prev = res.initial_objective;
        // Gauge changes and cache rescaling are exact up to rounding.
        let slack = |e: f64| e * 1e-12;
        for r in &res.history {
            for s in &r.stages {
                let e = s.objective.expect("traced");
                assert!(
                    e <= prev + slack(prev),
                    "{method:?} sweep {} {:?}: {prev} -> {e}",
                    r.sweep,
                    s.stage
                );
                prev = e;
            }
            assert!(r.objective <= prev + slack(prev));
            for g in &r.g_passes {
                assert!(g.accepted == 0 || g.worst_accepted < 0.0, "{g:?}");
            }
        }
        assert!(res.objective < res.initial_objective);
        assert!(res
            .history
            .iter()
            .any(|r| r.g_passes.iter().any(|g| g.accepted > 0)));
    }
}

#[test]
fn one_and_two_threads_give_identical_models() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let samples = thinned(&to_merl(&truth), 5);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                fit(
                    &samples,
                    FitOptions {
                        max_sweeps: 15,
                        tol: 0.0,
                        ..Default::default()
                    },
                )
            })
    };
    let (a, b) = (run(1), run(2));
    let bits = |r: &FitResult| {
        r.model
            .params()
            .iter()
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(a.objective.to_bits(), b.objective.to_bits());
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.history.len(), b.history.len());
}

/// A known anisotropic factor model on `Layout::anisotropic()`: D^m an
/// anisotropic GGX of (theta_h, phi_h), G^m a Smith G1 whose roughness
/// varies with phi, Schlick F.
fn known_anisotropic_model() -> npf::model::Model {
    use npf::model::{Lobe, Model};
    use npf::solver::init::{ggx_g1, theta_table};
    use std::f64::consts::PI;
    let layout = Layout::anisotropic();
    let on_grid = |grid: npf::grid::Grid, f: &dyn Fn(f64, f64) -> f64| -> Vec<f32> {
        (0..grid.len())
            .map(|k| {
                let (t, p) = grid.node(k);
                f(t, p) as f32
            })
            .collect()
    };
    let aniso_ggx = |t: f64, p: f64, ax: f64, ay: f64| {
        let c2 = t.cos().powi(2);
        let t2 = (1.0 - c2) / c2;
        let e = t2 * (p.cos().powi(2) / (ax * ax) + p.sin().powi(2) / (ay * ay));
        1.0 / (PI * ax * ay * c2 * c2 * (1.0 + e).powi(2))
    };
    let f0 = [0.9, 0.6, 0.3];
    let fresnel = f0.map(|f0: f64| {
        theta_table(layout.f, &|t| f0 + (1.0 - f0) * (1.0 - t.cos()).powi(5))
            .into_iter()
            .map(|v| v as f32)
            .collect()
    });
    let lobes = [(0.3, 0.6, [0.8, 0.5, 0.3]), (0.7, 0.4, [0.2, 0.3, 0.5])]
        .into_iter()
        .map(|(ax, ay, s)| Lobe {
            s,
            d: on_grid(layout.d, &|t, p| aniso_ggx(t, p, ax, ay)),
            g: on_grid(layout.g, &|t, p| {
                ggx_g1(t, 0.5 * (ax + ay) * (1.0 + 0.3 * p.cos()))
            }),
        })
        .collect();
    let m = Model {
        layout,
        diffuse: [0.05, 0.08, 0.1],
        diffuse_form: Default::default(),
        masking: Default::default(),
        compensation: None,
        fresnel,
        lobes,
    };
    m.validate().unwrap();
    m
}

/// Random direction pairs (theta up to 80 degrees), valued by `model`.
fn anisotropic_samples(model: &npf::model::Model, n: usize) -> MeasuredSamples {
    use npf::loaders::geometry::{spherical, Angles};
    use npf::loaders::MeasuredSample;
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let cmin = 80f64.to_radians().cos();
    let dir = |rng: &mut rand_pcg::Pcg64| {
        let c: f64 = rng.gen_range(cmin..1.0);
        spherical(c.acos(), rng.gen_range(0.0..std::f64::consts::TAU))
    };
    let samples = (0..n)
        .map(|_| {
            let (wi, wo) = (dir(&mut rng), dir(&mut rng));
            MeasuredSample {
                angles: Angles::from_directions(wi, wo),
                rgb: model.eval(wo, wi),
            }
        })
        .collect();
    MeasuredSamples {
        source: "synthetic anisotropic".into(),
        isotropic: false,
        samples,
        missing: 0,
    }
}

/// The same executor fits the 2010-parameter anisotropic layout: every
/// stage keeps the objective from rising, and the fit ends far below its
/// start. Isotropic layouts refuse anisotropic data.
#[test]
fn anisotropic_layout_is_fitted_by_the_same_executor() {
    let truth = known_anisotropic_model();
    let samples = anisotropic_samples(&truth, 6000);
    assert!(matches!(
        FitSet::build(&samples, Layout::default(), SampleOptions::default()),
        Err(npf::samples::SampleError::AnisotropicData(_))
    ));
    let set = FitSet::build(&samples, Layout::anisotropic(), SampleOptions::default()).unwrap();
    assert_eq!(set.stats.merged_pairs, 0);
    assert_eq!(set.gi_st.width, 8);
    assert_eq!(set.d_st.width, 4);
    let res = Executor::new(
        &set,
        FitOptions {
            max_sweeps: 25,
            tol: 0.0,
            trace_stages: true,
            ..Default::default()
        },
    )
    .run()
    .unwrap();
    assert_eq!(res.model.param_count(), 2010);
    assert_stages_monotone(&res, "");
    eprintln!(
        "anisotropic: {} -> {} in {} sweeps",
        res.initial_objective,
        res.objective,
        res.history.len()
    );
    assert!(res.objective < 1e-2 * res.initial_objective);
    assert!(res.model.validate().is_ok());
    let m = compare_model(&samples, 85.0, &res.model);
    eprintln!("anisotropic fit: {m:?}");
}

/// A per-lobe channel mask holds the masked scales at exactly 0 through the
/// whole fit (start, d, s solve, gauge, extrapolation), and the objective
/// still never rises.
#[test]
fn masked_scales_stay_exactly_zero() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.3]);
    let samples = thinned(&to_merl(&truth), 9);
    let mask = [[true, false, true], [false, true, true], [true; 3]];
    let res = fit(
        &samples,
        FitOptions {
            lobes: 2,
            max_sweeps: 12,
            tol: 0.0,
            channel_mask: mask,
            ..Default::default()
        },
    );
    for (m, lobe) in res.model.lobes.iter().enumerate() {
        for (c, (&on, s)) in mask[m].iter().zip(lobe.s).enumerate() {
            if !on {
                assert_eq!(s.to_bits(), 0, "lobe {m} channel {c}");
            }
        }
    }
    assert!(res.model.lobes[0].s[0] > 0.0 && res.model.lobes[1].s[1] > 0.0);
    let mut prev = res.initial_objective;
    for r in &res.history {
        assert!(r.objective <= prev * (1.0 + 1e-12));
        prev = r.objective;
    }
    let all_masked = FitOptions {
        lobes: 2,
        channel_mask: [[true; 3], [false; 3], [true; 3]],
        ..Default::default()
    };
    assert_eq!(
        all_masked.validate(),
        Err(npf::solver::SolverError::MaskedLobe(1))
    );
}

/// Merging reciprocal partners keeps the objective: the all-black model's
/// objective on the merged set (sum W y^2 plus the merged pairs' offset)
/// is the plain sum of w y^2 over every input sample within the cut-off.
#[test]
fn the_merged_set_keeps_the_unmerged_objective() {
    let brdf = metal_ggx();
    let samples = thinned(&brdf.table(), 3);
    // Own-value weights: pooled peak weights (the default) read a row mean,
    // which the direct sum below does not model; merging is what is tested.
    let so = SampleOptions {
        pool_scale_below_deg: None,
        ..Default::default()
    };
    let set = FitSet::build(&samples, Layout::default(), so).unwrap();
    let cut = so.max_theta_deg.to_radians();
    let inside: Vec<_> = samples
        .samples
        .iter()
        .filter(|s| s.angles.theta_i <= cut && s.angles.theta_o <= cut)
        .collect();
    let direct: f64 = inside
        .iter()
        .map(|s| {
            let ci = s.angles.theta_i.cos();
            s.rgb.iter().map(|&v| so.weight(v, ci) * v * v).sum::<f64>()
        })
        .sum();
    assert!(set.stats.merged_pairs > inside.len() / 8, "{:?}", set.stats);
    assert_eq!(set.stats.fitted + set.stats.merged_pairs, inside.len());
    assert_eq!(set.stats.cut, samples.samples.len() - inside.len());
    let merged = set.data_energy();
    assert!(
        (merged - direct).abs() <= 1e-12 * direct,
        "merged {merged:e} vs direct {direct:e}"
    );
}

/// `fit::fit_owned` (the samples freed during the fit, their table read
/// again for the error measures) gives `fit::fit`'s model, objective and
/// measures.
#[test]
fn an_owned_fit_is_the_borrowed_fit() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let table = to_merl(&truth);
    let config = npf::fit::FitConfig {
        max_sweeps: 3,
        threads: 2,
        ..Default::default()
    };
    let samples = table.samples("t");
    let a = npf::fit::fit(&samples, &config, &mut |_, _| {}).unwrap();
    let again = || Ok(npf::loaders::Table::Merl(table.clone()));
    let b = npf::fit::fit_owned(samples, again, &config, &mut |_, _| {}).unwrap();
    assert_eq!(a.result.objective.to_bits(), b.result.objective.to_bits());
    assert_eq!(a.result.model.params(), b.result.model.params());
    assert_eq!(a.metrics, b.metrics);
    assert_eq!(a.info.samples, b.info.samples);
}

/// A MERL table fitted from its grid (`MerlSamples`, the `npf fit` path:
/// no sample records, the set in grid-row order) agrees with the fit of
/// its samples to summation order (objective to 1e-9, the same sweeps),
/// and is the same for 1 and 2 threads, bit for bit.
#[test]
fn a_fit_from_the_merl_grid_is_the_fit_of_its_samples() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let table = to_merl(&truth);
    let fit_grid = |threads: usize| {
        let config = npf::fit::FitConfig {
            max_sweeps: 3,
            threads,
            ..Default::default()
        };
        let grid = npf::loaders::MerlSamples::new(table.clone(), "t");
        let again = || Ok(npf::loaders::Table::Merl(table.clone()));
        npf::fit::fit_owned(grid, again, &config, &mut |_, _| {}).unwrap()
    };
    let config = npf::fit::FitConfig {
        max_sweeps: 3,
        threads: 2,
        ..Default::default()
    };
    let records = npf::fit::fit(&table.samples("t"), &config, &mut |_, _| {}).unwrap();
    let (one, two) = (fit_grid(1), fit_grid(2));
    assert_eq!(
        one.result.objective.to_bits(),
        two.result.objective.to_bits()
    );
    assert_eq!(one.result.model.params(), two.result.model.params());
    let (a, b) = (records.result.objective, two.result.objective);
    assert!((a - b).abs() <= 1e-9 * a, "objectives {a:e} vs {b:e}");
    assert_eq!(records.result.history.len(), two.result.history.len());
    assert_eq!(records.info.samples, two.info.samples);
    assert_eq!(records.info.epsilon, two.info.epsilon);
    for (x, y) in records
        .result
        .model
        .params()
        .iter()
        .zip(two.result.model.params())
    {
        assert!((x - y).abs() <= 1e-5 * x.abs().max(1e-3), "{x} vs {y}");
    }
}

/// When the samples cannot be made again for the error measures (the
/// input vanished or changed during the fit), the owned fit fails with
/// that error rather than measuring against something else.
#[test]
fn an_owned_fit_reports_a_failed_remeasure() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let samples = to_merl(&truth).samples("t");
    let config = npf::fit::FitConfig {
        max_sweeps: 1,
        coarse: vec![],
        ..Default::default()
    };
    let gone = || {
        Err(npf::fit::FitError::Remeasure {
            source_name: "t".into(),
            problem: "the input changed during the fit".into(),
        })
    };
    let e = npf::fit::fit_owned(samples, gone, &config, &mut |_, _| {}).unwrap_err();
    assert!(matches!(e, npf::fit::FitError::Remeasure { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "t: cannot measure the fit's errors: the input changed during the fit"
    );
}

/// The post-fit energy scale (`FitConfig::energy_scale`): read against the
/// re-read table, it multiplies d and every s of channel C by the recorded
/// k_C, so the model's every value scales by k_C; off, the fit is the plain
/// one; by default a trusted table (this synthetic one) is left alone.
#[test]
fn the_energy_scale_scales_each_channel_by_the_recorded_ratio() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let table = to_merl(&truth);
    // The "re-read" table reflects more red and less blue light than the
    // fitted samples: what a fit that lands low on its table's energy sees.
    let k = [1.2, 1.0, 0.9];
    let brighter = MerlTable::from_fn(|th, td, pd| {
        let a = npf::loaders::geometry::Angles::from_half_diff(th, 0.0, td, pd);
        (a.theta_i.cos() > 0.0 && a.theta_o.cos() > 0.0).then(|| {
            let v = truth.eval_angles(&a);
            std::array::from_fn(|c| v[c] * k[c])
        })
    });
    let run = |scale: Option<bool>| {
        let config = npf::fit::FitConfig {
            lobes: 1,
            max_sweeps: 2,
            coarse: vec![],
            energy_scale: scale,
            ..Default::default()
        };
        let reread = || Ok(npf::loaders::Table::Merl(brighter.clone()));
        npf::fit::fit_owned(table.samples("t"), reread, &config, &mut |_, _| {}).unwrap()
    };
    let (on, off, default) = (run(Some(true)), run(Some(false)), run(None));
    let record = |f: &npf::fit::Fitted| {
        f.info
            .selection
            .as_ref()
            .unwrap()
            .get("energy_scale")
            .cloned()
    };
    assert!(record(&off).is_none() && record(&default).is_none());
    assert_eq!(default.result.model, off.result.model);
    let rec = record(&on).expect("a record");
    assert_eq!(rec["applied"], true);
    let got: Vec<f64> = rec["k"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    // The ratio is k times the plain fit's own ratio to its samples' table.
    let rule = npf::energy::scale::DEFAULT_RULE;
    let own = npf::energy::scale::energy_ratio(&table, 85.0, &rule, &off.result.model).unwrap();
    for c in 0..3 {
        assert!(
            (got[c] / (k[c] * own[c]) - 1.0).abs() < 1e-9,
            "{got:?} {own:?}"
        );
    }
    // Every value of the scaled model is the plain model's times k_C.
    for (ti, to, dphi) in [(0.2, 0.3, 0.5), (0.7, 0.1, 2.0), (1.1, 0.9, 3.0)] {
        let a = npf::loaders::geometry::Angles::from_directions(
            [f64::sin(ti), 0.0, f64::cos(ti)],
            [
                f64::sin(to) * f64::cos(dphi),
                f64::sin(to) * f64::sin(dphi),
                f64::cos(to),
            ],
        );
        let (v_on, v_off) = (
            on.result.model.eval_angles(&a),
            off.result.model.eval_angles(&a),
        );
        for c in 0..3 {
            assert!(
                (v_on[c] - got[c] * v_off[c]).abs() <= 1e-6 * v_on[c].abs(),
                "{v_on:?} {v_off:?}"
            );
        }
    }
    // The factors travel with the model.
    assert_eq!(
        on.result.factors.to_model().diffuse,
        on.result.model.diffuse
    );
}

/// `npf fit`'s path on a MERL table (`fit_owned` on its grid): the error
/// measures, whose reference part is prepared during the fit, are those of
/// `compare_model_table` against the table for the final model, to the
/// bit, with the post-fit energy scale (the untrusted tables' path) and
/// without it, for 1 and 2 threads.
#[test]
fn the_grid_fits_measures_are_the_tables_to_the_bit() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let table = to_merl(&truth);
    for (scale, threads) in [(Some(false), 1), (Some(false), 2), (Some(true), 2)] {
        let config = npf::fit::FitConfig {
            max_sweeps: 2,
            threads,
            energy_scale: scale,
            ..Default::default()
        };
        let grid = npf::loaders::MerlSamples::new(table.clone(), "t");
        let again = || Ok(npf::loaders::Table::Merl(table.clone()));
        let fitted = npf::fit::fit_owned(grid, again, &config, &mut |_, _| {}).unwrap();
        let scaled = fitted.info.selection.as_ref().unwrap().get("energy_scale");
        assert_eq!(scaled.is_some(), scale == Some(true));
        let want = npf::metrics::compare_model_table(
            &npf::loaders::Table::Merl(table.clone()),
            config.max_theta,
            &fitted.result.model,
        );
        let bits =
            |m: &npf::metrics::Metrics| [m.cos_rmse, m.rel_cos_rmse, m.log_rmse].map(f64::to_bits);
        assert!(want.samples > 1000 && want.log_rmse > 0.0);
        assert_eq!(fitted.metrics.samples, want.samples);
        assert_eq!(bits(&fitted.metrics), bits(&want), "{scale:?}, {threads}");
    }
}
