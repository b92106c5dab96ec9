//! Helpers shared by the end-to-end tests of the `fem2d` binary.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `fem2d ARGS` and returns its output.
pub fn fem2d(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fem2d"))
        .args(args)
        .output()
        .expect("fem2d runs")
}

/// A fresh, empty directory for one test (unique per test binary and name).
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fem2d-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A path as a command-line argument.
pub fn arg(p: &Path) -> &str {
    p.to_str().unwrap()
}
