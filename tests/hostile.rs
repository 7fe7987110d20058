//! Hostile inputs and operations (issue 17), one test per class: an input
//! or output that is the wrong kind of file, an output that is an input,
//! data or results a model cannot represent, special and endless files,
//! crafted layouts, absurd resource options, options checked after writing,
//! signals mid-write, reports that hide failures, misleading messages and
//! angles outside the convention. Every refusal must be a clear message, a
//! non-zero exit, no output, no temporary file and no lost file.

use npf::grid::Axis;
use npf::loaders::{MerlTable, UtiaTable};
use npf::model::{Layout, Model};
use npf::modelfile::{self, FitInfo, ModelFile};
use npf::synth::GgxLambert;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{s, stderr};

const BRDF: GgxLambert = GgxLambert {
    kd: [0.1, 0.1, 0.1],
    f0: [0.9, 0.7, 0.5],
    alpha: 0.3,
};

/// Run npf, killing it (and failing the test) if it takes over `limit`.
fn npf_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_npf"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run npf");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let _ = child.wait();
            panic!("npf {args:?} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A refusal is immediate: 20 s is generous on a loaded 2-core machine.
fn npf(args: &[&str]) -> Output {
    npf_within(args, Duration::from_secs(20))
}

fn assert_fails(o: &Output, needle: &str) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure, stderr: {err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// `npf sample MODEL --theta-o 30 --n N EXTRA...`.
fn sample(model: &Path, n: &str, extra: &[&str]) -> Output {
    let mut args = vec!["sample", s(model), "--theta-o", "30", "--n", n];
    args.extend_from_slice(extra);
    npf(&args)
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A small valid model (1 lobe, 30 values per table), made without a fit.
fn small_model() -> Model {
    let layout = Layout::isotropic(30);
    let n = layout.param_count(1);
    Model::from_params(layout, 1, &vec![0.25f32; n]).unwrap()
}

fn write_model(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    let file = ModelFile {
        model: small_model(),
        fit: None,
    };
    modelfile::write(&p, &file, false).unwrap();
    p
}

/// The test BRDF as a MERL table (`scale` 1), or a constant table of
/// 0.2 x `scale` (1/sr): the values a fit must represent.
fn table(dir: &Path, name: &str, scale: f64) -> PathBuf {
    let p = dir.join(name);
    let t = if scale == 1.0 {
        BRDF.table()
    } else {
        MerlTable::from_fn(|_, _, _| Some([0.2 * scale; 3]))
    };
    t.write(&p, false).unwrap();
    p
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_survives() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), "m.json");
    let before = std::fs::read(&m).unwrap();
    // The reported case: the model replaced by a 35 MB table.
    let o = npf(&["reconstruct", s(&m), "-o", s(&m), "--force"]);
    assert_fails(&o, ".binary");
    // Same file under another name: via `..`, a symbolic link, a hard link.
    let m_bin = write_model(dir.path(), "m.binary.npfb");
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let dotted = sub.join("..").join("m.binary.npfb");
    let o = npf(&["info", s(&dotted)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let t = table(dir.path(), "t.binary", 1.0);
    let t_before = std::fs::read(&t).unwrap();
    let link = dir.path().join("link.binary");
    std::os::unix::fs::symlink(&t, &link).unwrap();
    let hard = dir.path().join("hard.binary");
    std::fs::hard_link(&t, &hard).unwrap();
    for out in [&t, &link, &hard, &sub.join("..").join("t.binary")] {
        let o = npf(&["fit", s(&t), "-o", s(out), "--force", "--quiet"]);
        assert_fails(&o, "unknown model file extension");
    }
    // fit writes models: make the output a model name that is the input.
    let tj = dir.path().join("t.json");
    std::fs::hard_link(&t, &tj).unwrap();
    let o = npf(&["fit", s(&t), "-o", s(&tj), "--force", "--quiet"]);
    assert_fails(&o, "refusing to overwrite an input");
    let mj_link = dir.path().join("mlink.binary");
    std::os::unix::fs::symlink(&m_bin, &mj_link).unwrap();
    let o = npf(&["reconstruct", s(&m_bin), "-o", s(&mj_link), "--force"]);
    assert_fails(&o, "refusing to overwrite an input");
    assert_eq!(std::fs::read(&m).unwrap(), before);
    assert_eq!(std::fs::read(&t).unwrap(), t_before);
    assert!(!entries(dir.path()).iter().any(|e| e.ends_with(".tmp")));
}

#[test]
fn reconstruct_honours_the_output_extension() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), "m.npfb");
    let x = dir.path().join("x.json");
    let o = npf(&["reconstruct", s(&m), "-o", s(&x)]);
    assert_fails(&o, "must end in .binary");
    assert!(!x.exists());
}

#[test]
fn outputs_that_cannot_be_written_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path(), "t.binary", 1.0);
    let dangling = dir.path().join("dangling.json");
    std::os::unix::fs::symlink(dir.path().join("nowhere.json"), &dangling).unwrap();
    let folder = dir.path().join("folder.json");
    std::fs::create_dir(&folder).unwrap();
    let start = Instant::now();
    for (out, needle) in [
        (dangling.as_path(), "dangling symbolic link"),
        (folder.as_path(), "is a directory"),
    ] {
        // Default settings: the full fit would take far longer than a refusal.
        let o = npf(&["fit", s(&t), "-o", s(out), "--force", "--quiet"]);
        assert_fails(&o, needle);
    }
    // A device is never replaced, even with --force.
    let o = npf(&[
        "sample",
        s(&write_model(dir.path(), "m.json")),
        "--theta-o",
        "30",
        "--n",
        "10",
        "-o",
        "/dev/null",
        "--force",
    ]);
    assert_fails(&o, "character device");
    assert!(start.elapsed() < Duration::from_secs(20));
    assert!(Path::new("/dev/null").exists());
    assert_eq!(
        entries(dir.path()),
        vec!["dangling.json", "folder.json", "m.json", "t.binary"]
    );
}

#[test]
fn data_beyond_float32_and_absurd_weights_are_refused_not_converged() {
    let dir = tempfile::tempdir().unwrap();
    for (name, scale) in [("big.binary", 1e42), ("huge.binary", 1e300)] {
        let t = table(dir.path(), name, scale);
        let out = dir.path().join(format!("{name}.json"));
        let o = npf(&["fit", s(&t), "-o", s(&out), "--quiet", "--max-sweeps", "1"]);
        assert_fails(&o, "beyond what a model can represent");
        assert!(!out.exists());
    }
    let t = table(dir.path(), "t.binary", 1.0);
    let out = dir.path().join("t.json");
    for (flag, value) in [
        ("--epsilon", "1e300"),
        ("--epsilon", "0"),
        ("--max-theta", "1e9"),
    ] {
        let o = npf(&["fit", s(&t), "-o", s(&out), "--quiet", flag, value]);
        assert_fails(&o, flag);
    }
    assert!(!out.exists());
}

#[test]
fn a_model_file_that_could_not_be_read_back_is_never_written() {
    let dir = tempfile::tempdir().unwrap();
    let mut model = small_model();
    let info = FitInfo {
        objective: f64::INFINITY,
        ..Default::default()
    };
    let json = dir.path().join("m.json");
    let e = modelfile::write(
        &json,
        &ModelFile {
            model: model.clone(),
            fit: Some(info),
        },
        false,
    )
    .unwrap_err();
    assert!(e.to_string().contains("could not be read back"), "{e}");
    model.lobes[0].d[3] = f32::INFINITY;
    let bin = dir.path().join("m.npfb");
    let e = modelfile::write(&bin, &ModelFile { model, fit: None }, false).unwrap_err();
    assert!(e.to_string().contains("m.npfb"), "{e}");
    assert!(entries(dir.path()).is_empty());
}

#[test]
fn special_and_endless_inputs_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let zero = dir.path().join("zero.json");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let urandom = dir.path().join("random.npfb");
    std::os::unix::fs::symlink("/dev/urandom", &urandom).unwrap();
    let fifo = dir.path().join("fifo.binary");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let fifo_model = dir.path().join("fifo.json");
    Command::new("mkfifo").arg(&fifo_model).status().unwrap();
    let folder = dir.path().join("folder.binary");
    std::fs::create_dir(&folder).unwrap();
    let out = dir.path().join("o.json");
    let rbin = dir.path().join("r.binary");
    let svg = dir.path().join("p.svg");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["info", s(&zero)], "is a character device"),
        (
            vec!["eval", s(&urandom), "0", "0", "0", "0"],
            "is a character device",
        ),
        (vec!["info", s(&fifo_model)], "is a FIFO"),
        (vec!["fit", s(&fifo), "-o", s(&out)], "is a FIFO"),
        // A directory is a folder fit (tests/cli_folder.rs); an empty one is refused.
        (
            vec!["fit", s(&folder), "-o", s(&out)],
            "no measured tables (.binary or .bin files) in the folder",
        ),
        (vec!["info", s(&folder)], "is a directory"),
        (
            vec!["reconstruct", s(&fifo_model), "-o", s(&rbin)],
            "is a FIFO",
        ),
        (
            vec!["energy", "plot", "-o", s(&svg), "--font", s(&fifo_model)],
            "is a FIFO",
        ),
    ];
    for (args, needle) in cases {
        let o = npf_within(&args, Duration::from_secs(10));
        assert_fails(&o, needle);
    }
    // A model file larger than the documented maximum is refused unread
    // (a sparse file: no disk space used).
    let big = dir.path().join("big.json");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(modelfile::MAX_FILE_BYTES + 1)
        .unwrap();
    assert_fails(&npf(&["info", s(&big)]), "more than the");
    assert!(!out.exists());
}

/// A binary model header declaring `lobes` lobes of `n`-value tables, with
/// the parameters it promises.
fn crafted_npfb(lobes: u8, n: u16, params: u32) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend(b"NPFB");
    b.extend(1u16.to_le_bytes());
    b.extend(0u16.to_le_bytes());
    b.push(0);
    b.push(lobes);
    for _ in 0..3 {
        b.push(1);
        b.extend(n.to_le_bytes());
    }
    b.extend(params.to_le_bytes());
    b.extend(std::iter::repeat(0u8).take(4 * params as usize));
    b
}

#[test]
fn crafted_layouts_are_refused_from_the_header() {
    let dir = tempfile::tempdir().unwrap();
    // The reported case declared 255 lobes x 65,535 nodes (1.7 GB); the
    // header alone is enough to refuse it, whatever follows.
    let p = dir.path().join("lobes.npfb");
    std::fs::write(&p, crafted_npfb(255, 65535, 0)).unwrap();
    assert_fails(&npf(&["info", s(&p)]), "255 lobes, more than the");
    let p = dir.path().join("nodes.npfb");
    std::fs::write(&p, crafted_npfb(8, 65535, 0)).unwrap();
    let o = npf(&["sample", s(&p), "--theta-o", "10", "--n", "10"]);
    assert_fails(&o, "more than the 1048576");
    // Within the bounds a consistent file is still a model.
    let layout = Layout {
        d: npf::grid::Grid::line(Axis::Uniform { n: 8 }),
        f: npf::grid::Grid::line(Axis::Uniform { n: 8 }),
        g: npf::grid::Grid::line(Axis::Uniform { n: 8 }),
    };
    let count = layout.param_count(2) as u32;
    let p = dir.path().join("ok.npfb");
    std::fs::write(&p, crafted_npfb(2, 8, count)).unwrap();
    let o = npf(&["info", s(&p)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn resource_options_beyond_their_limits_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path(), "t.binary", 1.0);
    let m = write_model(dir.path(), "m.json");
    let out = dir.path().join("o.json");
    let (d, r) = (dir.path().join("d"), dir.path().join("r"));
    let start = Instant::now();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["fit", s(&t), "-o", s(&out), "--threads", "1000"],
            "--threads",
        ),
        (
            vec!["fit", s(&t), "-o", s(&out), "--threads", "99999999999"],
            "--threads",
        ),
        (
            vec!["fit", s(&t), "-o", s(&out), "--smooth-g", "1e9"],
            "--smooth-g",
        ),
        (vec!["demo", "-o", s(&d), "--threads", "1000"], "--threads"),
        (
            vec!["energy", "simulate", "--paths", "100000000000000"],
            "--paths",
        ),
        (
            vec!["energy", "tau", "--paths", "100000000000000"],
            "--paths",
        ),
        (
            vec!["sample", s(&m), "--theta-o", "10", "--n", "1000000000000"],
            "--n",
        ),
        (
            vec!["report", s(dir.path()), "-o", s(&r), "--jobs", "100000"],
            "--jobs",
        ),
    ];
    for (args, needle) in cases {
        assert_fails(&npf(&args), needle);
    }
    assert!(
        start.elapsed() < Duration::from_secs(30),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(entries(dir.path()), vec!["m.json", "t.binary"]);
}

#[test]
fn options_are_checked_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    // demo: a bad option leaves no table behind (the rerun is not refused).
    let d = dir.path().join("demo");
    assert_fails(
        &npf(&["demo", "-o", s(&d), "--nodes", "3", "--quiet"]),
        "--nodes",
    );
    assert!(!d.exists() || entries(&d).is_empty());
    // demo into a file that is not a folder.
    let f = dir.path().join("file");
    std::fs::write(&f, b"x").unwrap();
    assert_fails(&npf(&["demo", "-o", s(&f), "--quiet"]), "not a folder");
    // sample: one file for two outputs.
    let m = write_model(dir.path(), "m.json");
    let csv = dir.path().join("s.csv");
    let o = sample(&m, "100", &["-o", s(&csv), "--histogram", s(&csv)]);
    assert_fails(&o, "give each output its own file");
    // compare: an image folder holding an input.
    let t = table(dir.path(), "t.binary", 1.0);
    let img = dir.path().join("img");
    std::fs::create_dir(&img).unwrap();
    std::fs::hard_link(&t, img.join("test.png")).unwrap();
    let o = npf(&["compare", s(&t), s(&t), "--images", s(&img), "--force"]);
    assert_fails(&o, "refusing to overwrite an input");
    assert_eq!(
        entries(dir.path()),
        vec!["file", "img", "m.json", "t.binary"]
    );
    assert_eq!(entries(&img), vec!["test.png"]);
}

#[test]
fn a_signal_mid_write_leaves_no_temporary_file_and_stale_ones_are_cleaned() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), "m.json");
    let csv = dir.path().join("s.csv");
    for signal in ["TERM", "INT"] {
        let child = Command::new(env!("CARGO_BIN_EXE_npf"))
            .args([
                "sample",
                s(&m),
                "--theta-o",
                "30",
                "--n",
                "100000000",
                "-o",
                s(&csv),
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until the temporary file exists (the write is under way).
        let start = Instant::now();
        while !entries(dir.path()).iter().any(|e| e.ends_with(".tmp")) {
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "no temporary file appeared"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let st = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
        let o = child.wait_with_output().unwrap();
        let code = o.status.code();
        let want = if signal == "TERM" { 143 } else { 130 };
        assert_eq!(code, Some(want), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("removed 1 unfinished output"),
            "{}",
            stderr(&o)
        );
        assert_eq!(entries(dir.path()), vec!["m.json"]);
    }
    // A leftover of a killed run (a writer that no longer runs) is removed by
    // the next write of the same output; other files are left alone.
    let stale = format!(".s.csv.npf-{}.q1w2e3.tmp", u32::MAX - 1);
    std::fs::write(dir.path().join(&stale), b"partial").unwrap();
    std::fs::write(dir.path().join(".keep.tmp"), b"not ours").unwrap();
    let o = sample(&m, "10", &["-o", s(&csv)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(entries(dir.path()), vec![".keep.tmp", "m.json", "s.csv"]);
}

#[test]
fn a_report_fails_loudly_when_every_fit_failed_or_a_model_is_unreadable() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    std::fs::create_dir(&data).unwrap();
    table(&data, "big.binary", 1e42);
    let out = dir.path().join("r1");
    let quick = [
        "--configs",
        "ggx",
        "--no-convergence",
        "--res",
        "16",
        "--n-theta",
        "4",
        "--quiet",
    ];
    let mut args = vec!["report", s(&data), "-o", s(&out)];
    args.extend(quick);
    let o = npf_within(&args, Duration::from_secs(120));
    assert_fails(&o, "every fit failed (1 of 1)");
    assert!(out.join("report.md").exists(), "the report still says why");

    // A good run, then a model made unreadable: --reevaluate must not keep
    // the old measures silently.
    std::fs::remove_file(data.join("big.binary")).unwrap();
    table(&data, "good.binary", 1.0);
    let out = dir.path().join("r2");
    let mut args = vec!["report", s(&data), "-o", s(&out)];
    args.extend(quick);
    let o = npf_within(&args, Duration::from_secs(120));
    assert!(o.status.success(), "{}", stderr(&o));
    let model = out.join("good").join("ggx.json");
    assert!(model.exists());
    std::fs::write(&model, b"{ not a model").unwrap();
    let mut args = vec![
        "report",
        s(&data),
        "-o",
        s(&out),
        "--from-rows",
        "--reevaluate",
    ];
    args.extend(quick);
    let o = npf_within(&args, Duration::from_secs(120));
    assert_fails(&o, "cannot read its model");
}

#[test]
fn messages_say_what_a_file_is_when_it_is_not_what_was_expected() {
    let dir = tempfile::tempdir().unwrap();
    let utia = dir.path().join("u.binary");
    UtiaTable::from_fn(|_, _, _, _| Some([0.1; 3]))
        .write(&utia, false)
        .unwrap();
    let model = write_model(dir.path(), "m.json");
    let as_table = dir.path().join("model.binary");
    std::fs::copy(&model, &as_table).unwrap();
    let t = table(dir.path(), "t.binary", 1.0);
    let t_as_model = dir.path().join("t.json");
    std::fs::copy(&t, &t_as_model).unwrap();
    let out = dir.path().join("o.json");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["fit", s(&utia), "-o", s(&out)],
            // The size is a UTIA table's: the message says so (and how to
            // force a format).
            "is a UTIA table's",
        ),
        (
            vec!["fit", s(&as_table), "-o", s(&out)],
            "it looks like an npf model (JSON)",
        ),
        (
            vec!["compare", s(&as_table), s(&model)],
            "it looks like an npf model (JSON)",
        ),
        (vec!["info", s(&t_as_model)], "it looks like a MERL table"),
        (
            vec!["eval", s(&t_as_model), "0", "0", "0", "0"],
            "it looks like a MERL table",
        ),
    ];
    for (args, needle) in cases {
        assert_fails(&npf(&args), needle);
    }
    assert!(!out.exists());
}

#[test]
fn eval_follows_the_angle_convention() {
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), "m.json");
    let o = npf(&[
        "eval",
        s(&m),
        "90",
        "0",
        "30",
        "180",
        "30",
        "0",
        "90",
        "0",
        "30",
        "0",
        "30",
        "180",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3);
    // At the horizon (either direction) the value is exactly 0 ...
    assert_eq!(&rows[0][4..], &[0.0; 3]);
    assert_eq!(&rows[1][4..], &[0.0; 3]);
    // ... and above it the model's own, positive value.
    assert!(rows[2][4..].iter().all(|&v| v > 0.0), "{text}");
    // Below the horizon is refused, not mirrored.
    for bad in [["-5", "0", "30", "0"], ["30", "0", "95", "0"]] {
        let mut args = vec!["eval", s(&m)];
        args.extend(bad);
        assert_fails(&npf(&args), "0 to 90 degrees");
    }
    // --wavelengths is for spectral .bsdf files, and takes wavelengths.
    let q = ["30", "0", "30", "180"];
    for (extra, needle) in [
        (&["--wavelengths", "500"][..], "a model is RGB"),
        (
            &["--wavelengths", "500,nan"][..],
            "not a positive wavelength",
        ),
        (&["--wavelengths", "-400"][..], "not a positive wavelength"),
    ] {
        let mut args = vec!["eval", s(&m)];
        args.extend(q);
        args.extend(extra);
        assert_fails(&npf(&args), needle);
    }
    let many = vec!["500"; 65].join(",");
    let mut args = vec!["eval", s(&m)];
    args.extend(q);
    args.extend(["--wavelengths", &many]);
    assert_fails(&npf(&args), "at most 64");
}

mod parsers {
    //! Property tests of the model parsers (the table parsers have theirs in
    //! npf-data-loaders): mutated files are refused with a message naming
    //! the file, or are models that survive a write and a read unchanged.
    use super::*;
    use proptest::prelude::*;

    fn file() -> ModelFile {
        ModelFile {
            model: small_model(),
            fit: Some(FitInfo {
                source: "t.binary".into(),
                objective: 1.5,
                ..Default::default()
            }),
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn mutated_binary_models_are_refused_or_round_trip(
            edits in proptest::collection::vec((any::<u32>(), any::<u8>()), 0..8),
            cut in 0usize..8,
        ) {
            let p = Path::new("p.npfb");
            let mut b = modelfile::to_binary(&file().model);
            for (at, v) in edits {
                let i = at as usize % b.len();
                b[i] = v;
            }
            b.truncate(b.len() - cut);
            match modelfile::from_binary(&b, p) {
                Ok(m) => {
                    let again = modelfile::from_binary(&modelfile::to_binary(&m), p).unwrap();
                    prop_assert_eq!(again, m);
                }
                Err(e) => prop_assert!(e.to_string().starts_with("p.npfb: "), "{}", e),
            }
        }

        #[test]
        fn any_binary_header_is_refused_or_bounded(
            kind in 0u8..3, lobes: u8, axes in proptest::array::uniform6(any::<u16>()),
            codes in proptest::array::uniform3(0u8..4), count: u32,
        ) {
            let mut b = b"NPFB\x01\x00\x00\x00".to_vec();
            b.push(kind);
            b.push(lobes);
            for (i, c) in codes.iter().enumerate() {
                b.push(*c);
                b.extend(axes[2 * i].to_le_bytes());
                if kind == 1 {
                    b.extend(axes[2 * i + 1].to_le_bytes());
                }
            }
            b.extend(count.to_le_bytes());
            // No parameters follow: only a model with none could be valid,
            // and none is; nothing may be allocated from the header alone.
            let e = modelfile::from_binary(&b, Path::new("h.npfb")).unwrap_err();
            prop_assert!(e.to_string().starts_with("h.npfb: "), "{}", e);
        }

        #[test]
        fn mutated_json_models_are_refused_or_round_trip(
            edits in proptest::collection::vec(
                (any::<u32>(), prop::sample::select(vec!['0', '9', '-', 'e', '.', '"', '{', '}', '[', ']', ',', 'n', ' ', 'x', '\u{e9}'])),
                0..6,
            ),
            cut in 0usize..4,
        ) {
            let p = Path::new("p.json");
            let mut chars: Vec<char> = modelfile::to_json(&file()).chars().collect();
            for (at, c) in edits {
                let i = at as usize % chars.len();
                chars[i] = c;
            }
            chars.truncate(chars.len() - cut);
            let text: String = chars.into_iter().collect();
            match modelfile::from_json(&text, p) {
                Ok(f) => {
                    let again = modelfile::from_json(&modelfile::to_json(&f), p).unwrap();
                    prop_assert_eq!(again.model, f.model);
                }
                Err(e) => prop_assert!(e.to_string().starts_with("p.json: "), "{}", e),
            }
        }
    }
}

/// A reader that stops early (`npf sample ... | head`) ends npf quietly:
/// no panic message, killed by SIGPIPE as any Unix filter would be.
#[cfg(unix)]
#[test]
fn a_reader_that_stops_early_ends_npf_without_a_panic() {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let m = write_model(dir.path(), "m.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_npf"))
        .args(["sample", s(&m), "--theta-o", "30", "--n", "10000000"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run npf");
    let mut head = [0u8; 64];
    child.stdout.take().unwrap().read_exact(&mut head).unwrap();
    // The pipe's read end is dropped here: npf's next write finds no reader.
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.signal(), Some(13), "{:?}, {err}", o.status);
    assert!(
        String::from_utf8_lossy(&head).starts_with("wi_x"),
        "{head:?}"
    );
}
