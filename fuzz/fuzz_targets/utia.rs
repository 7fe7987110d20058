//! UTIA `.bin` parser: any bytes are refused or accepted without a panic,
//! and an accepted table writes back the same bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::loaders::UtiaTable;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = UtiaTable::from_bytes(data, Path::new("fuzz.bin")) {
        assert_eq!(t.to_bytes(), data);
    }
});
