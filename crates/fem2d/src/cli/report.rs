//! `fem2d report` (cases A-D, Table 1, figures, curves, animations and metadata in one HTML
//! page) and `fem2d figures` (the paper's figures and the plots, as PNG and SVG files).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use fem_cases::figures::{run_cases, write_figures};
use fem_cases::outdir::{FilesInto, OutDir};
use fem_cases::report::{ReportOptions, write_report};

/// Flags of `fem2d report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Output directory: `index.html` and `figures/` (created if missing).
    #[arg(long, value_name = "DIR", default_value = "report")]
    pub out: PathBuf,
    /// Worker threads per run (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Skip the case B stability sweep (156 short runs).
    #[arg(long)]
    pub no_stability: bool,
    /// Skip the animations.
    #[arg(long)]
    pub no_animations: bool,
    /// Skip the frame budget of cases A and D (about 40 s on one core).
    #[arg(long)]
    pub no_budget: bool,
}

/// Flags of `fem2d figures`.
#[derive(Debug, Args)]
pub struct FiguresArgs {
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR", default_value = "docs/figures")]
    pub out: PathBuf,
    /// Worker threads per run (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

fn check_threads(threads: Option<usize>) -> Result<(), String> {
    if threads == Some(0) {
        return Err("--threads 0: must be >= 1".into());
    }
    if let Some(n) = threads.filter(|&n| n > fem_cases::run::MAX_THREADS) {
        return Err(format!(
            "--threads {n}: must be at most {}",
            fem_cases::run::MAX_THREADS
        ));
    }
    Ok(())
}

/// Runs `fem2d report`.
pub fn run_report(args: &ReportArgs) -> Result<(), String> {
    check_threads(args.threads)?;
    let command = std::env::args()
        .enumerate()
        .map(|(i, a)| if i == 0 { "fem2d".to_owned() } else { a })
        .collect::<Vec<_>>()
        .join(" ");
    let options = ReportOptions {
        threads: args.threads,
        stability: !args.no_stability,
        animations: !args.no_animations,
        budget: !args.no_budget,
        command,
        date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
    };
    let out = OutDir::begin(&args.out).map_err(|e| e.to_string())?;
    let summary = write_report(out.path(), &options, |what| eprintln!("report: {what}..."))
        .map_err(|e| e.to_string())?;
    out.commit().map_err(|e| e.to_string())?;
    println!(
        "wrote {} ({:.1} MB, {} pictures) in {:.1} s; open it in a browser",
        args.out.join("index.html").display(),
        summary.bytes as f64 / 1e6,
        summary.figures.len(),
        summary.wall_seconds
    );
    Ok(())
}

/// Runs `fem2d figures`.
pub fn run_figures(args: &FiguresArgs) -> Result<(), String> {
    check_threads(args.threads)?;
    let start = Instant::now();
    // All pictures or none; the directory's other files stay.
    let out = FilesInto::begin(&args.out).map_err(|e| e.to_string())?;
    let runs = run_cases(args.threads, true, |what| eprintln!("figures: {what}..."))
        .map_err(|e| e.to_string())?;
    let figures = write_figures(&runs, out.path()).map_err(|e| e.to_string())?;
    out.commit(None).map_err(|e| e.to_string())?;
    for f in &figures {
        println!("{}: {}", args.out.join(&f.file).display(), f.title);
    }
    println!(
        "wrote {} pictures in {:.1} s",
        figures.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
