//! A fixed workload of `NpfBxdf` eval, pdf and sample calls for
//! instruction counting (repeatable on a loaded machine, unlike timings):
//!
//!     cargo build --release --example bsdf_callgrind
//!     valgrind --tool=callgrind '--toggle-collect=bsdf_callgrind::run_*' \
//!         target/release/examples/bsdf_callgrind 10
//!     callgrind_annotate --inclusive=yes callgrind.out.* | grep run_
//!
//! Each `run_*` makes 1024 calls per repetition (the bench's inputs: the
//! synthetic three-lobe model, or the model file named by
//! `NPF_BENCH_MODEL` as in the bench, views up to 80 degrees, pairs drawn
//! by the sampler), so inclusive counts / (1024 x repetitions) are instructions
//! per call. `run_eval_batch` and `run_sample_batch` make the same calls
//! through the batch interface. Prints a checksum of the results.

use npf::bsdf::{Directions, NpfBxdf, SampleBatch};

#[path = "../benches/common/bsdf_inputs.rs"]
mod bsdf_inputs;
use std::hint::black_box;

#[inline(never)]
fn run_eval(b: &NpfBxdf, pairs: &[([f64; 3], [f64; 3])]) -> f64 {
    let mut acc = 0.0;
    for &(wo, wi) in pairs {
        acc += b.eval(black_box(wo), black_box(wi))[1];
    }
    acc
}
#[inline(never)]
fn run_pdf(b: &NpfBxdf, pairs: &[([f64; 3], [f64; 3])]) -> f64 {
    let mut acc = 0.0;
    for &(wo, wi) in pairs {
        acc += b.pdf(black_box(wo), black_box(wi));
    }
    acc
}
#[inline(never)]
fn run_sample(b: &NpfBxdf, wos: &[[f64; 3]], us: &[[f64; 3]]) -> f64 {
    let mut acc = 0.0;
    for (wo, u) in wos.iter().zip(us) {
        acc += b.sample(black_box(*wo), u[0], [u[1], u[2]]).weight[1];
    }
    acc
}

/// Structure of arrays of directions.
type Soa = [Vec<f64>; 3];

fn soa(v: impl Iterator<Item = [f64; 3]>) -> Soa {
    let mut d: Soa = [vec![], vec![], vec![]];
    for x in v {
        (0..3).for_each(|c| d[c].push(x[c]));
    }
    d
}

fn dirs(d: &Soa) -> Directions<'_> {
    Directions::new(&d[0], &d[1], &d[2]).unwrap()
}

#[inline(never)]
fn run_eval_batch(b: &NpfBxdf, wo: &Soa, wi: &Soa, out: &mut Soa) -> f64 {
    let [x, y, z] = out;
    b.eval_batch(dirs(wo), dirs(wi), [x, y, z]).unwrap();
    out[1].iter().sum()
}
#[inline(never)]
fn run_sample_batch(b: &NpfBxdf, wo: &Soa, u: &Soa, out: &mut SampleBatch) -> f64 {
    b.sample_batch(dirs(wo), [&u[0], &u[1], &u[2]], out)
        .unwrap();
    out.weight[1].iter().sum()
}

fn main() {
    // The bench's model (NPF_BENCH_MODEL or the synthetic one).
    let model = match bsdf_inputs::model() {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let b = match NpfBxdf::new(model) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("bsdf_callgrind: {e}");
            std::process::exit(2);
        }
    };
    let bsdf_inputs::Inputs { us, wos, pairs } = bsdf_inputs::inputs(&b);
    let reps: usize = match std::env::args().nth(1).map(|s| s.parse()) {
        None => 20,
        Some(Ok(r)) => r,
        Some(Err(_)) => {
            eprintln!("usage: bsdf_callgrind [REPETITIONS]");
            std::process::exit(2);
        }
    };
    let (wo_s, wi_s) = (
        soa(pairs.iter().map(|p| p.0)),
        soa(pairs.iter().map(|p| p.1)),
    );
    let (views, u_s) = (soa(wos.iter().copied()), soa(us.iter().copied()));
    let mut out = soa(pairs.iter().map(|_| [0.0; 3]));
    let mut draws = SampleBatch::default();
    let mut acc = 0.0;
    for _ in 0..reps {
        acc += run_eval_batch(&b, &wo_s, &wi_s, &mut out);
        acc += run_sample_batch(&b, &views, &u_s, &mut draws);
        acc += run_eval(&b, &pairs);
        acc += run_pdf(&b, &pairs);
        acc += run_sample(&b, &wos, &us);
    }
    println!("{acc}");
}
