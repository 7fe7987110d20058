//! The loop around the sweep, with observers (argmin's executor split).

use super::g_update::update_g;
use super::g_work::GPassStats;
use super::gauge::{d_measure, fill_unconstrained, normalise, Scales};
use super::init::initial_factors;
use super::state::{set_residual, squared_error, Cache, Factors, State};
use super::updates::{
    solve_diffuse_and_scales, update_d, update_diffuse_and_scales, update_f, Scratch,
};
use super::{chunked_sum, chunked_sum_mut, FitOptions, SolverError, MAX_LOBES};
use crate::grid::Grid;
use crate::model::{DiffuseForm, Model};
use crate::samples::FitSet;
use rayon::prelude::*;
use std::time::Instant;

/// A step of a sweep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The D update of a lobe.
    D(usize),
    /// The F update (all channels).
    F,
    /// The G update of a lobe.
    G(usize),
    /// The G smoothing trial of a lobe.
    SmoothG(usize),
    /// The (d, s) solve.
    DiffuseAndScales,
    /// The diffuse form's refresh trial.
    DiffuseForm,
    /// Canonical rescaling and a fresh recomputation of all caches.
    Gauge,
    /// The extrapolation trial (accepted or not).
    Extrapolate,
    /// The joint Gauss-Newton trial (accepted or not).
    GaussNewton,
}

/// One stage's cost, and the objective after it when stages are traced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageRecord {
    /// Which stage.
    pub stage: Stage,
    /// Its wall time.
    pub seconds: f64,
    /// The objective after it (only when stages are traced).
    pub objective: Option<f64>,
}

/// What one sweep did; passed to every observer.
#[derive(Clone, Debug)]
pub struct SweepReport {
    /// 1-based.
    pub sweep: usize,
    /// The objective after the sweep.
    pub objective: f64,
    /// (previous - current) / previous.
    pub rel_decrease: f64,
    /// Seconds since the fit started.
    pub elapsed: f64,
    /// Per-stage records.
    pub stages: Vec<StageRecord>,
    /// What each lobe's G pass did.
    pub g_passes: Vec<GPassStats>,
    /// Smoothing passes reverted because they raised the objective.
    pub smoothing_reverted: usize,
    /// Whether the extrapolated point was kept.
    pub extrapolated: bool,
    /// Whether a joint Gauss-Newton step was kept.
    pub gauss_newton: bool,
    /// Lobes that were dead (all s = 0) and got a fresh D this sweep.
    pub revived: usize,
}

/// Receives every sweep's report as the fit runs.
pub trait Observer {
    /// Called after each sweep.
    fn observe(&mut self, report: &SweepReport);
    /// Called after [`Observer::observe`] with the factors the sweep ended
    /// at (for studies that evaluate every sweep's model); by default nothing.
    fn observe_factors(&mut self, _report: &SweepReport, _factors: &Factors) {}
}

impl<F: FnMut(&SweepReport)> Observer for F {
    fn observe(&mut self, report: &SweepReport) {
        self(report)
    }
}

/// The outcome of a fit.
#[derive(Clone, Debug)]
pub struct FitResult {
    /// The fitted model (f32).
    pub model: Model,
    /// The fitted factors in working precision.
    pub factors: Factors,
    /// The objective of the start (after the first d, s solve and gauge).
    pub initial_objective: f64,
    /// The final objective.
    pub objective: f64,
    /// One report per sweep.
    pub history: Vec<SweepReport>,
    /// Whether the tolerance ended the fit (not the sweep limit).
    pub converged: bool,
    /// Wall time.
    pub seconds: f64,
}

/// A held separable P joins the sweeps once one lowers the objective by
/// less than this fraction ([`Executor::hold_form`]).
const P_JOINS_BELOW: f64 = 1e-3;

/// Runs sweeps on a sample set until convergence, reporting to observers.
pub struct Executor<'a> {
    set: &'a FitSet,
    options: FitOptions,
    start: Option<Factors>,
    start_form: Option<DiffuseForm>,
    hold_form: bool,
    observers: Vec<&'a mut dyn Observer>,
    partner: Option<&'a super::duo::Duo>,
}

struct Recorder {
    trace: bool,
    t: Instant,
    stages: Vec<StageRecord>,
}

impl Recorder {
    fn mark(&mut self, stage: Stage, set: &FitSet, st: &State) {
        let objective = self.trace.then(|| st.objective(set));
        let now = Instant::now();
        self.stages.push(StageRecord {
            stage,
            seconds: (now - self.t).as_secs_f64(),
            objective,
        });
        self.t = now;
    }
}

impl<'a> Executor<'a> {
    /// A fit of `set` with `options`.
    pub fn new(set: &'a FitSet, options: FitOptions) -> Self {
        Executor {
            set,
            options,
            start: None,
            start_form: None,
            hold_form: false,
            observers: Vec::new(),
            partner: None,
        }
    }

    /// Start from these factors instead of the default initialisation.
    pub fn start_from(mut self, f: Factors) -> Self {
        self.start = Some(f);
        self
    }

    /// Start the diffuse form from this one where the options' kind can
    /// (a coarser level's separable P; the other kinds start as always).
    pub fn start_form(mut self, form: DiffuseForm) -> Self {
        self.start_form = Some(form);
        self
    }

    /// Hold a separable P that starts at 1 there until a sweep lowers the
    /// objective by less than [`P_JOINS_BELOW`] (or the tolerance). Updated
    /// from the first sweep (the default), P can take shapes the lobes' D
    /// and G should have and settle in a worse minimum than the Lambertian
    /// fit's (measured on nylon, yellow-plastic and white-fabric); held,
    /// the lobes can absorb the diffuse term's shape first (a synthetic
    /// Ashikhmin-Shirley table is then not recovered). Neither is better
    /// everywhere: the coarse-to-fine fit runs both on its first level and
    /// keeps the lower objective ([`crate::coarse`]).
    pub fn hold_form(mut self, hold: bool) -> Self {
        self.hold_form = hold;
        self
    }

    /// A decimated level's run: its G passes split each control point's
    /// entries in halves, handed to `duo`'s partner while one serves
    /// (the same sums either way, so the same result for any thread
    /// count; not the same last bits as a run without it).
    pub fn partner(mut self, duo: &'a super::duo::Duo) -> Self {
        self.partner = Some(duo);
        self
    }

    /// Add an observer.
    pub fn observe(mut self, o: &'a mut dyn Observer) -> Self {
        self.observers.push(o);
        self
    }

    /// Run the fit.
    pub fn run(mut self) -> Result<FitResult, SolverError> {
        self.options.validate()?;
        let set = self.set;
        let opts = self.options;
        let t0 = Instant::now();
        let measure = d_measure(set);
        let mut factors = self
            .start
            .take()
            .unwrap_or_else(|| initial_factors(set.layout, opts.lobes));
        if factors.layout != set.layout {
            return Err(SolverError::Start(
                "its layout differs from the sample set's".into(),
            ));
        }
        if factors.lobes() == 0 || factors.lobes() > MAX_LOBES {
            return Err(SolverError::Lobes(factors.lobes()));
        }
        let mask = opts.channel_mask;
        apply_mask(&mut factors, &mask);
        factors.masking = opts.masking;
        let monotone_from = d_monotone_from(set, opts.d_monotone_from_deg);
        let mut st = State::new(set, factors);
        let mut scratch = Scratch::new(set.len());
        let mut f_scratch = [
            Scratch::new(set.len()),
            Scratch::new(set.len()),
            Scratch::new(set.len()),
        ];
        let mut g_work = Vec::new();
        update_diffuse_and_scales(set, &mut st, &mask);
        super::diffuse::start(set, &mut st, &mask, opts.diffuse, self.start_form.as_ref());
        let p_inc = match &st.diffuse_form {
            DiffuseForm::Separable { p } if !opts.hold_p => {
                Some(super::separable::incidence(set, p.len()))
            }
            _ => None,
        };
        let p_held = opts.hold_p && opts.diffuse == super::DiffuseKind::Separable;
        // See `hold_form`.
        let mut form_held = self.hold_form
            && matches!(&st.diffuse_form,
            DiffuseForm::Separable { p } if p.iter().all(|&v| v == 1.0));
        let initial = gauge_objective(set, &mut st, &measure);
        let mut prev = initial;
        let mut prev_factors: Option<Factors> = None;
        let mut beta = 1.0;
        let mut damping = super::gauss_newton::Damping::default();
        // Sweeps until the next Gauss-Newton trial, and the current back-off.
        let (mut gn_wait, mut gn_backoff) = (0usize, 1usize);
        let mut history = Vec::new();
        let mut converged = false;
        let mut first_revival = vec![true; st.factors.lobes()];
        for sweep in 1..=opts.max_sweeps {
            let mut rec = Recorder {
                trace: opts.trace_stages,
                t: Instant::now(),
                stages: Vec::new(),
            };
            let mut g_passes = Vec::new();
            let mut reverted = 0;
            let lobes = st.factors.lobes();
            let mut revived = 0;
            let mut block_convergence = false;
            for m in 0..lobes {
                if update_d(set, &mut st, m, &mut scratch, monotone_from, mask[m]) {
                    revived += 1;
                    block_convergence |= std::mem::take(&mut first_revival[m]);
                }
                rec.mark(Stage::D(m), set, &st);
            }
            update_f(set, &mut st, &mut f_scratch);
            rec.mark(Stage::F, set, &st);
            for m in 0..lobes {
                g_passes.push(update_g(
                    set,
                    &mut st,
                    m,
                    opts.g_method,
                    &mut g_work,
                    self.partner,
                ));
                rec.mark(Stage::G(m), set, &st);
                if let Some(sigma) = opts.smooth_g {
                    let before = st.objective(set);
                    let saved = st.factors.g[m].clone();
                    smooth_theta(&set.layout.g, &mut st.factors.g[m], sigma);
                    st.refresh(set);
                    if st.objective(set) > before {
                        st.factors.g[m] = saved;
                        st.refresh(set);
                        reverted += 1;
                    }
                    rec.mark(Stage::SmoothG(m), set, &st);
                }
            }
            // Between the d, s solve and the rescaling gauge nothing reads
            // the residuals, so (untraced, Lambertian) their recomputation,
            // the rescaling and the objective share one pass.
            let lambert = opts.diffuse == super::DiffuseKind::Lambert;
            let fused = lambert && sweep % 10 != 0 && !opts.trace_stages;
            if fused {
                solve_diffuse_and_scales(set, &mut st, &mask);
            } else {
                update_diffuse_and_scales(set, &mut st, &mask);
            }
            rec.mark(Stage::DiffuseAndScales, set, &st);
            if !lambert && !form_held && !p_held {
                super::diffuse::refresh(set, &mut st, &mask, opts.diffuse, p_inc.as_ref());
                rec.mark(Stage::DiffuseForm, set, &st);
            }
            // An extrapolation trial refreshes every cache (to the trial's
            // factors, then back to the current ones if refused), so before
            // one the caches need not be updated, only the objective computed.
            let trial_follows = opts.accelerate && prev_factors.is_some();
            let mut e = if fused && trial_follows {
                residuals_objective(set, &mut st, &measure)
            } else if fused {
                residuals_rescale_objective(set, &mut st, &measure)
            } else if sweep % 10 == 0 {
                gauge_objective(set, &mut st, &measure)
            } else {
                gauge_rescale(set, &mut st, &measure);
                st.objective(set)
            };
            rec.mark(Stage::Gauge, set, &st);
            let mut extrapolated = false;
            if opts.accelerate {
                if let Some(old) = &prev_factors {
                    let current = st.factors.clone();
                    st.factors = extrapolate(&current, old, beta, monotone_from);
                    apply_mask(&mut st.factors, &mask);
                    let trial = gauge_objective(set, &mut st, &measure);
                    if trial < e {
                        e = trial;
                        extrapolated = true;
                        beta = (beta * 1.5).min(8.0);
                    } else {
                        st.factors = current;
                        st.refresh(set);
                        beta = (beta * 0.5).max(0.5);
                    }
                    rec.mark(Stage::Extrapolate, set, &st);
                }
            }
            // The caches are fresh here (every path above leaves them so).
            let mut newton = false;
            // The joint step's partials are those of the separable G G
            // product; the height-correlated form has its own G pass only.
            let newton_on = opts.gauss_newton && opts.masking == crate::model::Masking::Separable;
            // With a threshold, the step waits for the crawl: early, fast
            // sweeps are cheaper than it, and a step taken there can lead
            // to a worse stationary point (polyurethane-foam's coarse level).
            let crawling = opts
                .gauss_newton_below
                .map_or(true, |b| prev <= 0.0 || (prev - e) / prev < b);
            if newton_on && gn_wait > 0 {
                gn_wait -= 1;
            } else if newton_on && crawling {
                let project = |t: &mut Factors, x: &Factors| {
                    apply_mask(t, &mask);
                    for (d, xd) in t.d.iter_mut().zip(&x.d) {
                        project_d(d, xd, x.layout.d.n_phi(), monotone_from);
                    }
                };
                let (e_new, stats) =
                    super::gauss_newton::step(set, &mut st, &opts, e, &mut damping, &project);
                // Worth its passes only where it gains more than the sweep
                // before it did (near a minimum, where AWLS crawls); until
                // then it is tried at doubling intervals.
                let als_gain = if prev > 0.0 { (prev - e) / prev } else { 0.0 };
                let gain = if e > 0.0 { (e - e_new) / e } else { 0.0 };
                if stats.accepted && gain > als_gain {
                    gn_backoff = 1;
                } else {
                    gn_wait = gn_backoff;
                    gn_backoff = (2 * gn_backoff).min(16);
                }
                if stats.accepted {
                    e = e_new;
                    newton = true;
                    gauge_rescale(set, &mut st, &measure);
                }
                rec.mark(Stage::GaussNewton, set, &st);
            }
            if opts.accelerate {
                prev_factors = Some(st.factors.clone());
            }
            let rel = if prev > 0.0 { (prev - e) / prev } else { 0.0 };
            let report = SweepReport {
                sweep,
                objective: e,
                rel_decrease: rel,
                elapsed: t0.elapsed().as_secs_f64(),
                stages: rec.stages,
                g_passes,
                smoothing_reverted: reverted,
                extrapolated,
                gauss_newton: newton,
                revived,
            };
            for o in self.observers.iter_mut() {
                o.observe(&report);
                o.observe_factors(&report, &st.factors);
            }
            history.push(report);
            prev = e;
            // A revived lobe only pays off in the next sweep's d, s solve, so
            // its first revival may not end the fit (later ones may: a
            // lobe the data do not need stays dead).
            if form_held && rel < P_JOINS_BELOW.max(opts.tol) {
                form_held = false;
                continue;
            }
            if rel < opts.tol && !block_convergence {
                converged = true;
                break;
            }
        }
        Ok(FitResult {
            model: st.to_model(),
            objective: prev,
            factors: st.factors,
            initial_objective: initial,
            history,
            converged,
            seconds: t0.elapsed().as_secs_f64(),
        })
    }
}

/// The gauge applied to the caches by rescaling (every model value, hence
/// every residual, is unchanged), without re-reading the stencils. Filled
/// entries are read by no sample, so they need no cache update either.
fn gauge_rescale(set: &FitSet, st: &mut State, measure: &[f64]) {
    fill_unconstrained(&mut st.factors, set);
    let k = normalise(&mut st.factors, set, measure);
    let lobes = st.factors.lobes();
    st.cache.par_iter_mut().for_each(|c| rescale(c, &k, lobes));
}

/// A cache's factor values multiplied by the gauge's factors.
#[inline]
fn rescale(c: &mut Cache, k: &Scales, lobes: usize) {
    for m in 0..lobes {
        c.dv[m] *= k.d[m];
        c.gi[m] *= k.g[m];
        c.go[m] *= k.g[m];
    }
    for ch in 0..3 {
        c.fv[ch] *= k.f[ch];
    }
}

/// The full gauge (canonical form and fresh caches), returning the objective.
pub(super) fn gauge_objective(set: &FitSet, st: &mut State, measure: &[f64]) -> f64 {
    fill_unconstrained(&mut st.factors, set);
    normalise(&mut st.factors, set, measure);
    st.refresh_objective(set)
}

/// The objective `residuals_rescale_objective` returns, and the same gauge
/// of the factors, leaving the caches stale (for a caller that refreshes
/// them next).
fn residuals_objective(set: &FitSet, st: &mut State, measure: &[f64]) -> f64 {
    let solved = st.factors.clone();
    fill_unconstrained(&mut st.factors, set);
    normalise(&mut st.factors, set, measure);
    let (cache, basis) = (&st.cache, &st.basis);
    let [e] = chunked_sum(set.len(), |range| {
        let mut e = 0.0;
        for j in range {
            let mut c = cache[j];
            set_residual(set, &solved, basis, j, &mut c);
            e += squared_error(&c, &set.w[j]);
        }
        [e]
    });
    e + set.objective_offset
}

/// `recompute_residuals` after `solve_diffuse_and_scales`, then
/// `gauge_rescale` and the objective, in one pass over the caches: the
/// residuals use the factors before the gauge and the caches before their
/// rescaling, exactly as the three passes in turn (bit-identical).
fn residuals_rescale_objective(set: &FitSet, st: &mut State, measure: &[f64]) -> f64 {
    let solved = st.factors.clone();
    fill_unconstrained(&mut st.factors, set);
    let k = normalise(&mut st.factors, set, measure);
    let lobes = solved.lobes();
    let basis = &st.basis;
    let [e] = chunked_sum_mut(&mut st.cache, |start, chunk| {
        let mut e = 0.0;
        for (i, c) in chunk.iter_mut().enumerate() {
            let j = start + i;
            set_residual(set, &solved, basis, j, c);
            e += squared_error(c, &set.w[j]);
            rescale(c, &k, lobes);
        }
        [e]
    });
    e + set.objective_offset
}

/// Hold masked scales at exactly 0.
fn apply_mask(f: &mut Factors, mask: &[[bool; 3]; MAX_LOBES]) {
    for (s, on) in f.s.iter_mut().zip(mask) {
        for c in 0..3 {
            if !on[c] {
                s[c] = 0.0;
            }
        }
    }
}

/// The first D theta index whose half angle lies past `deg` (none: `usize::MAX`).
pub(super) fn d_monotone_from(set: &FitSet, deg: Option<f64>) -> usize {
    let Some(deg) = deg else {
        return usize::MAX;
    };
    let axis = set.layout.d.theta;
    (0..axis.len())
        .find(|&k| axis.node(k) > deg.to_radians())
        .unwrap_or(usize::MAX)
}

/// x + beta (x - old), clamped at 0, for every table (both in canonical
/// form); D is projected by [`project_d`] (no larger than x's largest D
/// value; tails no less monotone than x's).
///
/// A cap that follows the peak's own trend (max + beta (max - previous
/// max)) was measured on 2026-12-02: nylon's full set then takes 3 sweeps,
/// not 11, and renders 0.7 dB better, but the golden-G plain fit of
/// gold-metallic-paint runs off along the D x G valley again (23.1 dB
/// against 42.7), even with the trend allowed only for a maximum at
/// theta_h <= 30 degrees; not kept (BENCHMARKS.md as of 4d8d1ee, issue 15, "the
/// extrapolation's D cap").
fn extrapolate(x: &Factors, old: &Factors, beta: f64, monotone_from: usize) -> Factors {
    let mv = |a: f64, b: f64| (a + beta * (a - b)).max(0.0);
    let tab = |a: &Vec<f64>, b: &Vec<f64>| {
        a.iter()
            .zip(b)
            .map(|(&a, &b)| mv(a, b))
            .collect::<Vec<f64>>()
    };
    let lobes = x.lobes();
    Factors {
        layout: x.layout,
        diffuse: std::array::from_fn(|c| mv(x.diffuse[c], old.diffuse[c])),
        s: (0..lobes)
            .map(|m| std::array::from_fn(|c| mv(x.s[m][c], old.s[m][c])))
            .collect(),
        d: (0..lobes)
            .map(|m| {
                let mut d = tab(&x.d[m], &old.d[m]);
                project_d(&mut d, &x.d[m], x.layout.d.n_phi(), monotone_from);
                d
            })
            .collect(),
        g: (0..lobes).map(|m| tab(&x.g[m], &old.g[m])).collect(),
        f: std::array::from_fn(|c| tab(&x.f[c], &old.f[c])),
        masking: x.masking,
    }
}

/// A trial D table (from an extrapolation or a joint step away from the
/// current table `x`) made admissible: D and G trade off freely where G is
/// nearly 0 (D G G is all the data sees), and a step along that valley
/// would grow D without bound, so it may not raise D's maximum; past
/// `monotone_from` an entry may not rise above the one before it along
/// theta (`np` phi columns) unless `x` already does, and then not above
/// `x`'s own value: the interval the D update itself allows.
///
/// Forcing every tail non-increasing instead (as before 2026-12-03) moved
/// the tails the D update leaves above their neighbour (it never forces
/// them down), so a trial of step 0 already raised the objective by 3-7 %
/// and most trials were refused (white-fabric's coarse level: 0 of 49).
fn project_d(d: &mut [f64], x: &[f64], np: usize, monotone_from: usize) {
    let top = x.iter().cloned().fold(0.0, f64::max);
    for v in d.iter_mut() {
        *v = v.min(top);
    }
    for k in (monotone_from.max(1).saturating_mul(np)).min(d.len())..d.len() {
        let bound = if x[k] <= x[k - np] {
            d[k - np]
        } else {
            d[k - np].max(x[k])
        };
        d[k] = d[k].min(bound);
    }
}

/// [`gaussian_smooth`] along theta in every phi column of a table.
pub fn smooth_theta(grid: &Grid, table: &mut [f64], sigma: f64) {
    if grid.is_1d() {
        gaussian_smooth(table, sigma);
        return;
    }
    grid.for_each_column(table, |mut col| {
        let mut v = col.to_vec();
        gaussian_smooth(&mut v, sigma);
        col.assign(&ndarray::ArrayView1::from(&v[..]));
    });
}

/// Gaussian smoothing with a kernel truncated at 3 sigma and renormalised at
/// the ends (so a constant table stays constant).
pub fn gaussian_smooth(t: &mut [f64], sigma: f64) {
    let r = (3.0 * sigma).ceil() as isize;
    let src = t.to_vec();
    let n = src.len() as isize;
    for (k, out) in t.iter_mut().enumerate() {
        let (mut acc, mut wsum) = (0.0, 0.0);
        for o in -r..=r {
            let i = k as isize + o;
            if i >= 0 && i < n {
                let w = (-(o * o) as f64 / (2.0 * sigma * sigma)).exp();
                acc += w * src[i as usize];
                wsum += w;
            }
        }
        *out = acc / wsum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;

    #[test]
    fn extrapolation_never_raises_the_largest_d_value() {
        // A D cell growing while G shrinks (the flat D x G valley): the
        // extrapolated step must not carry it past the current maximum.
        let layout = Layout::isotropic(30);
        let mk = |d: Vec<f64>, g: Vec<f64>| Factors {
            layout,
            diffuse: [0.1; 3],
            s: vec![[1.0; 3]],
            d: vec![d],
            g: vec![g],
            f: std::array::from_fn(|_| vec![1.0; 30]),
            masking: Default::default(),
        };
        let mut d_old = vec![1.0; 30];
        let mut d_new = vec![1.0; 30];
        d_old[20] = 0.5;
        d_new[20] = 0.9;
        d_new[25] = 1.5; // the current maximum, and still growing
        d_old[25] = 1.0;
        let (g_old, g_new) = (vec![0.5; 30], vec![0.25; 30]);
        let x = mk(d_new.clone(), g_new);
        let old = mk(d_old, g_old);
        let e = extrapolate(&x, &old, 4.0, usize::MAX);
        let top = d_new.iter().cloned().fold(0.0, f64::max);
        assert!(e.d[0].iter().all(|&v| v <= top), "{:?}", e.d[0]);
        // Cells below the maximum still move: 0.9 + 4 (0.9 - 0.5) capped at 1.5.
        assert_eq!(e.d[0][20], 1.5);
        // G extrapolates freely, clamped at 0.
        assert!(e.g[0].iter().all(|&v| v == 0.0));
    }

    #[test]
    fn projection_keeps_the_current_table_and_monotone_tails() {
        // A tail the D update left rising (entry 6 above entry 5): a step
        // of 0 must give the current table back (the old projection forced
        // it down, so a trial at the current point raised the objective).
        let x = vec![4.0, 3.0, 2.0, 1.5, 1.0, 0.5, 0.8, 0.4];
        let mut d = x.clone();
        project_d(&mut d, &x, 1, 4);
        assert_eq!(d, x);
        // Where x's tail is non-increasing, the trial's is made so too;
        // where x rises, the trial may rise up to x's own value only.
        let mut d = vec![4.0, 3.0, 2.0, 1.5, 0.9, 1.2, 2.0, 0.45];
        project_d(&mut d, &x, 1, 4);
        assert_eq!(d, vec![4.0, 3.0, 2.0, 1.5, 0.9, 0.9, 0.9, 0.45]);
    }
}
