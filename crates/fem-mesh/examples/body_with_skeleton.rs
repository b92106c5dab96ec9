//! Shows the pipeline with a skeleton: the procedural body and its bones seen from the side and
//! from the front with case D's mesh parameters (alpha radius 0.02 m, epsilon 0.012 m, max area
//! 8e-4 m^2, min angle 30 degrees), the area of every region, the bones' clearance to the skin,
//! and a picture of each mesh coloured by region; then the same numbers for the lower-leg
//! close-up (`fem_mesh::shank`) at its suggested parameters.
//!
//! Run: `cargo run -p fem-mesh --example body_with_skeleton`. Output goes to
//! `out/body_with_skeleton/` (`side.png`, `front.png` with the png feature, and the mesh JSON).

use std::path::PathBuf;

use fem_mesh::alpha::AlphaParams;
use fem_mesh::body::{human_body, human_skeleton};
use fem_mesh::camera::Camera;
use fem_mesh::pipeline::{PipelineParams, mesh_surface_with_skeleton};
use fem_mesh::triangulate::TriangulateParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from("out/body_with_skeleton");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for (name, camera) in [("side", Camera::side(5.0)), ("front", Camera::front(5.0))] {
        let params = PipelineParams {
            camera,
            alpha: AlphaParams {
                radius: Some(0.02),
                ..AlphaParams::default()
            },
            epsilon: Some(0.012),
            triangulate: TriangulateParams {
                max_area: Some(8e-4),
                min_angle_deg: 30.0,
                ..TriangulateParams::default()
            },
            ..PipelineParams::default()
        };
        let out = mesh_surface_with_skeleton(human_body(), &human_skeleton(), &params)?;
        let mesh = &out.mesh;
        println!(
            "{name}: {} triangles, {} vertices, {} component(s), pipeline {:.3} s (triangulate {:.3} s), bone clearance {:.4} m",
            mesh.triangles.len(),
            mesh.vertices.len(),
            mesh.edge_components(),
            out.times.total().as_secs_f64(),
            out.times.triangulate.as_secs_f64(),
            out.bone_clearance.unwrap_or(f64::NAN),
        );
        println!("  {:?}", out.triangulate_report);
        for (k, region) in mesh.region_names.iter().enumerate() {
            println!(
                "  region {k} {region:<12} area {:.6e} m^2, {} component(s)",
                mesh.region_area(k as u32),
                mesh.region_components(k as u32)
            );
        }
        fem_mesh::io::write_mesh_json(&dir.join(format!("{name}.json")), mesh)?;
        #[cfg(feature = "png")]
        {
            use fem_mesh::preview::{Canvas, PreviewParams};
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for p in &mesh.vertices {
                lo = [lo[0].min(p[0]), lo[1].min(p[1])];
                hi = [hi[0].max(p[0]), hi[1].max(p[1])];
            }
            let mut canvas = Canvas::new(
                lo,
                hi,
                &PreviewParams {
                    height_px: 900,
                    ..PreviewParams::default()
                },
            );
            let colours: [[u8; 3]; 8] = [
                [240, 190, 170],
                [250, 250, 230],
                [120, 160, 220],
                [200, 120, 200],
                [230, 200, 80],
                [90, 190, 120],
                [240, 130, 60],
                [150, 150, 150],
            ];
            for t in 0..mesh.triangles.len() {
                let c = mesh.corners(t);
                let colour = colours[mesh.region_of(t) as usize % colours.len()];
                canvas.fill(&[&c[..]], colour);
            }
            for t in 0..mesh.triangles.len() {
                let c = mesh.corners(t);
                for k in 0..3 {
                    canvas.line(c[k], c[(k + 1) % 3], [60, 60, 60]);
                }
            }
            let png = canvas.to_png()?;
            fem_mesh::io::write_atomic(&dir.join(format!("{name}.png")), &png)?;
        }
    }
    let (skin, tibia) = fem_mesh::shank::shank_section();
    let start = std::time::Instant::now();
    let (mesh, report) = fem_mesh::triangulate::triangulate_regions(
        std::slice::from_ref(&skin),
        &tibia,
        &fem_mesh::shank::shank_params(),
    )?;
    println!(
        "shank: {} triangles, {} vertices in {:.3} s; soft tissue {:.6e} m^2 (outline {:.6e}), tibia {:.6e} m^2 (outline {:.6e})",
        mesh.triangles.len(),
        mesh.vertices.len(),
        start.elapsed().as_secs_f64(),
        mesh.region_area(0),
        skin.area() - tibia[0].area(),
        mesh.region_area(1),
        tibia[0].area(),
    );
    println!("  {report:?}");
    fem_mesh::io::write_mesh_json(&dir.join("shank.json"), &mesh)?;
    println!("wrote {}", dir.display());
    Ok(())
}
