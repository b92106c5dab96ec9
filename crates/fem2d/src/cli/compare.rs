//! `fem2d compare`: the energy x solver matrix on one scene, as markdown (printed), and
//! optionally markdown, CSV and JSON files.
//!
//! The scene may be 2D or 3D (`dim = 3`, e.g. `case-a-3d`): its `dim` key decides
//! ([`fem_cases::files::load_any`]), and a 3D scene runs the same matrix through
//! [`fem_cases::compare::compare3`] (three-component probes; a solver without a 3D path is an
//! error row). Every flag applies to both dimensions.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use fem_cases::compare::{CompareSpec, VariantAxis, compare, compare3};
use fem_cases::files::load_any;
use fem_cases::outdir::OutDir;
use fem_cases::run::write_atomic;
use fem_core::energy::EnergyKind;
use fem_scene::solid::AnyScene;
use fem_solvers::SolverKind;

use super::run::SceneArgs;

/// XPBD constraint forms on the command line (the values of the `xpbd_form` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Form {
    /// `C = sqrt(2 a psi)`.
    Consistent,
    /// `C = a psi` (the paper's text).
    Literal,
}

impl Form {
    fn value(self) -> &'static str {
        match self {
            Form::Consistent => "consistent",
            Form::Literal => "literal",
        }
    }
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
    /// Solvers (comma-separated): explicit, pbd, xpbd, implicit, static, vbd, pd, quasi-newton,
    /// linear-implicit (default: the paper's frameworks, explicit, pbd and xpbd). A solver
    /// without contact (pd; see docs/solvers.md) gives an error row on a scene with a ground or
    /// obstacles.
    #[arg(long, value_delimiter = ',')]
    pub solvers: Vec<String>,
    /// Iteration counts to compare, for the solvers that iterate (comma-separated; default:
    /// the scene's).
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
    let solvers = if args.solvers.is_empty() {
        SolverKind::ALL
            .into_iter()
            .filter(|k| k.capabilities().paper)
            .collect()
    } else {
        args.solvers
            .iter()
            .map(|s| {
                s.parse::<SolverKind>()
                    .map_err(|err| format!("--solvers: {err}"))
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    if let Some(0) = args.iterations.iter().copied().find(|&n| n == 0) {
        return Err("--iterations: 0 is not allowed (>= 1)".into());
    }
    // The forms first, so a row reads `consistent, 20 it`.
    let variants = vec![
        VariantAxis {
            key: "xpbd_form".into(),
            values: args.xpbd_forms.iter().map(|f| f.value().into()).collect(),
        },
        VariantAxis {
            key: "iterations".into(),
            values: args
                .iterations
                .iter()
                .map(|&n| toml::Value::Integer(n as i64))
                .collect(),
        },
    ];
    let spec = CompareSpec {
        energies,
        solvers,
        variants,
        threads: args.threads,
        snapshot_every: None,
    };
    // Fails before any run when the scene itself is bad.
    let base = load_any(&args.scene.scene, &args.scene.set).map_err(|e| e.to_string())?;
    let table = match base {
        AnyScene::Two(base) => compare(&base, &spec),
        AnyScene::Three(base) => compare3(&base, &spec),
    }
    .map_err(|e| e.to_string())?;
    let md = table.to_markdown();
    print!("{md}");
    if let Some(target) = &args.out {
        let out = OutDir::begin(target).map_err(|e| e.to_string())?;
        let dir = out.path();
        write_atomic(&dir.join("compare.md"), md.as_bytes()).map_err(|e| e.to_string())?;
        write_atomic(&dir.join("compare.csv"), table.to_csv().as_bytes())
            .map_err(|e| e.to_string())?;
        write_atomic(&dir.join("compare.json"), table.to_json().as_bytes())
            .map_err(|e| e.to_string())?;
        write_atomic(&dir.join("curves.csv"), table.to_curves_csv().as_bytes())
            .map_err(|e| e.to_string())?;
        out.commit().map_err(|e| e.to_string())?;
        println!(
            "wrote compare.md, compare.csv, compare.json, curves.csv in {}",
            target.display()
        );
    }
    Ok(())
}
