//! `npf fit`, `info`, `compare` and `reconstruct` on UTIA tables: detection,
//! `--format`, the anisotropic layout, and clear refusals.

use npf::synth_aniso::catalogue;
use std::path::Path;
use std::process::Output;

mod common;
use common::npf;

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn utia_tables_go_through_fit_info_compare_and_reconstruct() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("ggx.bin");
    catalogue()[2].table().write(&table, false).unwrap();

    let o = npf(&["info", p(&table)]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("UTIA table") && text(&o).contains("82944 of 82944"),
        "{}",
        text(&o)
    );

    let model = dir.path().join("m.json");
    let o = npf(&[
        "fit",
        p(&table),
        "-o",
        p(&model),
        "--max-sweeps",
        "5",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = npf(&["info", p(&model)]);
    assert!(text(&o).contains("2010"), "{}", text(&o));

    let o = npf(&[
        "compare",
        p(&table),
        p(&model),
        "--res",
        "32",
        "--n-theta",
        "8",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("rendering PSNR"), "{}", text(&o));

    let rec = dir.path().join("rec.bin");
    let o = npf(&["reconstruct", p(&model), "-o", p(&rec)]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::metadata(&rec).unwrap().len(),
        npf::loaders::UtiaTable::FILE_BYTES
    );
    let merl = dir.path().join("rec.binary");
    let o = npf(&["reconstruct", p(&model), "-o", p(&merl)]);
    assert!(
        !o.status.success() && text(&o).contains("anisotropic model"),
        "{}",
        text(&o)
    );
    assert!(!merl.exists());

    // A UTIA-sized file named .binary is ambiguous until forced.
    let odd = dir.path().join("odd.binary");
    std::fs::copy(&table, &odd).unwrap();
    let o = npf(&["info", p(&odd)]);
    assert!(
        !o.status.success() && text(&o).contains("ambiguous"),
        "{}",
        text(&o)
    );
    assert!(!text(&o).contains("panicked"));
    let o = npf(&["info", p(&odd), "--format", "utia"]);
    assert!(o.status.success(), "{}", text(&o));

    // A truncated UTIA table names the file and the problem; no output.
    let short = dir.path().join("short.bin");
    std::fs::write(&short, &std::fs::read(&table).unwrap()[..1000]).unwrap();
    let out = dir.path().join("x.json");
    let o = npf(&["fit", p(&short), "-o", p(&out)]);
    assert!(
        !o.status.success() && text(&o).contains("short.bin") && text(&o).contains("truncated"),
        "{}",
        text(&o)
    );
    assert!(!out.exists());
}
