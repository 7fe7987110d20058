//! `.npfb` parser: any bytes are refused or accepted without a panic or a
//! runaway allocation (the header is bounded before the parameters are
//! read), and an accepted model survives a write and a read unchanged.
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::modelfile;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let p = Path::new("fuzz.npfb");
    if let Ok(m) = modelfile::from_binary(data, p) {
        let again = modelfile::from_binary(&modelfile::to_binary(&m), p)
            .expect("a written model reads back");
        assert_eq!(again, m);
    }
});
