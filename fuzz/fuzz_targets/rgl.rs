//! RGL `.bsdf` tensor-file reader: any bytes are refused or accepted without
//! a panic or a runaway allocation (offsets and extents are checked against
//! the file length before anything is allocated), and an accepted file
//! survives a write and a read unchanged (the writer mirrors the reader);
//! the BRDF reader then checks its fields, and a BRDF it accepts evaluates
//! to finite, non-negative values.
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
        if let Ok(brdf) = npf::loaders::rgl_brdf::RglBrdf::from_file(&t, p) {
            for (wi, wo) in [([0.0, 0.0, 1.0], [0.6, 0.0, 0.8]), ([0.3, -0.4, 0.866], [-0.5, 0.1, 0.86])] {
                let v = brdf.rgb(wi, wo);
                assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{v:?}");
            }
        }
    }
});
