//! `cargo xtask bench-cases [--quick] [--out DIR]`: every built-in case (A-D) x energy x
//! solver on one thread, timed by `fem2d compare` (best of 3), written to
//! `docs/bench-cases.json` and `docs/bench-cases.md`.
//!
//! Each bench ([`BENCHES`]) runs `fem2d compare CASE --energies E,... [--solvers S,...]
//! [--set KEY=VALUE ...] --threads 1 --out TMP` [`REPEATS`] times; every row keeps the repeat
//! with the smallest `step_seconds` (the least disturbed: the wall time of the steps alone,
//! recording and mesh building excluded), with that repeat's element-steps per second and
//! real-time factor. Case D is benched twice: the scene as it is (the body with its bones,
//! implicit Euler with barrier contact at 1/90 s, beside VBD and the paper's frameworks at the
//! same step) and the paper's homogeneous body stepped explicitly at 0.1 ms. The targets are
//! checked and highlighted: case A, 2000 steps per energy under 20 ms on one core (explicit);
//! the homogeneous case D, a real-time factor of at least 2 on one core (explicit); case D with
//! bones, real time (a factor of at least 1) on one core under the scene's solver.
//!
//! `--quick` is a smoke test (one repeat, a tenth of the steps); it prints the markdown and
//! writes the files only into `--out DIR` when given, never into `docs/`.

use std::fmt::Write as _;
use std::path::PathBuf;

use serde_json::{Value, json};

use crate::util::{
    Fem2d, TempDir, array, command_line, cpu_name, num, read_json, root, text, write_atomic,
};

/// One benched configuration: a built-in case with overrides and the solvers it compares.
pub struct Bench {
    /// The name of the bench in the report.
    pub name: &'static str,
    /// The built-in case it runs.
    pub case: &'static str,
    /// `--set KEY=VALUE` overrides, applied to every row.
    pub sets: &'static [&'static str],
    /// `--solvers` (comma-separated); `None`: compare's default, the paper's frameworks.
    pub solvers: Option<&'static str>,
    /// The steps a `--quick` smoke run takes (about a tenth of the scene's).
    pub quick_steps: u64,
    /// What the bench is, in a sentence for the report.
    pub about: &'static str,
}

/// The benches, in order.
pub const BENCHES: [Bench; 5] = [
    Bench {
        name: "case-a",
        case: "case-a",
        sets: &[],
        solvers: None,
        quick_steps: 200,
        about: "The paper's cantilever under gravity.",
    },
    Bench {
        name: "case-b",
        case: "case-b",
        sets: &[],
        solvers: None,
        quick_steps: 300,
        about: "The paper's bar, stretched.",
    },
    Bench {
        name: "case-c",
        case: "case-c",
        sets: &[],
        solvers: None,
        quick_steps: 200,
        about: "The paper's cantilever, StVK under its three frameworks.",
    },
    Bench {
        name: "case-d",
        case: "case-d",
        sets: &[],
        solvers: Some("implicit,vbd,explicit,pbd,xpbd"),
        quick_steps: 13,
        about: "The scene as it is: the body with its rigid bones under a falling slab, every \
solver at the scene's step, 1/90 s. Implicit Euler (the scene's) and VBD use barrier contact; \
explicit FEM's critical step is the soft tissue's, 35 us, so at 1/90 s it blows up within a \
few steps; PBD and XPBD take one substep of the scene's iterations a frame (how wrong they are, and at which setting each framework fits a \
real-time frame, `fem2d budget case-d` says: [budget.md](budget.md)).",
    },
    Bench {
        name: "case-d-homogeneous",
        case: "case-d",
        sets: &[
            "regions=[]",
            "mesh.skeleton=false",
            "solver.kind=\"explicit\"",
            "solver.dt=1e-4",
            "solver.steps=10000",
        ],
        solvers: None,
        quick_steps: 1000,
        about: "The paper's case D: the same body without bones (one material, 1.85 MPa), \
stepped at the paper's 0.1 ms under its three frameworks (`--set regions=[] --set \
mesh.skeleton=false --set solver.kind=\"explicit\" --set solver.dt=1e-4 --set \
solver.steps=10000`).",
    },
];
/// Every energy `fem2d` knows.
pub const ENERGIES: &str = "stvk,corotational,neo-hookean,stable-neo-hookean,linear";
/// Timing repeats per case (the best is kept per row).
pub const REPEATS: usize = 3;
/// Case A target: 2000 steps per energy under this many seconds on one core.
pub const CASE_A_SECONDS: f64 = 0.020;
/// The homogeneous case D's target: real-time factor at least this on one core (explicit).
pub const CASE_D_RTF: f64 = 2.0;
/// Real time: a real-time factor at least this (case D with bones, the scene's solver).
pub const REAL_TIME: f64 = 1.0;

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
    for bench in &BENCHES {
        cases.push(bench_case(&fem2d, bench, repeats, quick)?);
    }
    let machine = machine();
    let targets = targets(&cases, quick);
    let report = json!({
        "generated_by": format!("cargo xtask bench-cases{}", if quick { " --quick" } else { "" }),
        "machine": machine,
        "command": format!(
            "fem2d compare CASE --energies {ENERGIES} [--solvers S,...] [--set KEY=VALUE ...] --threads 1 --out DIR"
        ),
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

/// The `fem2d compare` arguments of one repeat of `bench` (without `--out`).
fn compare_args(bench: &Bench, quick: bool) -> Vec<String> {
    let mut args: Vec<String> = [
        "compare",
        bench.case,
        "--energies",
        ENERGIES,
        "--threads",
        "1",
    ]
    .map(String::from)
    .to_vec();
    if let Some(s) = bench.solvers {
        args.extend(["--solvers".into(), s.into()]);
    }
    for set in bench.sets {
        args.extend(["--set".into(), (*set).into()]);
    }
    if quick {
        // Applied after the bench's own overrides.
        args.extend([
            "--set".into(),
            format!("solver.steps={}", bench.quick_steps),
        ]);
    }
    args
}

fn bench_case(fem2d: &Fem2d, bench: &Bench, repeats: usize, quick: bool) -> Result<Value, String> {
    let name = bench.name;
    let mut best: Vec<Value> = Vec::new();
    let mut header = Value::Null;
    let mut unstable_changed = Vec::new();
    let base_args = compare_args(bench, quick);
    for r in 0..repeats {
        eprintln!("bench-cases: {name}, repeat {} of {repeats}", r + 1);
        let dir = TempDir::new("bench-cases")?;
        let out = dir.arg();
        let mut args: Vec<&str> = base_args.iter().map(String::as_str).collect();
        args.extend(["--out", &out]);
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
            "{name}: stability differed between repeats of a deterministic run: {}",
            unstable_changed.join(", ")
        ));
    }
    Ok(json!({
        "case": name,
        "scene": bench.case,
        "about": bench.about,
        "command": format!("fem2d {}", base_args.join(" ")),
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

/// A real-time factor target on the scene solver's rows of `case`, judged on Neo-Hookean (the
/// scene's energy).
fn rtf_target(case: &Value, target: &str, at_least: f64, quick: bool) -> Value {
    let rows: Vec<Value> = scene_solver_rows(case)
        .iter()
        .map(|r| {
            let f = r["real_time_factor"].as_f64().unwrap_or(0.0);
            json!({
                "energy": r["energy"],
                "real_time_factor": f,
                "stable": r["stable"],
                "met": r["stable"] == true && f >= at_least,
            })
        })
        .collect();
    let scene = rows
        .iter()
        .find(|r| r["energy"] == "neo-hookean")
        .map(|r| r["met"] == true)
        .unwrap_or(false);
    json!({
        "target": target,
        "at_least": at_least,
        "solver": case["scene_solver"],
        "met": if quick { Value::Null } else { Value::Bool(scene) },
        "per_energy": rows,
    })
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
        rtf_target(
            c,
            "case D with bones (the scene: Neo-Hookean, implicit Euler at 1/90 s): real time (real-time factor >= 1) on one core",
            REAL_TIME,
            quick,
        )
    });
    let h = find_case(cases, "case-d-homogeneous").map(|c| {
        rtf_target(
            c,
            "case D without bones (the paper's: Neo-Hookean, explicit at 0.1 ms): real-time factor >= 2 on one core",
            CASE_D_RTF,
            quick,
        )
    });
    json!({
        "case_a_2000_steps_under_20_ms": a,
        "case_d_real_time": d,
        "case_d_homogeneous_real_time_factor_at_least_2": h,
    })
}

fn yes_no(v: &Value) -> &'static str {
    match v.as_bool() {
        Some(true) => "**yes**",
        Some(false) => "**no**",
        None => "not judged (--quick)",
    }
}

/// A real-time factor target's heading and per-energy table.
fn rtf_target_markdown(w: &mut String, heading: &str, t: &Value) -> Result<(), String> {
    let at_least = num(t, "at_least")?;
    let _ = writeln!(w, "\n**{heading}**: met: {}.\n", yes_no(&t["met"]));
    let _ = writeln!(
        w,
        "| energy ({}) | real-time factor | >= {at_least} |\n|---|---:|---|",
        t["solver"].as_str().unwrap_or("scene's solver")
    );
    for r in t["per_energy"].as_array().into_iter().flatten() {
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
    Ok(())
}

/// One sentence: which rows of `case` (every solver) reach a real-time factor of `at_least`.
fn reaching(case: &Value, at_least: f64) -> Result<String, String> {
    let rows = array(case, "rows")?;
    let fast: Vec<String> = rows
        .iter()
        .filter(|r| r["stable"] == true)
        .filter(|r| {
            r["real_time_factor"]
                .as_f64()
                .is_some_and(|f| f >= at_least)
        })
        .map(|r| {
            format!(
                "{} / {}",
                text(r, "energy").unwrap_or("?"),
                text(r, "solver").unwrap_or("?")
            )
        })
        .collect();
    let unstable = rows.iter().filter(|r| r["stable"] != true).count();
    Ok(format!(
        "Rows of {} that are stable and reach a real-time factor of {at_least}: {} of {}{}{}.",
        text(case, "case")?,
        fast.len(),
        rows.len(),
        if fast.is_empty() {
            String::new()
        } else {
            format!(" ({})", fast.join(", "))
        },
        if unstable > 0 {
            format!("; {unstable} rows are not stable")
        } else {
            String::new()
        }
    ) + " Stable and fast is not accurate: how far each framework's motion and stress are \
from a converged reference at a real-time setting is the frame budget's question \
([budget.md](budget.md)).")
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
        "Per case: `{}` (release build), {} time(s); each case below gives its own command. \
Step time = wall time of the steps alone (mesh building, probes, stress recording and output \
excluded), the smallest over the repeats. Element-steps/s = triangles x steps / step time. \
Real-time factor = simulated seconds / step time. Stable = the run finished without blowing \
up (a non-finite state, a runaway displacement or a failed step). PBD, XPBD and VBD use each \
scene's iteration count (10 unless the scene says otherwise). Regenerate with `cargo xtask \
bench-cases`.\n",
        text(report, "command")?,
        report["repeats"]
    );

    let t = &report["targets"];
    let _ = writeln!(w, "## The targets\n");
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
    let d = &t["case_d_real_time"];
    if !d.is_null() {
        rtf_target_markdown(
            &mut w,
            "Case D with bones: real time on one core (the scene: Neo-Hookean, implicit Euler with barrier contact at 1/90 s)",
            d,
        )?;
    }
    if let Some(case_d) = array(report, "cases")?
        .iter()
        .find(|c| c["case"] == "case-d")
    {
        let _ = writeln!(w, "\n{}", reaching(case_d, REAL_TIME)?);
    }
    let h = &t["case_d_homogeneous_real_time_factor_at_least_2"];
    if !h.is_null() {
        rtf_target_markdown(
            &mut w,
            "Case D without bones (the paper's: Neo-Hookean, explicit at 0.1 ms): real-time factor >= 2 on one core",
            h,
        )?;
    }
    if let Some(case_h) = array(report, "cases")?
        .iter()
        .find(|c| c["case"] == "case-d-homogeneous")
    {
        let _ = writeln!(w, "\n{}", reaching(case_h, CASE_D_RTF)?);
    }
    w.push('\n');

    for case in array(report, "cases")? {
        let _ = writeln!(
            w,
            "## {}\n\n{} {} triangles, dt = {:e} s, {} steps ({} s simulated), scene solver {}: `{}`.\n",
            text(case, "case")?,
            text(case, "about")?,
            case["triangles"],
            num(case, "dt")?,
            case["steps"],
            num(case, "dt")? * num(case, "steps")?,
            text(case, "scene_solver")?,
            text(case, "command")?
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
