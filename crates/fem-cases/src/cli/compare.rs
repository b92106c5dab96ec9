//! `fem2d compare`: the energy x solver matrix on one scene, as markdown (printed), and
//! optionally markdown, CSV and JSON files.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use fem_cases::cases::load_case_or_file;
use fem_cases::compare::{CompareSpec, compare};
use fem_cases::run::write_atomic;
use fem_cases::scene::{SolverKind, XpbdFormName};
use fem_core::energy::EnergyKind;

use super::run::SceneArgs;

/// XPBD constraint forms on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Form {
    /// `C = sqrt(2 a psi)`.
    Consistent,
    /// `C = a psi` (the paper's text).
    Literal,
}

/// Flags of `fem2d compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Energies (comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "stvk,corotational,neo-hookean"
    )]
    pub energies: Vec<String>,
    /// Solvers (comma-separated): explicit, pbd, xpbd, implicit, static. Implicit and static do
    /// not handle contact (their rows on a scene with a ground or obstacles carry the error).
    #[arg(long, value_delimiter = ',', default_value = "explicit,pbd,xpbd")]
    pub solvers: Vec<String>,
    /// PBD/XPBD iteration counts to compare (comma-separated; default: the scene's).
    #[arg(long, value_delimiter = ',')]
    pub iterations: Vec<usize>,
    /// XPBD forms to compare (comma-separated; default: the scene's).
    #[arg(long, value_delimiter = ',', value_enum)]
    pub xpbd_forms: Vec<Form>,
    /// Worker threads per run (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write compare.md, compare.csv, compare.json and curves.csv (every row's probe curves)
    /// here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Runs `fem2d compare`.
pub fn run(args: &CompareArgs) -> Result<(), String> {
    let energies = args
        .energies
        .iter()
        .map(|e| {
            e.parse::<EnergyKind>()
                .map_err(|err| format!("--energies: {err}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let solvers = args
        .solvers
        .iter()
        .map(|s| {
            s.parse::<SolverKind>()
                .map_err(|err| format!("--solvers: {err}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(s) = solvers.iter().find(|s| !SolverKind::AVAILABLE.contains(s)) {
        let names: Vec<&str> = SolverKind::AVAILABLE.iter().map(|k| k.name()).collect();
        return Err(format!(
            "--solvers: `{s}` is not available in this version (available: {})",
            names.join(", ")
        ));
    }
    if let Some(0) = args.iterations.iter().copied().find(|&n| n == 0) {
        return Err("--iterations: 0 is not allowed (>= 1)".into());
    }
    let spec = CompareSpec {
        energies,
        solvers,
        iterations: args.iterations.clone(),
        xpbd_forms: args
            .xpbd_forms
            .iter()
            .map(|f| match f {
                Form::Consistent => XpbdFormName::Consistent,
                Form::Literal => XpbdFormName::Literal,
            })
            .collect(),
        threads: args.threads,
        snapshot_every: None,
    };
    let load = |extra: &[String]| {
        let mut o = extra.to_vec();
        o.extend(args.scene.set.iter().cloned());
        load_case_or_file(&args.scene.scene, &o)
    };
    // Fail early, before any run, when the scene itself is bad.
    load(&[]).map_err(|e| e.to_string())?;
    let table = compare(&load, &spec).map_err(|e| e.to_string())?;
    let md = table.to_markdown();
    print!("{md}");
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create the directory: {e}", dir.display()))?;
        write_atomic(&dir.join("compare.md"), md.as_bytes()).map_err(|e| e.to_string())?;
        write_atomic(&dir.join("compare.csv"), table.to_csv().as_bytes())
            .map_err(|e| e.to_string())?;
        write_atomic(&dir.join("compare.json"), table.to_json().as_bytes())
            .map_err(|e| e.to_string())?;
        write_atomic(&dir.join("curves.csv"), table.to_curves_csv().as_bytes())
            .map_err(|e| e.to_string())?;
        println!(
            "wrote compare.md, compare.csv, compare.json, curves.csv in {}",
            dir.display()
        );
    }
    Ok(())
}
