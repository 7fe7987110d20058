//! `npf fit DIR -o OUTDIR`: every table of a folder (MERL and UTIA), a
//! corrupt file reported without stopping the rest, resume, `--force`, the
//! summary CSV, and options checked before any fit.

use npf::synth::GgxLambert;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{npf, s, stderr};

/// Every file of a folder with its bytes (to show a folder is untouched).
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            let bytes = std::fs::read(&p).unwrap_or_default();
            (p.file_name().unwrap().to_string_lossy().into_owned(), bytes)
        })
        .collect()
}

/// The summary's rows as maps from column to value.
fn summary(out: &Path) -> Vec<BTreeMap<String, String>> {
    let mut r = csv::Reader::from_path(out.join("summary.csv")).unwrap();
    let head = r.headers().unwrap().clone();
    r.records()
        .map(|rec| {
            head.iter()
                .zip(rec.unwrap().iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

fn row<'a>(rows: &'a [BTreeMap<String, String>], file: &str) -> &'a BTreeMap<String, String> {
    rows.iter()
        .find(|r| r["file"] == file)
        .unwrap_or_else(|| panic!("no row for {file}: {rows:?}"))
}

/// A folder of two MERL tables, one UTIA table, a truncated MERL table and
/// a file that is not a table.
fn folder(dir: &Path) -> PathBuf {
    let input = dir.join("in");
    std::fs::create_dir(&input).unwrap();
    let a = GgxLambert {
        kd: [0.1, 0.1, 0.1],
        f0: [0.9, 0.7, 0.5],
        alpha: 0.3,
    };
    let b = GgxLambert {
        kd: [0.3, 0.2, 0.1],
        f0: [0.04; 3],
        alpha: 0.15,
    };
    a.table().write(&input.join("a.binary"), false).unwrap();
    b.table().write(&input.join("b.binary"), false).unwrap();
    npf::synth_aniso::catalogue()[2]
        .table()
        .write(&input.join("c.bin"), false)
        .unwrap();
    let good = std::fs::read(input.join("a.binary")).unwrap();
    std::fs::write(input.join("broken.binary"), &good[..good.len() - 8]).unwrap();
    std::fs::write(input.join("README.txt"), "not a table").unwrap();
    input
}

fn fit_folder(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["fit", s(input), "-o", s(out), "--max-sweeps", "2"];
    args.extend_from_slice(extra);
    npf(&args)
}

#[test]
fn a_folder_is_fitted_table_by_table_resumed_and_forced() {
    let dir = tempfile::tempdir().unwrap();
    let input = folder(dir.path());
    let before = snapshot(&input);
    let out = dir.path().join("fits");

    // First run: three fits, the broken table reported by name, non-zero exit.
    let o = fit_folder(&input, &out, &[]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains("broken.binary: FAILED") && err.contains("truncated"),
        "{err}"
    );
    assert!(err.contains("1 of 4 tables failed: broken.binary"), "{err}");
    for name in ["a.json", "b.json", "c.json"] {
        let m = npf::modelfile::read(&out.join(name)).unwrap();
        let info = m.fit.expect("fit record");
        assert_eq!(info.sweeps, 2, "{name}");
    }
    assert!(!out.join("broken.json").exists());
    assert_eq!(snapshot(&input), before, "the input folder was written to");
    let rows = summary(&out);
    assert_eq!(rows.len(), 4, "{rows:?}");
    for (file, params) in [("a.binary", "822"), ("b.binary", "822"), ("c.bin", "2010")] {
        let r = row(&rows, file);
        assert_eq!(r["status"], "fitted", "{r:?}");
        assert_eq!(r["parameters"], params, "{r:?}");
        assert_eq!(r["sweeps"], "2", "{r:?}");
        assert!(r["seconds"].parse::<f64>().unwrap() > 0.0, "{r:?}");
        assert!(r["log_rmse"].parse::<f64>().unwrap().is_finite(), "{r:?}");
        assert_eq!(r["error"], "", "{r:?}");
    }
    let r = row(&rows, "broken.binary");
    assert_eq!(r["status"], "failed");
    assert!(
        r["error"].contains("broken.binary") && r["error"].contains("truncated"),
        "{r:?}"
    );
    assert_eq!(r["parameters"], "");

    // Resume: the fitted tables are kept (byte for byte), the broken one
    // fails again.
    let fitted = snapshot(&out);
    let o = fit_folder(&input, &out, &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("a.binary: skipped"), "{}", stderr(&o));
    for name in ["a.json", "b.json", "c.json"] {
        assert_eq!(
            fitted[name],
            std::fs::read(out.join(name)).unwrap(),
            "{name}"
        );
    }
    let rows = summary(&out);
    assert_eq!(row(&rows, "a.binary")["status"], "skipped");
    assert_eq!(row(&rows, "a.binary")["parameters"], "822");
    assert_eq!(row(&rows, "c.bin")["sweeps"], "2");
    assert_eq!(row(&rows, "broken.binary")["status"], "failed");

    // Repair the broken table: the run completes with only it fitted.
    std::fs::copy(input.join("a.binary"), input.join("broken.binary")).unwrap();
    let o = fit_folder(&input, &out, &["--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o), "", "--quiet prints nothing when all is well");
    let rows = summary(&out);
    assert_eq!(row(&rows, "broken.binary")["status"], "fitted");
    assert_eq!(row(&rows, "a.binary")["status"], "skipped");

    // --force refits everything (here with three sweeps, seen in the files;
    // no tolerance, so only the limit stops the full set's sweeps).
    let o = npf(&[
        "fit",
        s(&input),
        "-o",
        s(&out),
        "--max-sweeps",
        "3",
        "--kept-g-tol",
        "0",
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = summary(&out);
    assert!(rows.iter().all(|r| r["status"] == "fitted"), "{rows:?}");
    let m = npf::modelfile::read(&out.join("a.json")).unwrap();
    assert_eq!(m.fit.unwrap().sweeps, 3);
    // No temporary files are left in the output folder.
    let mut names: Vec<String> = snapshot(&out).into_keys().collect();
    names.sort();
    assert_eq!(
        names,
        ["a.json", "b.json", "broken.json", "c.json", "summary.csv"]
    );
}

#[test]
fn folder_options_are_checked_before_any_fit() {
    let dir = tempfile::tempdir().unwrap();
    let input = folder(dir.path());
    let out = dir.path().join("fits");
    let refused = |o: &Output, needle: &str| {
        let err = stderr(o);
        assert!(!o.status.success(), "{err}");
        assert!(err.contains(needle), "lacks {needle:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!err.contains("FAILED"), "a fit was started: {err}");
    };
    refused(&fit_folder(&input, &out, &["--lobes", "9"]), "--lobes");
    refused(&fit_folder(&input, &out, &["--nodes", "3"]), "--nodes");
    assert!(!out.exists(), "nothing may be created for a bad flag");
    // The input folder itself, a file, a model-file name, a missing parent.
    refused(&fit_folder(&input, &input, &[]), "is the input folder");
    let file = dir.path().join("file");
    std::fs::write(&file, "x").unwrap();
    refused(&fit_folder(&input, &file, &[]), "is not a folder");
    refused(
        &fit_folder(&input, &dir.path().join("m.json"), &[]),
        "looks like a model file",
    );
    refused(
        &fit_folder(&input, &dir.path().join("no/such"), &[]),
        "cannot create the output folder",
    );
    // Two tables that would share an output.
    std::fs::copy(input.join("c.bin"), input.join("a.bin")).unwrap();
    refused(&fit_folder(&input, &out, &[]), "would both be fitted into");
    std::fs::remove_file(input.join("a.bin")).unwrap();
    // A folder without tables.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    refused(&fit_folder(&empty, &out, &[]), "no measured tables");
    // --jobs: at least one.
    refused(
        &fit_folder(&input, &out, &["--jobs", "0"]),
        "--jobs must be at least 1",
    );
    // --form and --jobs belong to folder inputs.
    for flag in [["--form", "npfb"], ["--jobs", "2"]] {
        let (table, single) = (input.join("a.binary"), dir.path().join("x.json"));
        let mut args = vec!["fit", s(&table), "-o", s(&single)];
        args.extend(flag);
        refused(&npf(&args), "only for a folder input");
    }
}

#[test]
fn folder_outputs_take_the_form_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    GgxLambert {
        kd: [0.2; 3],
        f0: [0.5; 3],
        alpha: 0.2,
    }
    .table()
    .write(&input.join("x.y.binary"), false)
    .unwrap();
    let out = dir.path().join("fits");
    let o = fit_folder(&input, &out, &["--form", "npfb", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A dotted stem keeps its dots; the binary form holds the model alone.
    let m = npf::modelfile::read(&out.join("x.y.npfb")).unwrap();
    assert_eq!(m.model.param_count(), 822);
    // Resumed, it is reported from the model (no fit record in .npfb).
    let o = fit_folder(&input, &out, &["--form", "npfb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = summary(&out);
    assert_eq!(row(&rows, "x.y.binary")["status"], "skipped");
    assert_eq!(row(&rows, "x.y.binary")["parameters"], "822");
    assert_eq!(row(&rows, "x.y.binary")["sweeps"], "");
}

/// The lines of stderr that report a table, as `[k/n] file`.
fn table_lines(err: &str) -> Vec<String> {
    err.lines()
        .filter(|l| l.starts_with('['))
        .map(|l| l.split(':').next().unwrap().to_string())
        .collect()
}

#[test]
fn concurrent_fits_give_the_models_of_a_sequential_run_in_the_same_order() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir(&input).unwrap();
    for (k, alpha) in [0.1, 0.2, 0.35, 0.5].into_iter().enumerate() {
        GgxLambert {
            kd: [0.05 * k as f64, 0.1, 0.2],
            f0: [0.9, 0.5, 0.04 + 0.1 * k as f64],
            alpha,
        }
        .table()
        .write(&input.join(format!("t{k}.binary")), false)
        .unwrap();
    }
    // A failure amid the fits is reported in its place; the rest go on.
    std::fs::write(input.join("t2.binary"), b"not a table").unwrap();
    let run = |out: &str, jobs: &str, threads: &str| {
        let out = dir.path().join(out);
        let o = fit_folder(
            &input,
            &out,
            &["--form", "npfb", "--jobs", jobs, "--threads", threads],
        );
        assert!(!o.status.success());
        (out, stderr(&o))
    };
    let (one, err_one) = run("one", "1", "1");
    let (three, err_three) = run("three", "3", "3");
    assert!(err_one.contains("one at a time, 1 thread"), "{err_one}");
    assert!(
        err_three.contains("3 at a time, 1 thread each"),
        "{err_three}"
    );
    // Lines in name order whatever finished first, as in a sequential run.
    let expected: Vec<String> = (0..4)
        .map(|k| format!("[{}/4] t{k}.binary", k + 1))
        .collect();
    assert_eq!(table_lines(&err_one), expected, "{err_one}");
    assert_eq!(table_lines(&err_three), expected, "{err_three}");
    assert!(err_three.contains("t2.binary: FAILED"), "{err_three}");
    // The models are byte for byte those of the one-at-a-time run.
    for k in [0, 1, 3] {
        let name = format!("t{k}.npfb");
        let a = std::fs::read(one.join(&name)).unwrap();
        assert_eq!(a, std::fs::read(three.join(&name)).unwrap(), "{name}");
    }
    assert!(!three.join("t2.npfb").exists());
    // The summary's rows in name order, the same statuses and figures.
    let (r1, r3) = (summary(&one), summary(&three));
    let files: Vec<&str> = r3.iter().map(|r| r["file"].as_str()).collect();
    assert_eq!(files, ["t0.binary", "t1.binary", "t2.binary", "t3.binary"]);
    for (a, b) in r1.iter().zip(&r3) {
        for col in ["file", "status", "parameters", "error"] {
            assert_eq!(a[col], b[col], "{col}");
        }
    }
    // JSON models (with the fit record): the same fit as well, with the
    // threads each fit had recorded.
    let (oj, tj) = (dir.path().join("oj"), dir.path().join("tj"));
    std::fs::remove_file(input.join("t2.binary")).unwrap();
    for (out, jobs) in [(&oj, "1"), (&tj, "2")] {
        let o = fit_folder(&input, out, &["--jobs", jobs, "--threads", "2", "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    for k in [0, 1, 3] {
        let name = format!("t{k}.json");
        let a = npf::modelfile::read(&oj.join(&name)).unwrap();
        let b = npf::modelfile::read(&tj.join(&name)).unwrap();
        let (fa, fb) = (a.fit.unwrap(), b.fit.unwrap());
        assert_eq!((fa.threads, fb.threads), (2, 1), "{name}");
        assert_eq!(fa.objective.to_bits(), fb.objective.to_bits(), "{name}");
        assert_eq!(fa.sweeps, fb.sweeps, "{name}");
        assert_eq!(
            npf::modelfile::to_binary(&a.model),
            npf::modelfile::to_binary(&b.model),
            "{name}"
        );
    }
}
