//! MERL `.binary` parser: any bytes are refused or accepted without a
//! panic, an accepted table writes back the same bytes, and the sniffer
//! names any bytes without a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::loaders::{sniff, MerlTable};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = sniff::describe_bytes(data, data.len() as u64);
    if let Ok(t) = MerlTable::from_bytes(data, Path::new("fuzz.binary")) {
        assert_eq!(t.to_bytes(), data);
    }
});
