//! `cargo xtask consumer`: build `examples/consumer` (a program that uses the crates as the
//! docs say, from a workspace of its own) natively and for `wasm32-unknown-unknown`, run it
//! natively and under node, and require the same report, line for line.
//!
//! The report covers explicit and implicit time stepping and the mesh pipeline, each checked
//! by the program itself (a wrong result is an error and a non-zero exit). Its build goes to
//! `target/consumer/` (or `$CARGO_TARGET_DIR/consumer`), apart from the workspace's.

use std::path::PathBuf;
use std::process::Command;

use crate::util::{cargo_program, root};
use crate::web::{TARGET, install_target, output};

pub fn run(args: &[&str]) -> Result<(), String> {
    if let Some(a) = args.first() {
        return Err(format!(
            "unknown argument `{a}` (usage: cargo xtask consumer)"
        ));
    }
    install_target()?;
    let dir = root().join("examples/consumer");
    let target_dir = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"))
        .join("consumer");
    let cargo = |args: &[&str]| {
        eprintln!("$ (cd examples/consumer && cargo {})", args.join(" "));
        let mut cmd = Command::new(cargo_program());
        cmd.args(args)
            .current_dir(&dir)
            .env("CARGO_TARGET_DIR", &target_dir)
            // No debug information: nothing is stepped through, and it only fills the disk.
            .env("CARGO_PROFILE_DEV_DEBUG", "false")
            .env("CARGO_PROFILE_RELEASE_DEBUG", "false");
        cmd
    };
    // It is outside the workspace, so the workspace's `cargo fmt --check` does not see it.
    let status = cargo(&["fmt", "--check"])
        .status()
        .map_err(|e| format!("cannot run cargo fmt: {e}"))?;
    if !status.success() {
        return Err("examples/consumer is not formatted (cargo fmt in that directory)".into());
    }
    // The lock file is the consumer's own; `--locked` keeps CI on it.
    let native = output(&mut cargo(&["run", "--locked", "-q"]))?;
    let status = cargo(&[
        "build",
        "--locked",
        "--release",
        "--lib",
        "--target",
        TARGET,
    ])
    .status()
    .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!(
            "building the consumer for {TARGET} failed ({status})"
        ));
    }
    let module = target_dir
        .join(TARGET)
        .join("release")
        .join("fem2d_consumer.wasm");
    let node = std::env::var("NODE").unwrap_or_else(|_| "node".to_owned());
    let wasm = output(
        Command::new(&node)
            .arg(dir.join("run.mjs"))
            .arg(&module)
            .current_dir(&dir),
    )?;
    eprintln!("native:\n{native}\nWebAssembly (node):\n{wasm}");
    if native != wasm {
        return Err(
            "the consumer's report differs between the native build and WebAssembly".into(),
        );
    }
    for part in ["explicit:", "implicit:", "meshing:"] {
        if !native.lines().any(|l| l.starts_with(part)) {
            return Err(format!("the consumer's report has no `{part}` line"));
        }
    }
    eprintln!("the consumer gives the same report natively and in WebAssembly");
    Ok(())
}
