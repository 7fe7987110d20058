//! A one-lobe cosine-L2 fit of synthetic samples, optionally from a given
//! start (included by path by the tests of the model's options).

use npf::loaders::MeasuredSamples;
use npf::model::{Layout, Model};
use npf::reconstruct::to_merl;
use npf::samples::{FitSet, SampleOptions, Weighting};
use npf::solver::{Executor, Factors, FitOptions, FitResult};

/// Every `keep`-th sample of a model's MERL table.
pub fn samples(m: &Model, keep: usize) -> MeasuredSamples {
    let mut s = to_merl(m).samples("synthetic");
    s.samples = s.samples.into_iter().step_by(keep).collect();
    s
}

/// One lobe, cosine-L2 weights, `sweeps` sweeps (traced: tolerance 0 and
/// every stage's objective recorded), the other options from `opts`.
pub fn fit_one_lobe(
    s: &MeasuredSamples,
    opts: FitOptions,
    sweeps: usize,
    trace: bool,
    start: Option<&Model>,
) -> FitResult {
    let so = SampleOptions {
        weighting: Weighting::CosineL2,
        ..Default::default()
    };
    let set = FitSet::build(s, Layout::default(), so).unwrap();
    let ex = Executor::new(
        &set,
        FitOptions {
            lobes: 1,
            max_sweeps: sweeps,
            tol: if trace { 0.0 } else { 1e-9 },
            trace_stages: trace,
            ..opts
        },
    );
    match start {
        Some(m) => ex.start_from(Factors::from_model(m)),
        None => ex,
    }
    .run()
    .unwrap()
}
