//! Adds Kulla-Conty's multiple-scattering term of a fitted model's own
//! lobes to an existing model file (what `npf fit --compensate` does at the
//! end of a fit), so a fit can be compared with and without it without
//! fitting twice:
//!
//!     cargo run --release --example compensate -- IN.json OUT.json

use npf::energy::coupled::compensation;
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output] = &args[..] else {
        eprintln!("usage: compensate IN.{{json,npfb}} OUT.{{json,npfb}}");
        std::process::exit(2);
    };
    if Path::new(output).exists() {
        eprintln!("{output}: already exists (not overwritten)");
        std::process::exit(1);
    }
    let mut file = match npf::modelfile::read(Path::new(input)) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    file.model.compensation = Some(compensation(&file.model));
    if let Some(fit) = file.fit.as_mut() {
        if let Some(sel) = fit.selection.as_mut() {
            sel["compensated"] = true.into();
        }
    }
    if let Err(e) = npf::modelfile::write(Path::new(output), &file, false) {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
