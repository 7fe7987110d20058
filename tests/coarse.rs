//! Coarse-to-fine fits (`npf::coarse`): the decimated set is a fixed
//! fraction of the samples, the full level keeps the monotone objective and
//! the thread-count independence, and the result is as good as a plain fit.

use npf::coarse::{decimate, fit, Schedule, LEVEL_GN_CG};
use npf::loaders::MeasuredSamples;
use npf::model::Layout;
use npf::reconstruct::to_merl;
use npf::samples::{FitSet, SampleOptions};
use npf::solver::{init, Executor, FitOptions, FitResult, Stage, SweepReport};
use npf::synth::{known_factor_model, GgxLambert};
use std::borrow::Cow;

#[path = "common/monotone.rs"]
mod monotone;
use monotone::assert_stages_monotone;

fn samples() -> MeasuredSamples {
    let brdf = GgxLambert {
        kd: [0.05, 0.08, 0.12],
        f0: [0.95, 0.64, 0.54],
        alpha: 0.15,
    };
    let mut s = brdf.table().samples("ggx-lambert");
    // A sixth of the grid keeps the tests quick; still ~250 k samples.
    s.samples = s.samples.into_iter().step_by(6).collect();
    s
}

fn coarse_fit(s: &MeasuredSamples, levels: &[usize], opts: FitOptions, keep_g: bool) -> FitResult {
    let so = SampleOptions::default();
    let layout = Layout::default();
    let start = init::initial_factors(layout, opts.lobes);
    let mut quiet = |_: &SweepReport| {};
    let schedule = Schedule {
        factors: levels,
        tol: 1e-3,
        max_sweeps: 50,
        keep_g,
        kept_g_tol: opts.tol,
        gauss_newton: false,
    };
    let borrowed = Cow::Borrowed(s);
    let f = fit(borrowed, (layout, so), schedule, opts, start, &mut quiet).unwrap();
    assert_eq!(f.levels.len(), levels.iter().filter(|&&f| f > 1).count());
    for l in &f.levels {
        assert!(l.sweeps >= 1 && l.samples > 0, "{l:?}");
    }
    f.result
}

#[test]
fn decimation_keeps_a_fixed_fraction_and_is_repeatable() {
    let truth = known_factor_model(Layout::default(), &[0.05, 0.2, 0.5]);
    let s = to_merl(&truth).samples("known");
    assert_eq!(decimate(&s, 1).samples, s.samples);
    for factor in [4usize, 16, 32] {
        let d = decimate(&s, factor);
        let expect = s.samples.len() as f64 / factor as f64;
        let got = d.samples.len() as f64;
        assert!(
            (got - expect).abs() < 0.02 * expect,
            "factor {factor}: {got} of {}",
            s.samples.len()
        );
        assert_eq!(decimate(&s, factor).samples, d.samples);
        // Every theta_h row of the grid keeps samples (a stride could alias).
        let rows: std::collections::BTreeSet<i64> = d
            .samples
            .iter()
            .map(|x| (x.angles.theta_h.to_degrees() * 4.0).round() as i64)
            .collect();
        let all: std::collections::BTreeSet<i64> = s
            .samples
            .iter()
            .map(|x| (x.angles.theta_h.to_degrees() * 4.0).round() as i64)
            .collect();
        assert!(
            rows.len() * 10 >= all.len() * 9,
            "{} of {}",
            rows.len(),
            all.len()
        );
    }
}

#[test]
fn full_level_is_monotone_and_thread_independent() {
    let s = samples();
    let opts = FitOptions {
        max_sweeps: 4,
        tol: 0.0,
        trace_stages: true,
        ..Default::default()
    };
    for keep_g in [false, true] {
        full_level_check(&s, opts, keep_g);
    }
}

fn full_level_check(s: &MeasuredSamples, opts: FitOptions, keep_g: bool) {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| coarse_fit(s, &[8], opts, keep_g))
    };
    let (a, b) = (run(1), run(2));
    assert_stages_monotone(&a, "coarse-to-fine");
    assert_eq!(a.objective.to_bits(), b.objective.to_bits());
    assert_eq!(a.factors.d, b.factors.d);
    assert_eq!(a.factors.g, b.factors.g);
    assert_eq!(a.factors.f, b.factors.f);
}

/// With `keep_g` the full level is exactly: the coarse level's end, then
/// sweeps on the full set with G held (its set built without G's sample
/// lists, which a G update would need), and it ends near the fit that
/// updates G there too.
#[test]
fn kept_g_is_the_coarse_levels_g_held_on_the_full_set() {
    let s = samples();
    let opts = FitOptions {
        max_sweeps: 4,
        tol: 0.0,
        ..Default::default()
    };
    let (layout, so) = (Layout::default(), SampleOptions::default());
    let kept = coarse_fit(&s, &[8], opts, true);
    let updated = coarse_fit(&s, &[8], opts, false);
    // By hand: the level, then the full set with G fixed.
    let small = FitSet::build(&decimate(&s, 8), layout, so).unwrap();
    let level_opts = FitOptions {
        tol: 1e-3,
        max_sweeps: 50,
        ..opts
    };
    let start = init::initial_factors(layout, opts.lobes);
    // A level splits its G sums in halves (for its partner, `solver::duo`).
    let duo = npf::solver::duo::Duo::new();
    let level = Executor::new(&small, level_opts)
        .start_from(start)
        .partner(&duo)
        .run()
        .unwrap();
    let full = FitSet::build(&s, layout, so).unwrap();
    let fixed = FitOptions {
        g_method: npf::solver::GMethod::Fixed,
        ..opts
    };
    let by_hand = Executor::new(&full, fixed)
        .start_from(level.factors)
        .run()
        .unwrap();
    assert_eq!(kept.objective.to_bits(), by_hand.objective.to_bits());
    assert_eq!(kept.factors.g, by_hand.factors.g);
    assert_eq!(kept.factors.d, by_hand.factors.d);
    eprintln!(
        "after 4 full sweeps: G updated {:e}, G kept {:e}",
        updated.objective, kept.objective
    );
    // Measured: 4 % here (a level of 1/48 of the grid); 0.5-1.4 % on MERL
    // tables, whose renders move by -0.14 to +0.03 dB (BENCHMARKS.md as of 4d8d1ee).
    assert!(kept.objective < 1.06 * updated.objective);
}

/// After the same number of full-set sweeps, the fit started from the
/// coarse level's end is better than the plain fit (the coarse sweeps cost
/// an eighth of a full one each).
#[test]
fn coarse_start_is_ahead_after_equal_full_sweeps() {
    let s = samples();
    let opts = FitOptions {
        max_sweeps: 6,
        tol: 0.0,
        ..Default::default()
    };
    let set = FitSet::build(&s, Layout::default(), SampleOptions::default()).unwrap();
    let plain = Executor::new(&set, opts).run().unwrap();
    let coarse = coarse_fit(&s, &[8], opts, false);
    eprintln!(
        "after 6 full sweeps: plain {:e}, coarse-to-fine {:e}",
        plain.objective, coarse.objective
    );
    assert_eq!(coarse.history.len(), plain.history.len());
    assert!(coarse.objective < plain.objective);
}

/// A set too small for a level (fewer than 16 samples per parameter after
/// decimation) skips it: the fit is exactly the plain one.
#[test]
fn too_small_a_level_is_skipped() {
    let mut s = samples();
    s.samples = s.samples.into_iter().step_by(20).collect();
    let opts = FitOptions {
        max_sweeps: 3,
        tol: 0.0,
        ..Default::default()
    };
    let so = SampleOptions::default();
    let layout = Layout::default();
    let start = init::initial_factors(layout, opts.lobes);
    let mut quiet = |_: &SweepReport| {};
    let schedule = Schedule {
        factors: &[32],
        tol: 1e-3,
        max_sweeps: 50,
        keep_g: true,
        kept_g_tol: opts.tol,
        gauss_newton: false,
    };
    let borrowed = Cow::Borrowed(&s);
    let f = fit(borrowed, (layout, so), schedule, opts, start, &mut quiet).unwrap();
    assert!(f.levels.is_empty());
    let set = FitSet::build(&s, layout, so).unwrap();
    let plain = Executor::new(&set, opts).run().unwrap();
    assert_eq!(f.result.objective.to_bits(), plain.objective.to_bits());
}

/// The fit record says what the coarse-to-fine schedule did: the levels
/// run and whether the full set kept the coarse level's G.
#[test]
fn the_fit_record_names_the_schedule() {
    use npf::fit::FitConfig;
    let s = samples();
    let config = |coarse: Vec<usize>, keep: Option<bool>| FitConfig {
        coarse,
        coarse_max_sweeps: 4,
        keep_coarse_g: keep,
        max_sweeps: 2,
        tol: 0.0,
        ..Default::default()
    };
    let record = |c: &FitConfig| {
        let fitted = npf::fit::fit(&s, c, &mut |_, _| {}).unwrap();
        fitted.info.selection.unwrap().get("coarse").cloned()
    };
    // Isotropic data: G kept by default, the full set at twice `tol`.
    let kept = record(&config(vec![8], None)).expect("a level ran");
    assert_eq!(kept["g_on_full_set"], "kept");
    assert_eq!(kept["full_set_tol"], 0.0);
    let levels = kept["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 1);
    assert_eq!(levels[0]["factor"], 8);
    assert_eq!(levels[0]["sweeps"], 4);
    let updated = record(&config(vec![8], Some(false))).expect("a level ran");
    assert_eq!(updated["g_on_full_set"], "updated");
    // No level: nothing to record.
    assert!(record(&config(vec![1], None)).is_none());
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// The decimated levels' joint steps (`Schedule::gauss_newton`): on a level
/// run as `coarse::fit` runs it, every stage (the joint trial included)
/// keeps the objective from rising, steps are taken and kept once the
/// sweeps crawl, and one and two threads give the same bits, there and
/// through `coarse::fit` to the full set.
#[test]
fn coarse_gauss_newton_is_monotone_and_thread_independent() {
    let s = samples();
    let (layout, so) = (Layout::default(), SampleOptions::default());
    let small = FitSet::build(&decimate(&s, 8), layout, so).unwrap();
    // This synthetic level still gains 2-10 % a sweep after 30 sweeps (a
    // MERL level crawls at 0.1-0.3 %), so the threshold is raised to reach
    // the crawl within the test's sweeps.
    let below = 0.05;
    let level_opts = FitOptions {
        max_sweeps: 30,
        tol: 0.0,
        trace_stages: true,
        gauss_newton: true,
        gauss_newton_cg: LEVEL_GN_CG,
        gauss_newton_below: Some(below),
        ..Default::default()
    };
    let level =
        |threads| pool(threads).install(|| Executor::new(&small, level_opts).run().unwrap());
    let (a, b) = (level(1), level(2));
    assert_stages_monotone(&a, "coarse Gauss-Newton");
    let kept = a.history.iter().filter(|r| r.gauss_newton).count();
    assert!(kept > 0, "no joint step kept");
    // The threshold holds the step back while a sweep's AWLS stages gain
    // more than it: every trial follows a crawling sweep, and early sweeps
    // have none.
    let mut prev = a.initial_objective;
    let mut held_back = 0;
    for r in &a.history {
        let tried = r.stages.iter().position(|s| s.stage == Stage::GaussNewton);
        let before = match tried {
            Some(k) => r.stages[k - 1].objective.unwrap(),
            None => r.objective,
        };
        let gain = (prev - before) / prev;
        if tried.is_some() {
            assert!(gain < below, "sweep {}: gain {gain}", r.sweep);
        } else if gain >= below {
            held_back += 1;
        }
        prev = r.objective;
    }
    assert!(held_back > 0);
    assert_eq!(a.objective.to_bits(), b.objective.to_bits());
    assert_eq!(a.factors.d, b.factors.d);
    assert_eq!(a.factors.g, b.factors.g);
    assert_eq!(a.factors.f, b.factors.f);
    // The same level without the joint step ends higher after as many sweeps.
    let plain = Executor::new(
        &small,
        FitOptions {
            gauss_newton: false,
            trace_stages: false,
            ..level_opts
        },
    )
    .run()
    .unwrap();
    eprintln!(
        "level after 30 sweeps: AWLS {:e}, with {kept} joint steps {:e}",
        plain.objective, a.objective
    );
    assert!(a.objective < plain.objective);
    // Through the front door: the schedule's flag, one and two threads.
    let opts = FitOptions {
        max_sweeps: 3,
        tol: 0.0,
        ..Default::default()
    };
    let via_fit = |threads| {
        pool(threads).install(|| {
            let schedule = Schedule {
                factors: &[8],
                tol: 1e-3,
                max_sweeps: 30,
                keep_g: true,
                kept_g_tol: opts.tol,
                gauss_newton: true,
            };
            let start = init::initial_factors(layout, opts.lobes);
            let mut quiet = |_: &SweepReport| {};
            fit(
                Cow::Borrowed(&s),
                (layout, so),
                schedule,
                opts,
                start,
                &mut quiet,
            )
            .unwrap()
        })
    };
    let (x, y) = (via_fit(1), via_fit(2));
    assert_eq!(x.result.objective.to_bits(), y.result.objective.to_bits());
    assert_eq!(x.result.factors.d, y.result.factors.d);
    // The full set follows the fit's own options: no joint step there.
    assert!(x.result.history.iter().all(|r| !r.gauss_newton));
}

/// A decimated level's G halves on the partner (`solver::duo`): a level
/// whose partner serves gives the same bits as one that runs both halves
/// itself, keeps every stage monotone, and a level that ends at once (an
/// error) or is never served does not hang.
#[test]
fn a_level_with_its_partner_equals_one_without() {
    use npf::solver::duo::Duo;
    let s = samples();
    let (layout, so) = (Layout::default(), SampleOptions::default());
    let small = FitSet::build(&decimate(&s, 8), layout, so).unwrap();
    let opts = FitOptions {
        max_sweeps: 6,
        tol: 0.0,
        trace_stages: true,
        ..Default::default()
    };
    let alone = Duo::new();
    let a = Executor::new(&small, opts).partner(&alone).run().unwrap();
    assert_stages_monotone(&a, "level without a partner");
    // Served from the start: the partner waits for the lead, then serves.
    // Whether it wins any half is up to the scheduler (with the other
    // tests on two cores the lead sometimes takes every half back), so
    // the served run is repeated until the partner has run one or left;
    // every run must give the same bits.
    let mut exercised = false;
    for _ in 0..8 {
        let served = Duo::new();
        let b = served.with_partner(|| Executor::new(&small, opts).partner(&served).run().unwrap());
        // A partner preempted for long (a busy machine) leaves early.
        let (ran, back, left) = served.handed_off();
        eprintln!("partner: {ran} halves run, {back} taken back, left early: {left}");
        assert_eq!(a.objective.to_bits(), b.objective.to_bits());
        assert_eq!(a.factors.g, b.factors.g);
        assert_eq!(a.factors.d, b.factors.d);
        assert_eq!(a.factors.f, b.factors.f);
        if ran > 0 || left {
            exercised = true;
            break;
        }
    }
    assert!(exercised, "the partner ran no half in eight runs");
    // A level that fails at once (a start on another layout) releases its partner.
    let failing = Duo::new();
    let other = init::initial_factors(Layout::anisotropic(), 3);
    let r = failing.with_partner(|| {
        Executor::new(&small, opts)
            .start_from(other)
            .partner(&failing)
            .run()
    });
    assert!(r.is_err());
}
