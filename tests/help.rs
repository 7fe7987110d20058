//! Help says what the program does: every subcommand's short help (`-h`)
//! lists at most 15 options, its long help (`--help`) lists those and the
//! tuning knobs besides, and `npf export --help` names every output format
//! `npf export` writes.

use std::collections::BTreeSet;
use std::process::Command;

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_npf"))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "npf {args:?} failed");
    String::from_utf8(out.stdout).unwrap()
}

/// The subcommands `npf ARGS --help` lists (`help` left out).
fn subcommands(args: &[&str]) -> Vec<String> {
    let mut args = args.to_vec();
    args.push("--help");
    let text = help(&args);
    let block = text.split("Commands:").nth(1).unwrap();
    let block = block.split("\n\n").next().unwrap();
    block
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}

/// The option names (`--long`, or `-s` alone) a help text lists.
fn options(text: &str) -> BTreeSet<String> {
    text.lines()
        .map(str::trim_start)
        .filter(|l| l.starts_with('-'))
        .filter_map(|l| {
            let first = l.split([' ', ',', '=', '<']).next()?;
            let long = l.split_whitespace().find(|w| w.starts_with("--"));
            Some(
                long.unwrap_or(first)
                    .trim_end_matches(',')
                    .split(['=', '<'])
                    .next()?
                    .to_string(),
            )
        })
        .collect()
}

#[test]
fn short_help_lists_at_most_15_options_and_long_help_all() {
    let subs = subcommands(&[]);
    assert!(subs.len() >= 10, "subcommands: {subs:?}");
    for sub in subs {
        // `energy` has subcommands of its own
        let nested: Vec<Vec<String>> = if sub == "energy" {
            subcommands(&["energy"])
                .into_iter()
                .map(|c| vec![sub.clone(), c])
                .collect()
        } else {
            vec![vec![sub.clone()]]
        };
        for path in nested {
            let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
            args.push("-h");
            let short = options(&help(&args));
            args.pop();
            args.push("--help");
            let long = options(&help(&args));
            assert!(
                short.len() <= 15,
                "npf {path:?} -h lists {} options: {short:?}",
                short.len()
            );
            assert!(
                short.is_subset(&long),
                "npf {path:?}: -h lists options --help does not"
            );
        }
    }
}

#[test]
fn fit_long_help_groups_the_tuning_knobs() {
    let short = help(&["fit", "-h"]);
    let long = help(&["fit", "--help"]);
    assert!(!short.contains("Advanced"));
    assert!(long.contains("Advanced (tuning"));
    for knob in [
        "--coarse-tol",
        "--grazing-trust",
        "--epsilon-median",
        "--kept-g-tol",
        "--g-method",
    ] {
        assert!(!short.contains(knob), "-h shows {knob}");
        assert!(long.contains(knob), "--help lacks {knob}");
    }
    for decision in [
        "--output",
        "--model",
        "--lobes",
        "--nodes",
        "--threads",
        "--force",
        "--quiet",
    ] {
        assert!(short.contains(decision), "-h lacks {decision}");
    }
}

#[test]
fn export_help_names_every_format() {
    let long = help(&["export", "--help"]);
    let list = help(&["--help"]);
    for ext in [".bsdf", ".binary", ".glsl", ".h ", ".brdf"] {
        assert!(long.contains(ext), "npf export --help does not name {ext}");
        assert!(
            list.contains(ext.trim_end()),
            "npf --help does not name {ext}"
        );
    }
    // and export takes each of them
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    let m = npf::synth::known_factor_model(npf::model::Layout::default(), &[0.3]);
    npf::modelfile::write(
        &model,
        &npf::modelfile::ModelFile {
            model: m,
            fit: None,
        },
        false,
    )
    .unwrap();
    for ext in ["bsdf", "binary", "glsl", "h", "brdf"] {
        let out = dir.path().join(format!("m.{ext}"));
        let st = Command::new(env!("CARGO_BIN_EXE_npf"))
            .args([
                "export",
                model.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "-q",
            ])
            .status()
            .unwrap();
        assert!(st.success() && out.exists(), "npf export to .{ext}");
    }
}
