//! `cargo xtask`: the project's only script host (see `.cargo/config.toml` for the alias).
//!
//! - `cargo xtask ci`: the core of what `.ci/run` checks, in the same order (format, clippy on
//!   all targets with warnings denied, the test suite, Table 1 against its baseline, and the
//!   Python package's tests).
//! - `cargo xtask bench [ARGS...]`: the criterion benches of every crate, arguments passed on
//!   (`cargo xtask bench -- forces/neo-hookean`).
//! - `cargo xtask tidy`: the style and layering checks alone (they also run under `cargo test`).
//! - `cargo xtask table1 [--check]`: regenerate `docs/table1.md` and the baseline
//!   `docs/table1.json` from `fem2d table1`; `--check` compares a fresh run with the baseline
//!   (1 mm tolerance) and is part of CI.
//! - `cargo xtask bench-cases [--quick] [--out DIR]`: every case x energy x solver on one
//!   thread, best of 3, into `docs/bench-cases.md` and `docs/bench-cases.json`.
//! - `cargo xtask bench-peers --peers DIR [--quick] [--out FILE]`: the explicit kernel against
//!   the same kernel in NVIDIA Warp and Taichi (the peer scripts in `DIR`), side by side.
//! - `cargo xtask stability`: the stability and accuracy maps of every energy x solver
//!   (`docs/stability.md`, with SVG plots in `docs/figures/`).
//! - `cargo xtask figures`: the paper's Figures 1-5 and the plots into `docs/figures/`
//!   (`fem2d figures`).
//! - `cargo xtask web [--serve] [--port N] [--check] [--browser-test] [--screenshot PATH]`:
//!   build the interactive app for WebAssembly into `target/web/`, serve it on 127.0.0.1,
//!   check that the module steps scenes to the same bits as the native build, and drive the
//!   page in headless Chromium (`docs/interactive.md`).
//! - `cargo xtask consumer`: build `examples/consumer` (the crates used as
//!   `docs/using-the-crates.md` says, from a workspace of its own) natively and for WebAssembly,
//!   run it natively and under node, and require the same report (explicit, implicit and
//!   meshing, each checked by the program).
//! - `cargo xtask python [--bench] [--no-test]`: the Python package `pyfem2d`
//!   (`crates/fem-py`) in a virtual environment of its own under the target directory, built
//!   by maturin in release, and its pytest tests; `--bench` its per-step overhead benchmark.
//! - `cargo xtask goldens`: regenerate `fixtures/goldens/case-{a,b,c,d}.json`, checked by
//!   `crates/fem-cases/tests/suite/goldens.rs`.
//!
//! xtask depends on no workspace crate (the layering in `ARCHITECTURE.md`): it drives the
//! release `fem2d` binary as a subprocess and reads its JSON.

mod bench_cases;
mod bench_peers;
mod consumer;
mod figures;
mod goldens;
mod python;
mod stability;
mod svg;
mod table1;
mod util;
mod web;

use std::process::{Command, ExitCode};

const USAGE: &str = "usage: cargo xtask <task> [ARGS...]

tasks:
  ci                   the core of .ci/run: fmt, clippy (warnings denied), tests, Table 1
                       against its baseline, the Python package's tests
  bench [ARGS...]      the criterion benches of every crate (arguments passed on)
  tidy                 the style and layering checks alone
  table1 [--check]     regenerate docs/table1.md and docs/table1.json from `fem2d table1`;
                       --check: fail when a tip displacement moved by more than 1 mm
  bench-cases [--quick] [--out DIR]
                       cases A-D x 5 energies x 3 solvers on one thread, best of 3, into
                       docs/bench-cases.{md,json}; --quick: one repeat, a tenth of the steps,
                       printed (written only with --out)
  bench-peers --peers DIR [--quick] [--out FILE]
                       the explicit kernel (Neo-Hookean, StVK; 16k/64k/256k triangles; 1 and
                       2 threads) against the peer scripts in DIR (NVIDIA Warp, Taichi), run
                       alternately, best of 3; a markdown table
  stability            the stability map (largest stable dt against E) and the accuracy map
                       (error against cost) of every energy x solver, into docs/stability.md
                       and docs/figures/{stability,accuracy}-map.svg
  figures              the paper's Figures 1-5, the probe curves and the case B stability
                       map (PNG and SVG), from `fem2d figures`, into docs/figures/
  goldens              regenerate fixtures/goldens/case-{a,b,c,d}.json (checked by
                       cargo test -p fem-cases --test suite goldens)
  web [--serve] [--port N] [--check] [--browser-test] [--screenshot PATH]
                       build the interactive app (crates/fem-web) for WebAssembly into
                       target/web/ (installs the wasm32 target when missing); --serve: serve
                       it on http://127.0.0.1:8090/ (or N); --check: the module under node
                       reaches the native build's states bit for bit; --browser-test: drag
                       the body in headless Chromium (puppeteer-core from npm); --screenshot:
                       save the test's picture
  consumer             build examples/consumer (the crates used as the docs say, outside the
                       workspace) natively and for WebAssembly; run it natively and under
                       node; the two reports (explicit, implicit, meshing) must be equal
  python [--bench] [--no-test]
                       the Python package (crates/fem-py): a virtual environment in
                       target/python-venv with maturin, numpy, pytest and meshio from the
                       Python package index, `maturin develop --release`, its pytest tests;
                       --bench: the per-step overhead against the same steps in Rust";

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
            table1::run(&["--check"])?;
            python::run(&[])
        }
        Some("bench") => {
            let mut a = vec!["bench", "--workspace"];
            a.extend(rest);
            cargo(&a)
        }
        Some("tidy") => cargo(&["test", "-p", "xtask", "--test", "tidy"]),
        Some("table1") => table1::run(&rest),
        Some("stability") => stability::run(&rest),
        Some("bench-cases") => bench_cases::run(&rest),
        Some("bench-peers") => bench_peers::run(&rest),
        Some("goldens") => goldens::run(&rest),
        Some("figures") => figures::run(&rest),
        Some("web") => web::run(&rest),
        Some("consumer") => consumer::run(&rest),
        Some("python") => python::run(&rest),
        Some("help" | "-h" | "--help") => {
            println!("{USAGE}");
            Ok(())
        }
        Some(other) => Err(format!("unknown xtask `{other}`\n{USAGE}")),
        None => Err(USAGE.to_owned()),
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
