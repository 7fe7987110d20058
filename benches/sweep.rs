//! The fit's kernels on a synthetic MERL-sized table (GGX + Lambert,
//! `npf::synth`, all 1.46 M cells): building the sample set
//! (`FitSet::build`: weights, reciprocal merge, stencils, incidence) and a
//! one-sweep fit (start plus one AWLS sweep of D, F, G, diffuse/scales and
//! gauge), each in a one-thread and a two-thread pool; and the same
//! one-sweep fit on the default coarse-to-fine level (`npf::coarse`, a 32nd
//! of the samples), what the coarse level's sweeps cost against full ones.
//!
//! The `kernel` group times each stage of a sweep alone (D and G of one
//! lobe, F, the d, s solve, the full gauge, which is also an extrapolation
//! trial's cost, and a read-only objective pass) on the full synthetic set,
//! through `npf::solver::kernels` (the executor's own functions).
//!
//! cargo bench --bench sweep
//! cargo bench --bench sweep -- kernel
//!
//! Wall time (the kernels are parallel, so thread CPU time would not say
//! what a fit waits for); on a shared machine quote it with the load.

use criterion::{criterion_group, criterion_main, Criterion};
use npf::model::Layout;
use npf::samples::{FitSet, SampleOptions};
use npf::solver::kernels::Kernels;
use npf::solver::{Executor, FitOptions};
use npf::synth::GgxLambert;

/// The synthetic MERL-sized table's samples.
fn synthetic() -> npf::loaders::MeasuredSamples {
    let brdf = GgxLambert {
        kd: [0.1, 0.1, 0.1],
        f0: [0.9, 0.7, 0.5],
        alpha: 0.2,
    };
    brdf.table().samples("synthetic")
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

fn kernels(c: &mut Criterion) {
    let samples = synthetic();
    let factor = npf::fit::FitConfig::default().coarse[0];
    let coarse = FitSet::build(
        &npf::coarse::decimate(&samples, factor),
        Layout::default(),
        SampleOptions::default(),
    )
    .expect("coarse set");
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    for threads in [1, 2] {
        let pool = pool(threads);
        g.bench_function(format!("sample set, {threads} thread(s)"), |b| {
            b.iter(|| {
                pool.install(|| {
                    FitSet::build(&samples, Layout::default(), SampleOptions::default())
                        .expect("set")
                })
            })
        });
        let set =
            FitSet::build(&samples, Layout::default(), SampleOptions::default()).expect("set");
        g.bench_function(format!("start + 1 sweep, {threads} thread(s)"), |b| {
            b.iter(|| {
                pool.install(|| {
                    Executor::new(
                        &set,
                        FitOptions {
                            max_sweeps: 1,
                            ..Default::default()
                        },
                    )
                    .run()
                    .expect("fit")
                })
            })
        });
        g.bench_function(
            format!("start + 1 sweep, 1/{factor} of the samples, {threads} thread(s)"),
            |b| {
                b.iter(|| {
                    pool.install(|| {
                        Executor::new(
                            &coarse,
                            FitOptions {
                                max_sweeps: 1,
                                ..Default::default()
                            },
                        )
                        .run()
                        .expect("fit")
                    })
                })
            },
        );
    }
    g.finish();
}

fn stages(c: &mut Criterion) {
    let samples = synthetic();
    let set = FitSet::build(&samples, Layout::default(), SampleOptions::default()).expect("set");
    let mut g = c.benchmark_group("kernel");
    g.sample_size(10);
    for threads in [1, 2] {
        let pool = pool(threads);
        let mut k = pool.install(|| Kernels::new(&set, FitOptions::default()).expect("start"));
        type Stage = fn(&mut Kernels);
        let list: [(&str, Stage); 6] = [
            ("D (one lobe)", |k| k.d(0)),
            ("F", |k| k.f()),
            ("G (one lobe)", |k| k.g(0)),
            ("d, s", |k| k.diffuse_and_scales()),
            ("gauge (= extrapolation trial)", |k| {
                k.gauge();
            }),
            ("objective", |k| {
                std::hint::black_box(k.objective());
            }),
        ];
        for (name, stage) in list {
            g.bench_function(format!("{name}, {threads} thread(s)"), |b| {
                b.iter(|| pool.install(|| stage(&mut k)))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, kernels, stages);
criterion_main!(benches);
