//! `fem2d budget`: which energy x framework fits a real-time frame, at which setting, and how
//! wrong it is (see `fem_cases::budget`).

use std::path::PathBuf;

use clap::Args;
use fem_cases::budget::{BudgetRun, BudgetSpec, Cell, Framework, RankBy, budget, budget3};
use fem_cases::files::load_any;
use fem_cases::outdir::OutDir;
use fem_core::energy::EnergyKind;
use fem_scene::solid::AnyScene;

use super::run::SceneArgs;

/// Flags of `fem2d budget`.
#[derive(Debug, Args)]
pub struct BudgetArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Frames per second: every framework advances 1/fps per frame (default 90; 1000 with
    /// --haptics).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Physics budget per frame on one thread, ms (default 5; 0.5 with --haptics).
    #[arg(long = "budget-ms")]
    pub budget_ms: Option<f64>,
    /// The haptics preset: 1 kHz and 0.5 ms per frame.
    #[arg(long)]
    pub haptics: bool,
    /// Simulated seconds (default: the scene's steps x dt).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Energies (comma-separated; default all five).
    #[arg(long, value_delimiter = ',')]
    pub energies: Vec<String>,
    /// Frameworks (comma-separated; default all): explicit, pbd, xpbd, xpbd-small-steps, vbd,
    /// pd, quasi-newton, linear-implicit, implicit.
    #[arg(long, value_delimiter = ',')]
    pub frameworks: Vec<String>,
    /// The quantity to rank by: position, stress, stress-impact, pressure, pressure-impact
    /// (default: stress, the soft tissue's von Mises stress in the sustained phase, when the
    /// scene has material regions or contact; position otherwise).
    #[arg(long = "rank-by")]
    pub rank_by: Option<String>,
    /// The impact window ends when the reference's kinetic energy has fallen for good below
    /// this fraction of its peak (default 0.01).
    #[arg(long)]
    pub settle: Option<f64>,
    /// The relative error within which the sustained soft tissue stress and the peak contact
    /// pressure must stay (default 0.05).
    #[arg(long)]
    pub criterion: Option<f64>,
    /// Steps per frame of the reference, implicit Euler (default 10 with contact, 100
    /// without); its own error is estimated against half as many.
    #[arg(long = "reference-steps")]
    pub reference_steps: Option<u64>,
    /// The longest the comparison may take, in minutes of wall time (default 10:
    /// `fem2d budget case-a` takes about 1.5 minutes on a busy 2-core VM, `case-d` under one).
    /// Estimated from the step counts before anything runs, then from what was measured;
    /// past it the budget stops with an error saying which flag to change.
    #[arg(long = "max-minutes")]
    pub max_minutes: Option<f64>,
    /// Write budget.md, budget.csv, budget.json and the charts here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also write trajectories.json into --out: the layout, the windows and every trajectory
    /// the errors come from (large: about 1 MB per trajectory per 100 frames of a mesh of
    /// 1000 vertices).
    #[arg(long, requires = "out")]
    pub trajectories: bool,
}

/// Runs `fem2d budget`.
pub fn run(args: &BudgetArgs) -> Result<(), String> {
    let mut spec = if args.haptics {
        BudgetSpec::haptics()
    } else {
        BudgetSpec::default()
    };
    if let Some(f) = args.fps {
        spec.fps = f;
    }
    if let Some(b) = args.budget_ms {
        spec.budget_ms = b;
    }
    spec.duration = args.duration;
    if let Some(r) = &args.rank_by {
        spec.rank_by = Some(RankBy::parse(r).map_err(|err| format!("--rank-by: {err}"))?);
    }
    if let Some(x) = args.settle {
        spec.settle = x;
    }
    spec.reference_steps = args.reference_steps;
    if let Some(x) = args.criterion {
        spec.criterion = x;
    }
    if let Some(x) = args.max_minutes {
        spec.max_minutes = x;
    }
    if !args.energies.is_empty() {
        spec.energies = args
            .energies
            .iter()
            .map(|e| {
                e.parse::<EnergyKind>()
                    .map_err(|err| format!("--energies: {err}"))
            })
            .collect::<Result<_, _>>()?;
        twice("--energies", &args.energies)?;
    }
    if !args.frameworks.is_empty() {
        spec.frameworks = args
            .frameworks
            .iter()
            .map(|f| Framework::parse(f).map_err(|err| format!("--frameworks: {err}")))
            .collect::<Result<_, _>>()?;
        twice("--frameworks", &args.frameworks)?;
    }
    let base = load_any(&args.scene.scene, &args.scene.set).map_err(|e| e.to_string())?;
    // Take the output directory first, so a second writer fails before the runs.
    let out = match &args.out {
        Some(target) => Some(OutDir::begin(target).map_err(|e| e.to_string())?),
        None => None,
    };
    let progress = |what: &str| eprintln!("budget: {what}");
    match base {
        AnyScene::Two(base) => finish(
            budget(&base, &spec, progress).map_err(|e| e.to_string())?,
            out,
            args,
        ),
        AnyScene::Three(base) => finish(
            budget3(&base, &spec, progress).map_err(|e| e.to_string())?,
            out,
            args,
        ),
    }
}

/// Print the table and write the outputs of either dimension's budget.
fn finish<C: Cell>(
    result: BudgetRun<C>,
    out: Option<OutDir>,
    args: &BudgetArgs,
) -> Result<(), String> {
    print!("{}", result.budget.to_markdown());
    if let (Some(out), Some(target)) = (out, &args.out) {
        let written = result
            .write(out.path(), args.trajectories)
            .map_err(|e| e.to_string())?;
        out.commit().map_err(|e| e.to_string())?;
        println!("wrote {} in {}", written.join(", "), target.display());
    }
    Ok(())
}

/// A name listed twice in a comma-separated flag is an error naming the flag as written
/// (`--frameworks implicit,implicit: implicit is listed twice`): the rows would repeat.
fn twice(flag: &str, names: &[String]) -> Result<(), String> {
    for (k, name) in names.iter().enumerate() {
        if names[..k].contains(name) {
            return Err(format!(
                "{flag} {}: {name} is listed twice",
                names.join(",")
            ));
        }
    }
    Ok(())
}
