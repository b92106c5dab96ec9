//! `fem2d run`: one scene (a built-in case or a scene file) under one energy and solver; writes
//! `summary.json`, `probes.csv`, `frames.jsonl`, `mesh.json` and `scene.toml` into `--out`.

use std::path::PathBuf;

use clap::Args;
use fem_cases::cases::load_case_or_file;
use fem_cases::run::{RunOptions, run_scene};

/// Options shared by every command that loads a scene.
#[derive(Debug, Args, Clone)]
pub struct SceneArgs {
    /// A built-in case (case-a, case-b, case-c, case-d) or a scene file (.toml).
    pub scene: String,
    /// Override a scene value: the key is its path in the scene file
    /// (`--set material.youngs_modulus=2000`, `--set obstacles.0.mass=50`). Repeatable; applied
    /// after --energy, --solver, --dt and --steps.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

/// Flags of `fem2d run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Energy: stvk, corotational, neo-hookean, stable-neo-hookean, linear (default: the scene's).
    #[arg(long)]
    pub energy: Option<String>,
    /// Solver: explicit, pbd, xpbd (default: the scene's).
    #[arg(long)]
    pub solver: Option<String>,
    /// Time step, s (default: the scene's).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Number of steps (default: the scene's).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// The overrides of the common flags, then the user's `--set`s.
pub fn overrides(
    energy: Option<&str>,
    solver: Option<&str>,
    dt: Option<f64>,
    steps: Option<u64>,
    set: &[String],
) -> Vec<String> {
    let mut o = Vec::new();
    if let Some(e) = energy {
        o.push(format!("energy=\"{e}\""));
    }
    if let Some(s) = solver {
        o.push(format!("solver.kind=\"{s}\""));
    }
    if let Some(dt) = dt {
        o.push(format!("solver.dt={dt:e}"));
    }
    if let Some(n) = steps {
        o.push(format!("solver.steps={n}"));
    }
    o.extend(set.iter().cloned());
    o
}

/// Runs `fem2d run`.
pub fn run(args: &RunArgs) -> Result<(), String> {
    let overrides = overrides(
        args.energy.as_deref(),
        args.solver.as_deref(),
        args.dt,
        args.steps,
        &args.scene.set,
    );
    let scene = load_case_or_file(&args.scene.scene, &overrides).map_err(|e| e.to_string())?;
    let result = run_scene(
        &scene,
        &RunOptions {
            out_dir: Some(args.out.clone()),
            threads: args.threads,
            progress: !args.quiet,
        },
    )
    .map_err(|e| e.to_string())?;
    let s = &result.summary;
    if let Some(w) = &s.time_step_warning {
        eprintln!("warning: {w}");
    }
    println!(
        "{}: {} / {}, {} triangles, {} steps of {:e} s in {:.3} s ({:.3e} element-steps/s, real-time factor {:.2})",
        s.scene,
        s.energy,
        s.solver,
        s.triangles,
        s.steps_completed,
        s.dt,
        s.step_seconds,
        s.element_steps_per_second,
        s.real_time_factor
    );
    println!(
        "max von Mises {:.4e} Pa (step {}, element {} at [{:.3}, {:.3}] m), min det F {:.4}, inverted elements {}",
        s.max_von_mises,
        s.max_von_mises_step,
        s.max_von_mises_element,
        s.max_von_mises_at[0],
        s.max_von_mises_at[1],
        s.min_det_f,
        s.inverted_elements
    );
    for p in &s.probes {
        println!(
            "probe {}: vertex {} at [{}, {}], final displacement [{:.6}, {:.6}] m",
            p.name,
            p.vertex,
            p.rest[0],
            p.rest[1],
            p.final_displacement[0],
            p.final_displacement[1]
        );
    }
    println!(
        "wrote summary.json, probes.csv, mesh.json, scene.toml{} in {}",
        if scene.scene.output.frames {
            ", frames.jsonl"
        } else {
            ""
        },
        args.out.display()
    );
    match &s.blow_up_message {
        Some(m) => Err(format!(
            "the run blew up: {m} (outputs up to that point are in {})",
            args.out.display()
        )),
        None => Ok(()),
    }
}
