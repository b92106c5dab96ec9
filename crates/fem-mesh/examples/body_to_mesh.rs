//! Shows the whole pipeline as a library call: the procedural human body (or a model file given
//! on the command line) seen from the side, meshed with a max area and a min angle, then the
//! quality report, the stage times and the mesh JSON written next to the previews.
//!
//! Run: `cargo run -p fem-mesh --example body_to_mesh [-- MODEL.obj GROUP SCALE]`, for example
//! `cargo run -p fem-mesh --example body_to_mesh -- ../shared/fixtures/human/makehuman_base.obj body 0.1`.
//! Output goes to `out/body_to_mesh/`.

use std::path::{Path, PathBuf};

use fem_mesh::body::human_body;
use fem_mesh::load::{LoadOptions, load_model};
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::preview::{PreviewParams, write_previews};
use fem_mesh::triangulate::TriangulateParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut surface = match args.first() {
        Some(path) => {
            let groups = args.get(1).map(|g| vec![g.clone()]).unwrap_or_default();
            load_model(Path::new(path), &LoadOptions { groups })?
        }
        None => human_body(),
    };
    let scale: f64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(1.0);
    surface.scale(scale);

    // Every parameter spelled out: side view, suggested alpha radius, epsilon = radius / 4.
    let params = PipelineParams {
        triangulate: TriangulateParams {
            max_area: Some(2e-4),
            min_angle_deg: 25.0,
            max_steiner_points: 50_000,
        },
        ..PipelineParams::default()
    };
    let out = mesh_surface(surface, &params)?;
    println!(
        "alpha radius {:.4} (smallest single-component radius {:.4})",
        out.alpha.radius, out.alpha.suggestion.single_component_radius
    );
    print!("{}", out.quality);
    println!("stage times: {:?}", out.times);

    let dir = PathBuf::from("out/body_to_mesh");
    let stages = out.stages();
    write_previews(&dir, &stages, &PreviewParams::default())?;
    fem_mesh::io::write_mesh_json(&dir.join("mesh.json"), &out.mesh)?;
    println!("wrote {}", dir.display());
    Ok(())
}
