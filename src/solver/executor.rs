//! The loop around the sweep, with observers (argmin's executor split).

use super::g_update::{update_g, GPassStats};
use super::gauge::{d_measure, fill_unconstrained, normalise};
use super::init::initial_factors;
use super::state::{Factors, State};
use super::updates::{update_d, update_diffuse_and_scales, update_f, Scratch};
use super::FitOptions;
use crate::model::Model;
use crate::samples::FitSet;
use std::time::Instant;

/// A point inside a sweep at which the objective is recorded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    D(usize),
    F,
    G(usize),
    SmoothG(usize),
    DiffuseAndScales,
    /// Canonical rescaling and a fresh recomputation of all caches.
    Gauge,
}

/// What one sweep did; passed to every observer.
#[derive(Clone, Debug)]
pub struct SweepReport {
    /// 1-based.
    pub sweep: usize,
    pub objective: f64,
    /// (previous - current) / previous.
    pub rel_decrease: f64,
    /// Seconds since the fit started.
    pub elapsed: f64,
    /// The objective after each stage, in order.
    pub stages: Vec<(Stage, f64)>,
    pub g_passes: Vec<GPassStats>,
    /// Smoothing passes reverted because they raised the objective.
    pub smoothing_reverted: usize,
}

pub trait Observer {
    fn observe(&mut self, report: &SweepReport);
}

impl<F: FnMut(&SweepReport)> Observer for F {
    fn observe(&mut self, report: &SweepReport) {
        self(report)
    }
}

#[derive(Clone, Debug)]
pub struct FitResult {
    pub model: Model,
    pub factors: Factors,
    pub initial_objective: f64,
    pub objective: f64,
    pub history: Vec<SweepReport>,
    pub converged: bool,
    pub seconds: f64,
}

pub struct Executor<'a> {
    set: &'a FitSet,
    options: FitOptions,
    start: Option<Factors>,
    observers: Vec<&'a mut dyn Observer>,
}

impl<'a> Executor<'a> {
    pub fn new(set: &'a FitSet, options: FitOptions) -> Self {
        Executor { set, options, start: None, observers: Vec::new() }
    }

    /// Start from these factors instead of the default initialisation.
    pub fn start_from(mut self, f: Factors) -> Self {
        self.start = Some(f);
        self
    }

    pub fn observe(mut self, o: &'a mut dyn Observer) -> Self {
        self.observers.push(o);
        self
    }

    pub fn run(mut self) -> Result<FitResult, String> {
        self.options.validate()?;
        let set = self.set;
        let opts = self.options;
        let t0 = Instant::now();
        let measure = d_measure(set);
        let factors = self.start.take().unwrap_or_else(|| initial_factors(set.layout, opts.lobes));
        if factors.layout != set.layout {
            return Err("the starting model's layout differs from the sample set's".into());
        }
        let mut st = State::new(set, factors);
        let mut scratch = Scratch::new(set.len());
        update_diffuse_and_scales(set, &mut st);
        gauge(set, &mut st, &measure);
        let initial = st.objective(set);
        let mut prev = initial;
        let mut history = Vec::new();
        let mut converged = false;
        for sweep in 1..=opts.max_sweeps {
            let mut stages = Vec::new();
            let mut g_passes = Vec::new();
            let mut reverted = 0;
            let lobes = st.factors.lobes();
            for m in 0..lobes {
                update_d(set, &mut st, m, &mut scratch);
                stages.push((Stage::D(m), st.objective(set)));
            }
            update_f(set, &mut st, &mut scratch);
            stages.push((Stage::F, st.objective(set)));
            for m in 0..lobes {
                g_passes.push(update_g(set, &mut st, m, opts.g_method, &mut scratch));
                let before = st.objective(set);
                stages.push((Stage::G(m), before));
                if let Some(sigma) = opts.smooth_g {
                    let saved = st.factors.g[m].clone();
                    gaussian_smooth(&mut st.factors.g[m], sigma);
                    st.refresh(set);
                    let after = st.objective(set);
                    if after > before {
                        st.factors.g[m] = saved;
                        st.refresh(set);
                        reverted += 1;
                    }
                    stages.push((Stage::SmoothG(m), st.objective(set)));
                }
            }
            update_diffuse_and_scales(set, &mut st);
            stages.push((Stage::DiffuseAndScales, st.objective(set)));
            gauge(set, &mut st, &measure);
            let e = st.objective(set);
            stages.push((Stage::Gauge, e));
            let rel = if prev > 0.0 { (prev - e) / prev } else { 0.0 };
            let report = SweepReport {
                sweep,
                objective: e,
                rel_decrease: rel,
                elapsed: t0.elapsed().as_secs_f64(),
                stages,
                g_passes,
                smoothing_reverted: reverted,
            };
            for o in self.observers.iter_mut() {
                o.observe(&report);
            }
            history.push(report);
            prev = e;
            if rel < opts.tol {
                converged = true;
                break;
            }
        }
        Ok(FitResult {
            model: st.factors.to_model(),
            objective: prev,
            factors: st.factors,
            initial_objective: initial,
            history,
            converged,
            seconds: t0.elapsed().as_secs_f64(),
        })
    }
}

fn gauge(set: &FitSet, st: &mut State, measure: &[f64]) {
    fill_unconstrained(&mut st.factors, set);
    normalise(&mut st.factors, set, measure);
    st.refresh(set);
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
