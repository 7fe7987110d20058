//! Throughput of the factor model's BSDF: `eval`, `sample` and `pdf` of
//! [`NpfBxdf`] (single thread; criterion reports elements per second).
//!
//! cargo bench --bench bsdf
//!
//! The model is the synthetic three-lobe model of the tests (GGX-shaped
//! factors, roughness 0.02, 0.15 and 0.5, on the default 90-node layout),
//! or the model file named by `NPF_BENCH_MODEL` (e.g. a fit kept outside
//! the repository). Inputs are 1024 fixed random views (theta_o up to 80
//! degrees) and directions: `eval` and `pdf` on pairs drawn by the sampler
//! itself (where renderers evaluate), `sample` on random numbers.
//! `eval_batch` and `sample_batch` make the same calls through the batch
//! interface (structure of arrays, four pairs at a time).
//!
//! Time is the thread's CPU time (`CLOCK_THREAD_CPUTIME_ID` on Linux), not
//! wall time: the build machine is shared, and CPU time is what a core
//! spends, so elements/s are per core. `NPF_BENCH_WALL=1` measures wall
//! time instead (on an idle machine both agree).

use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use npf::bsdf::{Directions, NpfBxdf, SampleBatch};
use npf::model::Model;

#[path = "common/bsdf_inputs.rs"]
mod bsdf_inputs;
use bsdf_inputs::BATCH;

fn model() -> Model {
    bsdf_inputs::model().unwrap_or_else(|e| panic!("{e}"))
}

/// CPU time of the calling thread in nanoseconds (wall time when asked, or
/// off Linux).
fn now_ns() -> u64 {
    #[cfg(target_os = "linux")]
    if std::env::var_os("NPF_BENCH_WALL").is_none() {
        #[repr(C)]
        struct Timespec {
            sec: i64,
            nsec: i64,
        }
        extern "C" {
            fn clock_gettime(clock: i32, ts: *mut Timespec) -> i32;
        }
        const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
        let mut ts = Timespec { sec: 0, nsec: 0 };
        // SAFETY: clock_gettime writes one timespec, which ts is.
        if unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0 {
            return ts.sec as u64 * 1_000_000_000 + ts.nsec as u64;
        }
    }
    static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    START
        .get_or_init(std::time::Instant::now)
        .elapsed()
        .as_nanos() as u64
}

/// Criterion measurement on [`now_ns`].
struct CpuTime;

struct NsFormatter;

impl ValueFormatter for NsFormatter {
    fn scale_values(&self, typical: f64, values: &mut [f64]) -> &'static str {
        let (k, unit) = if typical >= 1e6 {
            (1e-6, "ms")
        } else if typical >= 1e3 {
            (1e-3, "us")
        } else {
            (1.0, "ns")
        };
        values.iter_mut().for_each(|v| *v *= k);
        unit
    }

    fn scale_throughputs(&self, _typical: f64, t: &Throughput, values: &mut [f64]) -> &'static str {
        let n = match *t {
            Throughput::Bytes(n) | Throughput::BytesDecimal(n) | Throughput::Elements(n) => {
                n as f64
            }
        };
        // ns per batch -> million elements per second.
        values.iter_mut().for_each(|v| *v = n * 1e3 / *v);
        "Melem/s"
    }

    fn scale_for_machines(&self, values: &mut [f64]) -> &'static str {
        let _ = values;
        "ns"
    }
}

impl Measurement for CpuTime {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        now_ns()
    }
    fn end(&self, i: u64) -> u64 {
        now_ns().saturating_sub(i)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &NsFormatter
    }
}

fn bench(c: &mut Criterion<CpuTime>) {
    let b = NpfBxdf::new(model()).expect("a valid model");
    let bsdf_inputs::Inputs { us, wos, pairs } = bsdf_inputs::inputs(&b);
    let mut g = c.benchmark_group("npf_bxdf");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for &(wo, wi) in &pairs {
                acc += b.eval(black_box(wo), black_box(wi))[1];
            }
            acc
        })
    });
    // The model's own evaluator, for comparison with the flat copy that
    // NpfBxdf::eval uses.
    g.bench_function("eval_model", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for &(wo, wi) in &pairs {
                acc += b.model().eval(black_box(wo), black_box(wi))[1];
            }
            acc
        })
    });
    // The batch interface on the same pairs, structure of arrays.
    let soa = |v: &mut dyn Iterator<Item = [f64; 3]>| {
        let mut d = [vec![], vec![], vec![]];
        for x in v {
            (0..3).for_each(|c| d[c].push(x[c]));
        }
        d
    };
    let (wo_s, wi_s) = (
        soa(&mut pairs.iter().map(|p| p.0)),
        soa(&mut pairs.iter().map(|p| p.1)),
    );
    let wo_d = Directions::new(&wo_s[0], &wo_s[1], &wo_s[2]).unwrap();
    let wi_d = Directions::new(&wi_s[0], &wi_s[1], &wi_s[2]).unwrap();
    let mut out = [vec![0.0; BATCH], vec![0.0; BATCH], vec![0.0; BATCH]];
    g.bench_function("eval_batch", |bench| {
        bench.iter(|| {
            let [a, b1, c] = &mut out;
            b.eval_batch(black_box(wo_d), black_box(wi_d), [a, b1, c])
                .unwrap();
            out[1].iter().sum::<f64>()
        })
    });
    g.bench_function("pdf", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for &(wo, wi) in &pairs {
                acc += b.pdf(black_box(wo), black_box(wi));
            }
            acc
        })
    });
    g.bench_function("pdf_reference", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for &(wo, wi) in &pairs {
                acc += b.pdf_reference(black_box(wo), black_box(wi));
            }
            acc
        })
    });
    g.bench_function("sample", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for (wo, u) in wos.iter().zip(&us) {
                acc += b.sample(black_box(*wo), u[0], [u[1], u[2]]).weight[1];
            }
            acc
        })
    });
    let views = soa(&mut wos.iter().copied());
    let views = Directions::new(&views[0], &views[1], &views[2]).unwrap();
    let u_s: [Vec<f64>; 3] = std::array::from_fn(|c| us.iter().map(|u| u[c]).collect());
    let mut draws = SampleBatch::default();
    g.bench_function("sample_batch", |bench| {
        bench.iter(|| {
            b.sample_batch(black_box(views), [&u_s[0], &u_s[1], &u_s[2]], &mut draws)
                .unwrap();
            draws.weight[1].iter().sum::<f64>()
        })
    });
    // The same draws at one view (theta_o 40 degrees): the sampler's
    // tables for that view stay in cache, as for coherent rays.
    let wo1 = {
        let t = 40f64.to_radians();
        [t.sin(), 0.0, t.cos()]
    };
    g.bench_function("sample_one_view", |bench| {
        bench.iter(|| {
            let mut acc = 0.0;
            for u in &us {
                acc += b.sample(black_box(wo1), u[0], [u[1], u[2]]).weight[1];
            }
            acc
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime);
    targets = bench
}
criterion_main!(benches);
