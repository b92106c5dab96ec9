//! The frame-budget answer: which energy x framework combination, at which setting, fits a
//! real-time frame, and how wrong it is in what the user reads.
//!
//! For a scene, a frame rate `fps` (the time step every framework must advance per frame,
//! `1 / fps`) and a physics budget per frame (milliseconds on one thread), every framework
//! climbs ladders of settings from the cheapest up ([`Framework::ladder`]): fixed counts
//! (substeps for explicit; substeps x iterations for PBD and XPBD, in XPBD's two schedules;
//! sweeps for VBD; iterations for Projective Dynamics and quasi-Newton; CG iterations, then the
//! Cholesky preconditioner's refresh and the direct solve, for linearly implicit Euler; the
//! velocity tolerance, then Newton's tolerance, for implicit Euler) and, for the iterative
//! solvers, residual tolerances (VBD, XPBD, PD and quasi-Newton stop when their residual falls
//! below the tolerance, at most 200 iterations). The solvers with a choice of time integrator
//! (implicit Euler, VBD, PD, quasi-Newton) climb their fixed ladder again under BDF2.
//! Each rung runs the scene's whole duration on one thread; its stepping time per frame, the
//! iterations it actually used and the largest residual its steps ended with are reported.
//!
//! **Reference.** Each energy's motion computed to convergence in time: implicit Euler at a
//! hundredth of the frame step with Newton's tolerance [`REFERENCE_TOLERANCE`], or, for a scene with contact, at
//! a tenth of the frame step with barrier contact (the penalty and projection solvers' errors
//! then include the barrier's cushion of up to `barrier_distance`, 1 mm). Rigid regions are
//! rigid bodies in it as in every framework. Explicit FEM is no reference for contact: its
//! penalty penetration is set by its stiffness, not by the step (6.5 mm on case D at half its
//! critical step), and at half its critical step it costs a thousand steps a frame. The
//! reference's own error is estimated by running it again at twice its step: for a first-order
//! method the difference between the two is the finer one's error, to first order
//! ([`Budget::references`]).
//!
//! **Errors** ([`measure::Errors`]) are taken per window ([`measure::Windows`], found on the
//! reference): the whole run; the impact, from the first contact (with an obstacle, or the
//! ground in a scene without one) until the reference's kinetic energy has fallen for good
//! below [`BudgetSpec::settle`] (1 %) of its peak; and the sustained phase after it. In each: position RMS and max; for the soft tissue (the
//! deformable regions, together and each) the relative L2 error of the von Mises field and the
//! relative error of its peak; for each rigid region the relative L2 error of the tissue's
//! force and torque on its bodies; for each contact target (the ground, each obstacle) the
//! relative error of its peak pressure and of its impulse; the absolute area error and the
//! most inverted triangles.
//!
//! **Ranking** by a declared quantity ([`RankBy`]): by default the soft tissue's stress in the
//! sustained phase when the scene has material regions or contact, position otherwise. Each
//! row's "best" is its stable setting within the budget with the smallest such error; the
//! table also gives its cheapest stable setting. One sentence per energy names the best and
//! the quantity, and with contact says which settings (if any) get both the sustained soft
//! tissue stress and peak contact pressure within [`BudgetSpec::criterion`] (5 %), or which
//! comes closest.

pub mod measure;
mod table;

use fem_core::energy::EnergyKind;
use fem_scene::SceneError;
use fem_scene::run::{RunEnv, RunResult, run};
use fem_scene::scene::LoadedScene;
use fem_solvers::SolverKind;
use serde::{Deserialize, Serialize};

use crate::files::FileSource;
use crate::run::SystemClock;
use measure::Recorder;
pub use measure::{Errors, Layout, Phase, Trajectory, WindowErrors, Windows, errors};

/// The frameworks a budget compares. Serde and command-line names: [`Framework::name`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Framework {
    /// Explicit FEM, climbing substeps.
    Explicit,
    /// Energy-based PBD, substeps x iterations.
    Pbd,
    /// XPBD, one substep of n iterations (and more substeps once iterations are many).
    Xpbd,
    /// XPBD "small steps": n substeps of one iteration.
    XpbdSmallSteps,
    /// Vertex Block Descent, sweeps.
    Vbd,
    /// Projective Dynamics (co-rotational only), iterations.
    Pd,
    /// Quasi-Newton (L-BFGS with the PD matrix), iterations.
    QuasiNewton,
    /// Linearly implicit Euler (one linear solve a step): CG iterations, then the Cholesky
    /// preconditioner's refresh, then the direct solve.
    LinearImplicit,
    /// Implicit Euler by Newton, tolerance.
    Implicit,
}

/// Newton's tolerance of the reference (relative to the force scale). Its solver error is then
/// far below its own time-discretisation error, which the budget estimates and states (on
/// case D, 1e-8 against 1e-10 moves no error of the table in its second digit and halves the
/// reference's cost).
pub const REFERENCE_TOLERANCE: f64 = 1e-8;

/// Most iterations of a tolerance rung (the top of the fixed ladders).
pub const TOLERANCE_MAX_ITERATIONS: u64 = 200;

impl Framework {
    /// Every framework, in table order.
    pub const ALL: [Framework; 9] = [
        Framework::Explicit,
        Framework::Pbd,
        Framework::Xpbd,
        Framework::XpbdSmallSteps,
        Framework::Vbd,
        Framework::Pd,
        Framework::QuasiNewton,
        Framework::LinearImplicit,
        Framework::Implicit,
    ];

    /// The name in tables and on the command line: the solver's, or `xpbd-small-steps`.
    pub fn name(self) -> &'static str {
        match self {
            Framework::XpbdSmallSteps => "xpbd-small-steps",
            f => f.solver().name(),
        }
    }

    /// The solver it runs.
    pub fn solver(self) -> SolverKind {
        match self {
            Framework::Explicit => SolverKind::Explicit,
            Framework::Pbd => SolverKind::Pbd,
            Framework::Xpbd | Framework::XpbdSmallSteps => SolverKind::Xpbd,
            Framework::Vbd => SolverKind::Vbd,
            Framework::Pd => SolverKind::Pd,
            Framework::QuasiNewton => SolverKind::QuasiNewton,
            Framework::LinearImplicit => SolverKind::LinearImplicit,
            Framework::Implicit => SolverKind::Implicit,
        }
    }

    /// Parse a name.
    pub fn parse(name: &str) -> Result<Framework, String> {
        Framework::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = Framework::ALL.iter().map(|f| f.name()).collect();
                format!(
                    "unknown framework `{name}` (expected one of: {})",
                    names.join(", ")
                )
            })
    }

    /// Its settings from the cheapest up: the fixed-count ladder (group 0), then for the
    /// iterative solvers the residual-tolerance ladder (group 1), loosest first, then for the
    /// solvers with a choice of time integrator a BDF2 ladder (group 2, [`BDF2_GROUP`]).
    /// Linearly implicit Euler climbs CG-Jacobi's iterations (group 0), then the Cholesky
    /// preconditioner's refresh period down to the direct solve (group 1).
    pub fn ladder(self) -> Vec<Setting> {
        let mut l = self.backward_euler_ladder();
        if self.solver().default_params().integrator().is_some() {
            l.extend(self.bdf2_ladder());
        }
        l
    }

    /// The BDF2 rungs (`integrator = "bdf2"`): implicit Euler's velocity tolerances, the
    /// iterative solvers' iteration counts from 2 to 100.
    fn bdf2_ladder(self) -> Vec<Setting> {
        let bdf2 = ("integrator".to_owned(), toml::Value::String("bdf2".into()));
        let base: Vec<Setting> = match self {
            Framework::Implicit => self
                .backward_euler_ladder()
                .into_iter()
                .filter(|s| s.group == 0)
                .collect(),
            _ => self
                .backward_euler_ladder()
                .into_iter()
                .filter(|s| {
                    s.group == 0
                        && [2, 5, 10, 20, 50, 100]
                            .map(|n| format!("{n} iterations"))
                            .contains(&s.label)
                })
                .collect(),
        };
        base.into_iter()
            .map(|mut s| {
                s.label = format!("bdf2, {}", s.label);
                s.values.push(bdf2.clone());
                s.group = BDF2_GROUP;
                s
            })
            .collect()
    }

    /// The ladders of backward Euler (every framework's time stepping but BDF2's rungs).
    fn backward_euler_ladder(self) -> Vec<Setting> {
        let int = |n: u64| toml::Value::Integer(n as i64);
        let sweeps = [1u64, 2, 3, 5, 10, 20, 50, 100, 200];
        let fixed = |label: String, values: Vec<(String, toml::Value)>| Setting {
            label,
            values,
            steps_per_frame: 1,
            tolerance: None,
            group: 0,
        };
        // Quasi-Newton's own `tolerance`; VBD, PD and XPBD's `residual_tolerance` (the flat
        // `[solver]` table's `tolerance` is implicit Euler's Newton tolerance).
        let key = if self == Framework::QuasiNewton {
            "tolerance"
        } else {
            "residual_tolerance"
        };
        let tolerances = |extra: Vec<(String, toml::Value)>, tols: &[f64]| -> Vec<Setting> {
            tols.iter()
                .map(|&t| {
                    let mut values = extra.clone();
                    values.push(("iterations".into(), int(TOLERANCE_MAX_ITERATIONS)));
                    values.push((key.into(), toml::Value::Float(t)));
                    Setting {
                        label: format!("tolerance {t:e}"),
                        values,
                        steps_per_frame: 1,
                        tolerance: Some(t),
                        group: 1,
                    }
                })
                .collect()
        };
        match self {
            Framework::Explicit => [
                1u64, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256,
            ]
            .iter()
            .map(|&n| Setting {
                steps_per_frame: n,
                ..fixed(format!("{n} substeps"), Vec::new())
            })
            .collect(),
            Framework::Pbd => sweeps
                .iter()
                .map(|&n| {
                    fixed(
                        format!("{n} iterations"),
                        vec![("substeps".into(), int(1)), ("iterations".into(), int(n))],
                    )
                })
                .collect(),
            Framework::Xpbd => {
                let mut l: Vec<Setting> = sweeps
                    .iter()
                    .map(|&n| {
                        fixed(
                            format!("{n} iterations"),
                            vec![("substeps".into(), int(1)), ("iterations".into(), int(n))],
                        )
                    })
                    .collect();
                // XPBD's residual is relative to the substep's first iteration.
                l.extend(tolerances(
                    vec![("substeps".into(), int(1))],
                    &[1e-1, 1e-2, 1e-3],
                ));
                l
            }
            // The named setting: n sweeps spent as n substeps of one.
            Framework::XpbdSmallSteps => sweeps
                .iter()
                .map(|&n| {
                    fixed(
                        format!("{n} substeps x 1"),
                        vec![
                            ("substeps".into(), int(1)),
                            ("iterations".into(), int(n)),
                            ("xpbd_schedule".into(), "small-steps".into()),
                        ],
                    )
                })
                .collect(),
            Framework::Vbd | Framework::Pd | Framework::QuasiNewton => {
                let mut l: Vec<Setting> = sweeps
                    .iter()
                    .map(|&n| {
                        fixed(
                            format!("{n} iterations"),
                            vec![("iterations".into(), int(n))],
                        )
                    })
                    .collect();
                l.extend(tolerances(Vec::new(), &[1e-2, 1e-4, 1e-6]));
                l
            }
            // CG with Jacobi's preconditioner for a fixed count (its tolerance 0: every
            // iteration runs), then CG preconditioned by a Cholesky factor refreshed every
            // `refresh` steps (to its default tolerance 1e-5), then the direct solve.
            Framework::LinearImplicit => [10u64, 25, 50, 100, 200]
                .iter()
                .map(|&n| {
                    fixed(
                        format!("cg-jacobi, {n} iterations"),
                        vec![
                            ("linear_solver".into(), "cg-jacobi".into()),
                            ("cg_iterations".into(), int(n)),
                            ("cg_tolerance".into(), toml::Value::Float(0.0)),
                        ],
                    )
                })
                .chain([30u64, 10, 3].iter().map(|&r| Setting {
                    group: 1,
                    ..fixed(
                        format!("cg-cholesky, refresh {r}"),
                        vec![
                            ("linear_solver".into(), "cg-cholesky".into()),
                            ("refresh".into(), int(r)),
                        ],
                    )
                }))
                .chain(std::iter::once(Setting {
                    group: 1,
                    ..fixed(
                        "direct".into(),
                        vec![("linear_solver".into(), "direct".into())],
                    )
                }))
                .collect(),
            // Newton's real-time stopping rule (a full step below the velocity tolerance times
            // the step, Newton's tolerance 1e-8 behind it), then its residual tolerance alone.
            Framework::Implicit => [1e-2, 1e-3, 1e-4]
                .iter()
                .map(|&v| {
                    fixed(
                        format!("velocity {v:e} m/s"),
                        vec![("velocity_tolerance".into(), toml::Value::Float(v))],
                    )
                })
                .chain([1e-2, 1e-4, 1e-6, 1e-8].iter().map(|&t| Setting {
                    tolerance: Some(t),
                    group: 1,
                    ..fixed(
                        format!("tolerance {t:e}"),
                        vec![
                            ("tolerance".into(), toml::Value::Float(t)),
                            ("velocity_tolerance".into(), toml::Value::Float(0.0)),
                        ],
                    )
                }))
                .collect(),
        }
    }
}

/// The ladder group of the BDF2 rungs ([`Framework::ladder`]).
pub const BDF2_GROUP: u8 = 2;

/// One rung of a ladder: solver parameters and how many steps make a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// Short label (`10 iterations`, `tolerance 1e-3`).
    pub label: String,
    /// `[solver]` keys and values set on the scene.
    pub values: Vec<(String, toml::Value)>,
    /// Steps per frame (explicit's substeps; 1 otherwise: the solver substeps itself).
    pub steps_per_frame: u64,
    /// The residual tolerance of a tolerance rung (and implicit Euler's Newton tolerance).
    pub tolerance: Option<f64>,
    /// The ladder it belongs to: 0 fixed counts, 1 residual tolerances (linearly implicit
    /// Euler: the Cholesky-preconditioned and direct solves), 2 BDF2 ([`BDF2_GROUP`]). A
    /// ladder stops once a rung costs twice the budget; the next ladder starts from its
    /// cheapest rung again.
    pub group: u8,
}

/// The quantity frameworks are ranked by (and each row's best setting chosen by).
/// Command-line names: [`RankBy::name`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RankBy {
    /// Position RMS over the whole run, m.
    Position,
    /// The soft tissue's von Mises field in the sustained phase, relative L2 error.
    Stress,
    /// The soft tissue's von Mises field in the impact window, relative L2 error.
    StressImpact,
    /// The largest relative error of a contact target's peak pressure, sustained phase.
    Pressure,
    /// The same in the impact window.
    PressureImpact,
}

impl RankBy {
    /// Every quantity.
    pub const ALL: [RankBy; 5] = [
        RankBy::Position,
        RankBy::Stress,
        RankBy::StressImpact,
        RankBy::Pressure,
        RankBy::PressureImpact,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            RankBy::Position => "position",
            RankBy::Stress => "stress",
            RankBy::StressImpact => "stress-impact",
            RankBy::Pressure => "pressure",
            RankBy::PressureImpact => "pressure-impact",
        }
    }

    /// Parse a name.
    pub fn parse(name: &str) -> Result<RankBy, String> {
        RankBy::ALL
            .into_iter()
            .find(|r| r.name() == name)
            .ok_or_else(|| {
                let names: Vec<&str> = RankBy::ALL.iter().map(|r| r.name()).collect();
                format!(
                    "unknown quantity `{name}` (expected one of: {})",
                    names.join(", ")
                )
            })
    }

    /// The default for `scene`: the soft tissue's sustained stress when the scene has material
    /// regions or contact (a medical scene), position otherwise.
    pub fn default_for(scene: &LoadedScene) -> RankBy {
        let s = &scene.scene;
        if !s.regions.is_empty() || s.ground.is_some() || !s.obstacles.is_empty() {
            RankBy::Stress
        } else {
            RankBy::Position
        }
    }

    /// The window it is measured over (`Whole` for position).
    pub fn phase(self) -> Phase {
        match self {
            RankBy::Position => Phase::Whole,
            RankBy::Stress | RankBy::Pressure => Phase::Sustained,
            RankBy::StressImpact | RankBy::PressureImpact => Phase::Impact,
        }
    }

    /// The window it is measured over given `windows` (the whole run when the phase does not
    /// exist: no contact, or a reference that never settles).
    pub fn effective_phase(self, windows: &Windows) -> Phase {
        let p = self.phase();
        if windows.get(p).is_some() {
            p
        } else {
            Phase::Whole
        }
    }

    /// Its value in `errors` (`None` when undefined: no stress or no contact in the
    /// reference's window).
    pub fn value(self, errors: &Errors, windows: &Windows) -> Option<f64> {
        let w = errors.get(self.effective_phase(windows))?;
        match self {
            RankBy::Position => Some(w.position_rms),
            RankBy::Stress | RankBy::StressImpact => w.stress_l2,
            RankBy::Pressure | RankBy::PressureImpact => w.pressure_peak,
        }
    }

    /// What it is, in words, for sentences and captions.
    pub fn describe(self, windows: &Windows) -> String {
        let phase = match self.effective_phase(windows) {
            Phase::Whole => "over the whole run",
            Phase::Impact => "in the impact window",
            Phase::Sustained => "in the sustained phase",
        };
        match self {
            RankBy::Position => format!("position RMS {phase} (m)"),
            RankBy::Stress | RankBy::StressImpact => {
                format!("the soft tissue's von Mises stress {phase} (relative L2 error)")
            }
            RankBy::Pressure | RankBy::PressureImpact => {
                format!("the peak contact pressure {phase} (relative error)")
            }
        }
    }
}

/// What to compare and against what.
#[derive(Clone, Debug)]
pub struct BudgetSpec {
    /// Frames per second: every framework advances `1 / fps` per frame. Default 90.
    pub fps: f64,
    /// Physics budget per frame on one thread, ms. Default 5.
    pub budget_ms: f64,
    /// Simulated seconds (`None`: the scene's `[budget] duration`, else its `steps x dt`).
    pub duration: Option<f64>,
    /// Energies (empty: the scene's `[budget] energies`, else all five).
    pub energies: Vec<EnergyKind>,
    /// Frameworks (default all).
    pub frameworks: Vec<Framework>,
    /// The ranking quantity (`None`: [`RankBy::default_for`] the scene).
    pub rank_by: Option<RankBy>,
    /// The impact ends when the reference's kinetic energy has fallen for good below this
    /// fraction of its peak, dimensionless, in (0, 1). Default 0.01.
    pub settle: f64,
    /// The relative error a medical answer must stay within, for the sustained soft tissue
    /// stress (L2) and the peak contact pressure, dimensionless. Default 0.05.
    pub criterion: f64,
    /// A rung is stopped once its stepping time exceeds this many times the budget over the
    /// whole run (it cannot be chosen, and its dearer neighbours are skipped). Default 4.
    pub cost_cap: f64,
    /// Steps per frame of the reference (`None`: the scene's `[budget] reference_steps`, else
    /// 10 with contact, 100 without; at least 2, its own error is estimated at half as many).
    pub reference_steps: Option<u64>,
}

impl Default for BudgetSpec {
    fn default() -> Self {
        BudgetSpec {
            fps: 90.0,
            budget_ms: 5.0,
            duration: None,
            energies: Vec::new(),
            frameworks: Framework::ALL.to_vec(),
            rank_by: None,
            settle: 0.01,
            criterion: 0.05,
            cost_cap: 4.0,
            reference_steps: None,
        }
    }
}

impl BudgetSpec {
    /// The haptics preset: 1 kHz, 0.5 ms.
    pub fn haptics() -> Self {
        BudgetSpec {
            fps: 1000.0,
            budget_ms: 0.5,
            ..BudgetSpec::default()
        }
    }
}

/// One setting's run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// The energy.
    pub energy: EnergyKind,
    /// The framework.
    pub framework: Framework,
    /// The setting's label.
    pub setting: String,
    /// The residual tolerance of a tolerance rung (or implicit Euler's Newton tolerance).
    pub tolerance: Option<f64>,
    /// Completed without a blow-up or a solver failure.
    pub stable: bool,
    /// Why not (a blow-up, a failed step, stopped over the cost cap).
    pub failure: Option<String>,
    /// Stopped because it cost more than [`BudgetSpec::cost_cap`] times the budget.
    pub over_cap: bool,
    /// Stepping time per frame on one thread, ms (NaN, `null` in JSON, for a rung stopped
    /// over the cost cap).
    #[serde(deserialize_with = "measure::nan_or_number")]
    pub ms_per_frame: f64,
    /// Solver iterations per frame actually used (sweeps, constraint, local-global, L-BFGS or
    /// Newton iterations, summed over substeps; 0 for explicit; NaN for a rung stopped over the
    /// cost cap).
    #[serde(deserialize_with = "measure::nan_or_number")]
    pub iterations_per_frame: f64,
    /// The largest final residual of a step over the run, in the solver's measure
    /// (`summary.json`'s `max_step_residual`); `None` for explicit.
    pub residual: Option<f64>,
    /// Errors against the reference (meaningful when stable).
    pub errors: Errors,
    /// The ranking quantity's value (`None` when undefined or unstable).
    pub rank_value: Option<f64>,
}

/// One energy x framework row of the table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The energy.
    pub energy: EnergyKind,
    /// The framework.
    pub framework: Framework,
    /// Why the framework cannot run the scene with this energy, if so.
    pub cannot_run: Option<String>,
    /// The cheapest stable setting.
    pub cheapest: Option<Trial>,
    /// The most accurate stable setting within the budget (smallest ranking quantity; ties
    /// and undefined values by position RMS).
    pub best: Option<Trial>,
}

/// An energy's reference (run as [`Budget::reference`] says): its windows and its own
/// estimated error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// The energy.
    pub energy: EnergyKind,
    /// The windows found on it.
    pub windows: Windows,
    /// The reference at twice its step against it: its own error to first order.
    pub error: Errors,
}

/// The whole answer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Budget {
    /// The scene's name.
    pub scene: String,
    /// Frames per second.
    pub fps: f64,
    /// Budget per frame, ms.
    pub budget_ms: f64,
    /// Frames compared.
    pub frames: u64,
    /// How the reference was run (`implicit Euler at dt = ... s (10 steps per frame), Newton
    /// tolerance 1e-8`).
    pub reference: String,
    /// The ranking quantity.
    pub rank_by: RankBy,
    /// [`BudgetSpec::criterion`].
    pub criterion: f64,
    /// [`BudgetSpec::cost_cap`].
    pub cost_cap: f64,
    /// Per energy: the reference's windows and its estimated error.
    pub references: Vec<Reference>,
    /// Every setting tried, ladder order.
    pub trials: Vec<Trial>,
    /// Per energy, the frameworks ranked (best within the budget first; those without one
    /// last).
    pub rows: Vec<Row>,
    /// One sentence per energy.
    pub sentences: Vec<String>,
}

/// Why a recorded run ended early, when the budget stopped it.
struct OverCap;

/// What [`record`] returns: the run's result, its trajectory and the mesh's layout.
type Recorded = (RunResult, Trajectory, Layout);

/// Run `scene` on one thread recording every `every`-th step; the result, its trajectory and
/// the layout of its mesh, or `Ok(Err(OverCap))` once the run passed `cap` seconds.
fn record(
    scene: &LoadedScene,
    every: u64,
    cap: Option<f64>,
) -> Result<Result<Recorded, OverCap>, SceneError> {
    let mut scene = scene.clone();
    scene.scene.output.frame_every = every;
    scene.scene.output.frames = false;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| SceneError::Usage(format!("thread pool: {e}")))?;
    pool.install(|| {
        let clock = SystemClock::new();
        let files = FileSource::for_scene(&scene);
        let mut rec = Recorder::new(
            scene.scene.ground.is_some(),
            scene.scene.obstacles.len(),
            cap,
        );
        let result = {
            let mut env = RunEnv {
                clock: &clock,
                files: &files,
                progress: None,
                sinks: vec![&mut rec],
                snapshot_every: None,
                drag: None,
            };
            run(&scene, &mut env)
        };
        if rec.over_cap {
            return Ok(Err(OverCap));
        }
        Ok(Ok((result?, rec.trajectory, rec.layout)))
    })
}

/// `scene` with `energy`, `solver` and `values`, `steps` steps of `dt`; validated (the typed
/// edit of a comparison's rows).
fn variant(
    base: &LoadedScene,
    energy: EnergyKind,
    solver: SolverKind,
    values: &[(String, toml::Value)],
    dt: f64,
    steps: u64,
) -> Result<LoadedScene, SceneError> {
    let mut settings = vec![
        ("dt".to_owned(), toml::Value::Float(dt)),
        ("steps".to_owned(), toml::Value::Integer(steps as i64)),
    ];
    settings.extend_from_slice(values);
    crate::compare::variant_scene(base, energy, solver, &settings)
}

/// Why `framework` cannot run `scene` with `energy`, if it cannot.
fn cannot_run(scene: &LoadedScene, energy: EnergyKind, framework: Framework) -> Option<String> {
    let s = &scene.scene;
    let contact = s.ground.is_some() || !s.obstacles.is_empty();
    if contact && !framework.solver().capabilities().contact {
        return Some(format!(
            "{} does not handle contact, and the scene has a ground or obstacles",
            framework.name()
        ));
    }
    if framework == Framework::Pd && energy != EnergyKind::Corotational {
        return Some("Projective Dynamics runs the co-rotational energy only".into());
    }
    None
}

/// A budget comparison with what its errors were computed from.
#[derive(Clone, Debug)]
pub struct BudgetRun {
    /// The answer.
    pub budget: Budget,
    /// The mesh, its regions and the contact targets.
    pub layout: Layout,
    /// The trajectories of each energy's reference (`ENERGY-reference`), of the reference at
    /// twice its step (`ENERGY-reference-coarse`) and of each row's best setting within the
    /// budget (`ENERGY-FRAMEWORK`).
    pub trajectories: Vec<(String, Trajectory)>,
}

/// `layout` with `scene`'s contact targets (the ground, then each obstacle) and the frame step.
fn with_targets(scene: &LoadedScene, mut layout: Layout, frame_dt: f64) -> Layout {
    let s = &scene.scene;
    layout.contact_targets.clear();
    if s.ground.is_some() {
        layout.contact_targets.push("ground".to_owned());
    }
    for (k, o) in s.obstacles.iter().enumerate() {
        layout.contact_targets.push(if o.name.is_empty() {
            format!("obstacle {k}")
        } else {
            o.name.clone()
        });
    }
    layout.has_ground = s.ground.is_some();
    layout.frame_dt = frame_dt;
    layout
}

/// Run the budget comparison of `base` (see the module docs); `progress` is told what runs.
pub fn budget(
    base: &LoadedScene,
    spec: &BudgetSpec,
    mut progress: impl FnMut(&str),
) -> Result<BudgetRun, SceneError> {
    let s = &base.scene;
    if !(spec.fps.is_finite() && spec.fps > 0.0) {
        return Err(SceneError::Usage(format!(
            "--fps {}: must be a finite number > 0",
            spec.fps
        )));
    }
    if !(spec.budget_ms.is_finite() && spec.budget_ms > 0.0) {
        return Err(SceneError::Usage(format!(
            "--budget-ms {}: must be a finite number > 0",
            spec.budget_ms
        )));
    }
    if !(spec.settle > 0.0 && spec.settle < 1.0) {
        return Err(SceneError::Usage(format!(
            "--settle {}: must be in the open interval (0, 1)",
            spec.settle
        )));
    }
    if !(spec.criterion.is_finite() && spec.criterion > 0.0) {
        return Err(SceneError::Usage(format!(
            "--criterion {}: must be a finite number > 0",
            spec.criterion
        )));
    }
    if !(spec.cost_cap.is_finite() && spec.cost_cap >= 1.0) {
        return Err(SceneError::Usage(format!(
            "cost cap {}: must be a finite number >= 1",
            spec.cost_cap
        )));
    }
    let defaults = s.budget.clone().unwrap_or_default();
    let energies: Vec<EnergyKind> = if !spec.energies.is_empty() {
        spec.energies.clone()
    } else if !defaults.energies.is_empty() {
        defaults.energies.clone()
    } else {
        EnergyKind::ALL.to_vec()
    };
    let reference_steps = spec.reference_steps.or(defaults.reference_steps);
    if reference_steps.is_some_and(|n| !(2..=10_000).contains(&n)) {
        return Err(SceneError::Usage(format!(
            "--reference-steps {}: must be an integer from 2 to 10000",
            reference_steps.unwrap_or_default()
        )));
    }
    let frame_dt = 1.0 / spec.fps;
    let duration = spec
        .duration
        .or(defaults.duration)
        .unwrap_or(s.solver.dt * s.solver.steps as f64);
    if !(duration.is_finite() && duration > 0.0) {
        return Err(SceneError::Usage(format!(
            "--duration {duration}: must be a finite number > 0"
        )));
    }
    let frames = (duration / frame_dt).round().max(1.0) as u64;
    if frames > 100_000 {
        return Err(SceneError::Usage(format!(
            "{frames} frames ({duration} s at {} frames per second): at most 100000",
            spec.fps
        )));
    }
    let rank_by = spec.rank_by.unwrap_or_else(|| RankBy::default_for(base));
    let contact = s.ground.is_some() || !s.obstacles.is_empty();
    let cap = spec.cost_cap * spec.budget_ms * 1e-3 * frames as f64;
    let mut lay = Layout::default();
    let mut trials = Vec::new();
    let mut rows = Vec::new();
    let mut kept = Vec::new();
    let mut references = Vec::new();
    let mut reference_label = String::new();
    for &energy in &energies {
        // The reference of this energy: implicit Euler converged to round-off, at a hundredth
        // of the frame step; with contact at a tenth (its barrier contact is the framework's
        // converged contact: the penalty of explicit FEM penetrates by a depth its stiffness
        // sets, whatever the step). Then again at twice that step, for its own error.
        let per_frame: u64 = reference_steps.unwrap_or(if contact { 10 } else { 100 });
        let values = vec![
            (
                "tolerance".to_owned(),
                toml::Value::Float(REFERENCE_TOLERANCE),
            ),
            ("max_iterations".to_owned(), toml::Value::Integer(200)),
            // Newton's tolerance alone stops it.
            ("velocity_tolerance".to_owned(), toml::Value::Float(0.0)),
        ];
        let label_of = |per: u64| {
            format!(
                "implicit Euler at dt = {:e} s ({per} steps per frame), Newton tolerance {REFERENCE_TOLERANCE:e}",
                frame_dt / per as f64
            )
        };
        let run_reference = |per: u64| -> Result<Recorded, SceneError> {
            let scene = variant(
                base,
                energy,
                SolverKind::Implicit,
                &values,
                frame_dt / per as f64,
                frames * per,
            )?;
            let Ok((result, trajectory, layout)) = record(&scene, per, None)? else {
                unreachable!("a run without a cap is never stopped");
            };
            if result.summary.blew_up {
                return Err(SceneError::Scene(format!(
                    "{}: the reference run ({}, {energy}) did not complete: {}",
                    base.origin,
                    label_of(per),
                    result.summary.blow_up_message.clone().unwrap_or_default()
                )));
            }
            Ok((result, trajectory, layout))
        };
        progress(&format!(
            "{energy}: reference ({}; and at half as many steps, alongside)",
            label_of(per_frame)
        ));
        // The two references are not timed: they run side by side, each on one thread.
        let (fine, coarse) = std::thread::scope(|scope| {
            let coarse = scope.spawn(|| run_reference(per_frame / 2));
            let fine = run_reference(per_frame);
            (fine, coarse.join())
        });
        let (_, reference, fine_layout) = fine?;
        let (_, coarse, _) =
            coarse.map_err(|_| SceneError::Scene("the coarse reference run panicked".into()))??;
        reference_label = label_of(per_frame);
        lay = with_targets(base, fine_layout, frame_dt);
        let windows = Windows::find(&lay, &reference, spec.settle);
        references.push(Reference {
            energy,
            windows,
            error: errors(&lay, &windows, &coarse, &reference),
        });
        let key = |t: &Trial| {
            (
                t.rank_value.unwrap_or(f64::INFINITY),
                t.errors.whole.position_rms,
            )
        };
        for &framework in &spec.frameworks {
            if let Some(why) = cannot_run(base, energy, framework) {
                rows.push(Row {
                    energy,
                    framework,
                    cannot_run: Some(why),
                    cheapest: None,
                    best: None,
                });
                continue;
            }
            progress(&format!("{energy}: {}", framework.name()));
            let mut cheapest: Option<Trial> = None;
            let mut best: Option<(Trial, Trajectory)> = None;
            let mut skip_group: Option<u8> = None;
            for setting in framework.ladder() {
                if skip_group == Some(setting.group) {
                    continue;
                }
                let per = setting.steps_per_frame;
                let scene = variant(
                    base,
                    energy,
                    framework.solver(),
                    &setting.values,
                    frame_dt / per as f64,
                    frames * per,
                )?;
                let mut trial = Trial {
                    energy,
                    framework,
                    setting: setting.label.clone(),
                    tolerance: setting.tolerance,
                    stable: false,
                    failure: None,
                    over_cap: false,
                    ms_per_frame: f64::NAN,
                    iterations_per_frame: f64::NAN,
                    residual: None,
                    errors: Errors::default(),
                    rank_value: None,
                };
                let trajectory = match record(&scene, per, Some(cap))? {
                    Err(OverCap) => {
                        trial.over_cap = true;
                        trial.failure = Some(format!(
                            "stopped: its stepping passed {} times the budget over the run",
                            fmt_num(spec.cost_cap)
                        ));
                        trials.push(trial);
                        skip_group = Some(setting.group);
                        continue;
                    }
                    Ok((result, trajectory, _)) => {
                        let s = &result.summary;
                        trial.stable = !s.blew_up;
                        trial.failure = s.blow_up_message.clone();
                        trial.ms_per_frame = 1e3 * s.step_seconds / frames as f64;
                        trial.iterations_per_frame = s.solver_iterations as f64 / frames as f64;
                        trial.residual = s.max_step_residual;
                        trajectory
                    }
                };
                if trial.stable {
                    trial.errors = errors(&lay, &windows, &trajectory, &reference);
                    trial.rank_value = rank_by.value(&trial.errors, &windows);
                }
                trials.push(trial.clone());
                let ms = trial.ms_per_frame;
                if trial.stable && cheapest.is_none() {
                    cheapest = Some(trial.clone());
                }
                if trial.stable
                    && ms <= spec.budget_ms
                    && best.as_ref().is_none_or(|(b, _)| {
                        key(&trial).partial_cmp(&key(b)).is_some_and(|o| o.is_lt())
                    })
                {
                    best = Some((trial.clone(), trajectory));
                }
                // Past the budget (after a stable rung), dearer settings of this ladder
                // cannot be chosen.
                if ms > 2.0 * spec.budget_ms && cheapest.is_some() {
                    skip_group = Some(setting.group);
                }
            }
            let best = best.map(|(t, traj)| {
                kept.push((format!("{}-{}", energy.name(), framework.name()), traj));
                t
            });
            rows.push(Row {
                energy,
                framework,
                cannot_run: None,
                cheapest,
                best,
            });
        }
        kept.push((format!("{}-reference", energy.name()), reference));
        kept.push((format!("{}-reference-coarse", energy.name()), coarse));
    }
    // Rank within each energy: the best setting's ranking quantity first.
    rows.sort_by(|a, b| {
        let key = |r: &Row| {
            r.best.as_ref().map_or((f64::INFINITY, f64::INFINITY), |t| {
                (
                    t.rank_value.unwrap_or(f64::INFINITY),
                    t.errors.whole.position_rms,
                )
            })
        };
        let ea = energies.iter().position(|e| *e == a.energy);
        let eb = energies.iter().position(|e| *e == b.energy);
        let (ka, kb) = (key(a), key(b));
        ea.cmp(&eb)
            .then(ka.0.total_cmp(&kb.0))
            .then(ka.1.total_cmp(&kb.1))
            .then(a.framework.cmp(&b.framework))
    });
    let mut budget = Budget {
        scene: s.name.clone(),
        fps: spec.fps,
        budget_ms: spec.budget_ms,
        frames,
        reference: reference_label,
        rank_by,
        criterion: spec.criterion,
        cost_cap: spec.cost_cap,
        references,
        trials,
        rows,
        sentences: Vec::new(),
    };
    budget.sentences = energies
        .iter()
        .map(|&e| table::sentence(&budget, e, spec))
        .collect();
    Ok(BudgetRun {
        budget,
        layout: lay,
        trajectories: kept,
    })
}

pub(crate) fn sci(x: f64) -> String {
    format!("{x:.2e}")
}

pub(crate) fn fmt_num(x: f64) -> String {
    if x >= 100.0 || (x.fract() == 0.0 && x.abs() < 1e15) {
        format!("{x:.0}")
    } else if x >= 1.0 {
        format!("{x:.2}")
    } else {
        format!("{x:.3}")
    }
}

/// A relative error as a percentage with two significant digits (`-` when undefined).
pub(crate) fn pct(x: Option<f64>) -> String {
    match x {
        None => "-".into(),
        Some(x) if !x.is_finite() => "-".into(),
        Some(x) if x >= 0.1 => format!("{:.0} %", 100.0 * x),
        Some(x) if x >= 0.01 => format!("{:.1} %", 100.0 * x),
        Some(x) => format!("{:.2} %", 100.0 * x),
    }
}

impl BudgetRun {
    /// Write `budget.md`, `budget.csv`, `budget.json`, one `pareto-ENERGY.svg` and `.png` and
    /// one `phases-ENERGY.svg` and `.png` per energy, and with `trajectories`
    /// `trajectories.json` (the layout, the windows, and every trajectory the table's errors
    /// come from) into `dir`.
    pub fn write(
        &self,
        dir: &std::path::Path,
        trajectories: bool,
    ) -> Result<Vec<String>, SceneError> {
        use crate::run::write_atomic;
        let render = |e: fem_render::RenderError| SceneError::Io(e.to_string());
        let mut written = Vec::new();
        let mut put = |name: &str, bytes: &[u8]| -> Result<(), SceneError> {
            write_atomic(&dir.join(name), bytes)?;
            written.push(name.to_owned());
            Ok(())
        };
        put("budget.md", self.budget.to_markdown().as_bytes())?;
        put("budget.csv", self.budget.to_csv().as_bytes())?;
        let json = serde_json::to_string_pretty(&self.budget)
            .map_err(|e| SceneError::Io(format!("budget.json: {e}")))?;
        put("budget.json", json.as_bytes())?;
        // A chart with nothing to draw (no stable setting at all) is not written.
        for (prefix, energy, chart) in self
            .budget
            .charts()
            .into_iter()
            .map(|(e, c)| ("pareto", e, c))
            .chain(
                self.phase_charts()
                    .into_iter()
                    .map(|(e, c)| ("phases", e, c)),
            )
            .filter(|(_, _, c)| c.series.iter().any(|s| !s.points.is_empty()))
        {
            let svg = chart.to_svg().map_err(render)?;
            put(&format!("{prefix}-{}.svg", energy.name()), svg.as_bytes())?;
            let png = chart.to_png().map_err(render)?.to_png().map_err(render)?;
            put(&format!("{prefix}-{}.png", energy.name()), &png)?;
        }
        if !trajectories {
            return Ok(written);
        }
        let value = serde_json::json!({
            "layout": self.layout,
            "windows": self
                .budget
                .references
                .iter()
                .map(|r| (r.energy.name().to_owned(), r.windows))
                .collect::<std::collections::BTreeMap<_, _>>(),
            "trajectories": self
                .trajectories
                .iter()
                .map(|(name, t)| (name.clone(), t))
                .collect::<std::collections::BTreeMap<_, _>>(),
        });
        let text = serde_json::to_string(&value)
            .map_err(|e| SceneError::Io(format!("trajectories.json: {e}")))?;
        put("trajectories.json", text.as_bytes())?;
        Ok(written)
    }
}
