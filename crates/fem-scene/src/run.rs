//! Running a scene: the step loop, the per-frame numbers (stress, peaks, probes, runaway
//! check), blow-up detection and the [`Summary`].
//!
//! One loop for every solver of the registry. A solver whose clock is time
//! ([`fem_solvers::Clock::Time`]) takes `solver.steps` steps and a frame is recorded every
//! `output.frame_every` steps (and at step 0 and the last step); a load-stepping solver
//! ([`fem_solvers::Clock::LoadFactor`], the quasi-static solver) raises the load factor from 0
//! to 1 (gravity, tractions and prescribed displacements together), one increment per step, and
//! every converged increment is a frame, numbered by the increments converged so far, with the
//! load factor as its `time`.
//!
//! A run *blows up* when a step fails (a non-finite value, which the solver refuses to write; a
//! Newton solve that does not converge) or a displacement exceeds a thousand times the body's
//! size. The result then describes the run up to that point and the summary says
//! `"blew_up": true`; [`run`] returns it (callers that treat a blow-up as an error check
//! [`Summary::blew_up`]).
//!
//! What the caller supplies ([`RunEnv`]): a [`Clock`] for the timings (none: they read 0), a
//! [`Progress`] report, [`FrameSink`]s that receive each recorded [`Frame`] (files, VTK, a
//! canvas), a [`MeshSource`] for mesh and model files, and how many frames to keep in memory.
//! This module reads no clock and touches no file.
//!
//! Rigid regions (`[[regions]]` with `rigid = true`): their triangles carry no stress (their
//! von Mises stress reads 0, their `det F` 1); each frame carries every rigid body's pose,
//! velocity and the force and torque the soft tissue puts on it ([`RigidFrame`]), and the
//! summary each body's last frame and peak load ([`RigidBodySummary`]).

use fem_core::PlaneModel;
use fem_core::dispatch_energy;
use fem_core::energy::{Energy, EnergyKind};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::stress::{ElementStress, VonMisesFormula, populate_element_stress, vertex_average};
use fem_solvers::diagnostics::rigid_loads;
use fem_solvers::{
    AnyStepper, BodyMotion, Clock as SolverClock, Contact, ContactPressure, Model, SolverError,
    SolverKind, State, StepReport, Stepper,
};
use serde::{Deserialize, Serialize};

use crate::build::{
    MaterialRegions, MeshSource, NoFiles, Probe, build_mesh, build_model, build_stepper, energy,
    initial_state, material_regions, resolve_probes, von_mises_formula,
};
use crate::drag::{DragPlayer, DragTrajectory};
use crate::error::SceneError;
use crate::region_stats::{RegionFrame, RegionSummary, RegionTracker};
use crate::scene::{Formulation, LoadedScene};

/// A monotonic clock, read for the run's timings.
pub trait Clock {
    /// Seconds since an arbitrary fixed origin.
    fn seconds(&self) -> f64;
}

/// No clock: every timing reads 0 (and rates derived from them 0).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn seconds(&self) -> f64 {
        0.0
    }
}

/// Progress of a run, for a progress bar or a status line. Every method defaults to nothing.
pub trait Progress {
    /// The run starts; `total` steps are planned (the nominal increments for load stepping).
    fn start(&mut self, _total: u64) {}
    /// `done` steps are complete.
    fn advance(&mut self, _done: u64) {}
    /// The run ended (finished or blew up).
    fn finish(&mut self) {}
}

/// One recorded frame, borrowed: what a [`FrameSink`] receives.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Step number (load increment for a load-stepping run).
    pub step: u64,
    /// Time, s (the load factor for a load-stepping run).
    pub time: f64,
    /// The rest mesh (rest positions and triangles).
    pub mesh: &'a Mesh,
    /// Vertex positions, m.
    pub positions: &'a [Vec2],
    /// Vertex velocities, m/s.
    pub velocities: &'a [Vec2],
    /// Per-element stress (Cauchy, von Mises, det F, ...).
    pub stress: &'a [ElementStress],
    /// Per-element von Mises stress, Pa (NaN where undefined, e.g. inverted elements).
    pub von_mises: &'a [f64],
    /// Obstacle polygons at this frame, m.
    pub obstacles: &'a [Vec<Vec2>],
    /// The contacts of the step that produced this frame (empty at step 0 and without
    /// contact): the features, the point, the normal, the gap (negative: penetration), m, and
    /// the normal force, N per unit thickness.
    pub contacts: &'a [Contact],
    /// The normal contact pressure on the boundary from those contacts
    /// ([`fem_solvers::pressure`]): per vertex, Pa (0 off contact), the loaded vertices, the
    /// contact length and the peak.
    pub pressure: &'a ContactPressure,
    /// The material regions: each region's material (the base material first, then each
    /// `[[regions]]` entry) and the region of each triangle.
    pub regions: &'a MaterialRegions,
    /// The rigid bodies of the rigid regions (empty without them), in the model's order.
    pub rigid: &'a [RigidFrame],
    /// The rigid body of each triangle plus one, 0 for a deformable triangle (empty without
    /// rigid regions).
    pub rigid_tags: &'a [u32],
}

/// One rigid body (a bone of a rigid region) at a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RigidFrame {
    /// Its centroid, m.
    #[serde(deserialize_with = "nullable::pair")]
    pub position: [f64; 2],
    /// Its rotation from the rest pose, rad (counter-clockwise).
    #[serde(deserialize_with = "nullable::f64")]
    pub angle: f64,
    /// The centroid's velocity, m/s.
    #[serde(deserialize_with = "nullable::pair")]
    pub velocity: [f64; 2],
    /// Angular velocity, rad/s.
    #[serde(deserialize_with = "nullable::f64")]
    pub angular_velocity: f64,
    /// The force the soft tissue puts on it, N per metre of thickness
    /// ([`fem_solvers::diagnostics::rigid_loads`]).
    #[serde(deserialize_with = "nullable::pair")]
    pub force: [f64; 2],
    /// The tissue's torque on it about its centroid, N m per metre of thickness.
    #[serde(deserialize_with = "nullable::f64")]
    pub torque: f64,
}

/// One rigid body over a run, in `summary.json`'s `rigid_bodies`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigidBodySummary {
    /// The name of its region (`[[regions]]` `name`).
    pub region: String,
    /// Its triangles.
    pub triangles: usize,
    /// Mass, kg per metre of thickness.
    pub mass: f64,
    /// Rotational inertia about its centroid, kg m^2 per metre of thickness.
    pub inertia: f64,
    /// `free`, `pinned` or `scheduled` (moved by a prescribed motion).
    pub motion: String,
    /// Rest centroid, m.
    pub rest_centroid: [f64; 2],
    /// At the last recorded frame.
    #[serde(rename = "final")]
    pub last: RigidFrame,
    /// Largest magnitude of the tissue's force on it over the recorded frames, N per metre.
    #[serde(deserialize_with = "nullable::f64")]
    pub peak_force: f64,
    /// The step of that frame.
    pub peak_force_step: u64,
    /// Largest magnitude of the tissue's torque on it over the recorded frames, N m per metre.
    #[serde(deserialize_with = "nullable::f64")]
    pub peak_torque: f64,
}

/// Receives every recorded frame of a run, in order (a file writer, a VTK writer, a canvas).
pub trait FrameSink {
    /// Take frame `frame`; an error ends the run with it.
    fn frame(&mut self, frame: &Frame<'_>) -> Result<(), SceneError>;
}

/// What the caller supplies to [`run`]. `RunEnv::default()`: no clock, no progress, no sink,
/// no files, no frame kept in memory.
pub struct RunEnv<'a> {
    /// Read for the timings in the summary.
    pub clock: &'a dyn Clock,
    /// Mesh and model files the scene names.
    pub files: &'a dyn MeshSource,
    /// Told about the steps as they complete.
    pub progress: Option<&'a mut dyn Progress>,
    /// Given every recorded frame.
    pub sinks: Vec<&'a mut dyn FrameSink>,
    /// Keep every `n`-th recorded frame in memory as a [`Snapshot`] (for pictures and
    /// animations), and always the last one. `None`: keep none.
    pub snapshot_every: Option<usize>,
    /// A hand's recorded drag, replayed into the run ([`crate::drag`]).
    pub drag: Option<&'a DragTrajectory>,
}

impl Default for RunEnv<'_> {
    fn default() -> Self {
        RunEnv {
            clock: &NoClock,
            files: &NoFiles,
            progress: None,
            sinks: Vec::new(),
            snapshot_every: None,
            drag: None,
        }
    }
}

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

/// One recorded frame kept in memory (see [`RunEnv::snapshot_every`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Step number (load increment for a load-stepping run).
    pub step: u64,
    /// Time, s (load factor for a load-stepping run).
    pub time: f64,
    /// Vertex positions, m.
    pub positions: Vec<[f64; 2]>,
    /// Vertex velocities, m/s (zero for a load-stepping run).
    pub velocities: Vec<[f64; 2]>,
    /// Per-element von Mises stress, Pa (NaN where undefined, e.g. inverted elements).
    pub von_mises: Vec<f64>,
    /// Per-element det F.
    pub det_f: Vec<f64>,
    /// Obstacle polygons, m.
    pub obstacles: Vec<Vec<[f64; 2]>>,
    /// Normal contact pressure per vertex, Pa (0 off contact; [`fem_solvers::pressure`]).
    pub contact_pressure: Vec<f64>,
    /// The rigid bodies (empty without rigid regions).
    pub rigid: Vec<RigidFrame>,
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
    /// The energy (its name in JSON).
    pub energy: EnergyKind,
    /// The solver (its name in JSON).
    pub solver: SolverKind,
    /// `plane-strain` or `plane-stress`.
    pub plane: PlaneModel,
    /// The element formulation the run used (`material.formulation` resolved): `standard` or
    /// `averaged-pressure`.
    #[serde(default)]
    pub formulation: Formulation,
    /// The von Mises formula used.
    pub von_mises_formula: String,
    /// Time step, s (as given in the scene; a load-stepping run does not use it).
    pub dt: f64,
    /// Steps requested (load stepping: the nominal load increments, `solver.load_steps`).
    pub steps: u64,
    /// Steps completed, less than `steps` after a blow-up (load stepping: increments
    /// converged, halved ones counted, so it can exceed `steps`).
    pub steps_completed: u64,
    /// Simulated time reached, s (0 for a load-stepping run).
    pub simulated_seconds: f64,
    /// Vertex count.
    pub vertices: usize,
    /// Triangle count.
    pub triangles: usize,
    /// Rayon threads used.
    pub threads: usize,
    /// Wall time of the whole run (mesh building excluded), s, by the caller's [`Clock`] (0
    /// without one).
    pub wall_seconds: f64,
    /// Wall time of the steps alone (no recording), s (0 without a clock).
    pub step_seconds: f64,
    /// Triangles x steps completed / step_seconds (0 without a clock).
    #[serde(deserialize_with = "nullable::f64")]
    pub element_steps_per_second: f64,
    /// Simulated seconds per wall second of stepping (0 for a load-stepping run).
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
    /// Newton iterations over the whole run, failed solves included (solvers implicit in time;
    /// 0 for the others).
    #[serde(default)]
    pub newton_iterations: u64,
    /// Smallest gap over the contacts of every step, m: negative means penetration (the
    /// penalty and projection solvers allow some; barrier contact never does); `null` when
    /// nothing touched (barrier contact counts pairs within its activation distance).
    #[serde(default)]
    pub contact_min_gap: Option<f64>,
    /// Largest normal force of a single contact over the run, N per unit thickness (0 without
    /// contact).
    #[serde(default)]
    pub contact_peak_force: f64,
    /// Total contact force on the soft body after the last step, N per unit thickness
    /// (`[0, 0]` without contact).
    #[serde(default)]
    pub final_contact_force: [f64; 2],
    /// Contacts after the last step.
    #[serde(default)]
    pub final_contacts: usize,
    /// Largest normal contact pressure at a boundary vertex over every step, Pa (0 without
    /// contact); the pressure is the nodal contact force over the vertex's tributary boundary
    /// length ([`fem_solvers::pressure`]).
    #[serde(default)]
    pub contact_peak_pressure: f64,
    /// Where that peak acted: the vertex's position at that step, m (`null` without contact).
    #[serde(default)]
    pub contact_peak_pressure_at: Option<[f64; 2]>,
    /// The step of that peak (load increment for a load-stepping run; 0 without contact).
    #[serde(default)]
    pub contact_peak_pressure_step: u64,
    /// Contact length after the last step, m: the tributary boundary length of the loaded
    /// vertices (0 without contact).
    #[serde(default)]
    pub final_contact_length: f64,
    /// Largest vertex contact pressure after the last step, Pa (0 without contact).
    #[serde(default)]
    pub final_contact_pressure_peak: f64,
    /// Time integral of the total normal contact force over every step (each step's force
    /// times its time step), N s per metre of thickness; 0 for a load-stepping run, which has
    /// no time.
    #[serde(default)]
    pub contact_impulse: f64,
    /// Residual (norm of the force imbalance on the free vertices) at the end of the last
    /// Newton solve that converged, N (the last step or load increment); `null` for solvers
    /// explicit in time or when no solve converged.
    #[serde(default)]
    pub final_residual: Option<f64>,
    /// Iterations over the whole run, summed over steps and substeps: Newton iterations, VBD
    /// sweeps, constraint sweeps (PBD, XPBD), local-global or L-BFGS iterations; 0 for explicit
    /// FEM. With a residual tolerance (`solver.residual_tolerance`, quasi-Newton's
    /// `solver.tolerance`) these are the iterations actually used.
    #[serde(default)]
    pub solver_iterations: u64,
    /// The largest of the steps' final residuals over the run, in the solver's own measure
    /// ([`fem_solvers::StepReport::residual`]: a gradient norm in N for Newton, VBD with a
    /// tolerance, PD with a tolerance and quasi-Newton; the constraint residual for PBD and
    /// XPBD); `null` for explicit FEM.
    #[serde(default)]
    pub max_step_residual: Option<f64>,
    /// The stress threshold of the regions' `area_above_threshold`, Pa
    /// (`output.stress_threshold`).
    #[serde(default)]
    pub stress_threshold: f64,
    /// Per material region (the base material first, then each `[[regions]]` entry): stress
    /// and strain over the run ([`crate::region_stats`]).
    #[serde(default)]
    pub regions: Vec<RegionSummary>,
    /// The explicit critical time step of the deformable elements at rest, s
    /// ([`fem_solvers::Model::elastic_critical_time_step`]; rigid regions' triangles left
    /// out), for every solver: what an explicit run of this scene would need.
    #[serde(default, deserialize_with = "nullable::f64")]
    pub critical_time_step: f64,
    /// The rigid bodies of the rigid regions (empty without them).
    #[serde(default)]
    pub rigid_bodies: Vec<RigidBodySummary>,
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
    /// Frames kept in memory ([`RunEnv::snapshot_every`]), in time order; the last one is the
    /// last recorded frame.
    pub snapshots: Vec<Snapshot>,
    /// Per material region (as in [`Summary::regions`]), per recorded frame: its stress and
    /// strain numbers.
    pub region_series: Vec<Vec<RegionFrame>>,
    /// The material region of each triangle (an index into [`Summary::regions`]).
    pub region_tags: Vec<u32>,
    /// The regions the mesh carries (tissues: the built-in body's bones), per triangle, and
    /// their names; empty when it carries none.
    pub mesh_regions: (Vec<u32>, Vec<String>),
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

/// Run a scene on the current rayon thread pool. Errors: building the mesh, the model or the
/// stepper, or a sink's error. A blow-up is not an error here: it is reported in the summary.
pub fn run(scene: &LoadedScene, env: &mut RunEnv<'_>) -> Result<RunResult, SceneError> {
    let mesh = build_mesh(scene, env.files)?;
    let energy = energy(scene)?;
    dispatch_energy!(energy, e => run_with(scene, env, mesh, e))
}

/// The per-frame numbers of a run: stress of the current frame, the peaks, the probe series,
/// the runaway check and the snapshots kept in memory. Buffers are sized on the first frame.
struct Recorder {
    formula: VonMisesFormula,
    stress: Vec<ElementStress>,
    von_mises: Vec<f64>,
    obstacles: Vec<Vec<Vec2>>,
    frame_times: Vec<(u64, f64)>,
    probe_series: Vec<Vec<[f64; 2]>>,
    /// Peak von Mises so far: value, step, element, deformed centroid.
    max_vm: (f64, u64, usize, [f64; 2]),
    body_size: f64,
    runaway: Option<String>,
    /// Snapshot cadence (in recorded frames) and the frames kept so far.
    snapshot_every: Option<usize>,
    snapshots: Vec<Snapshot>,
    /// The latest recorded frame when it is not in `snapshots` (kept so the last frame is).
    latest: Option<Snapshot>,
    /// Per-region stress and strain.
    regions: RegionTracker,
    /// The material regions, as the model was built with them.
    materials: MaterialRegions,
    /// The rigid bodies at the current frame, their peak loads (force, step, torque), the
    /// rigid body of each triangle plus one, and the buffers of the tissue's forces.
    rigid: Vec<RigidFrame>,
    rigid_peaks: Vec<(f64, u64, f64)>,
    rigid_tags: Vec<u32>,
    forces: Vec<Vec2>,
    scratch: fem_core::assembly::Scratch,
}

impl Recorder {
    /// Record a frame of `state`, numbered by the state's step and time, and hand it to the
    /// sinks.
    fn record<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &State,
        contacts: &[Contact],
        pressure: &ContactPressure,
        probes: &[Probe],
        sinks: &mut [&mut dyn FrameSink],
    ) -> Result<(), SceneError> {
        let (step, time) = (state.step, state.t);
        let mesh = model.mesh();
        populate_element_stress(
            mesh,
            model.energies(),
            &state.x,
            self.formula,
            &mut self.stress,
        );
        // A rigid triangle carries no stress (its F is a rotation, up to round-off).
        for (s, &tag) in self.stress.iter_mut().zip(&self.rigid_tags) {
            if tag > 0 {
                *s = ElementStress::UNSTRESSED;
            }
        }
        self.von_mises.clear();
        self.von_mises
            .extend(self.stress.iter().map(|s| s.von_mises));
        self.regions.record(mesh, &self.stress, &state.x, step);
        let loads = rigid_loads(model, state, &mut self.forces, &mut self.scratch);
        self.rigid.clear();
        for (k, (b, (force, torque))) in state.rigid.iter().zip(loads).enumerate() {
            self.rigid.push(RigidFrame {
                position: [b.position.x, b.position.y],
                angle: b.angle,
                velocity: [b.velocity.x, b.velocity.y],
                angular_velocity: b.angular_velocity,
                force: [force.x, force.y],
                torque,
            });
            let peak = &mut self.rigid_peaks[k];
            if force.norm() > peak.0 {
                (peak.0, peak.1) = (force.norm(), step);
            }
            peak.2 = peak.2.max(torque.abs());
        }
        if let Some((t, vm)) = self
            .von_mises
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .max_by(|a, b| a.1.total_cmp(b.1))
            && *vm > self.max_vm.0
        {
            let [a, b, c] = mesh.gather(t, &state.x);
            let centroid = (a + b + c) / 3.0;
            self.max_vm = (*vm, step, t, [centroid.x, centroid.y]);
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
        self.obstacles
            .resize_with(model.obstacles().len(), Vec::new);
        for ((poly, o), b) in self
            .obstacles
            .iter_mut()
            .zip(model.obstacles())
            .zip(&state.bodies)
        {
            poly.clear();
            poly.extend(o.world_polygon(b));
        }
        let frame = Frame {
            step,
            time,
            mesh,
            positions: &state.x,
            velocities: &state.v,
            stress: &self.stress,
            von_mises: &self.von_mises,
            obstacles: &self.obstacles,
            contacts,
            pressure,
            regions: &self.materials,
            rigid: &self.rigid,
            rigid_tags: &self.rigid_tags,
        };
        for sink in sinks.iter_mut() {
            sink.frame(&frame)?;
        }
        if let Some(every) = self.snapshot_every {
            let keep = (self.frame_times.len() - 1).is_multiple_of(every.max(1));
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
                self.obstacles
                    .iter()
                    .map(|poly| poly.iter().map(|p| [p.x, p.y]).collect()),
            );
            snap.contact_pressure.clear();
            snap.contact_pressure
                .extend_from_slice(pressure.vertex_pressure());
            snap.rigid.clone_from(&self.rigid);
            if keep {
                self.snapshots.push(snap);
            } else {
                self.latest = Some(snap);
            }
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

/// What the loop reports to the summary.
struct Outcome {
    wall: f64,
    stepping: f64,
    min_det_f: Real,
    inverted: usize,
    blow_up: Option<String>,
    done: u64,
    newton_iterations: u64,
    final_residual: Option<f64>,
    solver_iterations: u64,
    max_step_residual: Option<f64>,
    contact: ContactTally,
}

/// The contact numbers of a run, step by step.
#[derive(Clone, Copy, Debug, Default)]
struct ContactTally {
    min_gap: Option<f64>,
    peak_force: f64,
    final_force: [f64; 2],
    final_count: usize,
    /// Peak vertex pressure over the run: value, position, step.
    peak_pressure: (f64, Option<[f64; 2]>, u64),
    final_length: f64,
    final_peak_pressure: f64,
    impulse: f64,
}

impl ContactTally {
    /// Add a step that ended at `step` after `dt` seconds (0 for a load increment) with these
    /// contacts and their pressure.
    fn add(&mut self, contacts: &[Contact], pressure: &ContactPressure, step: u64, dt: f64) {
        let mut total = Vec2::zeros();
        for c in contacts {
            self.min_gap = Some(self.min_gap.map_or(c.gap, |g| g.min(c.gap)));
            self.peak_force = self.peak_force.max(c.force);
            total += c.normal * c.force;
        }
        self.final_force = [total.x, total.y];
        self.final_count = contacts.len();
        let peak = pressure.peak();
        if let Some(pk) = peak
            && pk.pressure > self.peak_pressure.0
        {
            self.peak_pressure = (pk.pressure, Some([pk.position.x, pk.position.y]), step);
        }
        self.final_length = pressure.contact_length();
        self.final_peak_pressure = peak.map_or(0.0, |pk| pk.pressure);
        self.impulse += pressure.total_force() * dt;
    }
}

fn run_with<E: Energy>(
    scene: &LoadedScene,
    env: &mut RunEnv<'_>,
    mesh: Mesh,
    energy: E,
) -> Result<RunResult, SceneError> {
    let s = &scene.scene;
    let mut model = build_model(scene, mesh, energy)?;
    let mut stepper = build_stepper(scene, &model)?;
    let probes = resolve_probes(scene, model.mesh());
    let time_step_warning = stepper.time_step_warning();
    let mut state = initial_state(scene, &model)?;
    let (lo, hi) = bounds(model.mesh().vertices());
    let regions = material_regions(scene, model.mesh())?;
    let region_tags = regions.tags.clone();
    let mut rec = Recorder {
        regions: RegionTracker::new(&regions, model.mesh(), s.output.stress_threshold),
        formula: von_mises_formula(scene),
        stress: Vec::new(),
        von_mises: Vec::new(),
        obstacles: Vec::new(),
        frame_times: Vec::new(),
        probe_series: vec![Vec::new(); probes.len()],
        max_vm: (f64::NEG_INFINITY, 0, 0, [f64::NAN; 2]),
        body_size: (hi - lo).norm().max(1e-12),
        runaway: None,
        snapshot_every: env.snapshot_every,
        snapshots: Vec::new(),
        latest: None,
        materials: regions,
        rigid: Vec::new(),
        rigid_peaks: vec![(0.0, 0, 0.0); model.rigid_bodies().len()],
        rigid_tags: rigid_tags(&model),
        forces: Vec::new(),
        scratch: fem_core::assembly::Scratch::new(),
    };
    let outcome = step_loop(
        scene,
        env,
        &mut model,
        &mut stepper,
        &mut state,
        &mut rec,
        &probes,
    )?;
    let load_stepping = stepper.kind().capabilities().clock == SolverClock::LoadFactor;

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
    let Outcome {
        wall,
        stepping,
        min_det_f,
        inverted,
        blow_up,
        done,
        newton_iterations,
        final_residual,
        solver_iterations,
        max_step_residual,
        contact,
    } = outcome;
    // A load-stepping run has no simulated time.
    let sim = if load_stepping {
        0.0
    } else {
        done as f64 * s.solver.dt
    };
    let mut summary = Summary {
        stress_threshold: rec.regions.threshold(),
        regions: Vec::new(),
        critical_time_step: f64::NAN,
        rigid_bodies: Vec::new(),
        scene: s.name.clone(),
        energy: s.energy,
        solver: s.solver.kind,
        plane: s.material.plane,
        formulation: if crate::build::averaged_pressure(scene) {
            Formulation::AveragedPressure
        } else {
            Formulation::Standard
        },
        von_mises_formula: rec.formula.describe(),
        dt: s.solver.dt,
        steps: s.solver.planned_steps(),
        steps_completed: done,
        simulated_seconds: sim,
        vertices: mesh.n_vertices(),
        triangles: mesh.n_triangles(),
        threads: fem_core::par::current_num_threads(),
        wall_seconds: wall,
        step_seconds: stepping,
        element_steps_per_second: if stepping > 0.0 {
            mesh.n_triangles() as f64 * done as f64 / stepping
        } else {
            0.0
        },
        real_time_factor: if stepping > 0.0 { sim / stepping } else { 0.0 },
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
        contact_min_gap: contact.min_gap,
        contact_peak_force: contact.peak_force,
        final_contact_force: contact.final_force,
        final_contacts: contact.final_count,
        contact_peak_pressure: contact.peak_pressure.0,
        contact_peak_pressure_at: contact.peak_pressure.1,
        contact_peak_pressure_step: contact.peak_pressure.2,
        final_contact_length: contact.final_length,
        final_contact_pressure_peak: contact.final_peak_pressure,
        contact_impulse: contact.impulse,
        newton_iterations,
        final_residual,
        solver_iterations,
        max_step_residual,
        version: env!("CARGO_PKG_VERSION").to_owned(),
    };
    summary.critical_time_step = model.elastic_critical_time_step();
    summary.rigid_bodies = (model.rigid_bodies().iter().zip(&rec.rigid))
        .zip(&rec.rigid_peaks)
        .map(|((body, last), peak)| RigidBodySummary {
            region: rec.materials.materials[body.region as usize].name.clone(),
            triangles: body.triangles.len(),
            mass: body.mass,
            inertia: body.inertia,
            motion: match body.motion {
                BodyMotion::Free => "free",
                BodyMotion::Pinned => "pinned",
                BodyMotion::Scheduled(_) => "scheduled",
            }
            .to_string(),
            rest_centroid: [body.centroid.x, body.centroid.y],
            last: *last,
            peak_force: peak.0,
            peak_force_step: peak.1,
            peak_torque: peak.2,
        })
        .collect();
    let snapshots = rec.take_snapshots();
    let (region_summaries, region_series) = rec.regions.finish();
    summary.regions = region_summaries;
    Ok(RunResult {
        region_series,
        region_tags,
        mesh_regions: (mesh.region_tags().to_vec(), mesh.region_names().to_vec()),
        summary,
        snapshots,
        rest: mesh.vertices().iter().map(|p| [p.x, p.y]).collect(),
        triangles: mesh.triangles().to_vec(),
        final_positions,
        final_von_mises: rec.von_mises,
        final_vertex_von_mises: vertex_vm,
        final_obstacles: rec
            .obstacles
            .iter()
            .map(|poly| poly.iter().map(|p| [p.x, p.y]).collect())
            .collect(),
        frame_times: rec.frame_times,
        probe_series: rec.probe_series,
        probes,
    })
}

/// The loop: steps until the run's end (`solver.steps` steps, or the full load), recording a
/// frame at the output cadence, stopping at the first failed step or runaway.
fn step_loop<E: Energy>(
    scene: &LoadedScene,
    env: &mut RunEnv<'_>,
    model: &mut Model<E>,
    stepper: &mut AnyStepper,
    state: &mut State,
    rec: &mut Recorder,
    probes: &[Probe],
) -> Result<Outcome, SceneError> {
    let mut drag = env.drag.map(DragPlayer::new);
    let s = &scene.scene;
    let caps = stepper.kind().capabilities();
    let load_stepping = caps.clock == SolverClock::LoadFactor;
    let clock = env.clock;
    let start = clock.seconds();
    // Updated after every step: the summary's peak and impulse count every step, not only
    // the recorded frames.
    let mut pressure = ContactPressure::new();
    pressure.update(model, &state.x, &[]);
    rec.record(model, state, &[], &pressure, probes, &mut env.sinks)?;
    let planned = s.solver.planned_steps();
    if let Some(p) = env.progress.as_deref_mut() {
        p.start(planned);
    }
    // Every converged load increment is a frame.
    let every = if load_stepping {
        1
    } else {
        s.output.frame_every
    };
    let finished = |done: u64, state: &State| {
        if load_stepping {
            state.t >= 1.0
        } else {
            done >= s.solver.steps
        }
    };
    let mut stepping = 0.0;
    let mut min_det_f = Real::INFINITY;
    let mut inverted = 0usize;
    let mut blow_up: Option<String> = None;
    let mut newton_iterations = 0u64;
    let mut final_residual = None;
    let mut solver_iterations = 0u64;
    let mut max_step_residual: Option<f64> = None;
    let mut contact = ContactTally::default();
    let mut done = 0u64;
    while !finished(done, state) && blow_up.is_none() {
        let chunk = if load_stepping {
            1
        } else {
            every.min(s.solver.steps - done)
        };
        let t0 = clock.seconds();
        let mut failed: Option<SolverError> = None;
        for _ in 0..chunk {
            if let Some(d) = drag.as_mut() {
                d.apply(model, state)?;
            }
            let t_before = state.t;
            match step(stepper, model, state) {
                Ok(report) => {
                    if let Some(d) = drag.as_ref() {
                        d.after_step(state, state.t - t_before);
                    }
                    min_det_f = min_det_f.min(report.min_det_f);
                    inverted = inverted.max(report.inverted);
                    pressure.update(model, &state.x, stepper.contacts());
                    let dt = if load_stepping {
                        0.0
                    } else {
                        state.t - t_before
                    };
                    contact.add(stepper.contacts(), &pressure, state.step, dt);
                    if caps.implicit {
                        newton_iterations += report.iterations as u64;
                        final_residual = Some(report.residual);
                    }
                    if caps.iterations || caps.implicit {
                        solver_iterations += report.iterations as u64;
                        max_step_residual = Some(
                            max_step_residual
                                .map_or(report.residual, |r: f64| r.max(report.residual)),
                        );
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
        stepping += clock.seconds() - t0;
        if let Some(e) = failed {
            blow_up = Some(crate::scales::explain(scene, &e));
        }
        if done.is_multiple_of(every) || finished(done, state) || blow_up.is_some() {
            if rec.frame_times.last().map(|f| f.0) != Some(state.step) {
                rec.record(
                    model,
                    state,
                    stepper.contacts(),
                    &pressure,
                    probes,
                    &mut env.sinks,
                )?;
            }
            if blow_up.is_none()
                && let Some(m) = rec.runaway.take()
            {
                blow_up = Some(format!("{}: {m}", scene.origin));
            }
        }
        if let Some(p) = env.progress.as_deref_mut() {
            p.advance(done);
        }
    }
    if let Some(p) = env.progress.as_deref_mut() {
        p.finish();
    }
    Ok(Outcome {
        wall: clock.seconds() - start,
        stepping,
        min_det_f,
        inverted,
        blow_up,
        done,
        newton_iterations,
        final_residual,
        solver_iterations,
        max_step_residual,
        contact,
    })
}

/// One step as a run takes it: the stepper's step, and a step whose solver reports a residual
/// that is not finite is an error ([`SolverError::BeyondPrecision`]): a residual that
/// overflowed measures nothing, so the step is no solution, whatever the solver concluded from
/// it. A host that steps a scene itself calls this to take the steps [`run`] takes.
pub fn step<E: Energy>(
    stepper: &mut AnyStepper,
    model: &Model<E>,
    state: &mut State,
) -> Result<StepReport, SolverError> {
    let caps = stepper.kind().capabilities();
    let report = stepper.step(model, state)?;
    if (caps.implicit || caps.iterations) && !report.residual.is_finite() {
        return Err(SolverError::BeyondPrecision {
            prefix: "run",
            detail: format!(
                "step {}: the solver's residual is not finite ({})",
                state.step.saturating_sub(1),
                report.residual
            ),
        });
    }
    Ok(report)
}

/// The rigid body of each triangle plus one (0: deformable); empty without rigid regions.
fn rigid_tags<E: Energy>(model: &Model<E>) -> Vec<u32> {
    if model.rigid_bodies().is_empty() {
        return Vec::new();
    }
    let mut tags = vec![0; model.mesh().n_triangles()];
    for (k, body) in model.rigid_bodies().iter().enumerate() {
        for &t in &body.triangles {
            tags[t as usize] = k as u32 + 1;
        }
    }
    tags
}

/// The largest finite value (`-inf` when there is none).
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
