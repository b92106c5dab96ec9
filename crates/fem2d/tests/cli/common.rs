//! Helpers shared by the end-to-end tests of the `fem2d` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

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

/// Runs `fem2d run ARGS --out DIR -q` and checks it succeeded with nothing on stderr.
pub fn run_ok(args: &[&str], dir: &Path) -> Output {
    let mut all = vec!["run"];
    all.extend(args);
    all.extend(["--out", arg(dir), "-q"]);
    let out = fem2d(&all);
    assert!(
        out.status.success(),
        "{all:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stderr.is_empty(),
        "{all:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `fem2d ARGS` expecting failure with exactly one `error: ` line on stderr; returns it.
pub fn one_line_error(args: &[&str]) -> String {
    let out = fem2d(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} should fail: {stderr}");
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("error: "))
        .collect();
    assert_eq!(errors.len(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.lines().all(|l| l.starts_with("error: ")),
        "{args:?}: {stderr}"
    );
    errors[0].to_owned()
}

/// A file's text (panics naming the file).
pub fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A JSON file, parsed (panics naming the file).
pub fn json(path: &Path) -> Value {
    serde_json::from_str(&read(path)).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
