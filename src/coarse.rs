//! Coarse-to-fine fits: sweeps on a decimated sample set first, then on all
//! samples from where they ended.
//!
//! A sweep costs time in proportion to the samples, but the 822 parameters
//! are pinned down by far fewer than the ~0.5 M merged MERL samples, so
//! most of a fit's descent (the early sweeps that move every table a lot)
//! can run on a fixed pseudo-random fraction of them. The full set then
//! starts close to its optimum and needs a few sweeps only. Each level is
//! an ordinary [`Executor`] run (monotone, deterministic for any thread
//! count); the final model and history are the last (full) level's, so its
//! objective is the true one. The decimated levels' objectives are on their
//! own, smaller scale and are not in the history.

use crate::model::Layout;
use crate::samples::{FitSet, GUse, SampleData, SampleError, SampleOptions, SampleSource};
use crate::solver::duo::Duo;
use crate::solver::{
    DiffuseKind, Executor, Factors, FitOptions, FitResult, GMethod, Observer, SolverError,
};
use npf_data_loaders::MeasuredSamples;

/// Every `factor`-th sample on average, chosen by a hash of the index (not a
/// stride: MERL's order is a regular grid, and a stride would alias with
/// it). The same samples for any thread count and run. `factor` <= 1 keeps
/// all.
pub fn decimate<S: SampleSource + ?Sized>(samples: &S, factor: usize) -> MeasuredSamples {
    let keep = kept_by(factor);
    MeasuredSamples {
        source: samples.source_name().to_string(),
        isotropic: samples.is_isotropic(),
        samples: (0..samples.sample_count())
            .filter(|&i| keep(i))
            .map(|i| samples.record(i))
            .collect(),
        missing: samples.missing_count(),
    }
}

/// Whether [`decimate`] keeps sample i: `mix(i) % factor == 0` (all for
/// `factor` <= 1), by a mask when `factor` is a power of two (the same
/// answer without a 64-bit division a sample: that division was most of
/// two serial passes over a MERL table's 1.1 million samples before the
/// coarse level starts).
fn kept_by(factor: usize) -> impl Fn(usize) -> bool {
    let (all, pow2, f) = (factor <= 1, factor.is_power_of_two(), factor as u64);
    move |i| {
        all || if pow2 {
            mix(i as u64) & (f - 1) == 0
        } else {
            mix(i as u64) % f == 0
        }
    }
}

/// splitmix64's finaliser: a fixed, well-mixed hash.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A decimated level runs only if it keeps at least this many (valid,
/// unmerged) samples per model parameter; otherwise it is skipped.
pub const MIN_SAMPLES_PER_PARAMETER: usize = 16;

/// What the decimated levels did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoarseLevel {
    /// The decimation factor.
    pub factor: usize,
    /// Samples the level's set held.
    pub samples: usize,
    /// Sweeps run on it.
    pub sweeps: usize,
    /// Whether its tolerance (not the sweep limit) ended it.
    pub converged: bool,
    /// Seconds: building its set and fitting it.
    pub seconds: f64,
    /// For a separable diffuse form's first level, whether the run that
    /// held P at 1 first was kept (lower objective) over the one that
    /// updated it from the first sweep.
    pub separable_held: Option<bool>,
}

/// Why a coarse-to-fine fit could not run.
#[derive(Debug, thiserror::Error)]
pub enum CoarseError {
    /// A level's sample set could not be built.
    #[error(transparent)]
    Samples(#[from] SampleError),
    /// The solver refused the options or the start.
    #[error(transparent)]
    Solver(#[from] SolverError),
}

/// The decimated levels to run before the full set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule<'a> {
    /// Decimation factors, coarsest first (0 and 1 are skipped).
    pub factors: &'a [usize],
    /// The levels' tolerance (their sweeps are cheap, so they may run
    /// further than the full set's).
    pub tol: f64,
    /// The levels' sweep limit (the full set keeps the fit's own).
    pub max_sweeps: usize,
    /// Hold G on the full set where the decimated levels fitted it (when
    /// at least one level runs). G is smooth (a few Catmull-Rom points per
    /// lobe), so a 32nd of the samples pins it down; D's narrow peaks are
    /// what needs them all. The G pass is half a full sweep's time
    /// (BENCHMARKS.md as of 4d8d1ee, issue 15, "G from the coarse level"). A separable
    /// diffuse form's P (16 nodes) is held with it
    /// ([`FitOptions::hold_p`]).
    pub keep_g: bool,
    /// The full set's tolerance when G is kept: its sweeps then move D, F,
    /// d and s only, which settle within a few sweeps.
    pub kept_g_tol: f64,
    /// The decimated levels try joint Gauss-Newton steps (with
    /// [`LEVEL_GN_CG`] iterations, once a sweep gains less than
    /// [`LEVEL_GN_BELOW`]) whatever the fit's options say; the full set
    /// follows them. A step costs about two coarse sweeps but sees the
    /// coupling AWLS crawls along (BENCHMARKS.md as of 4d8d1ee, g30).
    pub gauss_newton: bool,
}

/// Conjugate-gradient iterations of a decimated level's joint step
/// ([`Schedule::gauss_newton`]): measured on dark-red-paint's 1/32 level,
/// 8 keep its 28 sweeps (25: 29), 4 or 6 double them.
pub const LEVEL_GN_CG: usize = 8;

/// A decimated level's joint step waits until a sweep gains less than this
/// fraction ([`Schedule::gauss_newton`]): from the first sweep on, it
/// stopped polyurethane-foam's level at 29 sweeps at an objective 13 %
/// above AWLS's, 2.2 dB lower in rendering PSNR.
pub const LEVEL_GN_BELOW: f64 = 0.003;

/// A coarse-to-fine fit's result.
#[derive(Clone, Debug)]
pub struct CoarseFit {
    /// The full set's fit (its history, objective and model).
    pub result: FitResult,
    /// What each decimated level did, coarsest first.
    pub levels: Vec<CoarseLevel>,
    /// Samples in the full set.
    pub set_len: usize,
    /// Seconds until the full set was built (it is built while the
    /// decimated levels run).
    pub set_seconds: f64,
}

/// Where the decimated levels ended, for a screen that tries other
/// forms from there before the full set ([`fit_beside`]'s `screen`).
pub struct LevelsEnd<'s> {
    /// The last level's decimated samples.
    pub kept: &'s MeasuredSamples,
    /// Its sample set.
    pub set: &'s FitSet,
    /// The last level's run: the fit the screen starts from.
    pub result: &'s FitResult,
    /// The levels' layout.
    pub layout: Layout,
    /// Their sample options.
    pub so: SampleOptions,
    /// The schedule the levels ran.
    pub schedule: Schedule<'s>,
    duo: &'s Duo,
}

impl LevelsEnd<'_> {
    /// A run on a decimated set (this level's, or one built from
    /// [`Self::kept`] with other sample options) as the levels run: `opts`
    /// with the schedule's tolerance, at most `sweeps` sweeps (and the
    /// schedule's limit), the levels' partner; from `start` and, where
    /// given, a diffuse form.
    pub fn run(
        &self,
        set: &FitSet,
        (opts, sweeps): (FitOptions, usize),
        start: Factors,
        form: Option<crate::model::DiffuseForm>,
    ) -> Result<FitResult, SolverError> {
        let o = level_options(self.schedule, opts);
        let o = FitOptions {
            max_sweeps: o.max_sweeps.min(sweeps).max(1),
            ..o
        };
        let mut exec = Executor::new(set, o).start_from(start).partner(self.duo);
        if let Some(form) = form {
            exec = exec.start_form(form);
        }
        exec.run()
    }
}

/// What the full set runs after a screen.
pub struct Finish {
    /// The start (a decimated level's end).
    pub start: Factors,
    /// The diffuse form it ended with.
    pub form: Option<crate::model::DiffuseForm>,
    /// The full set's options (before G is kept, [`Schedule::keep_g`]).
    pub opts: FitOptions,
    /// Sample options other than the levels': the full set is built again
    /// with them.
    pub so: Option<SampleOptions>,
}

/// A screen: given where the levels ended, what the full set runs.
pub type Screen<'a> = Box<dyn FnOnce(LevelsEnd<'_>) -> Result<Finish, CoarseError> + Send + 'a>;

/// Fit `samples` on `layout` from `start`: first on each decimated set of
/// `schedule` (a level with fewer than [`MIN_SAMPLES_PER_PARAMETER`] is
/// skipped), each level
/// starting where the previous one ended, then on the full set. The full
/// set is built while the decimated levels run (the build's serial parts
/// leave a core free). The decimated levels use `opts` with the
/// schedule's tolerance and sweep limit; the observer sees the full set's
/// sweeps only.
/// Owned samples are freed once every set is built, before the full set's
/// sweeps: the measured samples (88 bytes each, 128 MB for a MERL table)
/// and the solver's caches are then never in memory together.
pub fn fit<'a>(
    samples: impl Into<SampleData<'a>>,
    (layout, so): (Layout, SampleOptions),
    schedule: Schedule,
    opts: FitOptions,
    start: Factors,
    observer: &mut dyn Observer,
) -> Result<CoarseFit, CoarseError> {
    let run = (schedule, opts, start);
    let nothing = |_: &SampleData| ();
    fit_beside(samples, (layout, so), run, observer, nothing, None).map(|(f, ())| f)
}

/// [`fit`] with `beside(samples)` run after the full set is built, while
/// the decimated levels run (the build's arm of the join then has a core
/// to spare): work on the samples that the full set's sweeps do not need
/// (the error measures' model-independent part), returned with the fit.
/// With a `screen`, where the levels end goes to it (while the partner
/// still helps), and the full set runs what it returns; without a level,
/// no screen runs.
pub fn fit_beside<'a, T: Send>(
    samples: impl Into<SampleData<'a>>,
    (layout, so): (Layout, SampleOptions),
    (schedule, opts, start): (Schedule, FitOptions, Factors),
    observer: &mut dyn Observer,
    beside: impl FnOnce(&SampleData) -> T + Send,
    screen: Option<Screen>,
) -> Result<(CoarseFit, T), CoarseError> {
    let t0 = std::time::Instant::now();
    let samples = samples.into();
    let keep_g = schedule.keep_g && levels_run(&samples, layout, schedule, opts.lobes);
    let full_options = |opts: FitOptions| {
        if keep_g {
            FitOptions {
                g_method: GMethod::Fixed,
                hold_p: true,
                tol: schedule.kept_g_tol,
                ..opts
            }
        } else {
            opts
        }
    };
    let g_use = if keep_g { GUse::Fixed } else { GUse::Updated };
    // The levels' partner: the build's thread once the build is done.
    let duo = Duo::new();
    let (set, coarse) = rayon::join(
        || {
            let set = FitSet::build_from(&samples, layout, so, g_use);
            let built = t0.elapsed().as_secs_f64();
            let beside = beside(&samples);
            duo.serve();
            ((set, built), beside)
        },
        || {
            duo.lead(|| {
                let (levels, last) =
                    levels_fit(&samples, (layout, so), schedule, opts, &start, &duo)?;
                let finish = match (screen, last) {
                    (Some(screen), Some((kept, set, result))) => screen(LevelsEnd {
                        kept: &kept,
                        set: &set,
                        result: &result,
                        layout,
                        so,
                        schedule,
                        duo: &duo,
                    })?,
                    (_, Some((_, _, r))) => Finish {
                        start: r.factors,
                        form: Some(r.model.diffuse_form),
                        opts,
                        so: None,
                    },
                    (_, None) => Finish {
                        start,
                        form: None,
                        opts,
                        so: None,
                    },
                };
                Ok::<_, CoarseError>((finish, levels))
            })
        },
    );
    if crate::phases::enabled() {
        let (ran, back, left) = duo.handed_off();
        let left = if left {
            " (left early: busy machine)"
        } else {
            ""
        };
        eprintln!("npf timing: coarse partner ran {ran} halves, {back} taken back{left}");
    }
    let ((set, set_seconds), beside) = set;
    let mut set = set?;
    let (finish, levels) = coarse?;
    if let Some(so) = finish.so {
        // The screen chose other sample options (weights): that set.
        drop(set);
        crate::memory::release_free();
        set = FitSet::build_from(&samples, layout, so, g_use)?;
    }
    drop(samples);
    // The decimated levels' sets and the build's temporaries are freed:
    // give their pages back before the full set's caches are allocated.
    crate::memory::release_free();
    let mut exec = Executor::new(&set, full_options(finish.opts)).start_from(finish.start);
    if let Some(form) = finish.form {
        exec = exec.start_form(form);
    }
    let result = exec.observe(observer).run()?;
    let fitted = CoarseFit {
        result,
        levels,
        set_len: set.len(),
        set_seconds,
    };
    Ok((fitted, beside))
}

/// With `NPF_TIMING`, a level's wall time per kind of stage, summed over
/// its sweeps (a coarse sweep is short, so its fixed costs show here).
fn print_stages(factor: usize, history: &[crate::solver::SweepReport]) {
    use crate::solver::Stage;
    if !crate::phases::enabled() {
        return;
    }
    type Kind = (&'static str, fn(&Stage) -> bool);
    let kinds: [Kind; 7] = [
        ("D", |s| matches!(s, Stage::D(_))),
        ("F", |s| matches!(s, Stage::F)),
        ("G", |s| matches!(s, Stage::G(_))),
        ("d, s", |s| matches!(s, Stage::DiffuseAndScales)),
        ("gauge", |s| matches!(s, Stage::Gauge)),
        ("extrapolation", |s| matches!(s, Stage::Extrapolate)),
        ("Gauss-Newton", |s| matches!(s, Stage::GaussNewton)),
    ];
    let stages = || history.iter().flat_map(|r| &r.stages);
    let tried = stages().filter(|s| s.stage == Stage::GaussNewton).count();
    let kept = history.iter().filter(|r| r.gauss_newton).count();
    // The joint step's entry only where the level tried one (an option).
    let shown = if tried > 0 {
        kinds.len()
    } else {
        kinds.len() - 1
    };
    let split: Vec<String> = kinds[..shown]
        .iter()
        .map(|(name, is)| {
            // + 0.0: an empty sum is -0.
            let t: f64 = stages()
                .filter(|s| is(&s.stage))
                .map(|s| s.seconds)
                .sum::<f64>()
                + 0.0;
            format!("{name} {:.0} ms", t * 1e3)
        })
        .collect();
    let steps = if tried > 0 {
        format!(" (steps {kept} of {tried} kept)")
    } else {
        String::new()
    };
    eprintln!(
        "npf timing: coarse 1/{factor} stages over {} sweeps: {}{steps}",
        history.len(),
        split.join(", ")
    );
}

/// Whether any decimated level of `schedule` will run (the count
/// [`levels_fit`] tests, without building the decimated samples).
fn levels_run(samples: &SampleData, layout: Layout, schedule: Schedule, lobes: usize) -> bool {
    levels_run_on(samples, layout, schedule.factors, lobes)
}

/// Whether a decimated level of `factors` runs on `samples`.
pub fn levels_run_on<S: SampleSource + ?Sized>(
    samples: &S,
    layout: Layout,
    factors: &[usize],
    lobes: usize,
) -> bool {
    let least = MIN_SAMPLES_PER_PARAMETER * layout.param_count(lobes);
    factors.iter().filter(|&&f| f > 1).any(|&factor| {
        let keep = kept_by(factor);
        let kept = (0..samples.sample_count()).filter(|&i| keep(i)).count();
        kept >= least
    })
}

/// A decimated level's options: `opts` with the schedule's tolerance,
/// sweep limit and joint steps.
fn level_options(schedule: Schedule, opts: FitOptions) -> FitOptions {
    let mut level_opts = FitOptions {
        tol: schedule.tol,
        max_sweeps: schedule.max_sweeps,
        ..opts
    };
    if schedule.gauss_newton {
        level_opts.gauss_newton = true;
        level_opts.gauss_newton_cg = LEVEL_GN_CG;
        level_opts.gauss_newton_below = Some(LEVEL_GN_BELOW);
    }
    level_opts
}

/// The last decimated level's samples, set and run.
type LastLevel = (MeasuredSamples, FitSet, FitResult);

/// The decimated levels of [`fit`], in turn, each from where the one
/// before ended (the first from `start`): what each did, and the last
/// one (none when no level ran), whose run holds the factors and the
/// diffuse form the full set starts from.
fn levels_fit(
    samples: &SampleData,
    (layout, so): (Layout, SampleOptions),
    schedule: Schedule,
    opts: FitOptions,
    start: &Factors,
    duo: &Duo,
) -> Result<(Vec<CoarseLevel>, Option<LastLevel>), CoarseError> {
    let mut done = Vec::new();
    let mut last: Option<LastLevel> = None;
    let level_opts = level_options(schedule, opts);
    for &factor in schedule.factors.iter().filter(|&&f| f > 1) {
        let t = std::time::Instant::now();
        let kept = decimate(samples, factor);
        // Too few samples per parameter and the level's optimum is not
        // the full set's: a start from it would cost full sweeps, not save them.
        if kept.samples.len() < MIN_SAMPLES_PER_PARAMETER * layout.param_count(opts.lobes) {
            continue;
        }
        let small = FitSet::build(&kept, layout, so)?;
        // The previous level's set goes before this one runs.
        let (start, form) = match last.take() {
            Some((_, _, r)) => (r.factors, Some(r.model.diffuse_form)),
            None => (start.clone(), None),
        };
        let run = |start: Factors, form: Option<crate::model::DiffuseForm>, hold: bool| {
            let mut exec = Executor::new(&small, level_opts).start_from(start);
            if let Some(form) = form {
                exec = exec.start_form(form);
            }
            exec.hold_form(hold).partner(duo).run()
        };
        // A separable P's first level runs both ways of starting it
        // (`Executor::hold_form`) and keeps the lower objective.
        let (r, held) = match form {
            None if opts.diffuse == DiffuseKind::Separable => {
                let free = run(start.clone(), None, false)?;
                let held = run(start, None, true)?;
                if held.objective < free.objective {
                    (held, Some(true))
                } else {
                    (free, Some(false))
                }
            }
            carried => (run(start, carried, false)?, None),
        };
        print_stages(factor, &r.history);
        done.push(CoarseLevel {
            factor,
            samples: small.len(),
            sweeps: r.history.len(),
            converged: r.converged,
            seconds: t.elapsed().as_secs_f64(),
            separable_held: held,
        });
        last = Some((kept, small, r));
    }
    Ok((done, last))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mask for a power of two keeps exactly what the modulo keeps.
    #[test]
    fn kept_samples_are_those_of_the_hash_modulo() {
        for factor in [0, 1, 2, 3, 7, 8, 32, 64, 100, 1 << 20] {
            let keep = kept_by(factor);
            let n = (0..200_000usize)
                .filter(|&i| {
                    let want = factor <= 1 || mix(i as u64) % factor as u64 == 0;
                    assert_eq!(keep(i), want, "factor {factor}, sample {i}");
                    want
                })
                .count();
            if factor > 1 && factor < 1000 {
                // Every factor-th sample on average: a check the test is not vacuous.
                let mean = 200_000 / factor;
                assert!(n.abs_diff(mean) < mean / 5 + 10, "factor {factor}: {n}");
            }
        }
    }
}
