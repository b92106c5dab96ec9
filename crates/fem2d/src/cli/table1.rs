//! `fem2d table1`: the paper's Table 1 regenerated from case A, beside the paper's values;
//! `--calibrate` scans the settings the paper does not state, `--sensitivity` varies each
//! around the scene's setting.

use std::path::PathBuf;

use clap::Args;
use fem_cases::run::write_atomic;
use fem_cases::table1::{
    CalibrationGrid, calibrate, calibration_markdown, scene_setting, sensitivity, table1,
};

/// Flags of `fem2d table1`.
#[derive(Debug, Args)]
pub struct Table1Args {
    /// Timing repeats per energy (the best is reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Worker threads. Default 1: the paper's timings are compared per core, and a 160-triangle
    /// mesh gains nothing from more threads (they only add synchronisation).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override a case A value (see `fem2d run --help`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Print JSON instead of markdown.
    #[arg(long)]
    pub json: bool,
    /// Scan mesh, diagonal, damping and tip node; print the best settings.
    #[arg(long)]
    pub calibrate: bool,
    /// With --calibrate: how many settings to print.
    #[arg(long, default_value_t = 15)]
    pub top: usize,
    /// Vary each factor alone around the scene's setting.
    #[arg(long)]
    pub sensitivity: bool,
    /// Also write the output to this file.
    #[arg(long, short = 'o', value_name = "PATH")]
    pub output: Option<PathBuf>,
}

/// Runs `fem2d table1`.
pub fn run(args: &Table1Args) -> Result<(), String> {
    let mut text = String::new();
    if args.calibrate {
        let grid = CalibrationGrid::default();
        let rows = calibrate(&grid).map_err(|e| e.to_string())?;
        let good = rows.iter().filter(|r| r.ordering).count();
        let within = rows
            .iter()
            .filter(|r| r.ordering && r.max_relative_10_to_120 <= 0.10)
            .count();
        text.push_str(&format!(
            "Calibration scan: {} settings x 3 energies; {good} keep the paper's ordering (gaps >= 3 mm at frames 120 and 200), {within} of them also within 10% at frames 10-120.\n\n",
            rows.len()
        ));
        text.push_str(&calibration_markdown(&rows, args.top));
    } else if args.sensitivity {
        let base = scene_setting(&args.set).map_err(|e| e.to_string())?;
        text.push_str(&format!(
            "Sensitivity around {}x{} cells, {} diagonals, c = {} 1/s, tip [{}, {}] m: one factor varied at a time.\n",
            base.cells[0], base.cells[1], base.diagonal.name(), base.damping, base.tip[0], base.tip[1]
        ));
        text.push_str(&sensitivity(&base, &CalibrationGrid::default()).map_err(|e| e.to_string())?);
    } else {
        let table = table1(&args.set, args.repeats, Some(args.threads.unwrap_or(1)))
            .map_err(|e| e.to_string())?;
        text = if args.json {
            serde_json::to_string_pretty(&table).map_err(|e| e.to_string())? + "\n"
        } else {
            table.to_markdown()
        };
    }
    print!("{text}");
    if let Some(path) = &args.output {
        write_atomic(path, text.as_bytes()).map_err(|e| e.to_string())?;
    }
    Ok(())
}
