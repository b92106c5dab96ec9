//! `fem2d scaling`: the cost of a real-time frame against mesh size, in 2D and in 3D (case A;
//! implicit Euler, XPBD and VBD; see `fem_cases::scaling`).

use std::path::PathBuf;

use clap::Args;
use fem_cases::outdir::OutDir;
use fem_cases::scaling::{ScalingSpec, scaling};

/// Flags of `fem2d scaling`.
#[derive(Debug, Args)]
pub struct ScalingArgs {
    /// Frames per second: one step of 1/fps a frame (default 90).
    #[arg(long)]
    pub fps: Option<f64>,
    /// The frame budget drawn on the chart, ms (default 5).
    #[arg(long = "budget-ms", default_value_t = 5.0)]
    pub budget_ms: f64,
    /// A quick measurement: smaller meshes, 3 frames, one repeat (a few seconds).
    #[arg(long)]
    pub quick: bool,
    /// Write scaling.md, scaling.json, scaling.svg and scaling.png here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Runs `fem2d scaling`.
pub fn run(args: &ScalingArgs) -> Result<(), String> {
    let mut spec = if args.quick {
        ScalingSpec::quick()
    } else {
        ScalingSpec::full()
    };
    if let Some(f) = args.fps {
        if !(f.is_finite() && f > 0.0 && f <= 1e6) {
            return Err(format!("--fps {f}: must be a finite number in (0, 1e6]"));
        }
        spec.fps = f;
    }
    if !(args.budget_ms.is_finite() && args.budget_ms > 0.0) {
        return Err(format!(
            "--budget-ms {}: must be a finite number > 0",
            args.budget_ms
        ));
    }
    // Take the output directory first, so a second writer fails before the runs.
    let out = match &args.out {
        Some(target) => Some(OutDir::begin(target).map_err(|e| e.to_string())?),
        None => None,
    };
    let result = scaling(&spec, |what| eprintln!("scaling: {what}")).map_err(|e| e.to_string())?;
    let md = result.to_markdown();
    print!("{md}");
    if let (Some(out), Some(target)) = (out, &args.out) {
        let chart = result.chart(args.budget_ms);
        let render = |e: fem_render::RenderError| e.to_string();
        let svg = chart.to_svg().map_err(render)?;
        let png = chart.to_png().map_err(render)?.to_png().map_err(render)?;
        let json = serde_json::to_string_pretty(&result).map_err(|e| e.to_string())?;
        let write = |name: &str, bytes: &[u8]| {
            fem_cases::run::write_atomic(&out.path().join(name), bytes).map_err(|e| e.to_string())
        };
        write("scaling.md", md.as_bytes())?;
        write("scaling.json", json.as_bytes())?;
        write("scaling.svg", svg.as_bytes())?;
        write("scaling.png", &png)?;
        out.commit().map_err(|e| e.to_string())?;
        println!(
            "wrote scaling.md, scaling.json, scaling.svg, scaling.png in {}",
            target.display()
        );
    }
    Ok(())
}
