//! `fem2d mesh`: model -> mesh with every pipeline parameter as a flag, the quality report,
//! per-stage timings and optional preview images of each stage (the paper's Figure 1).

use std::path::PathBuf;

use clap::Args;
use fem_mesh::alpha::{AlphaParams, Components};
use fem_mesh::body::human_body;
use fem_mesh::camera::{Camera, Projection, ProjectionParams};
use fem_mesh::io::{Staged, mesh_to_gmsh, mesh_to_json, mesh_to_vtk};
use fem_mesh::load::{LoadOptions, load_model};
use fem_mesh::pipeline::{PipelineOutput, PipelineParams, mesh_surface};
use fem_mesh::preview::{PREVIEW_FILES, PreviewParams, write_previews};
use fem_mesh::triangulate::TriangulateParams;
use fem_scene::build::preset_camera;
use fem_scene::scene::ViewName as View;

/// Flags of `fem2d mesh`. Lengths are in model units times `--scale` (metres for the built-in
/// body and for the MakeHuman body with `--scale 0.1`).
#[derive(Debug, Args)]
pub struct MeshArgs {
    /// Model file (.obj, .stl, .ply). Omit with --builtin-body.
    #[arg(
        required_unless_present = "builtin_body",
        conflicts_with = "builtin_body"
    )]
    pub input: Option<PathBuf>,
    /// Use the procedural human body (1.7 m, metres, +Y up) instead of a file.
    #[arg(long)]
    pub builtin_body: bool,
    /// OBJ only: keep faces of this group or object (repeatable; default every face).
    #[arg(long = "group", short = 'g', value_name = "NAME")]
    pub groups: Vec<String>,
    /// Scale factor applied to the model (0.1: decimetres to metres).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Preset camera direction; the focal point is the model's bounding-box centre.
    #[arg(long, value_parser = parse_view, default_value = "side")]
    pub view: View,
    /// Camera position c as X,Y,Z (overrides the preset).
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub camera_position: Option<[f64; 3]>,
    /// Focal point f as X,Y,Z (overrides the preset).
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub focal_point: Option<[f64; 3]>,
    /// Up vector u as X,Y,Z (overrides the preset).
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub up: Option<[f64; 3]>,
    /// Perspective projection instead of orthographic.
    #[arg(long)]
    pub perspective: bool,
    /// Merge projected points closer than this distance (besides points within 1e-9 of the
    /// drawing's size, which always merge).
    #[arg(long, default_value_t = 0.0)]
    pub merge_distance: f64,
    /// Alpha-shape radius: keep Delaunay triangles with circumradius below it. Default: the
    /// suggested radius, which is printed.
    #[arg(long)]
    pub alpha: Option<f64>,
    /// Factor on the smallest single-component radius when suggesting a radius.
    #[arg(long, default_value_t = 1.1)]
    pub alpha_margin: f64,
    /// Keep every component of the alpha shape (default: only the largest).
    #[arg(long)]
    pub all_components: bool,
    /// Fill enclosed holes whose triangles all have a circumradius below this multiple of the
    /// alpha radius (1 disables).
    #[arg(long, default_value_t = 2.0)]
    pub fill_holes_below: f64,
    /// Douglas-Peucker tolerance. Default: --epsilon-per-radius times the alpha radius.
    #[arg(long)]
    pub epsilon: Option<f64>,
    /// Tolerance as a fraction of the alpha radius when --epsilon is not given.
    #[arg(long, default_value_t = 0.25)]
    pub epsilon_per_radius: f64,
    /// Largest triangle area (default: no bound).
    #[arg(long)]
    pub max_area: Option<f64>,
    /// Smallest requested triangle angle in degrees.
    #[arg(long, default_value_t = 25.0)]
    pub min_angle: f64,
    /// Most Steiner points refinement may insert.
    #[arg(long, default_value_t = 50_000)]
    pub max_steiner: usize,
    /// Write the mesh JSON here.
    #[arg(long, short = 'o', value_name = "PATH")]
    pub output: Option<PathBuf>,
    /// Also export a Gmsh .msh 2.2 ASCII file.
    #[arg(long, value_name = "PATH")]
    pub msh: Option<PathBuf>,
    /// Also export a legacy VTK file.
    #[arg(long, value_name = "PATH")]
    pub vtk: Option<PathBuf>,
    /// Write a preview image of each stage (and all four side by side) into this directory.
    #[arg(long, value_name = "DIR")]
    pub preview: Option<PathBuf>,
    /// Height of each preview panel in pixels.
    #[arg(long, default_value_t = 600)]
    pub preview_height: usize,
    /// Exit with an error when the requested quality (angle, area) was not met.
    #[arg(long)]
    pub require_quality: bool,
}

fn parse_vec3(text: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got {text:?}"));
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("component {p:?} of {text:?} is not a finite number"))?;
    }
    Ok(v)
}

/// The numeric flags, checked before anything is loaded so each error names its flag.
fn check_flags(args: &MeshArgs) -> Result<(), String> {
    let positive = |flag: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(format!("{flag} {v}: must be a finite number > 0"))
        }
    };
    let non_negative = |flag: &str, v: f64| {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(format!("{flag} {v}: must be a finite number >= 0"))
        }
    };
    positive("--scale", args.scale)?;
    non_negative("--merge-distance", args.merge_distance)?;
    if let Some(a) = args.alpha {
        positive("--alpha", a)?;
    }
    positive("--alpha-margin", args.alpha_margin)?;
    non_negative("--fill-holes-below", args.fill_holes_below)?;
    if let Some(e) = args.epsilon {
        non_negative("--epsilon", e)?;
    }
    positive("--epsilon-per-radius", args.epsilon_per_radius)?;
    if let Some(a) = args.max_area {
        positive("--max-area", a)?;
    }
    if !(args.min_angle.is_finite() && (0.0..60.0).contains(&args.min_angle)) {
        return Err(format!(
            "--min-angle {}: must lie in [0, 60) degrees",
            args.min_angle
        ));
    }
    let max = fem_mesh::triangulate::MAX_STEINER_POINTS;
    if args.max_steiner > max {
        return Err(format!(
            "--max-steiner {}: must be at most {max}",
            args.max_steiner
        ));
    }
    if args.preview_height == 0 || args.preview_height > 8192 {
        return Err(format!(
            "--preview-height {}: must lie between 1 and 8192 pixels",
            args.preview_height
        ));
    }
    Ok(())
}

/// Runs `fem2d mesh`; errors are one-line messages.
pub fn run(args: &MeshArgs) -> Result<(), String> {
    check_flags(args)?;
    let (mut surface, source) = match (&args.input, args.builtin_body) {
        (_, true) => (human_body(), "built-in body".to_string()),
        (Some(path), false) => {
            let options = LoadOptions {
                groups: args.groups.clone(),
            };
            let start = std::time::Instant::now();
            let s = load_model(path, &options).map_err(|e| e.to_string())?;
            eprintln!("loaded {} in {:.1} ms", path.display(), ms(start.elapsed()));
            (s, path.display().to_string())
        }
        (None, false) => return Err("give a model file or --builtin-body".into()),
    };
    if !(args.scale.is_finite() && args.scale > 0.0) {
        return Err(format!("--scale must be positive, got {}", args.scale));
    }
    surface.scale(args.scale);
    let camera = camera_for(args, &surface)?;
    let params = PipelineParams {
        load: LoadOptions::default(),
        scale: 1.0,
        camera,
        projection: ProjectionParams {
            merge_distance: args.merge_distance,
            ..ProjectionParams::default()
        },
        alpha: AlphaParams {
            radius: args.alpha,
            auto_margin: args.alpha_margin,
            components: if args.all_components {
                Components::All
            } else {
                Components::Largest
            },
            fill_holes_below: args.fill_holes_below,
        },
        epsilon: args.epsilon,
        epsilon_per_radius: args.epsilon_per_radius,
        triangulate: TriangulateParams {
            max_area: args.max_area,
            min_angle_deg: args.min_angle,
            max_steiner_points: args.max_steiner,
        },
    };
    println!(
        "model: {source}: {} vertices, {} triangles",
        surface.vertices.len(),
        surface.triangles.len()
    );
    if args.min_angle > 30.0 {
        eprintln!(
            "warning: --min-angle {} is above 30 degrees, where Delaunay refinement is not \
             guaranteed to terminate; it will stop at --max-steiner points",
            args.min_angle
        );
    }
    // Pipeline errors name the stage; the model is named here.
    let out = mesh_surface(surface, &params).map_err(|e| format!("{source}: {e}"))?;
    print_summary(&out);

    if !out.triangulate_report.quality_met() {
        let t = &out.triangulate_report;
        let what = format!(
            "requested quality not met (min angle {:.2} deg, max area {:.4e}, refinement complete: {})",
            t.min_angle_deg, t.max_area, t.refinement_complete
        );
        // Checked before any mesh file is written: with --require-quality a failed run leaves
        // no mesh behind.
        if args.require_quality {
            return Err(what);
        }
        eprintln!("warning: {what}");
    }
    // All or none: the mesh files are staged (written beside their names), the previews
    // drawn, and only then are the files renamed into place.
    let mut outputs: Vec<(&str, &PathBuf, String)> = Vec::new();
    if let Some(path) = &args.output {
        outputs.push(("-o", path, mesh_to_json(&out.mesh)));
    }
    if let Some(path) = &args.msh {
        outputs.push(("--msh", path, mesh_to_gmsh(&out.mesh)));
    }
    if let Some(path) = &args.vtk {
        outputs.push(("--vtk", path, mesh_to_vtk(&out.mesh)));
    }
    for (k, (flag, path, _)) in outputs.iter().enumerate() {
        if let Some((other, _, _)) = outputs[..k].iter().find(|(_, p, _)| p == path) {
            return Err(format!(
                "{flag} {}: the same file as {other}; give each output its own path",
                path.display()
            ));
        }
    }
    let mut staged = Vec::new();
    for (_, path, text) in &outputs {
        staged.push(Staged::write(path, text.as_bytes()).map_err(|e| e.to_string())?);
    }
    if let Some(dir) = &args.preview {
        let stages = out.stages();
        let preview = PreviewParams {
            height_px: args.preview_height,
            ..PreviewParams::default()
        };
        write_previews(dir, &stages, &preview).map_err(|e| e.to_string())?;
    }
    for s in staged {
        s.commit().map_err(|e| e.to_string())?;
    }
    for (_, path, _) in &outputs {
        println!("wrote {}", path.display());
    }
    if let Some(dir) = &args.preview {
        println!("wrote {} in {}", PREVIEW_FILES.join(", "), dir.display());
    }
    Ok(())
}

fn camera_for(args: &MeshArgs, surface: &fem_mesh::Surface3) -> Result<Camera, String> {
    let (lo, hi) = surface
        .bounds()
        .ok_or_else(|| "the model has no vertex".to_string())?;
    let preset = preset_camera(args.view, lo, hi);
    let focal = args.focal_point.unwrap_or(preset.focal_point);
    // A moved focal point keeps the preset's viewing direction and distance.
    let position = args
        .camera_position
        .unwrap_or([0, 1, 2].map(|k| preset.position[k] - preset.focal_point[k] + focal[k]));
    let camera = Camera {
        position,
        focal_point: focal,
        up: args.up.unwrap_or(preset.up),
        projection: if args.perspective {
            Projection::Perspective
        } else {
            Projection::Orthographic
        },
    };
    camera.basis().map_err(|e| e.to_string())?;
    Ok(camera)
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn print_summary(out: &PipelineOutput) {
    let a = &out.alpha;
    println!(
        "projected points: {} distinct (from {} vertices)",
        out.points.len(),
        out.surface_vertices
    );
    let s = &a.suggestion;
    println!(
        "alpha radius: {:.6} ({}; suggested {:.6} = smallest single-component radius {:.6} x margin; median point spacing {:.6}; override with --alpha)",
        a.radius,
        if a.radius_was_suggested {
            "suggested"
        } else {
            "given"
        },
        s.radius,
        s.single_component_radius,
        s.median_spacing
    );
    println!(
        "alpha shape: {} component(s), total area {:.6e}, kept {}, {} small hole(s) filled, {} pinch triangle(s) removed",
        a.component_count,
        a.total_area,
        a.polygons.len(),
        a.holes_filled,
        a.pinch_triangles_removed
    );
    for (i, r) in out.simplify_reports.iter().enumerate() {
        println!(
            "simplify polygon {i}: {} -> {} vertices at epsilon {:.6} (requested {:.6})",
            r.vertices_before, r.vertices_after, r.epsilon_used, out.epsilon
        );
        for note in &r.notes {
            println!("  note: {note}");
        }
    }
    let t = &out.triangulate_report;
    println!(
        "refinement: {} Steiner points, complete: {}, min angle {:.2} deg (met: {}), max area {:.4e} (met: {}), smallest input corner {:.2} deg",
        t.steiner_points,
        t.refinement_complete,
        t.min_angle_deg,
        t.min_angle_met,
        t.max_area,
        t.max_area_met,
        t.smallest_input_angle_deg
    );
    print!("{}", out.quality);
    let tm = &out.times;
    println!(
        "time (ms): project {:.2}, alpha {:.2}, simplify {:.2}, triangulate {:.2}, quality {:.2}",
        ms(tm.project),
        ms(tm.alpha),
        ms(tm.simplify),
        ms(tm.triangulate),
        ms(tm.quality)
    );
}

/// `--view`: a camera preset by name.
fn parse_view(s: &str) -> Result<View, String> {
    s.parse()
}
