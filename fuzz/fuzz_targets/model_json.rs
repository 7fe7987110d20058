//! JSON model parser: any text is refused or accepted without a panic, and
//! an accepted model survives a write and a read unchanged.
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::modelfile;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let p = Path::new("fuzz.json");
    if let Ok(f) = modelfile::from_json(text, p) {
        let again =
            modelfile::from_json(&modelfile::to_json(&f), p).expect("a written model reads back");
        assert_eq!(again.model, f.model);
    }
});
