//! Running a 3D scene (`dim = 3`, [`fem_scene::solid`]) with files.
//!
//! Outputs (each written to a temporary file and renamed; `summary.json` last):
//! - `summary.json`: the [`Summary3`] (the 2D summary's fields where they apply, `dim = 3`,
//!   `tetrahedra`, three-component probes);
//! - `probes.csv`: one row per recorded frame, `step,time` then `NAME.ux,NAME.uy,NAME.uz`;
//! - `scene.toml`: the scene as run, overrides applied;
//! - with `vtk`, `vtk/run.pvd` and one `vtk/run_NNNNNN.vtu` per frame (tetrahedra; point data
//!   `displacement`, cell data `von_mises`);
//! - with `png`, `final.png`: the last frame's surface coloured by von Mises stress, drawn from
//!   [`View::OBLIQUE`] by the painter's algorithm ([`surface_picture`]).

use std::path::Path;

use fem_render::Image;
use fem_render::surface::{View, project};
use fem_render::vtk::{DataArray, PvdWriter, SolidFrame};
use fem_scene::SceneError;
use fem_scene::solid::{Frame3, LoadedScene3, RunResult3, run3};

use crate::pictures::{FieldKind, style};
use crate::run::{MAX_THREADS, SystemClock, write_atomic};

pub use fem_scene::solid::Summary3;

/// How to run a 3D scene.
#[derive(Clone, Debug, Default)]
pub struct RunOptions3 {
    /// Write the outputs here (created if missing). `None`: keep everything in memory.
    pub out_dir: Option<std::path::PathBuf>,
    /// Rayon threads (`None`: rayon's default).
    pub threads: Option<usize>,
    /// Keep every recorded frame in memory (and write VTK files of them with `vtk`).
    pub keep_frames: bool,
    /// Write `vtk/run.pvd` and its frames.
    pub vtk: bool,
    /// Draw `final.png`.
    pub png: bool,
}

/// Run a 3D scene on `options.threads` rayon threads with the system clock and write the
/// outputs. A blow-up is reported in the summary, not as an error.
pub fn run_scene3(
    scene: &LoadedScene3,
    options: &RunOptions3,
    progress: Option<&mut (dyn fem_scene::run::Progress + Send)>,
) -> Result<RunResult3, SceneError> {
    let go = |threads: usize| -> Result<RunResult3, SceneError> {
        let clock = SystemClock::new();
        let progress = progress.map(|p| p as &mut dyn fem_scene::run::Progress);
        let result = run3(
            scene,
            &clock,
            threads,
            options.keep_frames || options.vtk,
            progress,
        )?;
        if let Some(dir) = &options.out_dir {
            write_outputs3(scene, &result, dir, options)?;
        }
        Ok(result)
    };
    match options.threads {
        None => go(fem_core::par::current_num_threads()),
        Some(0) => Err(SceneError::Usage("--threads 0: must be >= 1".into())),
        Some(n) if n > MAX_THREADS => Err(SceneError::Usage(format!(
            "--threads {n}: must be at most {MAX_THREADS}"
        ))),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| SceneError::Usage(format!("--threads {n}: {e}")))?
            .install(|| go(n)),
    }
}

/// `probes.csv` of a 3D run.
pub fn probes_csv3(result: &RunResult3) -> String {
    let mut out = String::from("step,time");
    for p in &result.summary.probes {
        for c in ["ux", "uy", "uz"] {
            out.push_str(&format!(",{}.{c}", p.name));
        }
    }
    out.push('\n');
    for (step, time, row) in &result.probe_rows {
        out.push_str(&format!("{step},{time}"));
        for u in row {
            for c in u {
                out.push_str(&format!(",{c}"));
            }
        }
        out.push('\n');
    }
    out
}

fn write_outputs3(
    scene: &LoadedScene3,
    result: &RunResult3,
    dir: &Path,
    options: &RunOptions3,
) -> Result<(), SceneError> {
    if !dir.is_dir() {
        std::fs::create_dir_all(dir).map_err(|e| {
            SceneError::Io(format!(
                "{}: cannot create the output directory: {e}",
                dir.display()
            ))
        })?;
    }
    let io = |e: fem_render::RenderError| SceneError::Io(e.to_string());
    write_atomic(&dir.join("probes.csv"), probes_csv3(result).as_bytes())?;
    let toml =
        toml::to_string(&scene.scene).map_err(|e| SceneError::Io(format!("scene.toml: {e}")))?;
    write_atomic(&dir.join("scene.toml"), toml.as_bytes())?;
    if options.vtk {
        let vtk_dir = dir.join("vtk");
        std::fs::create_dir_all(&vtk_dir)
            .map_err(|e| SceneError::Io(format!("{}: {e}", vtk_dir.display())))?;
        let mut pvd = PvdWriter::new(&vtk_dir, "run").map_err(io)?;
        for frame in &result.frames {
            let u: Vec<[f64; 3]> = frame
                .x
                .iter()
                .zip(&result.rest)
                .map(|(x, r)| [x[0] - r[0], x[1] - r[1], x[2] - r[2]])
                .collect();
            let f = SolidFrame {
                positions: &frame.x,
                tetrahedra: &result.tetrahedra,
                point_data: vec![("displacement", DataArray::Vectors3(&u))],
                cell_data: vec![("von_mises", DataArray::Scalars(&frame.von_mises))],
            };
            pvd.add_solid(frame.time, &f).map_err(io)?;
        }
        pvd.finish().map_err(io)?;
    }
    if options.png && !result.summary.blew_up {
        let last = result
            .frames
            .last()
            .ok_or_else(|| SceneError::Io("the run recorded no frame to draw".into()))?;
        let title = format!(
            "{}: {} / {} (3D, {})",
            result.summary.scene,
            result.summary.energy,
            result.summary.solver,
            View::OBLIQUE.describe()
        );
        let image = surface_picture(result, last, View::OBLIQUE, &title, 720, 400)?;
        image.write_png(&dir.join("final.png")).map_err(io)?;
    }
    let summary = serde_json::to_string_pretty(&result.summary)
        .map_err(|e| SceneError::Io(format!("summary.json: {e}")))?;
    write_atomic(&dir.join("summary.json"), summary.as_bytes())
}

/// The surface of a 3D frame coloured by its tetrahedra's von Mises stress (each boundary
/// triangle takes the stress of the tetrahedron it bounds), seen from `view`: the visible
/// triangles projected and drawn far to near ([`fem_render::surface`]).
pub fn surface_picture(
    result: &RunResult3,
    frame: &Frame3,
    view: View,
    title: &str,
    width: u32,
    height: u32,
) -> Result<Image, SceneError> {
    surface_picture_in(result, frame, view, title, (width, height), None)
}

/// [`surface_picture`] with a colour range in kPa (`None`: the frame's own) and the world
/// window fitted to the frame.
pub fn surface_picture_in(
    result: &RunResult3,
    frame: &Frame3,
    view: View,
    title: &str,
    (width, height): (u32, u32),
    range_kpa: Option<(f64, f64)>,
) -> Result<Image, SceneError> {
    let faces: Vec<[usize; 3]> = result.surface.iter().map(|(f, _)| *f).collect();
    let projected = project(&frame.x, &faces, view);
    let values: Vec<f64> = projected
        .source
        .iter()
        .map(|&k| frame.von_mises[result.surface[k].1])
        .collect();
    let panel = fem_render::MeshView {
        field: Some(fem_render::FieldValues::PerElement(&values)),
        ..fem_render::MeshView::new(&projected.positions, &projected.faces)
    };
    let mut st = style(FieldKind::VonMises, title, width, height);
    st.rest_outline = false;
    if range_kpa.is_some() {
        st.range = range_kpa;
    }
    let rendered =
        fem_render::frame::render(&[panel], &st).map_err(|e| SceneError::Io(e.to_string()))?;
    Ok(rendered.image)
}

/// The report's 3D figure: `case-a-3d` (explicit, StVK) at case A's Table 1 times 0.5, 1.2 and
/// 2.0 s, side by side on one von Mises scale, from [`View::OBLIQUE`]. Returns the picture,
/// the tip deflection at each time (m) and the run's element-steps per second.
pub fn case_a_3d_figure() -> Result<(Image, Vec<f64>, f64), SceneError> {
    let scene = fem_scene::solid::load_case3("case-a-3d", &[])?;
    let clock = SystemClock::new();
    let result = run3(
        &scene,
        &clock,
        fem_core::par::current_num_threads(),
        true,
        None,
    )?;
    if let Some(m) = &result.summary.blow_up_message {
        return Err(SceneError::Scene(format!("case-a-3d blew up: {m}")));
    }
    let times = [0.5, 1.2, 2.0];
    let frames: Vec<&Frame3> = times
        .iter()
        .map(|&t| {
            result
                .frames
                .iter()
                .min_by(|a, b| (a.time - t).abs().total_cmp(&(b.time - t).abs()))
                .expect("the run recorded frames")
        })
        .collect();
    let top = frames
        .iter()
        .flat_map(|f| f.von_mises.iter().copied())
        .fold(0.0, f64::max)
        * 1e-3;
    let tip = result.summary.probes.first().map(|p| p.vertex);
    let mut panels = Vec::new();
    let mut tips = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        let title = format!(
            "{}t = {:.1} s",
            if k == 0 { "Case A in 3D: " } else { "" },
            f.time
        );
        panels.push(surface_picture_in(
            &result,
            f,
            View::OBLIQUE,
            &title,
            (360, 220),
            Some((0.0, top.max(1e-12))),
        )?);
        if let Some(v) = tip {
            tips.push(f.x[v][1] - result.rest[v][1]);
        }
    }
    let image = Image::hstack(&panels, 8, [255, 255, 255, 255]);
    Ok((image, tips, result.summary.element_steps_per_second))
}
