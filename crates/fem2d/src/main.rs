//! `fem2d`: the command line of the framework. Each subcommand lives in its own module under
//! [`cli`]; this file only parses the command line, dispatches, and turns errors into a one-line
//! message and a non-zero exit code.

mod cli;

use clap::{Parser, Subcommand};

/// 2D energy-based FEM prototyping framework.
#[derive(Debug, Parser)]
#[command(name = "fem2d", version, about)]
struct Fem2d {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run one scene (a built-in case or a scene file) under one energy and solver.
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Run(Box<cli::run::RunArgs>),
    /// The energy x solver matrix on one scene: probes, peak stress, cost, stability.
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Compare(Box<cli::compare::CompareArgs>),
    /// Which energy x framework fits a real-time frame (90 Hz, 5 ms by default), at which
    /// setting, and how wrong it is against a converged reference.
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Budget(Box<cli::budget::BudgetArgs>),
    /// The cost of a real-time frame against mesh size in 2D and 3D (case A; implicit Euler,
    /// XPBD and VBD), with a log-log chart.
    Scaling(Box<cli::scaling::ScalingArgs>),
    /// Regenerate the paper's Table 1 (case A) beside the paper's values; calibration scan.
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Table1(Box<cli::table1::Table1Args>),
    /// Run one shard of a parameter sweep (any batch scheduler can run the shards).
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Sweep(Box<cli::sweep::SweepArgs>),
    /// Join the shard files of a sweep into one table (JSON, CSV, markdown).
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Merge(Box<cli::sweep::MergeArgs>),
    /// Turn a 3D model (OBJ, STL, PLY or the built-in body) into a 2D FEM mesh.
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Mesh(Box<cli::mesh::MeshArgs>),
    /// Run cases A-D and write one self-contained HTML report (tables, figures, curves, animations).
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Report(Box<cli::report::ReportArgs>),
    /// Regenerate the paper's figures 1-5 and the plots (PNG and SVG).
    // Negative numbers are values (`--alpha -1` reaches validation, which names the flag).
    #[command(allow_negative_numbers = true)]
    Figures(Box<cli::report::FiguresArgs>),
}

fn main() -> std::process::ExitCode {
    let args = match Fem2d::try_parse() {
        Ok(args) => args,
        Err(e) if !e.use_stderr() => {
            // --help and --version.
            let _ = e.print();
            return std::process::ExitCode::SUCCESS;
        }
        Err(e) => {
            // clap's message spans several lines (usage, tips); the contract is one line.
            let text = e.to_string();
            let first = text.lines().next().unwrap_or("invalid arguments");
            let first = first.strip_prefix("error: ").unwrap_or(first);
            eprintln!("error: {first} (see fem2d --help)");
            return std::process::ExitCode::from(2);
        }
    };
    // An interruption leaves every output directory as it was before the command (see
    // fem_cases::outdir): the staging directories go, the previous outputs stay.
    let _ = ctrlc::set_handler(|| {
        fem_mesh::io::interrupted();
        let targets = fem_cases::outdir::interrupted();
        let names: Vec<String> = targets.iter().map(|t| t.display().to_string()).collect();
        if names.is_empty() {
            eprintln!("error: interrupted");
        } else {
            eprintln!("error: interrupted; {} left as it was", names.join(", "));
        }
        std::process::exit(130);
    });
    // A reader that goes away (`fem2d compare case-a | head -3`) makes the next print fail;
    // Rust's print macros then panic. That is not a bug to report: the command ends as if
    // interrupted, quietly, with the exit status of a process killed by SIGPIPE (128 + 13),
    // leaving every output directory as it was. Any other panic keeps the default report.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            fem_mesh::io::interrupted();
            fem_cases::outdir::interrupted();
            std::process::exit(141);
        }
        default_hook(info);
    }));
    // FEM2D_SIMD caps the instruction set of the force kernels; a value naming none is an
    // error rather than silently ignored.
    if let Err(message) = fem_core::simd::Isa::from_env() {
        eprintln!("error: {message}");
        return std::process::ExitCode::from(2);
    }
    let result = match args.command {
        Command::Run(a) => cli::run::run(&a),
        Command::Compare(a) => cli::compare::run(&a),
        Command::Budget(a) => cli::budget::run(&a),
        Command::Scaling(a) => cli::scaling::run(&a),
        Command::Table1(a) => cli::table1::run(&a),
        Command::Sweep(a) => cli::sweep::run_sweep(&a),
        Command::Merge(a) => cli::sweep::run_merge(&a),
        Command::Mesh(mesh) => cli::mesh::run(&mesh),
        Command::Report(a) => cli::report::run_report(&a),
        Command::Figures(a) => cli::report::run_figures(&a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {}", message.replace('\n', " "));
            std::process::ExitCode::FAILURE
        }
    }
}
