//! `npf sample`: output format, determinism, albedo, and refusals.

use npf::model::Layout;
use npf::modelfile::{self, ModelFile};
use npf::synth::known_factor_model;
use std::path::{Path, PathBuf};

mod common;
use common::{npf, stderr};

fn model_file(dir: &Path) -> PathBuf {
    let path = dir.join("glossy.json");
    let file = ModelFile {
        model: known_factor_model(Layout::default(), &[0.1, 0.4]),
        fit: None,
    };
    modelfile::write(&path, &file, false).unwrap();
    path
}

#[test]
fn writes_one_line_per_sample_whose_mean_weight_is_the_albedo() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_file(dir.path());
    let m = model.to_str().unwrap();
    let run = |seed: &str| {
        npf(&[
            "sample",
            m,
            "--theta-o",
            "30",
            "--n",
            "20000",
            "--seed",
            seed,
        ])
    };
    let o = run("5");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout.clone()).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("wi_x,wi_y,wi_z,pdf,w_r,w_g,w_b"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 20000);
    let mut mean = [0.0; 3];
    for r in &rows {
        assert_eq!(r.len(), 7);
        let norm = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        assert!((norm - 1.0).abs() < 1e-6);
        if r[2] <= 0.0 {
            assert_eq!(&r[3..], &[0.0; 4], "below the horizon: pdf and w are zero");
        } else {
            assert!(r[3] > 0.0);
        }
        for c in 0..3 {
            assert!(r[4 + c] >= 0.0 && r[4 + c].is_finite());
            mean[c] += r[4 + c] / rows.len() as f64;
        }
    }
    // The summary reports the same mean weight.
    let err = stderr(&o);
    let tail = err
        .split("mean w (directional albedo) ")
        .nth(1)
        .unwrap_or_else(|| panic!("no summary: {err}"));
    let reported: Vec<f64> = tail
        .split(';')
        .next()
        .unwrap()
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    for c in 0..3 {
        assert!(mean[c] > 0.0);
        assert!(
            (reported[c] - mean[c]).abs() < 1e-5 * mean[c],
            "{reported:?} vs {mean:?}"
        );
    }
    // Same seed, same output; another seed, another output.
    let again = run("5");
    assert_eq!(again.stdout, o.stdout);
    let other = run("6");
    assert_ne!(other.stdout, o.stdout);
}

#[test]
fn output_file_is_written_once_and_not_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_file(dir.path());
    let m = model.to_str().unwrap();
    let out = dir.path().join("s.csv");
    let o = out.to_str().unwrap();
    let first = npf(&["sample", m, "--theta-o", "0", "--n", "100", "-o", o]);
    assert!(first.status.success(), "{}", stderr(&first));
    let content = std::fs::read(&out).unwrap();
    assert_eq!(String::from_utf8_lossy(&content).lines().count(), 101);
    let second = npf(&["sample", m, "--theta-o", "0", "--n", "50", "-o", o]);
    assert!(!second.status.success());
    assert!(
        stderr(&second).contains("already exists"),
        "{}",
        stderr(&second)
    );
    assert_eq!(
        std::fs::read(&out).unwrap(),
        content,
        "refused output untouched"
    );
    let forced = npf(&[
        "sample",
        m,
        "--theta-o",
        "0",
        "--n",
        "50",
        "-o",
        o,
        "--force",
    ]);
    assert!(forced.status.success(), "{}", stderr(&forced));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 51);
    // The histogram picture: a PNG, also never overwritten without --force.
    let png = dir.path().join("h.png");
    let p = png.to_str().unwrap();
    let h = npf(&[
        "sample",
        m,
        "--theta-o",
        "40",
        "--n",
        "5000",
        "--histogram",
        p,
    ]);
    assert!(h.status.success(), "{}", stderr(&h));
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let again = npf(&["sample", m, "--theta-o", "40", "--n", "5", "--histogram", p]);
    assert!(!again.status.success());
    assert_eq!(std::fs::read(&png).unwrap(), bytes);
    let missing_dir = dir.path().join("nope").join("s.csv");
    let bad = npf(&[
        "sample",
        m,
        "--theta-o",
        "0",
        "--n",
        "5",
        "-o",
        missing_dir.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("does not exist"), "{}", stderr(&bad));
}

#[test]
fn bad_input_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_file(dir.path());
    let m = model.to_str().unwrap();
    let garbage = dir.path().join("garbage.json");
    std::fs::write(&garbage, "{ not a model").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["sample", m, "--theta-o", "90", "--n", "10"],
            "--theta-o",
        ),
        (
            vec!["sample", m, "--theta-o", "-1", "--n", "10"],
            "--theta-o",
        ),
        (
            vec!["sample", m, "--theta-o", "nan", "--n", "10"],
            "--theta-o",
        ),
        (vec!["sample", m, "--theta-o", "30", "--n", "0"], "--n"),
        (vec!["sample", m, "--theta-o", "30", "--n", "-3"], "--n"),
        (
            vec!["sample", m, "--theta-o", "abc", "--n", "10"],
            "theta-o",
        ),
        (vec!["sample", m, "--n", "10"], "--theta-o"),
        (
            vec!["sample", m, "--theta-o", "30", "--n", "10", "--bogus"],
            "--bogus",
        ),
        (
            vec![
                "sample",
                "/nonexistent/model.json",
                "--theta-o",
                "30",
                "--n",
                "10",
            ],
            "model.json",
        ),
        (
            vec![
                "sample",
                garbage.to_str().unwrap(),
                "--theta-o",
                "30",
                "--n",
                "10",
            ],
            "garbage.json",
        ),
    ];
    for (args, needle) in cases {
        let o = npf(&args);
        assert!(!o.status.success(), "{args:?} succeeded");
        let err = stderr(&o);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
