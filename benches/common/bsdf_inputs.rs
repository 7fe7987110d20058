//! The inputs of the BSDF throughput bench (`benches/bsdf.rs`), shared with
//! `examples/bsdf_callgrind.rs` so both time and count the same calls.

use npf::bsdf::NpfBxdf;
use npf::model::{Layout, Model};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// The benched model: the model file named by `NPF_BENCH_MODEL` (e.g. a
/// fit kept outside the repository), else the synthetic three-lobe model.
pub fn model() -> Result<Model, String> {
    match std::env::var_os("NPF_BENCH_MODEL") {
        Some(path) => npf::modelfile::read(std::path::Path::new(&path))
            .map(|f| f.model)
            .map_err(|e| format!("NPF_BENCH_MODEL: {e}")),
        None => Ok(npf::synth::known_factor_model(
            Layout::default(),
            &[0.02, 0.15, 0.5],
        )),
    }
}

/// Calls per batch.
pub const BATCH: usize = 1024;

/// Fixed random inputs for [`BATCH`] calls.
pub struct Inputs {
    /// Random numbers for `sample` (component, then the direction).
    pub us: Vec<[f64; 3]>,
    /// Views, theta_o up to 80 degrees.
    pub wos: Vec<[f64; 3]>,
    /// (wo, wi) pairs drawn by the sampler itself, for `eval` and `pdf`.
    pub pairs: Vec<([f64; 3], [f64; 3])>,
}

/// The bench's inputs for a BSDF (seeded, so the same every run).
pub fn inputs(b: &NpfBxdf) -> Inputs {
    let mut rng = Pcg64::seed_from_u64(1);
    let us: Vec<[f64; 3]> = (0..BATCH)
        .map(|_| [rng.gen(), rng.gen(), rng.gen()])
        .collect();
    let wos: Vec<[f64; 3]> = (0..BATCH)
        .map(|_| {
            let (t, p) = (
                rng.gen::<f64>() * 80f64.to_radians(),
                rng.gen::<f64>() * std::f64::consts::TAU,
            );
            [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
        })
        .collect();
    let mut pairs = Vec::with_capacity(BATCH);
    while pairs.len() < BATCH {
        let wo = wos[pairs.len()];
        let s = b.sample(wo, rng.gen(), [rng.gen(), rng.gen()]);
        if !s.is_lost() {
            pairs.push((wo, s.wi));
        }
    }
    Inputs { us, wos, pairs }
}
