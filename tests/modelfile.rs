//! Model files round-trip exactly in both forms, and damaged ones are refused.

use npf::model::{Layout, Model};
use npf::modelfile::{self, ModelFile};
use proptest::prelude::*;
use std::path::Path;

fn bits(m: &Model) -> Vec<u32> {
    m.params().iter().map(|v| v.to_bits()).collect()
}

fn model_from(lobes: usize, raw: &[f32]) -> Model {
    let n = Layout::default().param_count(lobes);
    Model::from_params(Layout::default(), lobes, &raw[..n]).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Any non-negative float32 parameters (tiny, huge, subnormal) survive
    /// JSON and binary forms bit for bit.
    #[test]
    fn any_model_round_trips_bit_exactly(
        lobes in 1usize..=3,
        raw in prop::collection::vec(
            prop_oneof![0.0f32..1.0, 0.0f32..1e30, Just(f32::MIN_POSITIVE / 3.0), Just(0.0f32), 1e-30f32..1e-20],
            822,
        ),
    ) {
        let model = model_from(lobes, &raw);
        let path = Path::new("mem");
        let file = ModelFile { model: model.clone(), fit: None };
        let back = modelfile::from_json(&modelfile::to_json(&file), path).unwrap();
        prop_assert_eq!(bits(&back.model), bits(&model));
        let back = modelfile::from_binary(&modelfile::to_binary(&model), path).unwrap();
        prop_assert_eq!(bits(&back), bits(&model));
    }
}

#[test]
fn files_on_disk_round_trip_and_are_not_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let raw: Vec<f32> = (0..822)
        .map(|k| (k as f32 * 0.37).sin().abs() * 3.0)
        .collect();
    let file = ModelFile {
        model: model_from(3, &raw),
        fit: None,
    };
    for name in ["m.json", "m.npfb"] {
        let p = dir.path().join(name);
        modelfile::write(&p, &file, false).unwrap();
        let back = modelfile::read(&p).unwrap();
        assert_eq!(bits(&back.model), bits(&file.model));
        let before = std::fs::read(&p).unwrap();
        assert!(modelfile::write(&p, &file, false).is_err());
        assert_eq!(std::fs::read(&p).unwrap(), before);
    }
    assert_eq!(
        std::fs::metadata(dir.path().join("m.npfb")).unwrap().len(),
        23 + 4 * 822
    );
}

#[test]
fn damaged_model_files_are_refused() {
    let path = Path::new("x.npfb");
    let raw: Vec<f32> = (0..822).map(|k| k as f32 / 822.0).collect();
    let model = model_from(3, &raw);
    let good = modelfile::to_binary(&model);
    assert!(modelfile::from_binary(&good[..good.len() - 4], path).is_err());
    assert!(modelfile::from_binary(&[good.as_slice(), &[0; 4]].concat(), path).is_err());
    let mut nan = good.clone();
    let at = good.len() - 4;
    nan[at..].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = modelfile::from_binary(&nan, path).unwrap_err().to_string();
    assert!(e.contains("x.npfb"), "{e}");
    let mut magic = good.clone();
    magic[0] = b'X';
    assert!(modelfile::from_binary(&magic, path).is_err());
    let mut neg = good;
    neg[at..].copy_from_slice(&(-1.0f32).to_le_bytes());
    assert!(modelfile::from_binary(&neg, path).is_err());

    let json = modelfile::to_json(&ModelFile { model, fit: None });
    let p = Path::new("x.json");
    assert!(modelfile::from_json(&json.replace("\"version\": 1", "\"version\": 99"), p).is_err());
    assert!(modelfile::from_json(&json[..json.len() / 2], p).is_err());
}

/// Files written before grids existed (the committed fits/) read as the same
/// isotropic model: the binary form is rewritten byte for byte, and the JSON
/// `model` object is written back unchanged.
#[test]
fn files_of_the_1d_format_read_identically() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits");
    let json_path = dir.join("ggx-lambert.json");
    let bin_path = dir.join("ggx-lambert.npfb");
    let from_json = modelfile::read(&json_path).unwrap();
    let from_bin = modelfile::read(&bin_path).unwrap();
    assert_eq!(from_json.model.layout, Layout::default());
    assert!(from_json.model.layout.is_isotropic());
    assert_eq!(bits(&from_json.model), bits(&from_bin.model));
    let bytes = std::fs::read(&bin_path).unwrap();
    assert_eq!(modelfile::to_binary(&from_bin.model), bytes);
    let old: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    let new: serde_json::Value = serde_json::from_str(&modelfile::to_json(&from_json)).unwrap();
    assert_eq!(old["model"], new["model"]);
    assert_eq!(old["fit"], new["fit"]);
}

/// The anisotropic layout (2-D D and G) round-trips in both forms, and
/// layouts out of bounds are refused.
#[test]
fn anisotropic_models_round_trip_and_bad_layouts_are_refused() {
    let layout = Layout::anisotropic();
    let n = layout.param_count(3);
    assert_eq!(n, 2010);
    let raw: Vec<f32> = (0..n).map(|k| (k as f32 * 0.11).cos().abs()).collect();
    let model = Model::from_params(layout, 3, &raw).unwrap();
    let path = Path::new("a.npfb");
    let bin = modelfile::to_binary(&model);
    assert_eq!(bin.len(), 29 + 4 * 2010);
    assert_eq!(modelfile::from_binary(&bin, path).unwrap(), model);
    let file = ModelFile {
        model: model.clone(),
        fit: None,
    };
    let back = modelfile::from_json(&modelfile::to_json(&file), Path::new("a.json")).unwrap();
    assert_eq!(back.model, model);
    assert_eq!(bits(&back.model), bits(&model));
    // D on the squared theta_h axis (file axis code 3) round-trips too.
    let mut squared = layout;
    squared.d.theta = npf::grid::Axis::Squared { n: 6 };
    let sq = Model::from_params(squared, 3, &raw).unwrap();
    assert_eq!(
        modelfile::from_binary(&modelfile::to_binary(&sq), path).unwrap(),
        sq
    );
    let file = ModelFile {
        model: sq.clone(),
        fit: None,
    };
    let back = modelfile::from_json(&modelfile::to_json(&file), Path::new("a.json")).unwrap();
    assert_eq!(back.model, sq);
    // A G grid with one theta node and a phi axis without nodes.
    let mut bad = Layout::default();
    bad.g.theta = npf::grid::Axis::CatmullRom { n: 1 };
    assert!(Model::from_params(bad, 1, &vec![0.5; bad.param_count(1)]).is_err());
    let mut bad = Layout::anisotropic();
    bad.d.phi = Some(npf::grid::PhiAxis { n: 0 });
    assert!(Model::from_params(bad, 1, &vec![0.5; bad.param_count(1)]).is_err());
    let mut cut = bin.clone();
    cut.truncate(27);
    assert!(modelfile::from_binary(&cut, path).is_err());
}
