//! Scene files: one TOML file describes a whole simulation (mesh, material, energy, solver,
//! boundary conditions, gravity and boundary tractions, obstacles, probes, steps and output
//! cadence). The schema is documented field by field in `docs/scenes.md`; the built-in cases
//! live in `fixtures/scenes/`.
//!
//! Loading is three steps, each with one-line errors that name the file, the field and the
//! value:
//! 1. parse the TOML text (syntax errors give the line and column);
//! 2. apply `--set key=value` overrides ([`apply_override`]), the key being the value's path in
//!    the file (`material.youngs_modulus`, `obstacles.0.mass`);
//! 3. deserialize into [`Scene`] (unknown fields are errors, so a typo never passes silently)
//!    and [`LoadedScene::validate`] every value (finite, positive, in range).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use fem_core::PlaneModel;
use fem_core::energy::EnergyKind;
use fem_core::math::readable;
use fem_core::structured::Diagonal;
use serde::{Deserialize, Serialize};

use crate::error::SceneError;
use crate::solver_spec::SolverSpec;

/// A whole simulation, as read from a scene file.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short name, used in outputs (`case-a`).
    pub name: String,
    /// One sentence on what the scene shows.
    #[serde(default)]
    pub description: String,
    /// The mesh.
    pub mesh: MeshSpec,
    /// Material parameters (of the whole body, or of what no region claims).
    pub material: MaterialSpec,
    /// Regions of the body with their own material (bones inside soft tissue).
    #[serde(default)]
    pub regions: Vec<MaterialRegionSpec>,
    /// The elastic energy. Default `neo-hookean`.
    #[serde(default = "default_energy")]
    pub energy: EnergyKind,
    /// The solver (any of the registry, [`fem_solvers::SolverKind`]), the time step, the step
    /// count and every solver's parameters.
    pub solver: SolverSpec,
    /// Gravitational acceleration, m/s^2. Default `[0, -9.8]`.
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 2],
    /// Pinned regions (zero velocity for the whole run).
    #[serde(default)]
    pub pinned: Vec<RegionSpec>,
    /// Regions moved with a constant velocity during a time window.
    #[serde(default)]
    pub prescribed: Vec<PrescribedSpec>,
    /// Uniform tractions on the boundary edges inside boxes of rest positions.
    #[serde(default)]
    pub traction: Vec<TractionSpec>,
    /// A ground half-space.
    #[serde(default)]
    pub ground: Option<GroundSpec>,
    /// Rigid polygonal obstacles.
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
    /// Contact parameters (penalty contact of the explicit solver; friction for all).
    #[serde(default)]
    pub contact: Option<ContactSpec>,
    /// Named points; each tracks the rest vertex nearest to it.
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
    /// Output cadence and contents.
    #[serde(default)]
    pub output: OutputSpec,
    /// The body's configuration at t = 0, if not its rest shape.
    #[serde(default)]
    pub initial: Option<InitialSpec>,
    /// How `fem2d budget` runs this scene unless its flags say otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetDefaults>,
}

/// The `[initial]` table: the body starts scaled about a point, at rest (zero velocity), e.g.
/// squashed to 10 % of its height and released.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Scale factors along x and y (finite, > 0): `x = origin + scale * (X - origin)`.
    pub scale: [f64; 2],
    /// The fixed point of the scaling, m. Default `[0, 0]`.
    #[serde(default)]
    pub origin: [f64; 2],
}

impl InitialSpec {
    /// The initial position of the rest position `p`.
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        [
            self.origin[0] + self.scale[0] * (p[0] - self.origin[0]),
            self.origin[1] + self.scale[1] * (p[1] - self.origin[1]),
        ]
    }
}

fn default_energy() -> EnergyKind {
    EnergyKind::NeoHookean
}

fn default_gravity() -> [f64; 2] {
    [0.0, -fem_solvers::model::STANDARD_GRAVITY]
}

/// How the mesh is made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum MeshKind {
    /// A structured rectangle (`width`, `height`, `nx`, `ny`, `diagonal`, `origin`).
    Rectangle,
    /// A mesh JSON file (`path`).
    File,
    /// A 3D model file (OBJ, STL, PLY) through the mesh pipeline (`path` and pipeline fields).
    Model,
    /// The built-in procedural human body through the mesh pipeline (pipeline fields), with
    /// its skeleton as inner regions unless `skeleton = false`.
    Body,
    /// The built-in lower-leg close-up: a longitudinal section of the shank with its tibia
    /// (`max_area`, `min_angle`).
    Shank,
}

/// Camera preset of the mesh pipeline (model +Y up, +Z forward).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ViewName {
    /// From the model's right (-X) side: image (z, y).
    #[default]
    Side,
    /// From the front (+Z): image (x, y).
    Front,
    /// From the back (-Z): image (-x, y).
    Back,
    /// From above (+Y): image (x, -z).
    Top,
}

impl ViewName {
    /// Every preset.
    pub const ALL: [ViewName; 4] = [
        ViewName::Side,
        ViewName::Front,
        ViewName::Back,
        ViewName::Top,
    ];

    /// The name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ViewName::Side => "side",
            ViewName::Front => "front",
            ViewName::Back => "back",
            ViewName::Top => "top",
        }
    }
}

impl FromStr for ViewName {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ViewName::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| format!("unknown view `{s}` (expected one of: side, front, back, top)"))
    }
}

/// The `[mesh]` table. Which fields apply depends on `kind`; a field that does not apply to
/// the chosen kind is an error.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// How the mesh is made.
    pub kind: Option<MeshKind>,
    /// Rectangle: width along x, m.
    pub width: Option<f64>,
    /// Rectangle: height along y, m.
    pub height: Option<f64>,
    /// Rectangle: cells along x.
    pub nx: Option<usize>,
    /// Rectangle: cells along y.
    pub ny: Option<usize>,
    /// Rectangle: diagonal pattern. Default `right`.
    pub diagonal: Option<Diagonal>,
    /// Rectangle: lower-left corner, m. Default `[0, 0]`.
    pub origin: Option<[f64; 2]>,
    /// File and model: the file, relative to the scene file's directory.
    pub path: Option<PathBuf>,
    /// Model: OBJ groups or objects to keep (default: every face).
    pub groups: Option<Vec<String>>,
    /// Model and body: factor on the model's coordinates (0.1 turns decimetres into metres).
    /// Default 1.
    pub scale: Option<f64>,
    /// Body: mesh the skeleton's bones as inner regions (mesh regions `skull`, `spine`,
    /// `pelvis`, `femur`, `tibia`, `fibula`, `humerus`; the rest is `soft-tissue`). Default
    /// true.
    #[serde(default)]
    pub skeleton: Option<bool>,
    /// Model and body: camera preset. Default `side`.
    pub view: Option<ViewName>,
    /// Model and body: alpha-shape radius, m. Default: the pipeline's suggestion.
    pub alpha: Option<f64>,
    /// Model and body: Douglas-Peucker tolerance, m. Default: a quarter of the alpha radius.
    pub epsilon: Option<f64>,
    /// Model and body: largest triangle area, m^2. Default: no bound.
    pub max_area: Option<f64>,
    /// Model and body: smallest requested angle, degrees. Default 25.
    pub min_angle: Option<f64>,
    /// Any kind: rotation of the 2D mesh about the origin, degrees counter-clockwise, applied
    /// first. Default 0.
    pub rotate_deg: Option<f64>,
    /// Any kind: after rotation, translate so the bounding box's lower-left corner lies here, m.
    pub align_min: Option<[f64; 2]>,
}

/// The `[material]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E, Pa (> 0).
    pub youngs_modulus: f64,
    /// Poisson ratio nu, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Total mass, kg per unit thickness (give this or `density`).
    pub total_mass: Option<f64>,
    /// Density, kg/m^3 with unit thickness (give this or `total_mass`).
    pub density: Option<f64>,
    /// `plane-strain` (default; the paper's Lamé parameters) or `plane-stress`.
    #[serde(default)]
    pub plane: PlaneModel,
    /// The name of this material in outputs when the scene has `[[regions]]`. Default `body`.
    #[serde(default)]
    pub name: Option<String>,
    /// The element formulation: `auto` (default), `standard` or `averaged-pressure`
    /// ([`Formulation`]).
    #[serde(default)]
    pub formulation: Formulation,
}

/// `material.formulation`: plain linear triangles, or the averaged nodal pressure triangle
/// ([`fem_core::nodal_pressure`]), locking-free for nearly incompressible bodies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Formulation {
    /// `averaged-pressure` when the body is in plane strain, an elastic material of it has
    /// `nu >= AUTO_POISSON` and the solver supports it; `standard` otherwise. Default.
    #[default]
    Auto,
    /// Plain linear triangles (one volume constraint per triangle).
    Standard,
    /// The averaged nodal pressure triangle; a solver without it refuses the scene.
    AveragedPressure,
}

impl Formulation {
    /// The Poisson ratio from which `auto` averages the pressure: at 0.45 plain triangles'
    /// locking error is already about twice that at 0.3 (docs/energies.md).
    pub const AUTO_POISSON: f64 = 0.45;

    /// The name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Auto => "auto",
            Formulation::Standard => "standard",
            Formulation::AveragedPressure => "averaged-pressure",
        }
    }
}

impl MaterialSpec {
    /// The base material's name in outputs (`name`, or `body`).
    pub fn name(&self) -> &str {
        self.name.as_deref().unwrap_or("body")
    }
}

/// A `[[regions]]` entry: elements with their own material, selected by a polygon of rest
/// positions or by the names of regions the mesh carries. Unset parameters are the base
/// material's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialRegionSpec {
    /// The region's name in outputs (unique, not the base material's).
    pub name: String,
    /// The elements whose rest centroid lies inside this polygon (m, at least 3 points).
    #[serde(default)]
    pub polygon: Option<Vec<[f64; 2]>>,
    /// The elements of these regions of the mesh (mesh JSON `region_names`, the built-in
    /// body's bones).
    #[serde(default)]
    pub mesh_regions: Vec<String>,
    /// Young's modulus E, Pa (> 0). Default: the base material's.
    #[serde(default)]
    pub youngs_modulus: Option<f64>,
    /// Poisson ratio nu, in (-1, 0.5). Default: the base material's.
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
    /// Density, kg/m^3 (> 0). Default: the base material's.
    #[serde(default)]
    pub density: Option<f64>,
    /// Rigid: each connected piece of the region is one rigid body (a bone) that the soft
    /// tissue is attached to ([`fem_solvers::rigid::body`]); its Young's modulus and Poisson
    /// ratio are then unused. Default `false` (elastic).
    #[serde(default)]
    pub rigid: bool,
}

/// A box of rest positions, m (closed, with a 1e-9 m margin).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Lower-left corner, m.
    pub min: [f64; 2],
    /// Upper-right corner, m.
    pub max: [f64; 2],
}

/// A region moved with a constant velocity during `[start, end]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrescribedSpec {
    /// Lower-left corner of the region, m.
    pub min: [f64; 2],
    /// Upper-right corner of the region, m.
    pub max: [f64; 2],
    /// Velocity, m/s.
    pub velocity: [f64; 2],
    /// Window start, s. Default 0.
    #[serde(default)]
    pub start: f64,
    /// Window end, s. Default: the end of the run.
    pub end: Option<f64>,
}

/// A uniform traction (force per unit boundary length per unit thickness, Pa) on every boundary
/// edge whose two end vertices lie in the box of rest positions `[min, max]` (closed, with a
/// 1e-9 m margin). A dead load: fixed in direction and magnitude, it does not follow the
/// deforming surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TractionSpec {
    /// Lower-left corner of the box, m.
    pub min: [f64; 2],
    /// Upper-right corner of the box, m.
    pub max: [f64; 2],
    /// Traction `[tx, ty]`, Pa (N/m^2 per unit thickness).
    pub traction: [f64; 2],
}

/// The ground `y >= height` (or a tilted half-space through `point` with `normal`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundSpec {
    /// Height of a horizontal ground, m (give this, or `point` and `normal`).
    pub height: Option<f64>,
    /// A point on a tilted ground, m.
    pub point: Option<[f64; 2]>,
    /// Outward normal of a tilted ground.
    pub normal: Option<[f64; 2]>,
}

/// How an obstacle moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionName {
    /// Never moves (default).
    #[default]
    Static,
    /// Prescribed velocity during a window.
    Kinematic,
    /// A rigid body with mass under gravity, pushed by the soft body.
    Dynamic,
}

/// A rigid polygonal obstacle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Name shown in outputs.
    #[serde(default)]
    pub name: String,
    /// Counter-clockwise polygon at t = 0, m.
    pub polygon: Vec<[f64; 2]>,
    /// Motion. Default `static`.
    #[serde(default)]
    pub motion: MotionName,
    /// Dynamic: mass per unit thickness, kg.
    pub mass: Option<f64>,
    /// Dynamic: whether the body may rotate. Default true.
    pub rotates: Option<bool>,
    /// Kinematic: velocity, m/s.
    pub velocity: Option<[f64; 2]>,
    /// Kinematic: angular velocity, rad/s. Default 0.
    pub angular_velocity: Option<f64>,
    /// Kinematic: window start, s. Default 0.
    pub start: Option<f64>,
    /// Kinematic: window end, s. Default: never stops.
    pub end: Option<f64>,
    /// Kinematic: further moves after the window, in time order (`[[obstacles.moves]]`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub moves: Vec<ObstacleMoveSpec>,
}

/// One more move of a kinematic obstacle, `[[obstacles.moves]]`: a velocity during `[start, end]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleMoveSpec {
    /// Velocity of the centroid, m/s.
    pub velocity: [f64; 2],
    /// Angular velocity, rad/s. Default 0.
    pub angular_velocity: Option<f64>,
    /// Window start, s: at or after the end of the window before.
    pub start: f64,
    /// Window end, s. Default: never stops (the last move only).
    pub end: Option<f64>,
}

/// The `[contact]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Penalty stiffness per unit vertex mass, 1/s^2. Default 1e6.
    pub stiffness: Option<f64>,
    /// Damping ratio of the penalty spring. Default 0.5.
    pub damping_ratio: Option<f64>,
    /// Coulomb friction coefficient. Default 0.5.
    pub friction: Option<f64>,
    /// Barrier contact (implicit, static): activation distance, m. Default 1e-3.
    pub barrier_distance: Option<f64>,
    /// Barrier contact: barrier stiffness, N/m^4 (0: automatic). Default 0.
    pub barrier_stiffness: Option<f64>,
    /// Barrier contact (implicit): slip speed below which friction sticks, m/s. Default 1e-3.
    pub friction_velocity: Option<f64>,
}

/// A named point; the probe follows the rest vertex nearest to it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// Name (letters, digits, `_` and `-`): the column prefix in `probes.csv`.
    pub name: String,
    /// Rest position, m.
    pub point: [f64; 2],
}

/// The `[budget]` table: the defaults of `fem2d budget` for this scene (its flags override
/// them).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BudgetDefaults {
    /// The energies compared. Default (empty): all five.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub energies: Vec<EnergyKind>,
    /// Simulated seconds, s. Default: the scene's `steps x dt`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration: Option<f64>,
    /// Steps per frame of the reference (implicit Euler). Default 10 with contact, 100
    /// without.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_steps: Option<u64>,
}

/// The `[output]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Steps per frame: probes and frames are recorded every this many steps (and at step 0).
    /// Default 10 (the paper's frames at dt = 1e-3).
    #[serde(default = "default_frame_every")]
    pub frame_every: u64,
    /// Write `frames.jsonl` (positions, obstacles and per-element von Mises of every frame).
    /// Default true.
    #[serde(default = "default_true")]
    pub frames: bool,
    /// The von Mises stress above which a region's area counts in `area_above_threshold`, Pa.
    /// Default 32 kPa.
    #[serde(default = "default_stress_threshold")]
    pub stress_threshold: f64,
}

/// [`OutputSpec::stress_threshold`]'s default, Pa: 32 kPa, the compressive stress skeletal
/// muscle tolerates for under an hour before cells die (Linder-Ganz et al., J. Biomech. 39,
/// 2006); docs/cases.md says how it is used.
pub const DEFAULT_STRESS_THRESHOLD: f64 = 32e3;

fn default_stress_threshold() -> f64 {
    DEFAULT_STRESS_THRESHOLD
}

fn default_frame_every() -> u64 {
    10
}
fn default_true() -> bool {
    true
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            frame_every: default_frame_every(),
            frames: true,
            stress_threshold: DEFAULT_STRESS_THRESHOLD,
        }
    }
}

/// A scene with where it came from (for error messages and relative paths).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// The file (or `built-in case-a`), named in error messages.
    pub origin: String,
    /// Directory relative paths resolve against.
    pub base_dir: PathBuf,
}

impl Scene {
    /// The frames a complete run records: the first, one every `output.frame_every` steps and
    /// the last (at most; fewer when the last step falls on the cadence), or for a load-stepping
    /// solver one per nominal load increment and the first. Sizes the frame outputs.
    pub fn planned_frames(&self) -> u64 {
        match self.solver.kind.capabilities().clock {
            fem_solvers::Clock::LoadFactor => self.solver.planned_steps() + 1,
            fem_solvers::Clock::Time => self.solver.steps / self.output.frame_every.max(1) + 2,
        }
    }
}

impl LoadedScene {
    /// Resolve a path given in the scene.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base_dir.join(path)
        }
    }

    /// An error naming this scene, a field and a value.
    pub fn error(&self, field: &str, value: impl fmt::Display, rule: &str) -> SceneError {
        SceneError::Scene(format!("{}: {field} = {value}: {rule}", self.origin))
    }
}

/// Parse `text` (from `origin`; a leading UTF-8 byte-order mark is skipped), apply `overrides`
/// (`key=value`), deserialize and validate.
pub fn parse_scene(
    text: &str,
    origin: &str,
    base_dir: &Path,
    overrides: &[String],
) -> Result<LoadedScene, SceneError> {
    let mut table = parse_table(text, origin, overrides)?;
    if dim_of(&table, origin)? == 3 {
        return Err(SceneError::Scene(format!(
            "{origin}: dim = 3: a 3D scene runs with `fem2d run`, `compare` and `budget` (docs/scenes.md, 3D scenes); this tool takes 2D scenes"
        )));
    }
    table.remove("dim");
    let scene: Scene = deserialize_table(table, origin)?;
    let loaded = LoadedScene {
        scene,
        origin: origin.to_owned(),
        base_dir: base_dir.to_path_buf(),
    };
    loaded.validate()?;
    Ok(loaded)
}

/// The TOML table of a scene's text (from `origin`; a leading UTF-8 byte-order mark is
/// skipped) with `overrides` (`key=value`) applied.
pub fn parse_table(
    text: &str,
    origin: &str,
    overrides: &[String],
) -> Result<toml::Table, SceneError> {
    // A UTF-8 byte-order mark, which some editors write first, is not part of the TOML.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        let place = e
            .span()
            .map(|s| {
                let (line, col) = line_col(text, s.start);
                format!(":{line}:{col}")
            })
            .unwrap_or_default();
        SceneError::Scene(format!(
            "{origin}{place}: {}",
            e.message().trim().replace('\n', " ")
        ))
    })?;
    for o in overrides {
        apply_override(&mut table, o).map_err(|m| SceneError::Scene(format!("{origin}: {m}")))?;
    }
    Ok(table)
}

/// The scene's dimension: its `dim` key, 2 (the default) or 3.
pub fn dim_of(table: &toml::Table, origin: &str) -> Result<u8, SceneError> {
    match table.get("dim") {
        None => Ok(2),
        Some(v) => match v.as_integer() {
            Some(2) => Ok(2),
            Some(3) => Ok(3),
            _ => Err(SceneError::Scene(format!(
                "{origin}: dim = {v}: must be 2 or 3"
            ))),
        },
    }
}

/// Deserialize a scene table (2D or 3D), with errors naming `origin` and the field's path
/// (`pinned.0.max`, `solver.iterations`).
pub(crate) fn deserialize_table<T: serde::de::DeserializeOwned>(
    table: toml::Table,
    origin: &str,
) -> Result<T, SceneError> {
    serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            // serde writes array elements as `pinned[0].max`; --set and the checks below use
            // `pinned.0.max`: one spelling everywhere.
            let mut path = e.path().to_string().replace('[', ".").replace(']', "");
            let mut inner = e.inner().message().trim().replace('\n', " ");
            // The solver table is read by `SolverSpec`, whose messages start with the key
            // (`iterations: invalid type ...`): join it to the path as any other field.
            if path == "solver"
                && let Some((key, rest)) = inner.split_once(": ")
                && !key.is_empty()
                && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            {
                path = format!("solver.{key}");
                inner = rest.to_owned();
            }
            if path == "." || path.is_empty() {
                SceneError::Scene(format!("{origin}: {inner}"))
            } else {
                SceneError::Scene(format!("{origin}: {path}: {inner}"))
            }
        },
    )
}

pub(crate) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

/// Apply one `key=value` override to a parsed TOML table. The key is a dotted path
/// (`material.youngs_modulus`; array elements by index: `obstacles.0.mass`); the value is TOML
/// (`2000`, `[0, -9.8]`, `"stvk"`) or, when it does not parse as TOML, a bare string
/// (`energy=stvk`). Missing tables along the path are created; indexing past the end of an
/// array is an error.
pub fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<(), String> {
    let (key, raw) = assignment
        .split_once('=')
        .ok_or_else(|| format!("--set {assignment:?}: expected key=value"))?;
    let key = key.trim();
    let raw = raw.trim();
    if key.is_empty() || key.split('.').any(str::is_empty) {
        return Err(format!("--set {assignment:?}: empty key component"));
    }
    let value = parse_override_value(raw);
    let parts: Vec<&str> = key.split('.').collect();
    let mut root = toml::Value::Table(std::mem::take(table));
    let result = set_path(&mut root, key, &parts, value);
    if let toml::Value::Table(t) = root {
        *table = t;
    }
    result
}

fn set_path(
    root: &mut toml::Value,
    key: &str,
    parts: &[&str],
    value: toml::Value,
) -> Result<(), String> {
    let mut cursor = root;
    for (depth, part) in parts.iter().enumerate() {
        let last = depth + 1 == parts.len();
        let here = if depth == 0 {
            "the scene".to_owned()
        } else {
            format!("`{}`", parts[..depth].join("."))
        };
        let next = match cursor {
            toml::Value::Table(t) => {
                if last {
                    t.insert((*part).to_owned(), value);
                    return Ok(());
                }
                t.entry((*part).to_owned())
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            }
            toml::Value::Array(a) => {
                let index: usize = part.parse().map_err(|_| {
                    format!("--set {key}: {here} is an array; `{part}` is not an index")
                })?;
                let len = a.len();
                let slot = a.get_mut(index).ok_or_else(|| {
                    format!("--set {key}: index {index} is past the end of {here} ({len} entries)")
                })?;
                if last {
                    *slot = value;
                    return Ok(());
                }
                slot
            }
            other => {
                return Err(format!(
                    "--set {key}: {here} is a {}, not a table",
                    other.type_str()
                ));
            }
        };
        cursor = next;
    }
    Ok(())
}

fn parse_override_value(raw: &str) -> toml::Value {
    let doc = format!("v = {raw}");
    match doc.parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").unwrap_or(toml::Value::String(raw.to_owned())),
        Err(_) => toml::Value::String(raw.to_owned()),
    }
}

/// Validation: every value finite and in range, fields consistent with their kind.
impl LoadedScene {
    /// Check every value; the first problem is returned as a one-line error naming the scene
    /// file, the field and the value.
    pub fn validate(&self) -> Result<(), SceneError> {
        let s = &self.scene;
        let finite = |field: &str, v: f64| -> Result<(), SceneError> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(self.error(field, readable(v), "must be a finite number"))
            }
        };
        let positive = |field: &str, v: f64, unit: &str| -> Result<(), SceneError> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(self.error(
                    field,
                    readable(v),
                    &format!("must be a finite number > 0 ({unit})"),
                ))
            }
        };
        let non_negative = |field: &str, v: f64, unit: &str| -> Result<(), SceneError> {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(self.error(
                    field,
                    readable(v),
                    &format!("must be a finite number >= 0 ({unit})"),
                ))
            }
        };
        let point = |field: &str, p: [f64; 2]| -> Result<(), SceneError> {
            if p.iter().all(|c| c.is_finite()) {
                Ok(())
            } else {
                Err(self.error(field, fmt_point(p), "must have finite coordinates"))
            }
        };
        let boxed = |field: &str, min: [f64; 2], max: [f64; 2]| -> Result<(), SceneError> {
            point(&format!("{field}.min"), min)?;
            point(&format!("{field}.max"), max)?;
            if min[0] > max[0] || min[1] > max[1] {
                return Err(self.error(
                    &format!("{field}.min"),
                    fmt_point(min),
                    &format!(
                        "must not exceed max = {} in either coordinate",
                        fmt_point(max)
                    ),
                ));
            }
            Ok(())
        };

        if s.name.trim().is_empty() {
            return Err(self.error("name", "\"\"", "must not be empty"));
        }
        self.validate_mesh()?;

        let m = &s.material;
        positive("material.youngs_modulus", m.youngs_modulus, "Pa")?;
        if !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5) {
            return Err(self.error(
                "material.poisson_ratio",
                m.poisson_ratio,
                "must lie in the open interval (-1, 0.5)",
            ));
        }
        // The range of Young's modulus (fem_core::material::MIN_YOUNGS_MODULUS and
        // MAX_YOUNGS_MODULUS); the message names `material.youngs_modulus`.
        fem_core::Material::new(m.youngs_modulus, m.poisson_ratio, 1.0)
            .map_err(|e| SceneError::Scene(format!("{}: {e}", self.origin)))?;
        match (m.total_mass, m.density) {
            (Some(t), None) => positive("material.total_mass", t, "kg per unit thickness")?,
            (None, Some(d)) => positive("material.density", d, "kg/m^3")?,
            (Some(_), Some(_)) => {
                return Err(self.error(
                    "material.density",
                    readable(m.density.unwrap_or_default()),
                    "give total_mass or density, not both",
                ));
            }
            (None, None) => {
                return Err(self.error(
                    "material.total_mass",
                    "(missing)",
                    "give total_mass (kg) or density (kg/m^3)",
                ));
            }
        }

        self.validate_regions()?;

        let v = &s.solver;
        if !v.kind.capabilities().contact && (s.ground.is_some() || !s.obstacles.is_empty()) {
            let with: Vec<&str> = fem_solvers::SolverKind::ALL
                .iter()
                .filter(|k| k.capabilities().contact)
                .map(|k| k.name())
                .collect();
            return Err(self.error(
                "solver.kind",
                v.kind,
                &format!(
                    "does not handle contact and the scene has a ground or obstacles (contact needs {})",
                    with.join(", ")
                ),
            ));
        }
        positive("solver.dt", v.dt, "s")?;
        if v.steps == 0 {
            return Err(self.error("solver.steps", 0, "must be >= 1"));
        }
        if v.steps > fem_solvers::limits::MAX_STEPS {
            return Err(self.error(
                "solver.steps",
                v.steps,
                &format!(
                    "must be at most {} (fem_solvers::limits::MAX_STEPS)",
                    fem_solvers::limits::MAX_STEPS
                ),
            ));
        }
        // The solvers' own rules, each in its parameter struct (fem-solvers), for every
        // solver's parameters: a scene is valid whichever solver it is later run with.
        v.validate()
            .map_err(|e| SceneError::Scene(format!("{}: {e}", self.origin)))?;

        point("gravity", s.gravity)?;
        for (i, r) in s.pinned.iter().enumerate() {
            boxed(&format!("pinned.{i}"), r.min, r.max)?;
        }
        for (i, p) in s.prescribed.iter().enumerate() {
            let f = format!("prescribed.{i}");
            boxed(&f, p.min, p.max)?;
            point(&format!("{f}.velocity"), p.velocity)?;
            non_negative(&format!("{f}.start"), p.start, "s")?;
            if let Some(end) = p.end
                && (end.is_nan() || end < p.start)
            {
                return Err(self.error(&format!("{f}.end"), end, "must be >= start (s)"));
            }
        }
        for (i, t) in s.traction.iter().enumerate() {
            let f = format!("traction.{i}");
            boxed(&f, t.min, t.max)?;
            point(&format!("{f}.traction"), t.traction)?;
        }
        if let Some(g) = &s.ground {
            match (g.height, g.point, g.normal) {
                (Some(h), None, None) => finite("ground.height", h)?,
                (None, Some(p), Some(n)) => {
                    point("ground.point", p)?;
                    point("ground.normal", n)?;
                    if n[0] == 0.0 && n[1] == 0.0 {
                        return Err(self.error("ground.normal", fmt_point(n), "must not be zero"));
                    }
                }
                _ => {
                    return Err(self.error(
                        "ground",
                        "(table)",
                        "give either height, or point and normal",
                    ));
                }
            }
        }
        for (i, o) in s.obstacles.iter().enumerate() {
            let f = format!("obstacles.{i}");
            if o.polygon.len() < 3 {
                return Err(self.error(
                    &format!("{f}.polygon"),
                    format!("({} points)", o.polygon.len()),
                    "needs at least 3 points",
                ));
            }
            for (k, p) in o.polygon.iter().enumerate() {
                point(&format!("{f}.polygon.{k}"), *p)?;
            }
            let poly: Vec<fem_core::math::Vec2> = o
                .polygon
                .iter()
                .map(|p| fem_core::math::Vec2::new(p[0], p[1]))
                .collect();
            if let Some((i, j)) = fem_solvers::contact::first_crossing(&poly) {
                return Err(self.error(
                    &format!("{f}.polygon"),
                    format!("(edges {i} and {j} cross)"),
                    "must be a simple polygon (no two edges may cross or touch)",
                ));
            }
            let area = signed_area(&o.polygon);
            if area.is_nan() || area <= 0.0 {
                return Err(self.error(
                    &format!("{f}.polygon"),
                    format!("(signed area {area:e})"),
                    "must be counter-clockwise with positive area",
                ));
            }
            let unexpected = |name: &str, present: bool| -> Result<(), SceneError> {
                if present {
                    Err(self.error(
                        &format!("{f}.{name}"),
                        "(set)",
                        &format!("does not apply to motion = \"{}\"", motion_name(o.motion)),
                    ))
                } else {
                    Ok(())
                }
            };
            match o.motion {
                MotionName::Static => {
                    unexpected("mass", o.mass.is_some())?;
                    unexpected("rotates", o.rotates.is_some())?;
                    unexpected("velocity", o.velocity.is_some())?;
                    unexpected("angular_velocity", o.angular_velocity.is_some())?;
                    unexpected("start", o.start.is_some())?;
                    unexpected("end", o.end.is_some())?;
                    unexpected("moves", !o.moves.is_empty())?;
                }
                MotionName::Dynamic => {
                    let mass = o.mass.ok_or_else(|| {
                        self.error(
                            &format!("{f}.mass"),
                            "(missing)",
                            "a dynamic obstacle needs a mass (kg)",
                        )
                    })?;
                    positive(&format!("{f}.mass"), mass, "kg per unit thickness")?;
                    unexpected("velocity", o.velocity.is_some())?;
                    unexpected("angular_velocity", o.angular_velocity.is_some())?;
                    unexpected("start", o.start.is_some())?;
                    unexpected("end", o.end.is_some())?;
                    unexpected("moves", !o.moves.is_empty())?;
                }
                MotionName::Kinematic => {
                    unexpected("mass", o.mass.is_some())?;
                    unexpected("rotates", o.rotates.is_some())?;
                    let vel = o.velocity.ok_or_else(|| {
                        self.error(
                            &format!("{f}.velocity"),
                            "(missing)",
                            "a kinematic obstacle needs a velocity (m/s)",
                        )
                    })?;
                    point(&format!("{f}.velocity"), vel)?;
                    finite(
                        &format!("{f}.angular_velocity"),
                        o.angular_velocity.unwrap_or(0.0),
                    )?;
                    let start = o.start.unwrap_or(0.0);
                    non_negative(&format!("{f}.start"), start, "s")?;
                    if let Some(end) = o.end
                        && (end.is_nan() || end < start)
                    {
                        return Err(self.error(&format!("{f}.end"), end, "must be >= start (s)"));
                    }
                    let mut previous = (format!("{f}.end"), o.end.unwrap_or(f64::INFINITY));
                    for (k, m) in o.moves.iter().enumerate() {
                        let g = format!("{f}.moves.{k}");
                        point(&format!("{g}.velocity"), m.velocity)?;
                        finite(
                            &format!("{g}.angular_velocity"),
                            m.angular_velocity.unwrap_or(0.0),
                        )?;
                        if m.start.is_nan() || m.start < previous.1 {
                            return Err(self.error(
                                &format!("{g}.start"),
                                m.start,
                                &format!(
                                    "must be at or after {} = {} s (moves follow each other in time)",
                                    previous.0, previous.1
                                ),
                            ));
                        }
                        let end = m.end.unwrap_or(f64::INFINITY);
                        if end.is_nan() || end < m.start {
                            return Err(self.error(
                                &format!("{g}.end"),
                                end,
                                "must be >= start (s)",
                            ));
                        }
                        previous = (format!("{g}.end"), end);
                    }
                }
            }
        }
        if let Some(c) = &s.contact {
            if let Some(k) = c.stiffness {
                positive("contact.stiffness", k, "1/s^2")?;
            }
            if let Some(z) = c.damping_ratio {
                non_negative("contact.damping_ratio", z, "dimensionless")?;
            }
            if let Some(mu) = c.friction {
                non_negative("contact.friction", mu, "dimensionless")?;
            }
            if let Some(d) = c.barrier_distance {
                positive("contact.barrier_distance", d, "m")?;
            }
            if let Some(k) = c.barrier_stiffness {
                non_negative("contact.barrier_stiffness", k, "N/m^4")?;
            }
            if let Some(v) = c.friction_velocity {
                positive("contact.friction_velocity", v, "m/s")?;
            }
        }
        if let Some(init) = &s.initial {
            point("initial.origin", init.origin)?;
            for (k, &c) in init.scale.iter().enumerate() {
                if !(c.is_finite() && c > 0.0) {
                    return Err(self.error(
                        &format!("initial.scale.{k}"),
                        c,
                        "must be a finite number > 0",
                    ));
                }
            }
        }
        for (i, p) in s.probes.iter().enumerate() {
            let f = format!("probes.{i}");
            if p.name.is_empty()
                || !p
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(self.error(
                    &format!("{f}.name"),
                    format!("{:?}", p.name),
                    "must be non-empty letters, digits, `_` or `-`",
                ));
            }
            if s.probes[..i].iter().any(|q| q.name == p.name) {
                return Err(self.error(
                    &format!("{f}.name"),
                    format!("{:?}", p.name),
                    "is used twice",
                ));
            }
            point(&format!("{f}.point"), p.point)?;
        }
        if s.output.frame_every == 0 {
            return Err(self.error("output.frame_every", 0, "must be >= 1"));
        }
        non_negative("output.stress_threshold", s.output.stress_threshold, "Pa")?;
        if let Some(b) = &s.budget {
            if let Some(d) = b.duration {
                positive("budget.duration", d, "s")?;
            }
            if let Some(n) = b.reference_steps
                && !(2..=10_000).contains(&n)
            {
                return Err(self.error(
                    "budget.reference_steps",
                    n,
                    "must be an integer from 2 to 10000",
                ));
            }
            for (k, e) in b.energies.iter().enumerate() {
                if b.energies[..k].contains(e) {
                    return Err(self.error(
                        "budget.energies",
                        format!("\"{}\"", e.name()),
                        "is listed twice",
                    ));
                }
            }
        }
        let frames = s.planned_frames();
        if frames > fem_solvers::limits::MAX_RECORDED_FRAMES {
            return Err(self.error(
                "output.frame_every",
                s.output.frame_every,
                &format!(
                    "records {frames} frames, more than {} (fem_solvers::limits::MAX_RECORDED_FRAMES); raise it",
                    fem_solvers::limits::MAX_RECORDED_FRAMES
                ),
            ));
        }
        Ok(())
    }

    fn validate_regions(&self) -> Result<(), SceneError> {
        let s = &self.scene;
        if let Some(name) = &s.material.name
            && let Err(rule) = fem_mesh::io::check_region_name(name)
        {
            return Err(self.error("material.name", format!("{name:?}"), rule));
        }
        if s.regions.len() > MAX_REGIONS {
            return Err(self.error(
                "regions",
                format!("({} entries)", s.regions.len()),
                &format!("must be at most {MAX_REGIONS} entries (fem_scene::scene::MAX_REGIONS)"),
            ));
        }
        let mut names = vec![s.material.name()];
        for (i, r) in s.regions.iter().enumerate() {
            let f = format!("regions.{i}");
            if fem_mesh::io::check_region_name(&r.name).is_err() || names.contains(&r.name.as_str())
            {
                return Err(self.error(
                    &format!("{f}.name"),
                    format!("{:?}", r.name),
                    "must be non-empty, without commas, double quotes or control characters (line breaks, tabs), and differ from material.name and the other regions' names",
                ));
            }
            names.push(&r.name);
            match (&r.polygon, r.mesh_regions.is_empty()) {
                (Some(_), false) | (None, true) => {
                    return Err(self.error(
                        &format!("{f}.polygon"),
                        if r.polygon.is_some() {
                            "(given)"
                        } else {
                            "(missing)"
                        },
                        "give exactly one of polygon and mesh_regions",
                    ));
                }
                (Some(poly), true) => {
                    if poly.len() < 3 {
                        return Err(self.error(
                            &format!("{f}.polygon"),
                            format!("{} points", poly.len()),
                            "needs at least 3 points",
                        ));
                    }
                    if let Some(k) = poly.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                        return Err(self.error(
                            &format!("{f}.polygon.{k}"),
                            fmt_point(poly[k]),
                            "must have finite coordinates",
                        ));
                    }
                }
                (None, false) => {}
            }
            // The material's own rules (fem_core::Material::new: Young's modulus in
            // [MIN_YOUNGS_MODULUS, MAX_YOUNGS_MODULUS], the Poisson ratio in (-1, 0.5)), named
            // as the entry's fields. The base material's values are valid (checked above), so
            // a field the entry does not set never fails here.
            if let Err(e) = fem_core::Material::new(
                r.youngs_modulus.unwrap_or(s.material.youngs_modulus),
                r.poisson_ratio.unwrap_or(s.material.poisson_ratio),
                r.density.unwrap_or(1.0),
            ) {
                return Err(self.error(&format!("{f}.{}", e.field), readable(e.value), e.rule));
            }
        }
        Ok(())
    }

    fn validate_mesh(&self) -> Result<(), SceneError> {
        let m = &self.scene.mesh;
        let kind = m.kind.ok_or_else(|| {
            self.error(
                "mesh.kind",
                "(missing)",
                "must be one of \"rectangle\", \"file\", \"model\", \"body\", \"shank\"",
            )
        })?;
        let kind_name = match kind {
            MeshKind::Rectangle => "rectangle",
            MeshKind::File => "file",
            MeshKind::Model => "model",
            MeshKind::Body => "body",
            MeshKind::Shank => "shank",
        };
        let rect = [
            ("width", m.width.is_some()),
            ("height", m.height.is_some()),
            ("nx", m.nx.is_some()),
            ("ny", m.ny.is_some()),
            ("diagonal", m.diagonal.is_some()),
            ("origin", m.origin.is_some()),
        ];
        let pipeline = [
            ("scale", m.scale.is_some()),
            ("view", m.view.is_some()),
            ("alpha", m.alpha.is_some()),
            ("epsilon", m.epsilon.is_some()),
            ("max_area", m.max_area.is_some()),
            ("min_angle", m.min_angle.is_some()),
        ];
        let path = [
            ("path", m.path.is_some()),
            ("groups", m.groups.is_some()),
            ("skeleton", m.skeleton.is_some()),
        ];
        let allowed: Vec<&str> = match kind {
            MeshKind::Rectangle => rect.iter().map(|r| r.0).collect(),
            MeshKind::File => vec!["path"],
            MeshKind::Model => pipeline
                .iter()
                .map(|r| r.0)
                .chain(["path", "groups"])
                .collect(),
            MeshKind::Body => pipeline.iter().map(|r| r.0).chain(["skeleton"]).collect(),
            MeshKind::Shank => vec!["max_area", "min_angle"],
        };
        for (name, present) in rect.iter().chain(&pipeline).chain(&path) {
            if *present && !allowed.contains(name) {
                return Err(self.error(
                    &format!("mesh.{name}"),
                    "(set)",
                    &format!("does not apply to kind = \"{kind_name}\""),
                ));
            }
        }
        let need = |name: &str, present: bool| -> Result<(), SceneError> {
            if present {
                Ok(())
            } else {
                Err(self.error(
                    &format!("mesh.{name}"),
                    "(missing)",
                    &format!("is required for kind = \"{kind_name}\""),
                ))
            }
        };
        let positive = |name: &str, v: Option<f64>| -> Result<(), SceneError> {
            match v {
                Some(v) if !(v.is_finite() && v > 0.0) => {
                    Err(self.error(&format!("mesh.{name}"), v, "must be a finite number > 0"))
                }
                _ => Ok(()),
            }
        };
        match kind {
            MeshKind::Rectangle => {
                for (name, present) in &rect[..4] {
                    need(name, *present)?;
                }
                positive("width", m.width)?;
                positive("height", m.height)?;
                for (name, n) in [("nx", m.nx), ("ny", m.ny)] {
                    if let Some(n) = n
                        && (n == 0 || n > 10_000)
                    {
                        return Err(self.error(
                            &format!("mesh.{name}"),
                            n,
                            "must lie in 1..=10000",
                        ));
                    }
                }
                if let Some(o) = m.origin
                    && !o.iter().all(|c| c.is_finite())
                {
                    return Err(self.error(
                        "mesh.origin",
                        fmt_point(o),
                        "must have finite coordinates",
                    ));
                }
            }
            MeshKind::File | MeshKind::Model => need("path", m.path.is_some())?,
            MeshKind::Body | MeshKind::Shank => {}
        }
        positive("scale", m.scale)?;
        positive("alpha", m.alpha)?;
        positive("epsilon", m.epsilon)?;
        positive("max_area", m.max_area)?;
        if let Some(a) = m.min_angle
            && !(a.is_finite() && (0.0..=33.0).contains(&a))
        {
            return Err(self.error("mesh.min_angle", a, "must lie in [0, 33] degrees"));
        }
        if let Some(r) = m.rotate_deg
            && !r.is_finite()
        {
            return Err(self.error("mesh.rotate_deg", r, "must be a finite number"));
        }
        if let Some(p) = m.align_min
            && !p.iter().all(|c| c.is_finite())
        {
            return Err(self.error(
                "mesh.align_min",
                fmt_point(p),
                "must have finite coordinates",
            ));
        }
        Ok(())
    }
}

/// Most `[[regions]]` entries a scene may have. Tagging the elements costs one pass over them
/// per entry (a point-in-polygon test each), and every entry adds four columns to
/// `regions.csv` and a record to every summary; a body has a handful of tissues (case D:
/// soft tissue and seven bones), and a thousand leaves room for a study per muscle or per
/// skin patch while keeping that work below a run's.
pub const MAX_REGIONS: usize = 1000;

fn motion_name(m: MotionName) -> &'static str {
    match m {
        MotionName::Static => "static",
        MotionName::Kinematic => "kinematic",
        MotionName::Dynamic => "dynamic",
    }
}

/// `[x, y]` for messages (numbers too long to read in scientific notation).
pub(crate) fn fmt_point(p: [f64; 2]) -> String {
    format!("[{}, {}]", readable(p[0]), readable(p[1]))
}

/// Shoelace signed area (positive counter-clockwise).
pub(crate) fn signed_area(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        * 0.5
}
