//! `cargo xtask bench-cases [--quick] [--out DIR]`: every built-in case (A-D) x energy x
//! solver on one thread, timed by `fem2d compare` (best of 3), written to
//! `docs/bench-cases.json` and `docs/bench-cases.md`.
//!
//! Each case runs `fem2d compare CASE --energies E,... --threads 1 --out TMP` (compare's default
//! solvers: the paper's frameworks, from the solver registry)
//! [`REPEATS`] times; every row keeps the repeat with the smallest `step_seconds` (the least
//! disturbed: the wall time of the steps alone, recording and mesh building excluded), with
//! that repeat's element-steps per second and real-time factor. The two targets of the issue
//! are checked and highlighted: case A, 2000 steps per energy under 20 ms on one core; case D,
//! a real-time factor of at least 2 on one core.
//!
//! `--quick` is a smoke test (one repeat, a tenth of the steps); it prints the markdown and
//! writes the files only into `--out DIR` when given, never into `docs/`.

use std::fmt::Write as _;
use std::path::PathBuf;

use serde_json::{Value, json};

use crate::util::{
    Fem2d, TempDir, array, command_line, cpu_name, num, read_json, root, text, write_atomic,
};

/// The cases, in order.
pub const CASES: [&str; 4] = ["case-a", "case-b", "case-c", "case-d"];
/// Every energy `fem2d` knows.
pub const ENERGIES: &str = "stvk,corotational,neo-hookean,stable-neo-hookean,linear";
/// Timing repeats per case (the best is kept per row).
pub const REPEATS: usize = 3;
/// Case A target: 2000 steps per energy under this many seconds on one core.
pub const CASE_A_SECONDS: f64 = 0.020;
/// Case D target: real-time factor at least this on one core.
pub const CASE_D_RTF: f64 = 2.0;

/// Entry point: `args` are what follows `bench-cases`.
pub fn run(args: &[&str]) -> Result<(), String> {
    let mut quick = false;
    let mut out: Option<PathBuf> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match *a {
            "--quick" => quick = true,
            "--out" => {
                out = Some(PathBuf::from(
                    it.next().ok_or("--out needs a directory")?.to_owned(),
                ));
            }
            other => {
                return Err(format!(
                    "unknown flag `{other}`; usage: cargo xtask bench-cases [--quick] [--out DIR]"
                ));
            }
        }
    }
    let fem2d = Fem2d::build()?;
    let repeats = if quick { 1 } else { REPEATS };
    let mut cases = Vec::new();
    for case in CASES {
        cases.push(bench_case(&fem2d, case, repeats, quick)?);
    }
    let machine = machine();
    let targets = targets(&cases, quick);
    let report = json!({
        "generated_by": format!("cargo xtask bench-cases{}", if quick { " --quick" } else { "" }),
        "machine": machine,
        "command": format!("fem2d compare CASE --energies {ENERGIES} --threads 1 --out DIR"),
        "repeats": repeats,
        "quick": quick,
        "timing": "per row, the repeat with the smallest step_seconds (wall time of the steps alone, s)",
        "targets": targets,
        "cases": cases,
    });
    let md = markdown(&report)?;
    let json_text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())? + "\n";
    let dir = match (out, quick) {
        (Some(d), _) => Some(d),
        (None, false) => Some(root().join("docs")),
        (None, true) => None,
    };
    match dir {
        Some(d) => {
            write_atomic(&d.join("bench-cases.json"), json_text.as_bytes())?;
            write_atomic(&d.join("bench-cases.md"), md.as_bytes())?;
        }
        None => print!("{md}"),
    }
    Ok(())
}

/// The row key: energy, solver, variant.
fn key(row: &Value) -> (String, String, String) {
    let s = |k: &str| row[k].as_str().unwrap_or_default().to_owned();
    (s("energy"), s("solver"), s("variant"))
}

fn bench_case(fem2d: &Fem2d, case: &str, repeats: usize, quick: bool) -> Result<Value, String> {
    let mut best: Vec<Value> = Vec::new();
    let mut header = Value::Null;
    let mut unstable_changed = Vec::new();
    for r in 0..repeats {
        eprintln!("bench-cases: {case}, repeat {} of {repeats}", r + 1);
        let dir = TempDir::new("bench-cases")?;
        let out = dir.arg();
        let mut args = vec![
            "compare",
            case,
            "--energies",
            ENERGIES,
            "--threads",
            "1",
            "--out",
            &out,
        ];
        let steps;
        if quick {
            // A tenth of each scene's steps (case D: 10000 -> 1000).
            steps = format!("solver.steps={}", if case == "case-d" { 1000 } else { 200 });
            args.extend(["--set", &steps]);
        }
        fem2d.run(&args)?;
        let cmp = read_json(&dir.path().join("compare.json"))?;
        if header.is_null() {
            header = json!({
                "scene_solver": cmp["scene_solver"],
                "triangles": cmp["triangles"],
                "dt": cmp["dt"],
                "steps": cmp["steps"],
            });
        }
        for row in array(&cmp, "rows")? {
            let row = json!({
                "energy": row["energy"],
                "solver": row["solver"],
                "variant": row["variant"],
                "stable": row["stable"],
                "steps_completed": row["steps_completed"],
                "step_seconds": row["step_seconds"],
                "element_steps_per_second": row["element_steps_per_second"],
                "real_time_factor": row["real_time_factor"],
                "error": row["error"],
            });
            match best.iter_mut().find(|b| key(b) == key(&row)) {
                None => best.push(row),
                Some(b) => {
                    if b["stable"] != row["stable"] {
                        unstable_changed.push(format!("{:?}", key(&row)));
                    }
                    if num(&row, "step_seconds")? < num(b, "step_seconds")? {
                        *b = row;
                    }
                }
            }
        }
    }
    if !unstable_changed.is_empty() {
        return Err(format!(
            "{case}: stability differed between repeats of a deterministic run: {}",
            unstable_changed.join(", ")
        ));
    }
    Ok(json!({
        "case": case,
        "scene_solver": header["scene_solver"],
        "triangles": header["triangles"],
        "dt": header["dt"],
        "steps": header["steps"],
        "rows": best,
    }))
}

fn machine() -> Value {
    let nproc = command_line("nproc", &[])
        .and_then(|s| s.parse::<u64>().ok())
        .or_else(|| {
            std::thread::available_parallelism()
                .ok()
                .map(|n| n.get() as u64)
        });
    let cpu = cpu_name().unwrap_or_else(|| "unknown".into());
    json!({
        "nproc": nproc,
        "cpu": cpu,
        "date": command_line("date", &["-u", "+%Y-%m-%d"]).unwrap_or_else(|| "unknown".into()),
        "rustc": command_line("rustc", &["--version"]).unwrap_or_else(|| "unknown".into()),
        "os": command_line("uname", &["-srm"]).unwrap_or_else(|| std::env::consts::OS.into()),
    })
}

fn find_case<'a>(cases: &'a [Value], name: &str) -> Option<&'a Value> {
    cases.iter().find(|c| c["case"] == name)
}

/// The rows of the solver the case's scene names (its targets are stated for that solver).
fn scene_solver_rows(case: &Value) -> Vec<&Value> {
    case["rows"]
        .as_array()
        .map(|rows| {
            rows.iter()
                .filter(|r| r["solver"] == case["scene_solver"])
                .collect()
        })
        .unwrap_or_default()
}

fn targets(cases: &[Value], quick: bool) -> Value {
    let a = find_case(cases, "case-a").map(|c| {
        let rows: Vec<Value> = scene_solver_rows(c)
            .iter()
            .map(|r| {
                let s = r["step_seconds"].as_f64().unwrap_or(f64::NAN);
                json!({
                    "energy": r["energy"],
                    "ms": 1e3 * s,
                    "stable": r["stable"],
                    "met": r["stable"] == true && s < CASE_A_SECONDS,
                })
            })
            .collect();
        let met = !rows.is_empty() && rows.iter().all(|r| r["met"] == true);
        json!({
            "target": "case A (explicit): 2000 steps per energy under 20 ms on one core",
            "steps": c["steps"],
            "met": if quick { Value::Null } else { Value::Bool(met) },
            "per_energy": rows,
        })
    });
    let d = find_case(cases, "case-d").map(|c| {
        let rows: Vec<Value> = scene_solver_rows(c)
            .iter()
            .map(|r| {
                let f = r["real_time_factor"].as_f64().unwrap_or(0.0);
                json!({
                    "energy": r["energy"],
                    "real_time_factor": f,
                    "stable": r["stable"],
                    "met": r["stable"] == true && f >= CASE_D_RTF,
                })
            })
            .collect();
        let scene = rows
            .iter()
            .find(|r| r["energy"] == "neo-hookean")
            .map(|r| r["met"] == true)
            .unwrap_or(false);
        json!({
            "target": "case D (the scene: Neo-Hookean, explicit): real-time factor >= 2 on one core",
            "met": if quick { Value::Null } else { Value::Bool(scene) },
            "per_energy": rows,
        })
    });
    json!({ "case_a_2000_steps_under_20_ms": a, "case_d_real_time_factor_at_least_2": d })
}

fn yes_no(v: &Value) -> &'static str {
    match v.as_bool() {
        Some(true) => "**yes**",
        Some(false) => "**no**",
        None => "not judged (--quick)",
    }
}

fn markdown(report: &Value) -> Result<String, String> {
    let mut w = String::new();
    let m = &report["machine"];
    let quick = report["quick"] == true;
    let _ = writeln!(w, "# Cases A-D: every energy x solver on one thread\n");
    let _ = writeln!(
        w,
        "<!-- Generated by `{}`; do not edit by hand. -->\n",
        text(report, "generated_by")?
    );
    if quick {
        let _ = writeln!(
            w,
            "**Quick smoke run: one repeat, a tenth of the steps. Not a measurement.**\n"
        );
    }
    let _ = writeln!(
        w,
        "Machine: {} cores (`nproc`), {}, {}; {}; measured {}. Every run uses one worker \
thread (`--threads 1`); the process is not pinned to a core, and other work on the machine \
can slow a repeat down, which is why each row keeps the fastest of {} repeats.\n",
        m["nproc"],
        text(m, "cpu")?,
        text(m, "os")?,
        text(m, "rustc")?,
        text(m, "date")?,
        report["repeats"]
    );
    let _ = writeln!(
        w,
        "Per case: `{}` (release build), {} time(s). Step time = wall time of the steps alone \
(mesh building, probes, stress recording and output excluded), the smallest over the \
repeats. Element-steps/s = triangles x steps / step time. Real-time factor = simulated \
seconds / step time. Stable = the run finished without blowing up (a non-finite state or a \
runaway displacement). PBD and XPBD use each scene's iteration count (10 unless the scene \
says otherwise). Regenerate with `cargo xtask bench-cases`.\n",
        text(report, "command")?,
        report["repeats"]
    );

    let t = &report["targets"];
    let _ = writeln!(w, "## The two targets\n");
    let a = &t["case_a_2000_steps_under_20_ms"];
    let _ = writeln!(
        w,
        "**Case A: 2000 steps per energy under 20 ms on one core (explicit)**: met: {}.\n",
        yes_no(&a["met"])
    );
    let _ = writeln!(
        w,
        "| energy | {} steps (ms) | under 20 ms |\n|---|---:|---|",
        a["steps"]
    );
    for r in a["per_energy"].as_array().into_iter().flatten() {
        let _ = writeln!(
            w,
            "| {} | {:.2} | {} |",
            text(r, "energy")?,
            num(r, "ms")?,
            if r["met"] == true { "yes" } else { "**no**" }
        );
    }
    let d = &t["case_d_real_time_factor_at_least_2"];
    let _ = writeln!(
        w,
        "\n**Case D: real-time factor >= 2 on one core (the scene: Neo-Hookean, explicit)**: met: {}.\n",
        yes_no(&d["met"])
    );
    let _ = writeln!(
        w,
        "| energy (explicit) | real-time factor | >= 2 |\n|---|---:|---|"
    );
    for r in d["per_energy"].as_array().into_iter().flatten() {
        let _ = writeln!(
            w,
            "| {}{} | {:.2} | {} |",
            text(r, "energy")?,
            if r["energy"] == "neo-hookean" {
                " (the scene)"
            } else {
                ""
            },
            num(r, "real_time_factor")?,
            if r["met"] == true { "yes" } else { "**no**" }
        );
    }
    if let Some(case_d) = array(report, "cases")?
        .iter()
        .find(|c| c["case"] == "case-d")
    {
        let others: Vec<f64> = array(case_d, "rows")?
            .iter()
            .filter(|r| r["solver"] != case_d["scene_solver"])
            .filter_map(|r| r["real_time_factor"].as_f64())
            .collect();
        if !others.is_empty() {
            let lo = others.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = others.iter().copied().fold(0.0, f64::max);
            let _ = writeln!(
                w,
                "\nPBD and XPBD on case D (scene iteration count): real-time factor {lo:.2} to {hi:.2}; {} of {} reach 2.",
                others.iter().filter(|f| **f >= CASE_D_RTF).count(),
                others.len()
            );
        }
    }
    w.push('\n');

    for case in array(report, "cases")? {
        let _ = writeln!(
            w,
            "## {}\n\n{} triangles, dt = {:e} s, {} steps ({} s simulated).\n",
            text(case, "case")?,
            case["triangles"],
            num(case, "dt")?,
            case["steps"],
            num(case, "dt")? * num(case, "steps")?
        );
        let variants = array(case, "rows")?
            .iter()
            .any(|r| r["variant"].as_str().is_some_and(|v| !v.is_empty()));
        let _ = writeln!(
            w,
            "| energy | solver |{} stable | step time (ms) | element-steps/s | real-time factor |\n|---|---|{}---|---:|---:|---:|",
            if variants { " variant |" } else { "" },
            if variants { "---|" } else { "" }
        );
        let mut errors = Vec::new();
        for r in array(case, "rows")? {
            let _ = writeln!(
                w,
                "| {} | {} |{} {} | {:.2} | {:.3e} | {:.2} |",
                text(r, "energy")?,
                text(r, "solver")?,
                if variants {
                    format!(" {} |", r["variant"].as_str().unwrap_or_default())
                } else {
                    String::new()
                },
                if r["stable"] == true {
                    "yes".to_owned()
                } else {
                    format!("**no** (step {})", r["steps_completed"])
                },
                1e3 * num(r, "step_seconds")?,
                num(r, "element_steps_per_second")?,
                num(r, "real_time_factor")?
            );
            if let Some(e) = r["error"].as_str() {
                let short: String = e.chars().take(300).collect();
                errors.push(format!(
                    "- {} / {}: {}{}",
                    text(r, "energy")?,
                    text(r, "solver")?,
                    short,
                    if short.len() < e.len() { " ..." } else { "" }
                ));
            }
        }
        if !errors.is_empty() {
            let _ = writeln!(w, "\n{}", errors.join("\n"));
        }
        w.push('\n');
    }
    Ok(w)
}
