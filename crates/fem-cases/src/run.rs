//! Running a scene: the step loop, probes and frames at the output cadence, stress and
//! inversion statistics, blow-up detection, timing, and the run outputs.
//!
//! Outputs (in `--out DIR`, each written to a temporary file and renamed, so a file is either
//! complete or absent):
//! - `summary.json`: the [`Summary`] (the BRIEF's contract fields plus more);
//! - `probes.csv`: one row per frame, `step,time` then `NAME.ux,NAME.uy` per probe (metres);
//! - `frames.jsonl` (unless `output.frames = false`): one JSON object per frame with the
//!   positions (`[x0, y0, x1, y1, ...]`), the obstacle polygons and the per-element von Mises
//!   stress, for renderers;
//! - `mesh.json`: the rest mesh (mesh JSON contract);
//! - `stress.json`: the last frame's von Mises stress per element and per vertex;
//! - `scene.toml`: the scene as run, overrides applied (a relative mesh path written absolute,
//!   so the copy runs from the output directory).
//!
//! A run *blows up* when a step produces a non-finite value (the solver refuses it), a Newton
//! solve does not converge (implicit, static) or a displacement exceeds a thousand times the
//! body's size; the outputs then describe the run up to that point, the summary says
//! `"blew_up": true`, and [`run_scene`] returns the summary (callers that treat a blow-up as an
//! error, like `fem2d run`, check [`Summary::blew_up`]).
//!
//! A `static` scene has no time steps: the loop raises the load factor (gravity, tractions and
//! prescribed displacements together) from 0 to 1 in `solver.load_steps` equal increments, each
//! solved to equilibrium by the quasi-static solver from the previous one; an increment whose
//! Newton solve fails is halved (at most 10 times in the run). Every converged increment is a
//! frame, numbered by the increments converged so far, with the load factor as its `time`.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use fem_core::dispatch_energy;
use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};
use fem_core::stress::{ElementStress, VonMisesFormula, populate_element_stress, vertex_average};
use fem_solvers::{Model, SolverError, State, StaticSolver, Stepper};
use serde::{Deserialize, Serialize};

use crate::build::{
    AnyStepper, Probe, build_mesh, build_model, build_stepper, energy, prescribed_displacements,
    static_params, von_mises_formula,
};
use crate::error::CaseError;
use crate::scene::{LoadedScene, SolverKind};

/// JSON has no NaN or infinity: `serde_json` writes them as `null`; these read `null` back as
/// NaN, so a summary of a run that blew up round-trips.
mod nullable {
    use serde::{Deserialize, Deserializer};

    pub fn f64<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    pub fn pair<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
        let [a, b] = <[Option<f64>; 2]>::deserialize(d)?;
        Ok([a.unwrap_or(f64::NAN), b.unwrap_or(f64::NAN)])
    }
}

/// How to run (not part of the scene).
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Write the outputs here (created if missing). `None`: keep everything in memory.
    pub out_dir: Option<PathBuf>,
    /// Rayon threads (`None`: rayon's default).
    pub threads: Option<usize>,
    /// Draw a progress bar on standard error (only when it is a terminal).
    pub progress: bool,
    /// Keep every `n`-th recorded frame in memory as a [`Snapshot`] (for pictures and
    /// animations), and always the last one. `None`: keep none.
    pub snapshot_every: Option<usize>,
    /// Also write the recorded frames as VTK files, `vtk/run.pvd` and one `vtk/run_NNNNNN.vtu`
    /// per frame, in the output directory (ignored without one).
    pub vtk: bool,
}

/// One recorded frame kept in memory (see [`RunOptions::snapshot_every`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Step number (load increment for a static run).
    pub step: u64,
    /// Time, s (load factor for a static run).
    pub time: f64,
    /// Vertex positions, m.
    pub positions: Vec<[f64; 2]>,
    /// Vertex velocities, m/s (zero for a static run).
    pub velocities: Vec<[f64; 2]>,
    /// Per-element von Mises stress, Pa (NaN where undefined, e.g. inverted elements).
    pub von_mises: Vec<f64>,
    /// Per-element det F.
    pub det_f: Vec<f64>,
    /// Obstacle polygons, m.
    pub obstacles: Vec<Vec<[f64; 2]>>,
}

/// Probe statistics in the summary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeSummary {
    /// Probe name.
    pub name: String,
    /// The tracked vertex.
    pub vertex: usize,
    /// Its rest position, m.
    pub rest: [f64; 2],
    /// Displacement at the last recorded frame, m.
    #[serde(deserialize_with = "nullable::pair")]
    pub final_displacement: [f64; 2],
    /// Smallest and largest vertical displacement over the recorded frames, m.
    #[serde(deserialize_with = "nullable::pair")]
    pub uy_range: [f64; 2],
}

/// `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// Energy name.
    pub energy: String,
    /// Solver name.
    pub solver: String,
    /// `plane-strain` or `plane-stress`.
    pub plane: String,
    /// The von Mises formula used.
    pub von_mises_formula: String,
    /// Time step, s (as given in the scene; a static run does not use it).
    pub dt: f64,
    /// Steps requested (static: load increments requested, `solver.load_steps`).
    pub steps: u64,
    /// Steps completed, less than `steps` after a blow-up (static: load increments converged,
    /// halved ones counted, so it can exceed `steps`).
    pub steps_completed: u64,
    /// Simulated time reached, s (0 for a static run).
    pub simulated_seconds: f64,
    /// Vertex count.
    pub vertices: usize,
    /// Triangle count.
    pub triangles: usize,
    /// Rayon threads used.
    pub threads: usize,
    /// Wall time of the whole run (mesh building excluded), s.
    pub wall_seconds: f64,
    /// Wall time of the steps alone (no recording), s.
    pub step_seconds: f64,
    /// Triangles x steps completed / step_seconds.
    #[serde(deserialize_with = "nullable::f64")]
    pub element_steps_per_second: f64,
    /// Simulated seconds per wall second of stepping (0 for a static run).
    #[serde(deserialize_with = "nullable::f64")]
    pub real_time_factor: f64,
    /// Largest per-element von Mises stress over the recorded frames, Pa.
    #[serde(deserialize_with = "nullable::f64")]
    pub max_von_mises: f64,
    /// The step of that frame.
    pub max_von_mises_step: u64,
    /// The element and its centroid in the deformed configuration of that frame, m.
    pub max_von_mises_element: usize,
    /// Centroid of that element at that frame, m.
    #[serde(deserialize_with = "nullable::pair")]
    pub max_von_mises_at: [f64; 2],
    /// Largest per-element von Mises stress at the last recorded frame, Pa.
    #[serde(deserialize_with = "nullable::f64")]
    pub final_max_von_mises: f64,
    /// Largest vertex-averaged von Mises stress at the last recorded frame, Pa.
    #[serde(deserialize_with = "nullable::f64")]
    pub final_max_vertex_von_mises: f64,
    /// Smallest det F over every step.
    #[serde(deserialize_with = "nullable::f64")]
    pub min_det_f: f64,
    /// Most inverted elements in any step.
    pub inverted_elements: usize,
    /// Whether the run blew up.
    pub blew_up: bool,
    /// What happened, when it blew up.
    pub blow_up_message: Option<String>,
    /// The explicit stability warning, when dt exceeds the estimated limit.
    pub time_step_warning: Option<String>,
    /// Largest displacement magnitude at the last recorded frame, m.
    #[serde(deserialize_with = "nullable::f64")]
    pub final_max_displacement: f64,
    /// Probes.
    pub probes: Vec<ProbeSummary>,
    /// Newton iterations over the whole run, failed solves included (implicit and static; 0
    /// for the other solvers).
    #[serde(default)]
    pub newton_iterations: u64,
    /// Residual (norm of the force imbalance on the free vertices) at the end of the last
    /// Newton solve that converged, N (implicit: the last step; static: the last load
    /// increment); `null` for the other solvers or when no solve converged.
    #[serde(default)]
    pub final_residual: Option<f64>,
    /// Framework version.
    pub version: String,
}

/// Everything a run produced, in memory.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// The summary.
    pub summary: Summary,
    /// Resolved probes.
    pub probes: Vec<Probe>,
    /// Recorded frames: `(step, time)`.
    pub frame_times: Vec<(u64, f64)>,
    /// Per probe, per frame: displacement `[ux, uy]`, m.
    pub probe_series: Vec<Vec<[f64; 2]>>,
    /// Rest positions, m.
    pub rest: Vec<[f64; 2]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Positions at the last recorded frame, m.
    pub final_positions: Vec<[f64; 2]>,
    /// Per-element von Mises at the last recorded frame, Pa.
    pub final_von_mises: Vec<f64>,
    /// Vertex-averaged von Mises at the last recorded frame, Pa.
    pub final_vertex_von_mises: Vec<f64>,
    /// Obstacle polygons at the last recorded frame, m.
    pub final_obstacles: Vec<Vec<[f64; 2]>>,
    /// Frames kept in memory ([`RunOptions::snapshot_every`]), in time order; the last one is
    /// the last recorded frame.
    pub snapshots: Vec<Snapshot>,
}

impl RunResult {
    /// The series of probe `name`, if it exists.
    pub fn probe(&self, name: &str) -> Option<&[[f64; 2]]> {
        self.probes
            .iter()
            .position(|p| p.name == name)
            .map(|i| self.probe_series[i].as_slice())
    }
}

/// Run a scene. Errors: building the mesh, model or stepper, or writing outputs. A blow-up is
/// not an error here: it is reported in the summary.
pub fn run_scene(scene: &LoadedScene, options: &RunOptions) -> Result<RunResult, CaseError> {
    let go = || -> Result<RunResult, CaseError> {
        let mesh = build_mesh(scene)?;
        let energy = energy(scene)?;
        dispatch_energy!(energy, e => run_with(scene, options, mesh, e))
    };
    match options.threads {
        None => go(),
        Some(0) => Err(CaseError::Usage("--threads 0: must be >= 1".into())),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| CaseError::Usage(format!("--threads {n}: {e}")))?
            .install(go),
    }
}

struct Recorder {
    formula: VonMisesFormula,
    stress: Vec<ElementStress>,
    von_mises: Vec<f64>,
    frame_times: Vec<(u64, f64)>,
    probe_series: Vec<Vec<[f64; 2]>>,
    frames: Option<FrameWriter>,
    max_vm: (f64, u64, usize, [f64; 2]),
    body_size: f64,
    runaway: Option<String>,
    /// Snapshot cadence (in recorded frames) and the frames kept so far.
    snapshot_every: Option<usize>,
    snapshots: Vec<Snapshot>,
    /// The latest recorded frame when it is not in `snapshots` (kept so the last frame is).
    latest: Option<Snapshot>,
    vtk: Option<fem_render::vtk::PvdWriter>,
    /// Scratch for the VTK point data.
    scratch: [Vec<[f64; 2]>; 3],
    scratch_det_f: Vec<f64>,
    scratch_von_mises: Vec<f64>,
    triangles: Vec<[usize; 3]>,
}

struct FrameWriter {
    tmp: PathBuf,
    dest: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    line: String,
}

impl Recorder {
    /// Record a frame of `state`, numbered `step` at `time` (the state's own step and time for
    /// a time stepper; the increment count and the load factor for a static run).
    fn record<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &State,
        probes: &[Probe],
        (step, time): (u64, f64),
    ) -> Result<(), CaseError> {
        let mesh = model.mesh();
        populate_element_stress(
            mesh,
            model.energy(),
            &state.x,
            self.formula,
            &mut self.stress,
        );
        self.von_mises.clear();
        self.von_mises
            .extend(self.stress.iter().map(|s| s.von_mises));
        if let Some((t, vm)) = self
            .von_mises
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .max_by(|a, b| a.1.total_cmp(b.1))
        {
            if *vm > self.max_vm.0 {
                let [a, b, c] = mesh.gather(t, &state.x);
                let centroid = (a + b + c) / 3.0;
                self.max_vm = (*vm, step, t, [centroid.x, centroid.y]);
            }
        }
        self.frame_times.push((step, time));
        for (series, p) in self.probe_series.iter_mut().zip(probes) {
            let u = state.displacement(model, p.vertex);
            series.push([u.x, u.y]);
        }
        if self.runaway.is_none() {
            let limit = 1e3 * self.body_size;
            if let Some((i, u)) = state
                .x
                .iter()
                .zip(mesh.vertices())
                .map(|(x, x0)| (x - x0).norm())
                .enumerate()
                .find(|(_, u)| *u > limit)
            {
                self.runaway = Some(format!(
                    "vertex {i} moved {u:.3e} m at step {step} (t = {time:.6} s), more than 1000 times the body size"
                ));
            }
        }
        if let Some(w) = &mut self.frames {
            w.line.clear();
            let _ = write!(w.line, "{{\"step\":{step},\"time\":{time},\"positions\":[");
            for (k, x) in state.x.iter().enumerate() {
                let sep = if k == 0 { "" } else { "," };
                let _ = write!(w.line, "{sep}{},{}", x.x, x.y);
            }
            w.line.push_str("],\"obstacles\":[");
            for (k, (o, b)) in model.obstacles().iter().zip(&state.bodies).enumerate() {
                w.line.push_str(if k == 0 { "[" } else { ",[" });
                for (j, p) in o.world_polygon(b).iter().enumerate() {
                    let sep = if j == 0 { "" } else { "," };
                    let _ = write!(w.line, "{sep}[{},{}]", p.x, p.y);
                }
                w.line.push(']');
            }
            w.line.push_str("],\"von_mises\":[");
            for (k, v) in self.von_mises.iter().enumerate() {
                let sep = if k == 0 { "" } else { "," };
                // JSON has no NaN: non-finite stresses (inverted elements) become null.
                if v.is_finite() {
                    let _ = write!(w.line, "{sep}{v}");
                } else {
                    let _ = write!(w.line, "{sep}null");
                }
            }
            w.line.push_str("]}\n");
            w.file
                .write_all(w.line.as_bytes())
                .map_err(|e| CaseError::Io(format!("{}: {e}", w.tmp.display())))?;
        }
        if let Some(every) = self.snapshot_every {
            let keep = (self.frame_times.len() - 1) % every.max(1) == 0;
            let mut snap = self.latest.take().unwrap_or_default();
            snap.step = step;
            snap.time = time;
            snap.positions.clear();
            snap.positions.extend(state.x.iter().map(|p| [p.x, p.y]));
            snap.velocities.clear();
            snap.velocities.extend(state.v.iter().map(|p| [p.x, p.y]));
            snap.von_mises.clone_from(&self.von_mises);
            snap.det_f.clear();
            snap.det_f.extend(self.stress.iter().map(|s| s.det_f));
            snap.obstacles.clear();
            snap.obstacles.extend(
                model
                    .obstacles()
                    .iter()
                    .zip(&state.bodies)
                    .map(|(o, b)| o.world_polygon(b).iter().map(|p| [p.x, p.y]).collect()),
            );
            if keep {
                self.snapshots.push(snap);
            } else {
                self.latest = Some(snap);
            }
        }
        if let Some(vtk) = &mut self.vtk {
            use fem_render::vtk::{DataArray, VtkFrame};
            let [u, v, positions] = &mut self.scratch;
            u.clear();
            u.extend(
                state
                    .x
                    .iter()
                    .zip(mesh.vertices())
                    .map(|(x, x0)| [x.x - x0.x, x.y - x0.y]),
            );
            v.clear();
            v.extend(state.v.iter().map(|p| [p.x, p.y]));
            positions.clear();
            positions.extend(state.x.iter().map(|p| [p.x, p.y]));
            let det_f = &mut self.scratch_det_f;
            det_f.clear();
            det_f.extend(self.stress.iter().map(|s| s.det_f));
            // VTK's ASCII readers cannot read NaN: an element whose stress is undefined
            // (inverted under a log-barrier energy; det_F <= 0 there) is written as -1, a value
            // von Mises stress never takes.
            let vm = &mut self.scratch_von_mises;
            vm.clear();
            vm.extend(
                self.von_mises
                    .iter()
                    .map(|&v| if v.is_finite() { v } else { -1.0 }),
            );
            let frame = VtkFrame {
                positions,
                triangles: &self.triangles,
                point_data: vec![
                    ("displacement", DataArray::Vectors(u)),
                    ("velocity", DataArray::Vectors(v)),
                ],
                cell_data: vec![
                    ("von_mises", DataArray::Scalars(vm)),
                    ("det_F", DataArray::Scalars(det_f)),
                ],
            };
            vtk.add(time, &frame)
                .map_err(|e| CaseError::Io(e.to_string()))?;
        }
        Ok(())
    }

    /// The kept snapshots, with the last recorded frame appended if it was not kept.
    fn take_snapshots(&mut self) -> Vec<Snapshot> {
        let mut out = std::mem::take(&mut self.snapshots);
        if let Some(last) = self.latest.take() {
            out.push(last);
        }
        out
    }
}

fn run_with<E: Energy>(
    scene: &LoadedScene,
    options: &RunOptions,
    mesh: fem_core::mesh::Mesh,
    energy: E,
) -> Result<RunResult, CaseError> {
    let s = &scene.scene;
    let model = build_model(scene, mesh, energy)?;
    let mut driver = if s.solver.kind == SolverKind::Static {
        let solver = StaticSolver::new(&model, static_params(scene))
            .map_err(|e| CaseError::Solver(format!("{}: {e}", scene.origin)))?;
        let prescribed = prescribed_displacements(scene, model.mesh().vertices())?;
        Driver::Static {
            solver: Box::new(solver),
            prescribed,
        }
    } else {
        Driver::Steps(Box::new(build_stepper(scene, &model)?))
    };
    let probes = crate::build::resolve_probes(scene, model.mesh());
    let time_step_warning = match &driver {
        Driver::Steps(stepper) => stepper.time_step_warning(),
        Driver::Static { .. } => None,
    };
    let mut state = State::at_rest(&model);

    if let Some(dir) = &options.out_dir {
        std::fs::create_dir_all(dir).map_err(|e| {
            CaseError::Io(format!(
                "{}: cannot create the output directory: {e}",
                dir.display()
            ))
        })?;
    }
    let frames = match (&options.out_dir, s.output.frames) {
        (Some(dir), true) => {
            let dest = dir.join("frames.jsonl");
            let tmp = dir.join(".frames.jsonl.tmp");
            let file = std::fs::File::create(&tmp)
                .map_err(|e| CaseError::Io(format!("{}: {e}", tmp.display())))?;
            Some(FrameWriter {
                tmp,
                dest,
                file: std::io::BufWriter::new(file),
                line: String::new(),
            })
        }
        _ => None,
    };
    let (lo, hi) = bounds(model.mesh().vertices());
    let mut rec = Recorder {
        formula: von_mises_formula(scene),
        stress: Vec::new(),
        von_mises: Vec::new(),
        frame_times: Vec::new(),
        probe_series: vec![Vec::new(); probes.len()],
        frames,
        max_vm: (f64::NEG_INFINITY, 0, 0, [f64::NAN; 2]),
        body_size: (hi - lo).norm().max(1e-12),
        runaway: None,
        snapshot_every: options.snapshot_every,
        snapshots: Vec::new(),
        latest: None,
        vtk: match &options.out_dir {
            Some(dir) if options.vtk => Some(
                fem_render::vtk::PvdWriter::new(&dir.join("vtk"), "run")
                    .map_err(|e| CaseError::Io(e.to_string()))?,
            ),
            _ => None,
        },
        scratch: [Vec::new(), Vec::new(), Vec::new()],
        scratch_det_f: Vec::new(),
        scratch_von_mises: Vec::new(),
        triangles: model
            .mesh()
            .triangles()
            .iter()
            .map(|t| t.map(|i| i as usize))
            .collect(),
    };
    let result = match &mut driver {
        Driver::Steps(stepper) => step_loop(
            scene, options, &model, stepper, &mut state, &mut rec, &probes,
        ),
        Driver::Static { solver, prescribed } => static_loop(
            scene, &model, solver, prescribed, &mut state, &mut rec, &probes,
        ),
    };
    let outcome = match result {
        Ok(r) => r,
        Err(e) => {
            if let Some(w) = &rec.frames {
                let _ = std::fs::remove_file(&w.tmp);
            }
            return Err(e);
        }
    };
    let Outcome {
        wall,
        stepping,
        min_det_f,
        inverted,
        blow_up,
        done,
        newton_iterations,
        final_residual,
    } = outcome;
    let is_static = s.solver.kind == SolverKind::Static;

    let mesh = model.mesh();
    let mut vertex_vm = vec![0.0; mesh.n_vertices()];
    vertex_average(mesh, &rec.von_mises, &mut vertex_vm);
    let final_positions: Vec<[f64; 2]> = state.x.iter().map(|p| [p.x, p.y]).collect();
    let final_max_displacement = state
        .x
        .iter()
        .zip(mesh.vertices())
        .map(|(x, x0)| (x - x0).norm())
        .fold(0.0, f64::max);
    let step_seconds = stepping.as_secs_f64();
    // A static run has no simulated time.
    let sim = if is_static {
        0.0
    } else {
        done as f64 * s.solver.dt
    };
    let summary = Summary {
        scene: s.name.clone(),
        energy: s.energy.0.name().to_owned(),
        solver: s.solver.kind.name().to_owned(),
        plane: match s.material.plane {
            crate::scene::PlaneName::PlaneStrain => "plane-strain".into(),
            crate::scene::PlaneName::PlaneStress => "plane-stress".into(),
        },
        von_mises_formula: rec.formula.describe(),
        dt: s.solver.dt,
        steps: if is_static {
            s.solver.load_steps as u64
        } else {
            s.solver.steps
        },
        steps_completed: done,
        simulated_seconds: sim,
        vertices: mesh.n_vertices(),
        triangles: mesh.n_triangles(),
        threads: rayon::current_num_threads(),
        wall_seconds: wall.as_secs_f64(),
        step_seconds,
        element_steps_per_second: if step_seconds > 0.0 {
            mesh.n_triangles() as f64 * done as f64 / step_seconds
        } else {
            0.0
        },
        real_time_factor: if step_seconds > 0.0 {
            sim / step_seconds
        } else {
            0.0
        },
        max_von_mises: rec.max_vm.0,
        max_von_mises_step: rec.max_vm.1,
        max_von_mises_element: rec.max_vm.2,
        max_von_mises_at: rec.max_vm.3,
        final_max_von_mises: max_finite(&rec.von_mises),
        final_max_vertex_von_mises: max_finite(&vertex_vm),
        min_det_f,
        inverted_elements: inverted,
        blew_up: blow_up.is_some(),
        blow_up_message: blow_up,
        time_step_warning,
        final_max_displacement,
        probes: probes
            .iter()
            .zip(&rec.probe_series)
            .map(|(p, series)| ProbeSummary {
                name: p.name.clone(),
                vertex: p.vertex,
                rest: p.rest,
                final_displacement: *series.last().unwrap_or(&[0.0, 0.0]),
                uy_range: series
                    .iter()
                    .fold([f64::INFINITY, f64::NEG_INFINITY], |r, u| {
                        [r[0].min(u[1]), r[1].max(u[1])]
                    }),
            })
            .collect(),
        newton_iterations,
        final_residual,
        version: env!("CARGO_PKG_VERSION").to_owned(),
    };
    let snapshots = rec.take_snapshots();
    let result = RunResult {
        summary,
        snapshots,
        rest: mesh.vertices().iter().map(|p| [p.x, p.y]).collect(),
        triangles: mesh.triangles().to_vec(),
        final_positions,
        final_von_mises: rec.von_mises.clone(),
        final_vertex_von_mises: vertex_vm,
        final_obstacles: model
            .obstacles()
            .iter()
            .zip(&state.bodies)
            .map(|(o, b)| o.world_polygon(b).iter().map(|p| [p.x, p.y]).collect())
            .collect(),
        frame_times: rec.frame_times,
        probe_series: rec.probe_series,
        probes,
    };
    if let Some(dir) = &options.out_dir {
        if let Some(mut w) = rec.frames {
            w.file
                .flush()
                .map_err(|e| CaseError::Io(format!("{}: {e}", w.tmp.display())))?;
            drop(w.file);
            std::fs::rename(&w.tmp, &w.dest)
                .map_err(|e| CaseError::Io(format!("{}: {e}", w.dest.display())))?;
        }
        if let Some(vtk) = rec.vtk.take() {
            vtk.finish().map_err(|e| CaseError::Io(e.to_string()))?;
        }
        write_outputs(scene, &result, dir)?;
    }
    Ok(result)
}

/// What advances the state: a time stepper, or the quasi-static solver with what the static
/// loop needs (the model without loads, to scale them, and the prescribed displacements).
enum Driver {
    Steps(Box<AnyStepper>),
    Static {
        solver: Box<StaticSolver>,
        /// `(vertex, displacement at the full load)` of the prescribed vertices.
        prescribed: Vec<(usize, Vec2)>,
    },
}

/// What a loop reports to the summary.
struct Outcome {
    wall: Duration,
    stepping: Duration,
    min_det_f: Real,
    inverted: usize,
    blow_up: Option<String>,
    done: u64,
    newton_iterations: u64,
    final_residual: Option<f64>,
}

/// The time-stepping loop: `solver.steps` steps, a frame every `output.frame_every` steps.
fn step_loop<E: Energy>(
    scene: &LoadedScene,
    options: &RunOptions,
    model: &Model<E>,
    stepper: &mut AnyStepper,
    state: &mut State,
    rec: &mut Recorder,
    probes: &[Probe],
) -> Result<Outcome, CaseError> {
    let s = &scene.scene;
    let newton = s.solver.kind.uses_newton();
    let start = Instant::now();
    rec.record(model, state, probes, (state.step, state.t))?;
    let bar = progress_bar(options.progress, s.solver.steps);
    let mut stepping = Duration::ZERO;
    let mut min_det_f = Real::INFINITY;
    let mut inverted = 0usize;
    let mut blow_up: Option<String> = None;
    let mut newton_iterations = 0u64;
    let mut final_residual = None;
    let every = s.output.frame_every;
    let mut done = 0u64;
    while done < s.solver.steps && blow_up.is_none() {
        let chunk = every.min(s.solver.steps - done);
        let t0 = Instant::now();
        let mut failed: Option<SolverError> = None;
        for _ in 0..chunk {
            match stepper.step(model, state) {
                Ok(report) => {
                    min_det_f = min_det_f.min(report.min_det_f);
                    inverted = inverted.max(report.inverted);
                    if newton {
                        newton_iterations += report.iterations as u64;
                        final_residual = Some(report.residual);
                    }
                    done += 1;
                }
                Err(e) => {
                    if let SolverError::NotConverged { iterations, .. } = e {
                        newton_iterations += iterations as u64;
                    }
                    failed = Some(e);
                    break;
                }
            }
        }
        stepping += t0.elapsed();
        if let Some(e) = failed {
            blow_up = Some(format!("{}: {e}", scene.origin));
        }
        if done % every == 0 || done == s.solver.steps || blow_up.is_some() {
            if rec.frame_times.last().map(|f| f.0) != Some(state.step) {
                rec.record(model, state, probes, (state.step, state.t))?;
            }
            if blow_up.is_none() {
                if let Some(m) = rec.runaway.take() {
                    blow_up = Some(format!("{}: {m}", scene.origin));
                }
            }
        }
        if let Some(b) = &bar {
            b.set_position(done);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(Outcome {
        wall: start.elapsed(),
        stepping,
        min_det_f,
        inverted,
        blow_up,
        done,
        newton_iterations,
        final_residual,
    })
}

/// The static run: [`StaticSolver::solve_with`] takes the load factor from 0 to 1 in
/// `solver.load_steps` increments (halving one that fails), moving the prescribed vertices with
/// it; every converged increment is a frame (`step` = increment, `time` = load factor).
fn static_loop<E: Energy>(
    scene: &LoadedScene,
    model: &Model<E>,
    solver: &mut StaticSolver,
    prescribed: &[(usize, Vec2)],
    state: &mut State,
    rec: &mut Recorder,
    probes: &[Probe],
) -> Result<Outcome, CaseError> {
    let start = Instant::now();
    rec.record(model, state, probes, (0, 0.0))?;
    let mut recording = Duration::ZERO;
    let mut record_error = None;
    let mut done = 0u64;
    let t0 = Instant::now();
    let outcome = solver.solve_with(model, state, prescribed, |factor, st, _| {
        let t = Instant::now();
        done += 1;
        if record_error.is_none() {
            record_error = rec.record(model, st, probes, (done, factor)).err();
        }
        recording += t.elapsed();
    });
    let stepping = t0.elapsed().saturating_sub(recording);
    if let Some(e) = record_error {
        return Err(e);
    }
    let report = solver.last_report();
    let mut blow_up = outcome.err().map(|e| format!("{}: {e}", scene.origin));
    if blow_up.is_none() {
        blow_up = rec.runaway.take().map(|m| format!("{}: {m}", scene.origin));
    }
    Ok(Outcome {
        wall: start.elapsed(),
        stepping,
        min_det_f: report
            .increments
            .iter()
            .map(|r| r.min_det_f)
            .fold(Real::INFINITY, Real::min),
        inverted: report
            .increments
            .iter()
            .map(|r| r.inverted)
            .max()
            .unwrap_or(0),
        blow_up,
        done,
        newton_iterations: (report.iterations() + report.failed_iterations) as u64,
        final_residual: report
            .increments
            .last()
            .and_then(|r| r.residuals.last().copied()),
    })
}

fn max_finite(v: &[f64]) -> f64 {
    v.iter()
        .copied()
        .filter(|x| x.is_finite())
        .fold(f64::NEG_INFINITY, f64::max)
}

fn bounds(x: &[Vec2]) -> (Vec2, Vec2) {
    x.iter().fold(
        (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

fn progress_bar(enabled: bool, steps: u64) -> Option<indicatif::ProgressBar> {
    if !enabled || steps < 1000 {
        return None;
    }
    // indicatif draws nothing when standard error is not a terminal.
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(steps),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {pos}/{len} steps ({per_sec}, eta {eta})",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    Some(bar)
}

/// Write `bytes` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CaseError> {
    fem_mesh::io::write_atomic(path, bytes).map_err(|e| CaseError::Io(e.to_string()))
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

fn write_outputs(scene: &LoadedScene, result: &RunResult, dir: &Path) -> Result<(), CaseError> {
    let summary = serde_json::to_string_pretty(&result.summary)
        .map_err(|e| CaseError::Io(format!("summary.json: {e}")))?;
    write_atomic(&dir.join("probes.csv"), probes_csv(result).as_bytes())?;
    let mesh = fem_mesh::Mesh2 {
        vertices: result.rest.clone(),
        triangles: result
            .triangles
            .iter()
            .map(|t| t.map(|i| i as usize))
            .collect(),
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
        toml::to_string_pretty(&as_run).map_err(|e| CaseError::Io(format!("scene.toml: {e}")))?;
    write_atomic(&dir.join("scene.toml"), toml.as_bytes())?;
    write_atomic(&dir.join("stress.json"), stress_json(result).as_bytes())?;
    // The summary last: its presence says the other files are complete.
    write_atomic(&dir.join("summary.json"), summary.as_bytes())
}
