//! The checked-in fits (`fits/`, made by `npf demo`) load in both forms,
//! agree bit for bit, and still describe the BRDF they were fitted to.

use npf::cli::demo::DEMO_BRDF;
use npf::loaders::geometry::Angles;
use npf::modelfile;
use std::path::Path;

#[test]
fn demo_fit_files_load_agree_and_match_their_brdf() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits");
    let json = modelfile::read(&dir.join("ggx-lambert.json")).unwrap();
    let bin = modelfile::read(&dir.join("ggx-lambert.npfb")).unwrap();
    let bits = |m: &npf::model::Model| m.params().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&json.model), bits(&bin.model));
    assert_eq!(json.model.param_count(), 822);
    let fit = json.fit.expect("provenance");
    assert_eq!(fit.lobes, 3);

    // Cosine-weighted relative error on a coarse grid within the 85 degree cut.
    let (mut err, mut norm) = (0.0, 0.0);
    for th in 0..45 {
        for td in 0..45 {
            for pd in 0..18 {
                let a = Angles::from_half_diff(
                    (th as f64 / 45.0).powi(2) * std::f64::consts::FRAC_PI_2,
                    0.0,
                    td as f64 / 45.0 * std::f64::consts::FRAC_PI_2,
                    pd as f64 / 18.0 * std::f64::consts::PI,
                );
                if a.theta_i > 85f64.to_radians() || a.theta_o > 85f64.to_radians() {
                    continue;
                }
                let Some(want) = DEMO_BRDF.eval_angles(&a) else {
                    continue;
                };
                let got = json.model.eval_angles(&a);
                let c = a.theta_i.cos();
                for ch in 0..3 {
                    err += ((got[ch] - want[ch]) * c).powi(2);
                    norm += (want[ch] * c).powi(2);
                }
            }
        }
    }
    let rel = (err / norm).sqrt();
    assert!(rel < 3e-3, "relative cosine-weighted RMSE {rel}");
}
