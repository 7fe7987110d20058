//! RGL `.bsdf` tensor-file reader: any bytes are refused or accepted without
//! a panic or a runaway allocation (offsets and extents are checked against
//! the file length before anything is allocated), and an accepted file
//! survives a write and a read unchanged (the writer mirrors the reader).
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::loaders::TensorFile;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let p = Path::new("fuzz.bsdf");
    if let Ok(t) = TensorFile::from_bytes(data, p) {
        let bytes = t.to_bytes();
        let again = TensorFile::from_bytes(&bytes, p).expect("a written tensor file reads back");
        assert_eq!(again.to_bytes(), bytes);
    }
});
