//! Writes the synthetic anisotropic set as UTIA tables: every material of
//! `npf::synth_aniso::catalogue()` as NAME.bin, and the known 2010-parameter
//! model's table as known-2010.bin (with its model as known-2010.json).
//!
//!     cargo run --release --example make_utia -- OUT_DIR [--force]

use npf::modelfile::{self, ModelFile};
use npf::synth_aniso::{catalogue, known_model};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let force = args.iter().any(|a| a == "--force");
    let Some(dir) = args.iter().find(|a| !a.starts_with("--")) else {
        eprintln!("usage: make_utia OUT_DIR [--force]");
        std::process::exit(2);
    };
    let dir = Path::new(dir);
    if !dir.is_dir() {
        eprintln!("{}: not a folder", dir.display());
        std::process::exit(1);
    }
    let fail = |e: &dyn std::fmt::Display| -> ! {
        eprintln!("{e}");
        std::process::exit(1)
    };
    for m in catalogue() {
        let p = dir.join(format!("{}.bin", m.name));
        m.table().write(&p, force).unwrap_or_else(|e| fail(&e));
        println!("wrote {}", p.display());
    }
    let model = known_model();
    let p = dir.join("known-2010.bin");
    npf::reconstruct::to_utia(&model)
        .write(&p, force)
        .unwrap_or_else(|e| fail(&e));
    println!("wrote {}", p.display());
    let j = dir.join("known-2010.json");
    modelfile::write(&j, &ModelFile { model, fit: None }, force).unwrap_or_else(|e| fail(&e));
    println!("wrote {}", j.display());
}
