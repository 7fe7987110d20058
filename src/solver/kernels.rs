//! One sweep's stages as separately callable steps on a live fit state,
//! so that benchmarks (benches/sweep.rs) and profilers can time each
//! kernel alone. The executor runs the same functions in the same order;
//! nothing here is a second implementation.

use super::executor::{d_monotone_from, gauge_objective};
use super::g_update::update_g;
use super::g_work::GWork;
use super::gauge::d_measure;
use super::init::initial_factors;
use super::state::State;
use super::updates::{update_d, update_diffuse_and_scales, update_f, Scratch};
use super::{FitOptions, SolverError, MAX_LOBES};
use crate::samples::FitSet;

/// A fit state after the start (d, s solve and gauge), on which each of a
/// sweep's stages can be run alone.
pub struct Kernels<'a> {
    set: &'a FitSet,
    opts: FitOptions,
    st: State,
    scratch: Scratch,
    f_scratch: [Scratch; 3],
    g_work: Vec<GWork>,
    measure: Vec<f64>,
    monotone_from: usize,
    mask: [[bool; 3]; MAX_LOBES],
}

impl<'a> Kernels<'a> {
    /// The default start on `set`, after its first d, s solve and gauge.
    pub fn new(set: &'a FitSet, opts: FitOptions) -> Result<Self, SolverError> {
        opts.validate()?;
        let mut st = State::new(set, initial_factors(set.layout, opts.lobes));
        let measure = d_measure(set);
        update_diffuse_and_scales(set, &mut st, &opts.channel_mask);
        gauge_objective(set, &mut st, &measure);
        Ok(Kernels {
            set,
            opts,
            st,
            scratch: Scratch::new(set.len()),
            f_scratch: std::array::from_fn(|_| Scratch::new(set.len())),
            g_work: Vec::new(),
            measure,
            monotone_from: d_monotone_from(set, opts.d_monotone_from_deg),
            mask: opts.channel_mask,
        })
    }

    /// Lobes of the fit.
    pub fn lobes(&self) -> usize {
        self.st.factors.lobes()
    }

    /// The D update of lobe `m`.
    pub fn d(&mut self, m: usize) {
        let mask = self.mask[m];
        update_d(
            self.set,
            &mut self.st,
            m,
            &mut self.scratch,
            self.monotone_from,
            mask,
        );
    }

    /// The F update (all channels).
    pub fn f(&mut self) {
        update_f(self.set, &mut self.st, &mut self.f_scratch);
    }

    /// The G update of lobe `m`.
    pub fn g(&mut self, m: usize) {
        update_g(
            self.set,
            &mut self.st,
            m,
            self.opts.g_method,
            &mut self.g_work,
            None,
        );
    }

    /// The (d, s) solve with its residual recomputation.
    pub fn diffuse_and_scales(&mut self) {
        update_diffuse_and_scales(self.set, &mut self.st, &self.mask);
    }

    /// The full gauge (canonical form, every cache recomputed): also what
    /// an extrapolation trial costs. Returns the objective.
    pub fn gauge(&mut self) -> f64 {
        gauge_objective(self.set, &mut self.st, &self.measure)
    }

    /// The objective (one read-only pass).
    pub fn objective(&self) -> f64 {
        self.st.objective(self.set)
    }
}
