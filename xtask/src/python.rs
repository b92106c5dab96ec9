//! `cargo xtask python [--bench] [--no-test]`: the Python package `pyfem2d` (crates/fem-py)
//! built and tested as a user installs it.
//!
//! - creates a virtual environment in `target/python-venv/` (or `$CARGO_TARGET_DIR/...`) with
//!   the machine's `python3` (or `$PYTHON`), and installs maturin, numpy, pytest and meshio
//!   into it from the Python package index (once; a later run reuses them);
//! - builds the extension in release with `maturin develop --release` into that environment
//!   (the release `fem2d` binary first: the tests compare with it, and the two builds share
//!   the workspace's crates);
//! - runs the pytest tests of `crates/fem-py/tests`;
//! - `--bench`: runs `crates/fem-py/bench/overhead.py`, the per-step overhead of driving
//!   scenes from Python against the same steps in Rust.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{Fem2d, root};

/// What the environment needs from the Python package index.
const PACKAGES: [&str; 4] = ["maturin>=1.5,<2", "numpy", "pytest", "meshio"];

pub fn run(args: &[&str]) -> Result<(), String> {
    let mut bench = false;
    let mut test = true;
    for a in args {
        match *a {
            "--bench" => bench = true,
            "--no-test" => test = false,
            other => {
                return Err(format!(
                    "unknown argument `{other}` (usage: cargo xtask python [--bench] [--no-test])"
                ));
            }
        }
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target"));
    let venv = target.join("python-venv");
    let python = venv.join("bin").join("python");
    if !python.exists() {
        let system = std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_owned());
        run_cmd(
            Command::new(&system).args(["-m", "venv"]).arg(&venv),
            &format!("{system} -m venv {}", venv.display()),
        )?;
    }
    let have = Command::new(&python)
        .args(["-c", "import maturin, numpy, pytest, meshio"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
        && venv.join("bin").join("maturin").exists();
    if !have {
        let mut cmd = Command::new(&python);
        cmd.args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
        ])
        .args(PACKAGES);
        run_cmd(&mut cmd, &format!("pip install {}", PACKAGES.join(" ")))?;
    }
    let fem2d = Fem2d::build()?;
    let crate_dir = root().join("crates").join("fem-py");
    let path = format!(
        "{}:{}",
        venv.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let with_env = |cmd: &mut Command| {
        cmd.current_dir(&crate_dir)
            .env("VIRTUAL_ENV", &venv)
            .env("PATH", &path)
            .env("CARGO_TARGET_DIR", &target)
            .env("FEM2D_BIN", &fem2d.exe);
    };
    let mut cmd = Command::new(venv.join("bin").join("maturin"));
    cmd.args(["develop", "--release", "--quiet"]);
    with_env(&mut cmd);
    run_cmd(&mut cmd, "maturin develop --release (crates/fem-py)")?;
    if test {
        let mut cmd = Command::new(&python);
        cmd.args(["-m", "pytest", "tests", "-q", "-p", "no:cacheprovider"]);
        with_env(&mut cmd);
        run_cmd(&mut cmd, "pytest crates/fem-py/tests")?;
    }
    if bench {
        let mut cmd = Command::new(&python);
        cmd.arg(Path::new("bench").join("overhead.py"));
        with_env(&mut cmd);
        run_cmd(&mut cmd, "python crates/fem-py/bench/overhead.py")?;
    }
    Ok(())
}

fn run_cmd(cmd: &mut Command, what: &str) -> Result<(), String> {
    eprintln!("$ {what}");
    let status = cmd
        .status()
        .map_err(|e| format!("cannot run `{what}`: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("`{what}` failed ({status})"))
    }
}
