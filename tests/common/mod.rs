//! Helpers shared by the tests that run the `npf` program.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `npf` program cargo built for these tests.
pub fn npf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_npf"))
        .args(args)
        .output()
        .expect("run npf")
}

/// A path as a command-line argument (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The program's standard error, lossily decoded.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
