//! Model files written before the separable diffuse form (npf at aca7d2e,
//! tests/data/pre-separable/README.md) load, and evaluate bit for bit as
//! that version evaluated them: every model kind and diffuse form of the
//! time, both file formats, isotropic and anisotropic.

use npf::modelfile;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pre-separable")
}

fn file(name: &str) -> PathBuf {
    let in_fits = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fits")
        .join(name);
    if name.starts_with("ggx-lambert.") {
        in_fits
    } else {
        data().join(name)
    }
}

#[test]
fn old_model_files_evaluate_bit_for_bit_as_they_did() {
    let text = std::fs::read_to_string(data().join("expected-eval.txt")).unwrap();
    let mut by_file: BTreeMap<&str, Vec<[f64; 9]>> = BTreeMap::new();
    for line in text.lines() {
        let mut parts = line.split_whitespace();
        let name = parts.next().unwrap();
        let v: Vec<f64> = parts
            .map(|h| f64::from_bits(u64::from_str_radix(h, 16).unwrap()))
            .collect();
        by_file.entry(name).or_default().push(v.try_into().unwrap());
    }
    // Every kind of file the fixture was made with is here.
    assert_eq!(by_file.len(), 11, "{:?}", by_file.keys());
    let mut nonzero = 0;
    for (name, rows) in &by_file {
        let m = modelfile::read(&file(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        // Written before the separable form: Lambert or an analytic form.
        assert!(
            !matches!(
                m.model.diffuse_form,
                npf::model::DiffuseForm::Separable { .. }
            ),
            "{name}"
        );
        for r in rows {
            let (wo, wi) = ([r[0], r[1], r[2]], [r[3], r[4], r[5]]);
            let got = m.model.eval(wo, wi);
            for c in 0..3 {
                assert_eq!(
                    got[c].to_bits(),
                    r[6 + c].to_bits(),
                    "{name}: wo {wo:?} wi {wi:?} channel {c}: {} against {}",
                    got[c],
                    r[6 + c]
                );
            }
            nonzero += got.iter().filter(|v| **v > 0.0).count();
        }
    }
    // Not vacuous: the values compared are mostly non-zero.
    assert!(nonzero > 11 * 24 * 3 / 2, "{nonzero}");
}
