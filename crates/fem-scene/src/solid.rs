//! 3D scenes (`dim = 3`): a box of tetrahedra under the dimension-generic solvers
//! ([`fem_solvers::nd`]), and their step loop.
//!
//! A 3D scene has the 2D scene's keys where they make sense, with three coordinates:
//!
//! ```toml
//! name = "case-a-3d"
//! dim = 3
//! energy = "stvk"
//! gravity = [0.0, -9.8, 0.0]
//! [mesh]                      # kind = "box": case A's rectangle extruded by `depth`
//! kind = "box"
//! width = 5.0
//! height = 1.0
//! depth = 1.0
//! nx = 20
//! ny = 4
//! nz = 4
//! [material]                  # youngs_modulus, poisson_ratio, density (kg/m^3) or total_mass
//! [solver]                    # as in 2D; the solver needs a 3D path (docs/solvers.md)
//! [[pinned]]                  # min, max: every component held
//! [[fixed]]                   # min, max, axes = ["z"]: chosen components held (plane strain)
//! [[traction]]                # min, max, traction = [tx, ty, tz] Pa on the boundary faces
//! [[probes]]                  # name, point = [x, y, z]
//! [output]                    # frame_every
//! ```
//!
//! Keys of 2D features without a 3D path yet (material regions, prescribed motion, ground,
//! obstacles, contact, an initial shape, budget defaults) are refused in one line naming the
//! key; so is a solver without a 3D path. The energies are [`Hyperelastic<D3>`], written once
//! over `F` with the 2D ones; the material's Lamé parameters are the 3D ones (`material.plane`
//! does not apply).
//!
//! [`run3`] steps the scene and returns a [`Summary3`] (`summary.json`'s fields as in 2D where
//! they apply, with `dim`, `tetrahedra` and three-component probes) and the recorded frames.

use std::path::{Path, PathBuf};

use fem_core::dim::{D3, Dim, Mat3, Vec3};
use fem_core::energy::{AnyEnergy, EnergyKind, Hyperelastic};
use fem_core::material::Material;
use fem_core::simplex::SimplexMesh;
use fem_core::structured::{BoxParams, box_mesh};
use fem_solvers::nd::{self, AnyNdStepper, NdModel, NdRegion, NdState, NdStepper};
use fem_solvers::{Clock as SolverClock, SolverKind};
use serde::{Deserialize, Serialize};

use crate::error::SceneError;
use crate::run::{Clock, Progress};
use crate::scene::{deserialize_table, dim_of, parse_table};
use crate::solver_spec::SolverSpec;

/// The built-in 3D cases and their scene files' text.
pub const CASES_3D: [(&str, &str); 1] = [("case-a-3d", include_str!("../cases/case-a-3d.toml"))];

/// The text of built-in 3D case `name`.
pub fn case_text_3d(name: &str) -> Option<&'static str> {
    CASES_3D.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Keys of a 2D scene that 3D scenes do not have yet.
const TWO_D_ONLY: [&str; 7] = [
    "regions",
    "prescribed",
    "ground",
    "obstacles",
    "contact",
    "initial",
    "budget",
];

/// A 3D scene, as read from a scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene3 {
    /// Short name, used in outputs.
    pub name: String,
    /// One sentence on what the scene shows.
    #[serde(default)]
    pub description: String,
    /// Always 3.
    pub dim: u8,
    /// The mesh: a box of tetrahedra.
    pub mesh: BoxSpec,
    /// Material parameters.
    pub material: Material3,
    /// The elastic energy. Default `neo-hookean`.
    #[serde(default = "default_energy")]
    pub energy: EnergyKind,
    /// The solver, as in 2D.
    pub solver: SolverSpec,
    /// Gravitational acceleration, m/s^2. Default `[0, -9.8, 0]`.
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    /// Regions held in place.
    #[serde(default)]
    pub pinned: Vec<Box3>,
    /// Regions with some components held (`axes`).
    #[serde(default)]
    pub fixed: Vec<Fixed3>,
    /// Uniform tractions on the boundary faces inside boxes.
    #[serde(default)]
    pub traction: Vec<Traction3>,
    /// Named points; each tracks the rest vertex nearest to it.
    #[serde(default)]
    pub probes: Vec<Probe3>,
    /// Output cadence.
    #[serde(default)]
    pub output: Output3,
}

fn default_energy() -> EnergyKind {
    EnergyKind::NeoHookean
}

fn default_gravity() -> [f64; 3] {
    [0.0, -fem_solvers::model::STANDARD_GRAVITY, 0.0]
}

/// The `[mesh]` table of a 3D scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// `box`.
    pub kind: String,
    /// Extent along x, m.
    pub width: f64,
    /// Extent along y, m.
    pub height: f64,
    /// Extent along z, m.
    pub depth: f64,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Cells along z.
    pub nz: usize,
    /// The corner with the smallest coordinates, m. Default `[0, 0, 0]`.
    #[serde(default)]
    pub origin: [f64; 3],
}

/// The `[material]` table of a 3D scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material3 {
    /// Young's modulus E, Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Density, kg/m^3 (give this or `total_mass`).
    pub density: Option<f64>,
    /// Total mass, kg (give this or `density`).
    pub total_mass: Option<f64>,
}

/// A box of rest positions, m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Box3 {
    /// Smallest corner.
    pub min: [f64; 3],
    /// Largest corner.
    pub max: [f64; 3],
}

/// Some components held on a box of rest positions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fixed3 {
    /// Smallest corner.
    pub min: [f64; 3],
    /// Largest corner.
    pub max: [f64; 3],
    /// The held components: `x`, `y`, `z`.
    pub axes: Vec<String>,
}

/// A uniform traction on the boundary faces inside a box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Traction3 {
    /// Smallest corner.
    pub min: [f64; 3],
    /// Largest corner.
    pub max: [f64; 3],
    /// Pa.
    pub traction: [f64; 3],
}

/// A named point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Probe3 {
    /// Name in outputs.
    pub name: String,
    /// Rest position, m.
    pub point: [f64; 3],
}

/// The `[output]` table of a 3D scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output3 {
    /// Record a frame every this many steps (>= 1). Default 10.
    #[serde(default = "default_frame_every")]
    pub frame_every: usize,
}

fn default_frame_every() -> usize {
    10
}

impl Default for Output3 {
    fn default() -> Self {
        Output3 {
            frame_every: default_frame_every(),
        }
    }
}

/// A parsed and validated 3D scene.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedScene3 {
    /// The scene.
    pub scene: Scene3,
    /// The file (or `built-in case-a-3d`), named in error messages.
    pub origin: String,
    /// The scene file's directory.
    pub base_dir: PathBuf,
}

/// A scene of either dimension.
#[derive(Clone, Debug)]
pub enum AnyScene {
    /// A 2D scene.
    Two(Box<crate::scene::LoadedScene>),
    /// A 3D scene.
    Three(Box<LoadedScene3>),
}

/// Parse a scene of either dimension: its `dim` key (after `overrides`) decides.
pub fn parse_any(
    text: &str,
    origin: &str,
    base_dir: &Path,
    overrides: &[String],
) -> Result<AnyScene, SceneError> {
    let table = parse_table(text, origin, overrides)?;
    if dim_of(&table, origin)? == 3 {
        Ok(AnyScene::Three(Box::new(parse_scene3(
            text, origin, base_dir, overrides,
        )?)))
    } else {
        Ok(AnyScene::Two(Box::new(crate::scene::parse_scene(
            text, origin, base_dir, overrides,
        )?)))
    }
}

/// Parse and validate a 3D scene.
pub fn parse_scene3(
    text: &str,
    origin: &str,
    base_dir: &Path,
    overrides: &[String],
) -> Result<LoadedScene3, SceneError> {
    let table = parse_table(text, origin, overrides)?;
    if dim_of(&table, origin)? != 3 {
        return Err(SceneError::Scene(format!(
            "{origin}: dim: a 3D scene needs dim = 3"
        )));
    }
    if let Some(key) = TWO_D_ONLY.iter().find(|k| table.contains_key(**k)) {
        return Err(SceneError::Scene(format!(
            "{origin}: {key}: not available in 3D scenes yet (dim = 3 supports mesh, material, energy, solver, gravity, pinned, fixed, traction, probes, output)"
        )));
    }
    let scene: Scene3 = deserialize_table(table, origin)?;
    let loaded = LoadedScene3 {
        scene,
        origin: origin.to_owned(),
        base_dir: base_dir.to_path_buf(),
    };
    loaded.validate()?;
    Ok(loaded)
}

/// Load a built-in 3D case with overrides.
pub fn load_case3(name: &str, overrides: &[String]) -> Result<LoadedScene3, SceneError> {
    let text =
        case_text_3d(name).ok_or_else(|| SceneError::Usage(format!("unknown 3D case `{name}`")))?;
    parse_scene3(text, &format!("built-in {name}"), Path::new("."), overrides)
}

impl LoadedScene3 {
    fn error(&self, field: &str, value: impl std::fmt::Display, rule: &str) -> SceneError {
        SceneError::Scene(format!("{}: {field} = {value}: {rule}", self.origin))
    }

    /// Check every key of the scene (the checks [`parse_scene3`] runs), naming the first wrong one.
    pub fn validate(&self) -> Result<(), SceneError> {
        let s = &self.scene;
        if s.mesh.kind != "box" {
            return Err(self.error(
                "mesh.kind",
                &s.mesh.kind,
                "a 3D scene's mesh is a box (kind = \"box\")",
            ));
        }
        for (key, n) in [("nx", s.mesh.nx), ("ny", s.mesh.ny), ("nz", s.mesh.nz)] {
            if n == 0 {
                return Err(self.error(&format!("mesh.{key}"), 0, "must be >= 1"));
            }
        }
        for (key, v) in [
            ("width", s.mesh.width),
            ("height", s.mesh.height),
            ("depth", s.mesh.depth),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(self.error(
                    &format!("mesh.{key}"),
                    v,
                    "must be a finite number > 0 (m)",
                ));
            }
        }
        if !s.gravity.iter().all(|g| g.is_finite()) {
            return Err(self.error("gravity", format!("{:?}", s.gravity), "must be finite"));
        }
        if s.output.frame_every == 0 {
            return Err(self.error("output.frame_every", 0, "must be >= 1"));
        }
        if s.solver.steps == 0 {
            return Err(self.error("solver.steps", 0, "must be >= 1"));
        }
        if !(s.solver.dt.is_finite() && s.solver.dt > 0.0) {
            return Err(self.error("solver.dt", s.solver.dt, "must be a finite number > 0"));
        }
        s.solver
            .validate()
            .map_err(|e| SceneError::Scene(format!("{}: {e}", self.origin)))?;
        if s.solver.kind.capabilities().dims < 3 {
            return Err(self.error(
                "solver.kind",
                s.solver.kind,
                &format!(
                    "has no 3D path yet (solvers with one: {})",
                    nd::with_nd_path().join(", ")
                ),
            ));
        }
        match (s.material.density, s.material.total_mass) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(self.error(
                    "material",
                    "density and total_mass",
                    "give exactly one of them",
                ));
            }
            _ => {}
        }
        for (i, f) in s.fixed.iter().enumerate() {
            if f.axes.is_empty() {
                return Err(self.error(
                    &format!("fixed.{i}.axes"),
                    "[]",
                    "name at least one of x, y, z",
                ));
            }
            if let Some(a) = f
                .axes
                .iter()
                .find(|a| !["x", "y", "z"].contains(&a.as_str()))
            {
                return Err(self.error(&format!("fixed.{i}.axes"), a, "must be x, y or z"));
            }
        }
        for (i, p) in s.probes.iter().enumerate() {
            if !p.point.iter().all(|c| c.is_finite()) {
                return Err(self.error(
                    &format!("probes.{i}.point"),
                    format!("{:?}", p.point),
                    "must be finite",
                ));
            }
        }
        Ok(())
    }

    /// The frames a complete run records (the first, one every `frame_every` steps, the last).
    pub fn planned_frames(&self) -> u64 {
        match self.scene.solver.kind.capabilities().clock {
            SolverClock::LoadFactor => self.scene.solver.planned_steps() + 1,
            SolverClock::Time => self.scene.solver.steps / self.scene.output.frame_every as u64 + 2,
        }
    }
}

/// What a 3D scene builds into: the model, the stepper, the initial state and the probes'
/// vertices.
pub struct Built3 {
    /// The body.
    pub model: NdModel<D3, AnyEnergy>,
    /// The solver.
    pub stepper: AnyNdStepper<D3>,
    /// At rest.
    pub state: NdState<D3>,
    /// `(name, vertex)` per probe.
    pub probes: Vec<(String, usize)>,
}

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// Build a 3D scene's mesh, model, stepper and probes.
pub fn build3(loaded: &LoadedScene3) -> Result<Built3, SceneError> {
    let s = &loaded.scene;
    let m = &s.mesh;
    let mesh: SimplexMesh<D3> = box_mesh(&BoxParams {
        origin: m.origin,
        ..BoxParams::new(m.width, m.height, m.depth, m.nx, m.ny, m.nz)
    })
    .map_err(|e| SceneError::Scene(format!("{}: mesh: {e}", loaded.origin)))?;
    let field = |e: fem_solvers::SolverError| SceneError::Scene(format!("{}: {e}", loaded.origin));
    let density = s.material.density.unwrap_or(1.0);
    let material = Material::new(s.material.youngs_modulus, s.material.poisson_ratio, density)
        .map_err(|e| SceneError::Scene(format!("{}: material: {e}", loaded.origin)))?;
    // The true 3D Lamé parameters (plane strain's are the 3D ones).
    let lame = material.lame(fem_core::PlaneModel::PlaneStrain);
    let energy = s
        .energy
        .build(lame)
        .map_err(|e| SceneError::Scene(format!("{}: energy: {e}", loaded.origin)))?;
    let mut model = match s.material.total_mass {
        Some(total) => NdModel::with_total_mass(mesh, energy, total)
            .map_err(|e| SceneError::Scene(format!("{}: material.{e}", loaded.origin)))?,
        None => NdModel::with_density(mesh, energy, density)
            .map_err(|e| SceneError::Scene(format!("{}: material.{e}", loaded.origin)))?,
    };
    model.set_gravity(v3(s.gravity)).map_err(field)?;
    for (i, b) in s.pinned.iter().enumerate() {
        model
            .fix(
                &NdRegion::in_box(v3(b.min), v3(b.max)),
                &[true; 3],
                &format!("pinned.{i}"),
            )
            .map_err(field)?;
    }
    for (i, f) in s.fixed.iter().enumerate() {
        let axes = ["x", "y", "z"].map(|a| f.axes.iter().any(|b| b == a));
        model
            .fix(
                &NdRegion::in_box(v3(f.min), v3(f.max)),
                &axes,
                &format!("fixed.{i}"),
            )
            .map_err(field)?;
    }
    for (i, t) in s.traction.iter().enumerate() {
        model
            .add_traction(&NdRegion::in_box(v3(t.min), v3(t.max)), v3(t.traction))
            .map_err(|e| SceneError::Scene(format!("{}: traction.{i}: {e}", loaded.origin)))?;
    }
    let stepper = nd::build(&model, &s.solver.params(), "solver").map_err(field)?;
    let state = NdState::at_rest(&model);
    let probes = s
        .probes
        .iter()
        .map(|p| {
            let q = v3(p.point);
            let v = (0..model.mesh().n_vertices())
                .min_by(|&a, &b| {
                    let (da, db) = (
                        (model.mesh().vertices()[a] - q).norm_squared(),
                        (model.mesh().vertices()[b] - q).norm_squared(),
                    );
                    da.total_cmp(&db)
                })
                .unwrap_or(0);
            (p.name.clone(), v)
        })
        .collect();
    Ok(Built3 {
        model,
        stepper,
        state,
        probes,
    })
}

/// A probe of a 3D run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeSummary3 {
    /// Probe name.
    pub name: String,
    /// The tracked vertex.
    pub vertex: usize,
    /// Its rest position, m.
    pub rest: [f64; 3],
    /// Displacement at the last recorded frame, m.
    pub final_displacement: [f64; 3],
}

/// `summary.json` of a 3D run (the 2D summary's fields where they apply).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary3 {
    /// Scene name.
    pub scene: String,
    /// 3.
    pub dim: u8,
    /// The energy.
    pub energy: EnergyKind,
    /// The solver.
    pub solver: SolverKind,
    /// The von Mises formula: the full 3D one.
    pub von_mises_formula: String,
    /// Time step, s.
    pub dt: f64,
    /// Steps requested (load stepping: the nominal increments).
    pub steps: u64,
    /// Steps completed.
    pub steps_completed: u64,
    /// Simulated time reached, s (0 for a load-stepping run).
    pub simulated_seconds: f64,
    /// Vertex count.
    pub vertices: usize,
    /// Tetrahedron count.
    pub tetrahedra: usize,
    /// Rayon threads used.
    pub threads: usize,
    /// Wall time of the run, s (0 without a clock).
    pub wall_seconds: f64,
    /// Wall time of the steps alone, s.
    pub step_seconds: f64,
    /// Tetrahedra x steps completed / step_seconds (0 without a clock).
    pub element_steps_per_second: f64,
    /// Simulated seconds per wall second of stepping.
    pub real_time_factor: f64,
    /// Largest per-element von Mises stress over the recorded frames, Pa.
    pub max_von_mises: f64,
    /// The step of that frame.
    pub max_von_mises_step: u64,
    /// The element.
    pub max_von_mises_element: usize,
    /// Largest per-element von Mises stress at the last recorded frame, Pa.
    pub final_max_von_mises: f64,
    /// Smallest det F over every step.
    pub min_det_f: f64,
    /// Most inverted elements in any step.
    pub inverted_elements: usize,
    /// Whether the run blew up.
    pub blew_up: bool,
    /// What happened, when it blew up.
    pub blow_up_message: Option<String>,
    /// Largest displacement magnitude at the last recorded frame, m.
    pub final_max_displacement: f64,
    /// Probes.
    pub probes: Vec<ProbeSummary3>,
    /// Solver iterations over the run (Newton, sweeps, ...; 0 for explicit).
    pub iterations: u64,
    /// The last step's residual (0 for explicit).
    pub final_residual: f64,
    /// The largest final residual of a step, in the solver's measure (`None` for a solver
    /// without iterations: explicit).
    #[serde(default)]
    pub max_step_residual: Option<f64>,
}

/// One recorded frame of a 3D run.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame3 {
    /// Step number.
    pub step: u64,
    /// Time, s (the load factor for a load-stepping run).
    pub time: f64,
    /// Positions, m.
    pub x: Vec<[f64; 3]>,
    /// Per-tetrahedron von Mises stress, Pa.
    pub von_mises: Vec<f64>,
}

/// A 3D run's result.
#[derive(Clone, Debug)]
pub struct RunResult3 {
    /// The summary.
    pub summary: Summary3,
    /// The recorded frames (with `keep_frames`; otherwise only the last).
    pub frames: Vec<Frame3>,
    /// The probes' displacements per recorded frame: `(step, time, [[ux, uy, uz]; probes])`.
    pub probe_rows: Vec<(u64, f64, Vec<[f64; 3]>)>,
    /// The rest positions.
    pub rest: Vec<[f64; 3]>,
    /// The tetrahedra.
    pub tetrahedra: Vec<[usize; 4]>,
    /// The boundary triangles (outward, counter-clockwise from outside) and the tetrahedron
    /// each belongs to.
    pub surface: Vec<([usize; 3], usize)>,
}

/// Per-tetrahedron von Mises stress (full 3D) at positions `x`, into `out`.
pub fn von_mises3<E: Hyperelastic<D3>>(model: &NdModel<D3, E>, x: &[Vec3], out: &mut Vec<f64>) {
    out.clear();
    let mut corners = [Vec3::zeros(); 4];
    for (c, cell) in model.mesh().cells().iter().enumerate() {
        for (k, &i) in cell.iter().enumerate() {
            corners[k] = x[i as usize];
        }
        let f: Mat3 = model.mesh().elements()[c].deformation_gradient(&corners);
        let sigma = model.energy().cauchy_stress(&f);
        out.push(D3::von_mises(&sigma, 0.0));
    }
}

/// Run a 3D scene: every step of the scene's solver, a frame recorded every
/// `output.frame_every` steps (and the first and last), the summary. A step that fails ends
/// the run as a blow-up (the summary says so; the state stays at the last good step).
pub fn run3<'a>(
    loaded: &LoadedScene3,
    clock: &'a dyn Clock,
    threads: usize,
    keep_frames: bool,
    progress: Option<&'a mut dyn Progress>,
) -> Result<RunResult3, SceneError> {
    run3_with(
        loaded,
        RunEnv3 {
            clock,
            threads,
            keep_frames,
            progress,
            sinks: Vec::new(),
        },
    )
}

/// One recorded frame of a 3D run, borrowed: what a [`FrameSink3`] receives.
#[derive(Clone, Copy, Debug)]
pub struct FrameView3<'a> {
    /// Step number.
    pub step: u64,
    /// Time, s (the load factor for a load-stepping run).
    pub time: f64,
    /// Positions, m.
    pub x: &'a [Vec3],
    /// Velocities, m/s.
    pub v: &'a [Vec3],
    /// Lumped vertex masses, kg.
    pub masses: &'a [f64],
    /// Per-tetrahedron von Mises stress, Pa.
    pub von_mises: &'a [f64],
    /// The tetrahedra.
    pub tetrahedra: &'a [[u32; 4]],
}

/// Receives every recorded frame of a 3D run, in order.
pub trait FrameSink3 {
    /// Take `frame`; an error ends the run with it.
    fn frame(&mut self, frame: &FrameView3<'_>) -> Result<(), SceneError>;
}

/// What the caller of [`run3_with`] supplies.
pub struct RunEnv3<'a> {
    /// Read for the timings in the summary.
    pub clock: &'a dyn Clock,
    /// Rayon threads, for the summary.
    pub threads: usize,
    /// Keep every recorded frame in [`RunResult3::frames`] (otherwise the last only).
    pub keep_frames: bool,
    /// Told the steps.
    pub progress: Option<&'a mut dyn Progress>,
    /// Given every recorded frame; the first error ends the run with it.
    pub sinks: Vec<&'a mut dyn FrameSink3>,
}

/// [`run3`] with frame sinks. The summary's `step_seconds` is the solver's steps alone
/// (recording frames and the sinks are not counted), as in 2D.
pub fn run3_with(loaded: &LoadedScene3, env: RunEnv3<'_>) -> Result<RunResult3, SceneError> {
    let RunEnv3 {
        clock,
        threads,
        keep_frames,
        mut progress,
        mut sinks,
    } = env;
    let start = clock.seconds();
    let Built3 {
        model,
        mut stepper,
        mut state,
        probes,
    } = build3(loaded)?;
    let s = &loaded.scene;
    let load_factor = s.solver.kind.capabilities().clock == SolverClock::LoadFactor;
    let planned = s.solver.planned_steps();
    let every = s.output.frame_every as u64;
    let rest: Vec<[f64; 3]> = model
        .mesh()
        .vertices()
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .collect();
    let tetrahedra: Vec<[usize; 4]> = model
        .mesh()
        .cells()
        .iter()
        .map(|c| c.map(|i| i as usize))
        .collect();
    let surface: Vec<([usize; 3], usize)> = model
        .mesh()
        .boundary_facets()
        .into_iter()
        .zip(model.mesh().boundary_cells())
        .map(|(f, &(c, _))| ([f[0] as usize, f[1] as usize, f[2] as usize], c as usize))
        .collect();
    let mut summary = Summary3 {
        scene: s.name.clone(),
        dim: 3,
        energy: s.energy,
        solver: s.solver.kind,
        von_mises_formula: "3D: sqrt(3/2 s:s), s the deviatoric Cauchy stress".to_owned(),
        dt: s.solver.dt,
        steps: planned,
        steps_completed: 0,
        simulated_seconds: 0.0,
        vertices: model.mesh().n_vertices(),
        tetrahedra: model.mesh().n_cells(),
        threads,
        wall_seconds: 0.0,
        step_seconds: 0.0,
        element_steps_per_second: 0.0,
        real_time_factor: 0.0,
        max_von_mises: 0.0,
        max_von_mises_step: 0,
        max_von_mises_element: 0,
        final_max_von_mises: 0.0,
        min_det_f: f64::INFINITY,
        inverted_elements: 0,
        blew_up: false,
        blow_up_message: None,
        final_max_displacement: 0.0,
        probes: Vec::new(),
        iterations: 0,
        final_residual: 0.0,
        max_step_residual: None,
    };
    let mut frames = Vec::new();
    let mut probe_rows = Vec::new();
    let mut vm = Vec::new();
    let mut record = |step: u64,
                      state: &NdState<D3>,
                      frames: &mut Vec<Frame3>,
                      summary: &mut Summary3|
     -> Result<(), SceneError> {
        von_mises3(&model, &state.x, &mut vm);
        for sink in sinks.iter_mut() {
            sink.frame(&FrameView3 {
                step,
                time: state.t,
                x: &state.x,
                v: &state.v,
                masses: model.masses(),
                von_mises: &vm,
                tetrahedra: model.mesh().cells(),
            })?;
        }
        let (k, peak) =
            vm.iter()
                .copied()
                .enumerate()
                .fold((0, f64::NEG_INFINITY), |(bk, bv), (k, v)| {
                    if v > bv { (k, v) } else { (bk, bv) }
                });
        if peak > summary.max_von_mises {
            summary.max_von_mises = peak;
            summary.max_von_mises_step = step;
            summary.max_von_mises_element = k;
        }
        summary.final_max_von_mises = peak;
        let row: Vec<[f64; 3]> = probes
            .iter()
            .map(|(_, v)| {
                let u = state.displacement(&model, *v);
                [u.x, u.y, u.z]
            })
            .collect();
        probe_rows.push((step, state.t, row));
        // Without `keep_frames` only the latest frame is held.
        if !keep_frames {
            frames.clear();
        }
        frames.push(Frame3 {
            step,
            time: state.t,
            x: state.x.iter().map(|p| [p.x, p.y, p.z]).collect(),
            von_mises: vm.clone(),
        });
        Ok(())
    };
    record(0, &state, &mut frames, &mut summary)?;
    if let Some(p) = progress.as_deref_mut() {
        p.start(planned);
    }
    let caps = s.solver.kind.capabilities();
    let mut step_seconds = 0.0;
    let mut step = 0u64;
    let finished = |step: u64, state: &NdState<D3>| {
        if load_factor {
            state.t >= 1.0
        } else {
            step >= s.solver.steps
        }
    };
    while !finished(step, &state) {
        let t0 = clock.seconds();
        let outcome = stepper.step(&model, &mut state);
        step_seconds += clock.seconds() - t0;
        match outcome {
            Ok(report) => {
                step += 1;
                summary.min_det_f = summary.min_det_f.min(report.min_det_f);
                summary.inverted_elements = summary.inverted_elements.max(report.inverted);
                summary.iterations += report.iterations as u64;
                summary.final_residual = report.residual;
                if caps.iterations || caps.implicit {
                    summary.max_step_residual = Some(
                        summary
                            .max_step_residual
                            .map_or(report.residual, |r| r.max(report.residual)),
                    );
                }
            }
            Err(e) => {
                summary.blew_up = true;
                summary.blow_up_message = Some(e.to_string());
                break;
            }
        }
        if step.is_multiple_of(every) || finished(step, &state) || load_factor {
            record(step, &state, &mut frames, &mut summary)?;
        }
        if let Some(p) = progress.as_deref_mut() {
            p.advance(step);
        }
    }
    if let Some(p) = progress {
        p.finish();
    }
    // The last state is always a frame (a blow-up's last good step included).
    if frames.last().is_none_or(|f| f.step != step) {
        record(step, &state, &mut frames, &mut summary)?;
    }
    summary.steps_completed = step;
    summary.simulated_seconds = if load_factor { 0.0 } else { state.t };
    summary.step_seconds = step_seconds;
    summary.wall_seconds = clock.seconds() - start;
    if step_seconds > 0.0 {
        summary.element_steps_per_second = (summary.tetrahedra as f64 * step as f64) / step_seconds;
        summary.real_time_factor = summary.simulated_seconds / step_seconds;
    }
    summary.final_max_displacement = (0..state.x.len())
        .map(|v| state.displacement(&model, v).norm())
        .fold(0.0, f64::max);
    summary.probes = probes
        .iter()
        .map(|(name, v)| {
            let u = state.displacement(&model, *v);
            let r = model.mesh().vertices()[*v];
            ProbeSummary3 {
                name: name.clone(),
                vertex: *v,
                rest: [r.x, r.y, r.z],
                final_displacement: [u.x, u.y, u.z],
            }
        })
        .collect();
    Ok(RunResult3 {
        summary,
        frames,
        probe_rows,
        rest,
        tetrahedra,
        surface,
    })
}
