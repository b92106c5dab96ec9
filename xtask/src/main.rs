//! `cargo xtask`: the project's only script host (see `.cargo/config.toml` for the alias).
//!
//! - `cargo xtask ci`: what `.ci/run` checks, in the same order (format, clippy on all targets
//!   with warnings denied, the test suite, and compiling the benches).
//! - `cargo xtask bench [ARGS...]`: the criterion benches of every crate, arguments passed on
//!   (`cargo xtask bench -- forces/neo-hookean`).
//! - `cargo xtask tidy`: the style and layering checks alone (they also run under `cargo test`).

use std::process::{Command, ExitCode};

fn cargo(args: &[&str]) -> Result<(), String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    eprintln!("$ cargo {}", args.join(" "));
    let status = Command::new(&cargo)
        .args(args)
        .status()
        .map_err(|e| format!("cannot run {cargo}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`cargo {}` failed ({status})", args.join(" ")))
    }
}

fn run(args: &[String]) -> Result<(), String> {
    let rest: Vec<&str> = args.iter().skip(1).map(String::as_str).collect();
    match args.first().map(String::as_str) {
        Some("ci") => {
            cargo(&["fmt", "--all", "--", "--check"])?;
            cargo(&[
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ])?;
            cargo(&["test", "--workspace"])?;
            cargo(&["bench", "--workspace", "--no-run"])
        }
        Some("bench") => {
            let mut a = vec!["bench", "--workspace"];
            a.extend(rest);
            cargo(&a)
        }
        Some("tidy") => cargo(&["test", "-p", "xtask", "--test", "tidy"]),
        Some(other) => Err(format!(
            "unknown xtask `{other}` (expected one of: ci, bench, tidy)"
        )),
        None => Err("usage: cargo xtask <ci|bench|tidy> [ARGS...]".to_owned()),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
