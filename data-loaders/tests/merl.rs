//! MERL table I/O on self-made tables (no external data).

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use npf_data_loaders::{LoadError, MerlTable};

const CELLS: usize = MerlTable::CELLS;

/// A smooth, distinct value per node and channel; None on a pattern of cells.
fn synthetic(th: f64, td: f64, pd: f64) -> Option<[f64; 3]> {
    if (pd - 5.0 * PI / 180.0).abs() < 1e-12 {
        return None;
    }
    Some([
        0.1 + th + 1e-3 * pd,
        0.2 + 2.0 * td + 1e-4 * th,
        0.3 + 0.5 * pd + td * th,
    ])
}

fn synthetic_table() -> MerlTable {
    MerlTable::from_fn(synthetic)
}

fn rel_close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// cos θi and cos θo of a node with φh = 0, by the closed form.
fn cosines(th: f64, td: f64, pd: f64) -> (f64, f64) {
    let a = td.cos() * th.cos();
    let b = td.sin() * pd.cos() * th.sin();
    (a - b, a + b)
}

fn file_name(p: &Path) -> String {
    p.file_name().unwrap().to_string_lossy().into_owned()
}

#[test]
fn write_read_round_trip_is_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    let t = synthetic_table();

    // Cell values survive the division by SCALE and back.
    for (i_th, i_td, i_pd) in [(0, 0, 0), (13, 19, 93), (45, 60, 120), (89, 89, 179)] {
        let (th, td, pd) = MerlTable::node_angles(i_th, i_td, i_pd);
        let want = synthetic(th, td, pd).unwrap();
        let got = t.cell(MerlTable::index(i_th, i_td, i_pd)).unwrap();
        for c in 0..3 {
            assert!(rel_close(got[c], want[c]), "{c}: {} vs {}", got[c], want[c]);
        }
    }
    assert_eq!(t.cell(MerlTable::index(10, 10, 5)), None);
    assert_eq!(t.raw()[MerlTable::index(10, 10, 5)], MerlTable::MISSING);

    let p = dir.path().join("synthetic.binary");
    t.write(&p, false).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    assert_eq!(bytes.len() as u64, MerlTable::FILE_BYTES);
    assert_eq!(&bytes[..12], &[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]);
    assert!(bytes == t.to_bytes(), "write and to_bytes differ");

    let back = MerlTable::read(&p).unwrap();
    assert!(back.raw() == t.raw(), "values changed in the round trip");
    assert!(back.to_bytes() == bytes, "to_bytes of a read table differs");
    assert_eq!(back.valid_cells(), 90 * 90 * 179);

    // Every stored bit pattern survives, including -0.0, subnormals and
    // negatives, whether or not they mark missing cells.
    let mut raw = t.raw().to_vec();
    raw[7] = -0.0;
    raw[CELLS + 8] = f64::MIN_POSITIVE / 3.0;
    raw[2 * CELLS + 9] = -123.456;
    raw[10] = f64::MAX;
    let odd = MerlTable::from_raw(raw);
    let bytes = odd.to_bytes();
    let back = MerlTable::from_bytes(&bytes, Path::new("odd.binary")).unwrap();
    assert!(back.to_bytes() == bytes);
    assert_eq!(back.raw()[7].to_bits(), (-0.0f64).to_bits());
    assert!(back.cell(7).is_some(), "-0.0 is not negative");
    assert_eq!(back.raw()[2 * CELLS + 9], -123.456);
}

#[test]
fn malformed_files_give_the_right_error() {
    let dir = tempfile::tempdir().unwrap();
    let good = MerlTable::from_fn(|_, _, _| Some([1.0, 2.0, 3.0])).to_bytes();
    let n = good.len() as u64;
    let put = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let check = |p: &Path, e: LoadError, want: &str| {
        let s = e.to_string();
        assert!(s.contains(&file_name(p)), "no file name in {s:?}");
        assert!(s.contains(want), "{s:?} lacks {want:?}");
        assert_eq!(e.path(), p);
    };
    let wrong_size = |name: &str, bytes: &[u8], want: &str| {
        let p = put(name, bytes);
        let e = MerlTable::read(&p).unwrap_err();
        match e {
            LoadError::WrongSize {
                expected, actual, ..
            } => {
                assert_eq!(expected, n);
                assert_eq!(actual, bytes.len() as u64);
            }
            ref other => panic!("{name}: {other:?}"),
        }
        check(&p, e, want);
        // The same check without a file.
        let e = MerlTable::from_bytes(bytes, &p).unwrap_err();
        assert!(matches!(e, LoadError::WrongSize { .. }), "{e:?}");
    };
    wrong_size("empty.binary", &[], "empty");
    wrong_size("five.binary", &good[..5], "truncated");
    wrong_size("short.binary", &good[..good.len() - 1], "truncated");
    let mut long = good.clone();
    long.push(0);
    wrong_size("long.binary", &long, "too long");
    drop(long);

    let mut bad = good.clone();
    bad[8..12].copy_from_slice(&90i32.to_le_bytes());
    let p = put("header.binary", &bad);
    let e = MerlTable::read(&p).unwrap_err();
    assert!(
        matches!(
            e,
            LoadError::BadHeader {
                dims: [90, 90, 90],
                ..
            }
        ),
        "{e:?}"
    );
    check(&p, e, "90 90 90");

    let non_finite = |name: &str, channel: usize, cell: usize, v: f64| {
        let mut bad = good.clone();
        let at = 12 + 8 * (channel * CELLS + cell);
        bad[at..at + 8].copy_from_slice(&v.to_le_bytes());
        // A later non-finite value must not be the one reported.
        let later = 12 + 8 * (2 * CELLS + CELLS - 1);
        bad[later..later + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let p = put(name, &bad);
        let e = MerlTable::read(&p).unwrap_err();
        match e {
            LoadError::NonFinite {
                channel: c,
                cell: i,
                ..
            } => assert_eq!((c, i), (channel, cell), "{name}"),
            ref other => panic!("{name}: {other:?}"),
        }
        check(&p, e, &format!("cell {cell}"));
        std::fs::remove_file(&p).unwrap();
    };
    non_finite("nan.binary", 1, 12_345, f64::NAN);
    non_finite("inf.binary", 2, 0, f64::INFINITY);
    non_finite("neginf.binary", 0, CELLS - 1, f64::NEG_INFINITY);

    let p = dir.path().join("absent.binary");
    let e = MerlTable::read(&p).unwrap_err();
    assert!(matches!(e, LoadError::Io { .. }), "{e:?}");
    check(&p, e, "");
}

#[test]
fn write_respects_overwrite_and_leaves_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.binary");
    let a = MerlTable::from_fn(|_, _, _| Some([1.0, 1.0, 1.0]));
    let b = MerlTable::from_fn(|_, _, _| Some([2.0, 2.0, 2.0]));
    a.write(&p, false).unwrap();

    let e = b.write(&p, false).unwrap_err();
    assert!(matches!(e, LoadError::Exists { .. }), "{e:?}");
    assert!(e.to_string().contains("t.binary"), "{e}");
    assert!(e.to_string().contains("already exists"), "{e}");
    assert!(MerlTable::read(&p).unwrap() == a, "old content damaged");

    b.write(&p, true).unwrap();
    assert!(MerlTable::read(&p).unwrap() == b, "not overwritten");

    // A table that could not be read back is not written.
    let mut raw = a.raw().to_vec();
    raw[CELLS + 3] = f64::NAN;
    let e = MerlTable::from_raw(raw).write(&p, true).unwrap_err();
    assert!(
        matches!(
            e,
            LoadError::NonFinite {
                channel: 1,
                cell: 3,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        MerlTable::read(&p).unwrap() == b,
        "refused write damaged file"
    );

    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec!["t.binary"], "temporary files left behind");

    let q = dir.path().join("no-such-dir").join("t.binary");
    let e = a.write(&q, false).unwrap_err();
    assert!(matches!(e, LoadError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("t.binary"), "{e}");
    assert!(!q.exists());
    assert!(!dir.path().join("no-such-dir").exists());
}

#[test]
fn samples_lookup_and_missing_cells() {
    let mut raw = synthetic_table().raw().to_vec();
    // A negative in one channel only: the cell is missing, the value is kept.
    let neg = MerlTable::index(30, 40, 50);
    raw[CELLS + neg] = -0.5;
    let t = MerlTable::from_raw(raw);
    assert_eq!(t.raw()[CELLS + neg], -0.5);
    assert_eq!(t.cell(neg), None);
    assert_eq!(t.valid_cells(), 90 * 90 * 179 - 1);
    let back = MerlTable::from_bytes(&t.to_bytes(), Path::new("neg.binary")).unwrap();
    assert_eq!(back.raw()[CELLS + neg], -0.5, "negative value was altered");

    let s = t.samples("synthetic");
    assert_eq!(s.source, "synthetic");
    assert!(s.isotropic);
    assert_eq!(s.samples.len() + s.missing, CELLS);

    // Independent count by the closed-form cosines; nodes within 1e-12 of
    // the horizon may go either way.
    let (mut sure, mut unsure, mut below) = (0usize, 0usize, 0usize);
    for i_th in 0..90 {
        for i_td in 0..90 {
            for i_pd in 0..180 {
                let idx = MerlTable::index(i_th, i_td, i_pd);
                if i_pd == 5 || idx == neg {
                    continue;
                }
                let (th, td, pd) = MerlTable::node_angles(i_th, i_td, i_pd);
                let (ci, co) = cosines(th, td, pd);
                let m = ci.min(co);
                if m > 1e-12 {
                    sure += 1;
                } else if m >= -1e-12 {
                    unsure += 1;
                } else {
                    below += 1;
                }
            }
        }
    }
    assert!(
        below > 100_000,
        "the synthetic table has few below-horizon cells"
    );
    let n = s.samples.len();
    assert!(
        sure <= n && n <= sure + unsure,
        "{n} kept, {sure} + {unsure} expected"
    );

    for smp in &s.samples {
        let a = smp.angles;
        assert!(a.theta_i <= FRAC_PI_2 && a.theta_o <= FRAC_PI_2, "{a:?}");
        assert_eq!(a.phi_h, 0.0);
        let want = synthetic(a.theta_h, a.theta_d, a.phi_d).unwrap();
        for (got, want) in smp.rgb.into_iter().zip(want) {
            assert!(rel_close(got, want), "{a:?}");
        }
    }
    // Spot-check one kept sample by index.
    let idx = MerlTable::index(20, 30, 40);
    let (th, td, pd) = MerlTable::node_angles(20, 30, 40);
    let smp = s
        .samples
        .iter()
        .find(|m| m.angles.theta_h == th && m.angles.theta_d == td && m.angles.phi_d == pd)
        .expect("sample (20, 30, 40) missing");
    assert_eq!(Some(smp.rgb), t.cell(idx));

    // lookup agrees with cell at every node and inside every bin.
    for i_th in 0..90 {
        for i_td in 0..90 {
            for i_pd in 0..180 {
                let idx = MerlTable::index(i_th, i_td, i_pd);
                let (th, td, pd) = MerlTable::node_angles(i_th, i_td, i_pd);
                assert_eq!(
                    t.lookup(th, td, pd),
                    t.cell(idx),
                    "node {i_th} {i_td} {i_pd}"
                );
                let u = (i_th as f64 + 0.7) / 90.0;
                let th_in = u * u * FRAC_PI_2;
                let td_in = (i_td as f64 + 0.3) * PI / 180.0;
                let pd_in = (i_pd as f64 + 0.5) * PI / 180.0;
                assert_eq!(t.lookup(th_in, td_in, pd_in), t.cell(idx));
                // Negative phi_d folds by +pi.
                assert_eq!(t.lookup(th_in, td_in, pd_in - PI), t.cell(idx));
            }
        }
    }
    // Out-of-range angles clamp; NaN finds nothing.
    let last = t.cell(CELLS - 1);
    assert_eq!(t.lookup(2.0, 2.0, PI), last);
    assert_eq!(t.lookup(-1.0, -1.0, 0.0), t.cell(0));
    assert_eq!(t.lookup(f64::NAN, 0.1, 0.1), None);
}
