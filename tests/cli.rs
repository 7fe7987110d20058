//! The `npf` program as a user meets it: every bad input is a clear message
//! naming the file, a non-zero exit, no output file and no lost file.

use npf::loaders::MerlTable;
use npf::modelfile;
use npf::synth::GgxLambert;
use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{npf, s, stderr};

const BRDF: GgxLambert = GgxLambert {
    kd: [0.1, 0.1, 0.1],
    f0: [0.9, 0.7, 0.5],
    alpha: 0.3,
};

/// A failed run: non-zero exit, a message containing `needle`, no panic.
fn assert_fails(o: &Output, needle: &str) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure, stderr: {err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

fn good_table(dir: &Path) -> PathBuf {
    let p = dir.join("ggx.binary");
    BRDF.table().write(&p, false).unwrap();
    p
}

/// A quick fit through the CLI (two sweeps: the file plumbing is under test).
fn quick_fit(input: &Path, output: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "fit",
        s(input),
        "-o",
        s(output),
        "--max-sweeps",
        "2",
        "--quiet",
    ];
    args.extend_from_slice(extra);
    npf(&args)
}

#[test]
fn malformed_tables_are_rejected_with_the_file_and_problem_named() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read(good_table(dir.path())).unwrap();
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.binary", vec![], "the file is empty"),
        (
            "truncated.binary",
            good[..good.len() - 8].to_vec(),
            "truncated",
        ),
        (
            "long.binary",
            [good.as_slice(), &[0u8; 8]].concat(),
            "too long",
        ),
    ];
    let mut dims = good.clone();
    dims[0..4].copy_from_slice(&91i32.to_le_bytes());
    cases.push(("dims.binary", dims, "header dimensions are 91 90 180"));
    let mut nan = good.clone();
    nan[12 + 8 * 1000..12 + 8 * 1001].copy_from_slice(&f64::NAN.to_le_bytes());
    cases.push((
        "nan.binary",
        nan,
        "NaN or infinite (red channel, cell 1000)",
    ));
    let mut missing = good.clone();
    for v in missing[12..].chunks_mut(8) {
        v.copy_from_slice(&(-1.0f64).to_le_bytes());
    }
    let all_missing = dir.path().join("missing.binary");
    std::fs::write(&all_missing, missing).unwrap();
    for (name, bytes, problem) in cases {
        let input = dir.path().join(name);
        std::fs::write(&input, bytes).unwrap();
        let out = dir.path().join(format!("{name}.json"));
        let o = quick_fit(&input, &out, &[]);
        assert_fails(&o, problem);
        assert!(stderr(&o).contains(s(&input)), "{name}: {}", stderr(&o));
        assert!(!out.exists(), "{name}: partial output left behind");
        assert_fails(&npf(&["info", s(&input)]), problem);
    }
    // An all-missing table is a readable file, but there is nothing to fit.
    let o = npf(&["info", s(&all_missing)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("missing.json");
    assert_fails(&quick_fit(&all_missing, &out, &[]), s(&all_missing));
    assert!(!out.exists());
    // A fresh output path, so only the missing input can be the problem.
    let out = dir.path().join("x.json");
    assert_fails(
        &npf(&["fit", "/nonexistent/x.binary", "-o", s(&out)]),
        "/nonexistent/x.binary",
    );
    // An existing output too: the missing input is still what is reported.
    std::fs::write(&out, b"kept").unwrap();
    let o = npf(&["fit", "/nonexistent/x.binary", "-o", s(&out)]);
    assert_fails(&o, "/nonexistent/x.binary");
    assert!(!stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), b"kept");
}

#[test]
fn an_all_zero_table_fits_to_a_black_model_without_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("zero.binary");
    MerlTable::from_fn(|_, _, _| Some([0.0; 3]))
        .write(&input, false)
        .unwrap();
    let out = dir.path().join("zero.json");
    let o = quick_fit(&input, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = modelfile::read(&out).unwrap().model;
    let v = m.eval_angles(&npf::loaders::geometry::Angles::from_half_diff(
        0.3, 0.0, 0.2, 1.0,
    ));
    assert_eq!(v, [0.0; 3]);
}

#[test]
fn bad_flags_and_outputs_fail_cleanly_and_nothing_is_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let input = good_table(dir.path());
    let out = dir.path().join("m.json");
    assert_fails(
        &quick_fit(&input, &out, &["--lobes", "4"]),
        "--lobes must be 1 to 3",
    );
    assert_fails(
        &quick_fit(&input, &out, &["--lobes", "0"]),
        "--lobes must be 1 to 3",
    );
    assert_fails(&quick_fit(&input, &out, &["--tol=-1"]), "--tol");
    assert_fails(
        &quick_fit(&input, &out, &["--kept-g-tol=NaN"]),
        "--kept-g-tol",
    );
    assert_fails(
        &quick_fit(&input, &out, &["--weighting", "cubic"]),
        "invalid value 'cubic'",
    );
    assert_fails(
        &quick_fit(&input, &out, &["--frobnicate"]),
        "unexpected argument '--frobnicate'",
    );
    assert!(!out.exists());
    let bad_ext = dir.path().join("m.txt");
    assert_fails(&quick_fit(&input, &bad_ext, &[]), "m.txt");
    assert!(!bad_ext.exists());
    let no_dir = dir.path().join("absent/m.json");
    assert_fails(&quick_fit(&input, &no_dir, &[]), "does not exist");
    // An output folder nobody can write in fails before the fit starts.
    if Path::new("/proc").is_dir() {
        assert_fails(
            &quick_fit(&input, Path::new("/proc/m.json"), &[]),
            "cannot write in /proc",
        );
    }

    // An existing output survives a run without --force, byte for byte.
    std::fs::write(&out, b"keep me").unwrap();
    assert_fails(&quick_fit(&input, &out, &[]), "already exists");
    assert_eq!(std::fs::read(&out).unwrap(), b"keep me");
    let o = quick_fit(&input, &out, &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(modelfile::read(&out).is_ok());

    // reconstruct and demo refuse to overwrite too.
    let rec = dir.path().join("r.binary");
    std::fs::write(&rec, b"keep").unwrap();
    assert_fails(
        &npf(&["reconstruct", s(&out), "-o", s(&rec)]),
        "already exists",
    );
    assert_eq!(std::fs::read(&rec).unwrap(), b"keep");
    // A damaged model file is named with its problem.
    let broken = dir.path().join("broken.json");
    std::fs::write(&broken, b"{\"format\": \"npf-model\"").unwrap();
    assert_fails(
        &npf(&["eval", s(&broken), "10", "0", "10", "180"]),
        s(&broken),
    );
    let short = dir.path().join("short.npfb");
    std::fs::write(&short, b"NPFB").unwrap();
    assert_fails(&npf(&["info", s(&short)]), s(&short));
    assert_fails(&npf(&["eval", s(&out), "10", "0", "10"]), "4");
    assert_fails(&npf(&["eval", s(&out), "10", "0", "NaN", "0"]), "NaN");
}

#[test]
fn fit_exports_both_forms_which_reload_exactly_and_reconstruct_and_evaluate() {
    let dir = tempfile::tempdir().unwrap();
    let input = good_table(dir.path());
    let json = dir.path().join("m.json");
    let o = quick_fit(&input, &json, &["--lobes", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = modelfile::read(&json).unwrap();
    assert_eq!(file.model.param_count(), 3 + 6 + 90 * 7);
    let fit = file.fit.as_ref().expect("fit record");
    assert_eq!(fit.lobes, 2);

    // The binary form holds the same float32 parameters, bit for bit.
    let bin = dir.path().join("m.npfb");
    assert!(quick_fit(&input, &bin, &["--lobes", "2"]).status.success());
    let from_bin = modelfile::read(&bin).unwrap().model;
    let bits = |m: &npf::model::Model| m.params().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&from_bin), bits(&file.model));
    assert_eq!(
        std::fs::metadata(&bin).unwrap().len() as usize,
        23 + 4 * from_bin.param_count()
    );

    // info names the coarse schedule the record holds.
    let coarse = fit.selection.as_ref().unwrap()["coarse"].clone();
    let level = &coarse["levels"][0];
    let o = npf(&["info", s(&json)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let line = format!(
        "coarse levels  1/{} {} sweeps; G {} on the full set",
        level["factor"],
        level["sweeps"],
        coarse["g_on_full_set"].as_str().unwrap()
    );
    assert!(out.contains(&line), "{line:?} not in {out}");

    // reconstruct: a MERL table whose cells are the model's values.
    let rec = dir.path().join("rec.binary");
    let o = npf(&["reconstruct", s(&json), "-o", s(&rec)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = MerlTable::read(&rec).unwrap();
    let idx = MerlTable::index(20, 30, 40);
    let (th, td, pd) = MerlTable::node_angles(20, 30, 40);
    let want = file
        .model
        .eval_angles(&npf::loaders::geometry::Angles::from_half_diff(
            th, 0.0, td, pd,
        ));
    let got = table.cell(idx).expect("valid cell");
    for c in 0..3 {
        assert!(
            (got[c] - want[c]).abs() <= 1e-9 * want[c].abs().max(1e-3),
            "{got:?} {want:?}"
        );
    }

    // eval prints one RGB line per direction pair, the library's values.
    let o = npf(&["eval", s(&json), "30", "0", "30", "180"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let line = String::from_utf8(o.stdout).unwrap();
    let nums: Vec<f64> = line
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter_map(|t| t.parse().ok())
        .collect();
    let r = 30f64.to_radians();
    let wi = [r.sin(), 0.0, r.cos()];
    let wo = [-r.sin(), 0.0, r.cos()];
    let v = file.model.eval(wo, wi);
    assert!(nums.len() >= 3, "{line}");
    let tail = &nums[nums.len() - 3..];
    for c in 0..3 {
        assert!(
            (tail[c] - v[c]).abs() <= 1e-6 * v[c].abs().max(1e-6),
            "{line} vs {v:?}"
        );
    }

    // info describes data and models.
    let o = npf(&["info", s(&input)]);
    assert!(o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("1111432"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let o = npf(&["info", s(&bin)]);
    assert!(o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("639"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
}

#[test]
fn model_selection_records_its_choice_and_refuses_contradictions() {
    let dir = tempfile::tempdir().unwrap();
    let input = good_table(dir.path());
    let out = dir.path().join("sel.json");
    // A loose target: the first candidate (1 lobe, 30 values) meets it.
    let o = quick_fit(&input, &out, &["--target", "log-rmse=0.5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = modelfile::read(&out).unwrap();
    assert_eq!(file.model.param_count(), 156);
    assert_eq!(file.model.lobes.len(), 1);
    let sel = file.fit.unwrap().selection.expect("selection record");
    assert_eq!(sel["mode"], "target");
    assert_eq!(sel["met"], true);
    assert_eq!(sel["chosen"]["params"], 156);

    let out2 = dir.path().join("budget.npfb");
    let o = quick_fit(&input, &out2, &["--budget", "200"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(modelfile::read(&out2).unwrap().model.param_count(), 156);

    let out3 = dir.path().join("x.json");
    assert_fails(
        &quick_fit(&input, &out3, &["--target", "log-rmse=0.1", "--lobes", "2"]),
        "cannot be used with",
    );
    assert_fails(
        &quick_fit(&input, &out3, &["--target", "mse=0.1"]),
        "unknown metric",
    );
    // A rendering-PSNR target: the reference render of the input table is
    // compared with each candidate's; 5 dB is met by the first.
    let out4 = dir.path().join("psnr.json");
    let o = quick_fit(&input, &out4, &["--target", "psnr=5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sel = modelfile::read(&out4)
        .unwrap()
        .fit
        .unwrap()
        .selection
        .unwrap();
    assert_eq!(sel["met"], true);
    assert!(sel["chosen"]["value"].as_f64().unwrap() >= 5.0, "{sel}");
    assert_fails(
        &quick_fit(&input, &out3, &["--budget", "10"]),
        "no candidate model has that few parameters",
    );
    assert_fails(
        &quick_fit(&input, &out3, &["--nodes", "2"]),
        "--nodes must be 4 to 90",
    );
    assert!(!out3.exists());
}

#[test]
fn energy_commands_write_the_seed_format_and_reject_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("E_on.csv");
    let o = npf(&[
        "energy",
        "table",
        "--model",
        "oren-nayar",
        "--res",
        "8",
        "-q",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect();
    // "mu, alpha, E", mu fastest, alpha = 0 is Lambert (E = 1).
    assert_eq!(rows.len(), 64);
    assert!(rows.iter().all(|r| r.len() == 3));
    assert!(rows[..8]
        .iter()
        .all(|r| r[1] == 0.0 && (r[2] - 1.0).abs() < 1e-12));
    assert_eq!(rows[1][0], 1.0 / 7.0);

    // Never overwrite without --force; the file is left as it was.
    let again = npf(&[
        "energy",
        "table",
        "--model",
        "oren-nayar",
        "-q",
        "-o",
        s(&out),
    ]);
    assert_fails(&again, "already exists");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), text);

    let bad = dir.path().join("bad.csv");
    assert_fails(
        &npf(&["energy", "table", "--res", "1", "-o", s(&bad)]),
        "--res 1",
    );
    assert_fails(
        &npf(&["energy", "table", "--tol", "NaN", "-o", s(&bad)]),
        "--tol",
    );
    assert_fails(&npf(&["energy", "simulate", "--paths", "1"]), "--paths");
    assert_fails(&npf(&["energy", "simulate", "--theta", "95"]), "--theta 95");
    assert_fails(
        &npf(&[
            "energy",
            "plot",
            "--model",
            "oren-nayar",
            "-o",
            s(&dir.path().join("x.gif")),
        ]),
        ".svg or .png",
    );
    assert_fails(&npf(&["energy", "furnace", "--bogus"]), "--bogus");
    assert!(!bad.exists());

    let o = npf(&["energy", "furnace", "--model", "oren-nayar", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let line = String::from_utf8_lossy(&o.stdout).into_owned();
    let err: f64 = line
        .split("= ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no error in {line:?}"));
    assert!(err < 1e-3, "{line}");
}
