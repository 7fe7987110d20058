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

/// docs/fitting.md's table of options has a row for every option
/// `npf fit --help` lists (and none that it does not), each naming where
/// its effect is measured.
#[test]
fn fitting_docs_list_every_fit_option() {
    let docs = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/fitting.md"))
        .expect("docs/fitting.md");
    let start = docs
        .find("## Every option of `npf fit`")
        .expect("the options section");
    let section = &docs[start..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let rows: Vec<&str> = section.lines().filter(|l| l.starts_with("| `-")).collect();
    let mut documented = BTreeSet::new();
    for row in &rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        // | option | default | what | effect |
        assert_eq!(cells.len(), 6, "row {row:?}");
        assert!(
            cells[2..5].iter().all(|c| !c.is_empty()),
            "row {row:?} has an empty cell"
        );
        for name in cells[1].split(',') {
            let name = name.trim().trim_matches('`');
            if name.starts_with("--") {
                documented.insert(name.to_string());
            }
        }
    }
    // Long options only (possible-value lines start with "- ").
    let listed: BTreeSet<String> = options(&help(&["fit", "--help"]))
        .into_iter()
        .filter(|o| o.starts_with("--") && o != "--help")
        .collect();
    assert_eq!(
        documented, listed,
        "docs/fitting.md's options table and npf fit --help differ"
    );
}

#[test]
fn benchmarks_are_short_and_every_section_has_its_command() {
    // BENCHMARKS.md holds today's figures (superseded runs live in git
    // history); a section of figures without the command that gives them
    // cannot be rerun by anyone.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/BENCHMARKS.md"))
        .expect("BENCHMARKS.md");
    let lines = text.lines().count();
    assert!(lines < 600, "BENCHMARKS.md has {lines} lines (limit 600)");
    let sections: Vec<&str> = text.split("\n## ").skip(1).collect();
    assert!(sections.len() >= 10, "only {} sections", sections.len());
    for section in sections {
        let title = section.lines().next().unwrap_or_default();
        // "Tried and not taken" points into git history for its commands.
        let has_command = section
            .lines()
            .any(|l| l.starts_with("    ") && !l.trim().is_empty())
            || section.contains("git show ");
        assert!(has_command, "section {title:?} gives no command");
    }
}
