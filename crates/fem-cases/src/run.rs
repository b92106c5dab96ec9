//! Running a scene with files: the run of `fem-scene` on a rayon pool of the requested size,
//! with the system clock, mesh files read next to the scene file, and the run outputs.
//!
//! Outputs (in [`RunOptions::out_dir`], each written to a temporary file and renamed, so a file
//! is either complete or absent; `fem2d run` points it at the staging directory of an
//! [`OutDir`](crate::outdir::OutDir), so the whole directory is replaced as a unit):
//! - `summary.json`: the [`Summary`] (the BRIEF's contract fields plus more);
//! - `probes.csv`: one row per frame, `step,time` then `NAME.ux,NAME.uy` per probe (metres);
//! - `regions.csv`: one row per frame, `step,time` then per material region its peak and mean
//!   von Mises stress, largest compressive strain and area fraction above the stress threshold;
//! - `frames.jsonl` (unless `output.frames = false`): one JSON object per frame with the
//!   positions (`[x0, y0, x1, y1, ...]`), the obstacle polygons, the per-element von Mises
//!   stress, the contacts and the contact pressure of the loaded boundary vertices
//!   (`[[vertex, pressure_Pa], ...]`), and with rigid regions `rigid`: per rigid body its
//!   `position`, `angle`, `velocity`, `angular_velocity` and the `force` and `torque` the soft
//!   tissue puts on it, for renderers;
//! - `mesh.json`: the rest mesh (mesh JSON contract);
//! - `stress.json`: the last frame's von Mises stress per element and per vertex;
//! - `scene.toml`: the scene as run, overrides applied (a relative mesh path written absolute,
//!   so the copy runs from the output directory);
//! - with [`RunOptions::vtk`], `vtk/run.pvd` and one `vtk/run_NNNNNN.vtu` per frame (point
//!   data `displacement`, `velocity`, `contact_pressure` in Pa; cell data `von_mises`,
//!   `det_F`; for a body with `[[regions]]` the integer cell data `region`, the material
//!   region of each element, with the regions' names in the field data `region_names`; for a
//!   mesh that carries regions (the built-in body's bones) `mesh_region` and
//!   `mesh_region_names` likewise; with rigid regions the integer cell data `rigid_body` (the
//!   body of each element plus one, 0 for soft tissue) and the field data `rigid_bodies`, one
//!   line per body with its pose, velocity, force and torque; a homogeneous body's files
//!   have none of them).
//!
//! The summary is written last: its presence says the other files are complete.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use fem_scene::SceneError;
use fem_scene::run::{Clock, Frame, FrameSink, Progress, RunEnv, run};
use fem_scene::scene::LoadedScene;
use fem_solvers::ContactKind;

use crate::files::FileSource;

pub use fem_scene::run::{ProbeSummary, RunResult, Snapshot, Summary};

/// Most numbers `frames.jsonl` may hold (frames x (2 x vertices + triangles)): about 20 GB of
/// text.
pub const MAX_FRAME_VALUES: u64 = 1_000_000_000;

/// Most rayon threads a run may ask for (`--threads`): far above any machine this runs on, and
/// low enough that a typo cannot make the pool allocate thousands of stacks.
pub const MAX_THREADS: usize = 1024;

/// How to run (not part of the scene).
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Write the outputs here (created if missing). `None`: keep everything in memory.
    pub out_dir: Option<PathBuf>,
    /// Rayon threads (`None`: rayon's default).
    pub threads: Option<usize>,
    /// Keep every `n`-th recorded frame in memory as a [`Snapshot`] (for pictures and
    /// animations), and always the last one. `None`: keep none.
    pub snapshot_every: Option<usize>,
    /// Also write the recorded frames as VTK files, `vtk/run.pvd` and one `vtk/run_NNNNNN.vtu`
    /// per frame, in the output directory (ignored without one).
    pub vtk: bool,
    /// A recorded drag to replay into the run (`fem2d run --drag FILE`).
    pub drag: Option<fem_scene::drag::DragTrajectory>,
}

/// The system's monotonic clock.
#[derive(Clone, Copy, Debug)]
pub struct SystemClock(Instant);

impl SystemClock {
    /// A clock whose origin is now.
    pub fn new() -> Self {
        SystemClock(Instant::now())
    }
}

impl Default for SystemClock {
    fn default() -> Self {
        SystemClock::new()
    }
}

impl Clock for SystemClock {
    fn seconds(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }
}

/// Run a scene: [`run_scene_with`] without progress reports.
pub fn run_scene(scene: &LoadedScene, options: &RunOptions) -> Result<RunResult, SceneError> {
    run_scene_with(scene, options, None)
}

/// Run a scene on `options.threads` rayon threads with the system clock and mesh files read
/// next to the scene file, telling `progress` about the steps, and write the outputs when
/// `options.out_dir` is set. Errors: building the mesh, model or stepper, or writing outputs.
/// A blow-up is not an error here: it is reported in the summary.
pub fn run_scene_with(
    scene: &LoadedScene,
    options: &RunOptions,
    progress: Option<&mut (dyn Progress + Send)>,
) -> Result<RunResult, SceneError> {
    let go = || -> Result<RunResult, SceneError> { run_in_pool(scene, options, progress) };
    match options.threads {
        None => go(),
        Some(0) => Err(SceneError::Usage("--threads 0: must be >= 1".into())),
        Some(n) if n > MAX_THREADS => Err(SceneError::Usage(format!(
            "--threads {n}: must be at most {MAX_THREADS}"
        ))),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| SceneError::Usage(format!("--threads {n}: {e}")))?
            .install(go),
    }
}

fn run_in_pool(
    scene: &LoadedScene,
    options: &RunOptions,
    progress: Option<&mut (dyn Progress + Send)>,
) -> Result<RunResult, SceneError> {
    let clock = SystemClock::new();
    let files = FileSource::for_scene(scene);
    let mut frames = None;
    let mut vtk = None;
    if let Some(dir) = &options.out_dir {
        // Only when missing: a staging directory removed by an interruption is not recreated.
        if !dir.is_dir() {
            std::fs::create_dir_all(dir).map_err(|e| {
                SceneError::Io(format!(
                    "{}: cannot create the output directory: {e}",
                    dir.display()
                ))
            })?;
        }
        if scene.scene.output.frames {
            let planned = scene.scene.planned_frames();
            frames = Some(FramesJsonl::create(dir, planned)?);
        }
        if options.vtk {
            vtk = Some(VtkSink::create(dir)?);
        }
    }
    let mut sinks: Vec<&mut dyn FrameSink> = Vec::new();
    if let Some(f) = frames.as_mut() {
        sinks.push(f);
    }
    if let Some(v) = vtk.as_mut() {
        sinks.push(v);
    }
    let mut env = RunEnv {
        clock: &clock,
        files: &files,
        progress: progress.map(|p| -> &mut dyn Progress { p }),
        sinks,
        snapshot_every: options.snapshot_every,
        drag: options.drag.as_ref(),
    };
    let outcome = run(scene, &mut env);
    drop(env);
    let result = match outcome {
        Ok(r) => r,
        Err(e) => {
            if let Some(f) = frames {
                f.discard();
            }
            return Err(e);
        }
    };
    if let Some(dir) = &options.out_dir {
        if let Some(f) = frames {
            f.finish()?;
        }
        if let Some(v) = vtk {
            v.finish()?;
        }
        write_outputs(scene, &result, dir)?;
    }
    Ok(result)
}

/// `frames.jsonl`, written frame by frame into a temporary file renamed at the end.
struct FramesJsonl {
    planned: u64,
    tmp: PathBuf,
    dest: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    line: String,
}

impl FramesJsonl {
    fn create(dir: &Path, planned: u64) -> Result<Self, SceneError> {
        let dest = dir.join("frames.jsonl");
        let tmp = dir.join(".frames.jsonl.tmp");
        let file = std::fs::File::create(&tmp)
            .map_err(|e| SceneError::Io(format!("{}: {e}", tmp.display())))?;
        Ok(FramesJsonl {
            planned,
            tmp,
            dest,
            file: std::io::BufWriter::new(file),
            line: String::new(),
        })
    }

    fn finish(mut self) -> Result<(), SceneError> {
        self.file
            .flush()
            .map_err(|e| SceneError::Io(format!("{}: {e}", self.tmp.display())))?;
        drop(self.file);
        std::fs::rename(&self.tmp, &self.dest)
            .map_err(|e| SceneError::Io(format!("{}: {e}", self.dest.display())))
    }

    fn discard(self) {
        drop(self.file);
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// A number as JSON (which has no NaN or infinity: those become `null`).
fn json_number(v: f64) -> String {
    if v.is_finite() {
        v.to_string()
    } else {
        "null".to_owned()
    }
}

impl FrameSink for FramesJsonl {
    fn frame(&mut self, f: &Frame<'_>) -> Result<(), SceneError> {
        if f.step == 0 {
            // Checked on the first frame, when the mesh size is known.
            let per_frame = (2 * f.positions.len() + f.von_mises.len()) as u64;
            let total = self.planned.saturating_mul(per_frame);
            if total > MAX_FRAME_VALUES {
                return Err(SceneError::Usage(format!(
                    "output.frames: {} frames of {per_frame} numbers is {total:e} numbers in frames.jsonl, more than {MAX_FRAME_VALUES:e} (about 20 GB); raise output.frame_every or set output.frames = false",
                    self.planned
                )));
            }
        }
        let w = &mut self.line;
        w.clear();
        let _ = write!(
            w,
            "{{\"step\":{},\"time\":{},\"positions\":[",
            f.step, f.time
        );
        for (k, x) in f.positions.iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            let _ = write!(w, "{sep}{},{}", x.x, x.y);
        }
        w.push_str("],\"obstacles\":[");
        for (k, poly) in f.obstacles.iter().enumerate() {
            w.push_str(if k == 0 { "[" } else { ",[" });
            for (j, p) in poly.iter().enumerate() {
                let sep = if j == 0 { "" } else { "," };
                let _ = write!(w, "{sep}[{},{}]", p.x, p.y);
            }
            w.push(']');
        }
        w.push_str("],\"von_mises\":[");
        for (k, v) in f.von_mises.iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            // JSON has no NaN: non-finite stresses (inverted elements) become null.
            if v.is_finite() {
                let _ = write!(w, "{sep}{v}");
            } else {
                let _ = write!(w, "{sep}null");
            }
        }
        w.push_str("],\"contacts\":[");
        for (k, c) in f.contacts.iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            let (kind, features) = match c.kind {
                ContactKind::VertexGround { vertex } => ("vertex-ground", vec![vertex]),
                ContactKind::VertexObstacle {
                    vertex,
                    obstacle,
                    edge,
                } => ("vertex-obstacle", vec![vertex, obstacle, edge]),
                ContactKind::CornerEdge {
                    obstacle,
                    corner,
                    edge,
                } => ("corner-edge", vec![obstacle, corner, edge[0], edge[1]]),
                _ => ("other", Vec::new()),
            };
            let _ = write!(
                w,
                "{sep}{{\"kind\":\"{kind}\",\"features\":{features:?},\"point\":[{},{}],\"normal\":[{},{}],\"gap\":{},\"force\":{}}}",
                c.point.x,
                c.point.y,
                c.normal.x,
                c.normal.y,
                json_number(c.gap),
                json_number(c.force)
            );
        }
        w.push_str("],\"pressure\":[");
        let p = f.pressure.vertex_pressure();
        for (k, &v) in f.pressure.loaded_vertices().iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            let _ = write!(w, "{sep}[{v},{}]", json_number(p[v as usize]));
        }
        w.push(']');
        if !f.rigid.is_empty() {
            w.push_str(",\"rigid\":[");
            for (k, b) in f.rigid.iter().enumerate() {
                let sep = if k == 0 { "" } else { "," };
                let n = json_number;
                let _ = write!(
                    w,
                    "{sep}{{\"position\":[{},{}],\"angle\":{},\"velocity\":[{},{}],\"angular_velocity\":{},\"force\":[{},{}],\"torque\":{}}}",
                    n(b.position[0]),
                    n(b.position[1]),
                    n(b.angle),
                    n(b.velocity[0]),
                    n(b.velocity[1]),
                    n(b.angular_velocity),
                    n(b.force[0]),
                    n(b.force[1]),
                    n(b.torque)
                );
            }
            w.push(']');
        }
        w.push_str("}\n");
        self.file
            .write_all(w.as_bytes())
            .map_err(|e| SceneError::Io(format!("{}: {e}", self.tmp.display())))
    }
}

/// The recorded frames as VTK: `vtk/run.pvd` and one `vtk/run_NNNNNN.vtu` per frame.
struct VtkSink {
    writer: fem_render::vtk::PvdWriter,
    /// The material region of each element and the regions' names, when the scene has
    /// `[[regions]]` (set on the first frame, from its mesh, as the run sets them).
    region: Option<(Vec<u32>, Vec<String>)>,
    /// The mesh's own region of each element and their names, when it carries regions.
    mesh_region: Option<(Vec<u32>, Vec<String>)>,
    triangles: Vec<[usize; 3]>,
    displacement: Vec<[f64; 2]>,
    velocity: Vec<[f64; 2]>,
    positions: Vec<[f64; 2]>,
    det_f: Vec<f64>,
    von_mises: Vec<f64>,
    pressure: Vec<f64>,
    /// One line per rigid body (field data `rigid_bodies`).
    rigid_lines: Vec<String>,
}

impl VtkSink {
    fn create(dir: &Path) -> Result<Self, SceneError> {
        // Not recursive: fails rather than recreate a staging directory removed meanwhile.
        let vtk = dir.join("vtk");
        if let Err(e) = std::fs::create_dir(&vtk)
            && e.kind() != std::io::ErrorKind::AlreadyExists
        {
            return Err(SceneError::Io(format!("{}: {e}", vtk.display())));
        }
        Ok(VtkSink {
            writer: fem_render::vtk::PvdWriter::new(&dir.join("vtk"), "run")
                .map_err(|e| SceneError::Io(e.to_string()))?,
            region: None,
            mesh_region: None,
            triangles: Vec::new(),
            displacement: Vec::new(),
            velocity: Vec::new(),
            positions: Vec::new(),
            det_f: Vec::new(),
            von_mises: Vec::new(),
            pressure: Vec::new(),
            rigid_lines: Vec::new(),
        })
    }

    fn finish(self) -> Result<(), SceneError> {
        self.writer
            .finish()
            .map(|_| ())
            .map_err(|e| SceneError::Io(e.to_string()))
    }
}

impl FrameSink for VtkSink {
    fn frame(&mut self, f: &Frame<'_>) -> Result<(), SceneError> {
        use fem_render::vtk::{DataArray, VtkFrame};
        if self.triangles.is_empty() {
            // fem-render takes plain index triples.
            self.triangles
                .extend(f.mesh.triangles().iter().map(|t| t.map(|i| i as usize)));
            if f.regions.materials.len() > 1 {
                let names = f.regions.materials.iter().map(|m| m.name.clone()).collect();
                self.region = Some((f.regions.tags.clone(), names));
            }
            if !f.mesh.region_tags().is_empty() {
                self.mesh_region = Some((
                    f.mesh.region_tags().to_vec(),
                    f.mesh.region_names().to_vec(),
                ));
            }
        }
        self.displacement.clear();
        self.displacement.extend(
            f.positions
                .iter()
                .zip(f.mesh.vertices())
                .map(|(x, x0)| [x.x - x0.x, x.y - x0.y]),
        );
        self.velocity.clear();
        self.velocity
            .extend(f.velocities.iter().map(|p| [p.x, p.y]));
        self.positions.clear();
        self.positions
            .extend(f.positions.iter().map(|p| [p.x, p.y]));
        // A blowing-up run overflows: det F of huge positions is inf - inf = NaN. Written as
        // -1e30 (VTK's ASCII readers cannot read NaN), so the frames up to the blow-up stay
        // readable and the run still reports the blow-up.
        self.det_f.clear();
        self.det_f.extend(
            f.stress
                .iter()
                .map(|s| if s.det_f.is_finite() { s.det_f } else { -1e30 }),
        );
        // VTK's ASCII readers cannot read NaN: an element whose stress is undefined (inverted
        // under a log-barrier energy; det_F <= 0 there) is written as -1, a value von Mises
        // stress never takes.
        self.von_mises.clear();
        self.von_mises.extend(
            f.von_mises
                .iter()
                .map(|&v| if v.is_finite() { v } else { -1.0 }),
        );
        // Pa, 0 off contact; a non-finite pressure (a touching barrier pair) as -1, which a
        // pressure never is.
        self.pressure.clear();
        self.pressure.extend(
            f.pressure
                .vertex_pressure()
                .iter()
                .map(|&p| if p.is_finite() { p } else { -1.0 }),
        );
        let mut frame = VtkFrame {
            positions: &self.positions,
            triangles: &self.triangles,
            point_data: vec![
                ("displacement", DataArray::Vectors(&self.displacement)),
                ("velocity", DataArray::Vectors(&self.velocity)),
                ("contact_pressure", DataArray::Scalars(&self.pressure)),
            ],
            cell_data: vec![
                ("von_mises", DataArray::Scalars(&self.von_mises)),
                ("det_F", DataArray::Scalars(&self.det_f)),
            ],
            field_data: Vec::new(),
        };
        if let Some((tags, names)) = &self.region {
            frame.cell_data.push(("region", DataArray::Tags(tags)));
            frame.field_data.push(("region_names", names));
        }
        if let Some((tags, names)) = &self.mesh_region {
            frame.cell_data.push(("mesh_region", DataArray::Tags(tags)));
            frame.field_data.push(("mesh_region_names", names));
        }
        // Rigid bodies: which triangles each one is (`rigid_body`, its index plus one, 0 for
        // soft tissue) and, per body, a line with its pose, velocity and the tissue's load.
        self.rigid_lines.clear();
        for (k, b) in f.rigid.iter().enumerate() {
            self.rigid_lines.push(format!(
                "body {k} position {} {} angle {} velocity {} {} angular_velocity {} force {} {} torque {}",
                b.position[0],
                b.position[1],
                b.angle,
                b.velocity[0],
                b.velocity[1],
                b.angular_velocity,
                b.force[0],
                b.force[1],
                b.torque
            ));
        }
        if !f.rigid_tags.is_empty() {
            frame
                .cell_data
                .push(("rigid_body", DataArray::Tags(f.rigid_tags)));
            frame.field_data.push(("rigid_bodies", &self.rigid_lines));
        }
        self.writer
            .add(f.time, &frame)
            .map(|_| ())
            .map_err(|e| SceneError::Io(e.to_string()))
    }
}

/// Write `bytes` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    fem_mesh::io::write_atomic(path, bytes).map_err(|e| SceneError::Io(e.to_string()))
}

/// `probes.csv` text: `step,time` then `NAME.ux,NAME.uy` per probe, one row per frame.
pub fn probes_csv(result: &RunResult) -> String {
    let mut out = String::from("step,time");
    for p in &result.probes {
        let _ = write!(out, ",{0}.ux,{0}.uy", p.name);
    }
    out.push('\n');
    for (k, (step, t)) in result.frame_times.iter().enumerate() {
        let _ = write!(out, "{step},{t}");
        for series in &result.probe_series {
            let u = series[k];
            let _ = write!(out, ",{},{}", u[0], u[1]);
        }
        out.push('\n');
    }
    out
}

/// `regions.csv` text: `step,time` then, per material region `NAME` (the summary's
/// `regions`), `NAME.peak_von_mises,NAME.mean_von_mises` (Pa),
/// `NAME.max_compressive_strain` and `NAME.area_above_threshold`, one row per frame.
pub fn regions_csv(result: &RunResult) -> String {
    let mut out = String::from("step,time");
    for r in &result.summary.regions {
        let _ = write!(
            out,
            ",{0}.peak_von_mises,{0}.mean_von_mises,{0}.max_compressive_strain,{0}.area_above_threshold",
            r.name
        );
    }
    out.push('\n');
    for (k, (step, t)) in result.frame_times.iter().enumerate() {
        let _ = write!(out, "{step},{t}");
        for series in &result.region_series {
            let f = series[k];
            let _ = write!(
                out,
                ",{},{},{},{}",
                f.peak_von_mises,
                f.mean_von_mises,
                f.max_compressive_strain,
                f.area_above_threshold
            );
        }
        out.push('\n');
    }
    out
}

/// `stress.json`: the von Mises stress of the last recorded frame per element (triangle order)
/// and area-averaged per vertex (vertex order), Pa, with the formula used; non-finite values
/// (inverted elements) are `null`.
pub fn stress_json(result: &RunResult) -> String {
    let finite =
        |v: &[f64]| -> Vec<Option<f64>> { v.iter().map(|x| x.is_finite().then_some(*x)).collect() };
    let value = serde_json::json!({
        "formula": result.summary.von_mises_formula,
        "step": result.frame_times.last().map_or(0, |f| f.0),
        "per_element": finite(&result.final_von_mises),
        "per_vertex": finite(&result.final_vertex_von_mises),
    });
    serde_json::to_string(&value).unwrap_or_default()
}

fn write_outputs(scene: &LoadedScene, result: &RunResult, dir: &Path) -> Result<(), SceneError> {
    let summary = serde_json::to_string_pretty(&result.summary)
        .map_err(|e| SceneError::Io(format!("summary.json: {e}")))?;
    write_atomic(&dir.join("probes.csv"), probes_csv(result).as_bytes())?;
    write_atomic(&dir.join("regions.csv"), regions_csv(result).as_bytes())?;
    let mesh = fem_mesh::Mesh2 {
        vertices: result.rest.clone(),
        triangles: result
            .triangles
            .iter()
            .map(|t| t.map(|i| i as usize))
            .collect(),
        regions: result.mesh_regions.0.clone(),
        region_names: result.mesh_regions.1.clone(),
    };
    write_atomic(
        &dir.join("mesh.json"),
        fem_mesh::io::mesh_to_json(&mesh).as_bytes(),
    )?;
    // The copy lives in the output directory, not beside the original: a relative mesh path
    // is written absolute so that the copy still finds the mesh.
    let mut as_run = scene.scene.clone();
    if let Some(path) = &as_run.mesh.path {
        let resolved = scene.resolve(path);
        as_run.mesh.path = Some(std::path::absolute(&resolved).unwrap_or(resolved));
    }
    let toml =
        toml::to_string_pretty(&as_run).map_err(|e| SceneError::Io(format!("scene.toml: {e}")))?;
    write_atomic(&dir.join("scene.toml"), toml.as_bytes())?;
    write_atomic(&dir.join("stress.json"), stress_json(result).as_bytes())?;
    // The summary last: its presence says the other files are complete.
    write_atomic(&dir.join("summary.json"), summary.as_bytes())
}
