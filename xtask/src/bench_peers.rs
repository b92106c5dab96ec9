//! `cargo xtask bench-peers --peers DIR [--quick] [--out FILE]`: the explicit kernel of case A
//! against the same kernel written in NVIDIA Warp and Taichi, run side by side on this machine.
//!
//! `DIR` holds the peer scripts (`fem_warp.py`, `fem_taichi.py`: the case A beam, left edge
//! pinned, gravity, E = 1000 Pa, nu = 0.3, 1 kg, symplectic Euler, damping 1/s; each prints
//! one `RESULT {json}` line with `elem_steps_per_s`). Python is `$PEERS_VENV/bin/python`, by
//! default `~/.cache/peers-venv/bin/python` (the venv the scripts' `setup_venv.sh` makes).
//! Ours is `cargo run --release -p fem-solvers --example throughput -- --json`, the same beam.
//!
//! For Neo-Hookean and StVK at 16k, 64k and 256k triangles, one and two threads (Warp's CPU
//! backend is single-threaded), the three programs run in turn, [`ROUNDS`] rounds, and each
//! keeps its best (the shared VM's noise only ever slows a run down). One-thread runs are
//! pinned to one core (`taskset -c 1`). On an AVX-512 machine the one-thread rows also run ours
//! capped at AVX2 (`FEM2D_SIMD=avx2`), the path of machines without AVX-512. The table (markdown) goes to standard output, or to
//! `--out FILE`; `--quick` runs one round at 16k only (a smoke test).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

use crate::util::{build_release, command_line, cpu_name, write_atomic};

/// Alternating rounds per configuration.
pub const ROUNDS: usize = 3;
/// `(triangles, nx, ny, peer steps)`: the beam meshes (`2 nx ny` triangles) and how many
/// steps a peer run takes (about a second of work).
const SIZES: [(usize, usize, usize, usize); 3] = [
    (16_000, 200, 40, 4000),
    (64_000, 400, 80, 1000),
    (256_000, 800, 160, 250),
];
/// `(our name, the peers' name)`.
const ENERGIES: [(&str, &str); 2] = [("neo-hookean", "nh"), ("stvk", "stvk")];

/// Entry point: `args` are what follows `bench-peers`.
pub fn run(args: &[&str]) -> Result<(), String> {
    const USAGE: &str = "usage: cargo xtask bench-peers --peers DIR [--quick] [--out FILE]";
    let (mut peers, mut out, mut quick) = (None, None, false);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match *a {
            "--peers" => peers = Some(PathBuf::from(it.next().ok_or(USAGE)?)),
            "--out" => out = Some(PathBuf::from(it.next().ok_or(USAGE)?)),
            "--quick" => quick = true,
            other => return Err(format!("unknown flag `{other}`; {USAGE}")),
        }
    }
    let peers = peers.ok_or(USAGE)?;
    for script in ["fem_warp.py", "fem_taichi.py"] {
        if !peers.join(script).is_file() {
            return Err(format!("{}: no {script} there", peers.display()));
        }
    }
    let python = python()?;
    let ours = build_release(
        &["-p", "fem-solvers", "--example", "throughput"],
        "throughput",
    )?;
    let sizes: &[_] = if quick { &SIZES[..1] } else { &SIZES };
    let rounds = if quick { 1 } else { ROUNDS };

    let mut rows = Vec::new();
    let mut isa = String::from("?");
    for &(ours_energy, peer_energy) in &ENERGIES {
        for &(n, nx, ny, steps) in sizes {
            for threads in [1, 2] {
                let mut best = [0.0f64; 4];
                for _ in 0..rounds {
                    let r = run_ours(&ours, ours_energy, n, threads, None)?;
                    isa = r.1;
                    best[0] = best[0].max(r.0);
                    if threads == 1 && isa == "avx512" {
                        let r = run_ours(&ours, ours_energy, n, threads, Some("avx2"))?;
                        best[3] = best[3].max(r.0);
                    }
                    if threads == 1 {
                        let w = run_peer(
                            &python,
                            &peers,
                            "fem_warp.py",
                            peer_energy,
                            nx,
                            ny,
                            steps,
                            1,
                        )?;
                        best[1] = best[1].max(w);
                    }
                    let t = run_peer(
                        &python,
                        &peers,
                        "fem_taichi.py",
                        peer_energy,
                        nx,
                        ny,
                        steps,
                        threads,
                    )?;
                    best[2] = best[2].max(t);
                }
                eprintln!(
                    "{ours_energy} {n} x{threads}: ours {:.3e} (capped at avx2 {:.3e}), warp {:.3e}, taichi {:.3e}",
                    best[0], best[3], best[1], best[2]
                );
                rows.push((ours_energy, n, threads, best));
            }
        }
    }

    let mut md = String::new();
    let cpu = cpu_name().unwrap_or_else(|| "unknown CPU".into());
    let _ = writeln!(
        md,
        "Explicit case A beam, f64, element-steps per second, best of {rounds} alternating rounds \
         ({cpu}, {}; fem2d force kernel: {isa}, picked at run time from the default build). \
         One-thread runs pinned to one core; Warp's CPU backend is single-threaded.\n",
        command_line("date", &["-u", "+%Y-%m-%d"]).unwrap_or_default()
    );
    md.push_str(
        "| energy | triangles | threads | fem2d | Warp | Taichi | fem2d / Warp | fem2d / Taichi \
         | fem2d capped at AVX2 | AVX2 / Warp |\n",
    );
    md.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    let (fmt, ratio) = (
        |v: f64| {
            if v > 0.0 {
                format!("{v:.2e}")
            } else {
                "-".into()
            }
        },
        |a: f64, b: f64| {
            if a > 0.0 && b > 0.0 {
                format!("{:.2}", a / b)
            } else {
                "-".into()
            }
        },
    );
    for (energy, n, threads, [o, w, t, avx2]) in rows {
        let _ = writeln!(
            md,
            "| {energy} | {n} | {threads} | {} | {} | {} | {} | {} | {} | {} |",
            fmt(o),
            fmt(w),
            fmt(t),
            ratio(o, w),
            ratio(o, t),
            fmt(avx2),
            ratio(avx2, w)
        );
    }
    match out {
        Some(path) => write_atomic(&path, md.as_bytes()),
        None => {
            print!("{md}");
            Ok(())
        }
    }
}

fn python() -> Result<PathBuf, String> {
    let venv = std::env::var_os("PEERS_VENV")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/peers-venv")))
        .ok_or("set PEERS_VENV (the peers' virtual environment)")?;
    let py = venv.join("bin/python");
    if py.is_file() {
        Ok(py)
    } else {
        Err(format!(
            "{}: no Python there; make the venv with the peers' setup_venv.sh",
            py.display()
        ))
    }
}

/// `program args`, under `taskset -c 1` for one thread; the `RESULT` lines of its output.
fn results(
    program: &Path,
    args: &[String],
    threads: usize,
    simd_cap: Option<&str>,
) -> Result<Vec<Value>, String> {
    let mut cmd = if threads == 1 && command_line("taskset", &["-c", "1", "true"]).is_some() {
        let mut c = Command::new("taskset");
        c.args(["-c", "1"]).arg(program);
        c
    } else {
        Command::new(program)
    };
    if let Some(cap) = simd_cap {
        cmd.env("FEM2D_SIMD", cap);
    }
    let out = cmd
        .args(args)
        .output()
        .map_err(|e| format!("cannot run {}: {e}", program.display()))?;
    if !out.status.success() {
        return Err(format!(
            "{} {} failed ({}): {}",
            program.display(),
            args.join(" "),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("RESULT "))
        .map(|j| serde_json::from_str(j).map_err(|e| format!("bad RESULT line {j}: {e}")))
        .collect()
}

fn rate(v: &Value) -> Result<f64, String> {
    v.get("elem_steps_per_s")
        .and_then(Value::as_f64)
        .ok_or_else(|| format!("RESULT without elem_steps_per_s: {v}"))
}

/// Our rate and the instruction set the kernel ran under (`cap`: `FEM2D_SIMD`).
fn run_ours(
    exe: &Path,
    energy: &str,
    n: usize,
    threads: usize,
    cap: Option<&str>,
) -> Result<(f64, String), String> {
    let args = [
        "--threads",
        &threads.to_string(),
        "--sizes",
        &n.to_string(),
        "--energies",
        energy,
        "--skip-pbd",
        "--repeat",
        "1",
        "--seconds",
        "1",
        "--json",
    ]
    .map(str::to_owned);
    let r = results(exe, &args, threads, cap)?;
    let v = r
        .first()
        .ok_or("the throughput example printed no RESULT")?;
    let isa = v
        .get("isa")
        .and_then(Value::as_str)
        .unwrap_or("?")
        .to_owned();
    Ok((rate(v)?, isa))
}

#[allow(clippy::too_many_arguments)]
fn run_peer(
    python: &Path,
    dir: &Path,
    script: &str,
    energy: &str,
    nx: usize,
    ny: usize,
    steps: usize,
    threads: usize,
) -> Result<f64, String> {
    let mut args = vec![
        dir.join(script).display().to_string(),
        "--nx".into(),
        nx.to_string(),
        "--ny".into(),
        ny.to_string(),
        "--dt".into(),
        "5e-5".into(),
        "--steps".into(),
        steps.to_string(),
        "--model".into(),
        energy.into(),
        "--repeat".into(),
        "1".into(),
    ];
    if script.contains("taichi") {
        args.extend(["--threads".into(), threads.to_string()]);
    }
    let r = results(python, &args, threads, None)?;
    rate(
        r.first()
            .ok_or_else(|| format!("{script} printed no RESULT"))?,
    )
}
