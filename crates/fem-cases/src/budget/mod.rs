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
//!
//! **Measured.** A stable setting's errors are measured when every value they read, in its
//! run and in the reference, is finite and no error overflowed ([`measure::non_finite`],
//! [`Errors::is_finite`]); otherwise its note says why, its numbers are left out of the
//! tables, and it is never a row's best. No table holds a NaN or an infinity.
//!
//! **Checks and the time bound.** Every setting is checked first, the error naming its flag
//! and value; the wall time is estimated from the step counts before anything runs and again
//! from what was measured, and past [`BudgetSpec::max_minutes`] the comparison stops with an
//! error naming `--max-minutes` ([`DEFAULT_MAX_MINUTES`] says why ten).

pub mod measure;
mod subject;
mod table;

use fem_core::energy::EnergyKind;
use fem_scene::SceneError;
use fem_scene::scene::LoadedScene;
use fem_scene::solid::LoadedScene3;
use fem_solvers::SolverKind;
use serde::{Deserialize, Serialize};

pub use measure::{Cell, Errors, Layout, Phase, Trajectory, WindowErrors, Windows, errors};
use subject::{OverCap, Recorded, Subject};
pub use table::{dimensions_sentence, drawable};

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
    /// The longest the whole comparison may take, in minutes of wall time: estimated before
    /// anything runs and again as it runs, it stops with an error naming
    /// `--max-minutes` once the estimate passes this. Default [`DEFAULT_MAX_MINUTES`].
    pub max_minutes: f64,
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
            max_minutes: DEFAULT_MAX_MINUTES,
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
    /// Errors against the reference (meaningful when `measured`; zero otherwise).
    pub errors: Errors,
    /// The ranking quantity's value (`None` when undefined, unstable or not measured).
    pub rank_value: Option<f64>,
    /// Its errors were measured: it is stable, every value its errors read (and the
    /// reference's) is finite, and so is every error. Only a measured setting can be a row's
    /// best; the others rank after every measured one.
    #[serde(default)]
    pub measured: bool,
    /// What its numbers do not say: why a stable setting's errors were not measured (`its
    /// von Mises stress is not finite in 908 places (...)`, `the reference's ...`), and that
    /// the largest residual of its steps was not finite (then `residual` is `None`).
    #[serde(default)]
    pub note: Option<String>,
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
    /// The reference at twice its step against it: its own error to first order (zero when
    /// `note` says it could not be estimated).
    pub error: Errors,
    /// Why its own error is not given (a value of either run that is not finite, the coarse
    /// run did not complete), or why nothing was measured against it (the reference's `...`
    /// is not finite).
    #[serde(default)]
    pub note: Option<String>,
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

/// A budget comparison with what its errors were computed from; `C` is the mesh's cell
/// (triangles, the default, or tetrahedra for a 3D scene).
#[derive(Clone, Debug)]
pub struct BudgetRun<C: Cell = [u32; 3]> {
    /// The answer.
    pub budget: Budget,
    /// The mesh, its regions and the contact targets.
    pub layout: Layout<C>,
    /// The trajectories of each energy's reference (`ENERGY-reference`), of the reference at
    /// twice its step (`ENERGY-reference-coarse`) and of each row's best setting within the
    /// budget (`ENERGY-FRAMEWORK`).
    pub trajectories: Vec<(String, Trajectory<C::Point>)>,
}

/// Default of [`BudgetSpec::max_minutes`] (`--max-minutes`): ten minutes. `fem2d budget
/// case-a` (five energies over 2 s) takes 85-90 s and `fem2d budget case-d` 46-47 s on this
/// 2-core VM with other builds running (measured 2026-11-27), and their estimates
/// are at most 3.1 and 0.8 minutes, so ten minutes leaves room for a slower or
/// busier machine or a few times the duration, and stops a run of hours (`--haptics
/// --duration 100`: a hundred thousand frames) before it starts.
pub const DEFAULT_MAX_MINUTES: f64 = 10.0;

/// The most frames a budget compares.
pub const MAX_FRAMES: u64 = 100_000;

/// The highest `--fps`: a frame of at least a nanosecond.
pub const MAX_FPS: f64 = 1e9;

/// `--budget-ms` bounds: from a nanosecond (the clock's resolution) to 1000 s a frame.
pub const BUDGET_MS_RANGE: [f64; 2] = [1e-6, 1e6];

/// The smallest `--settle`: a smaller fraction of the peak kinetic energy is round-off.
pub const MIN_SETTLE: f64 = 1e-9;

/// `--criterion` bounds (a relative error: 0.05 is 5 %).
pub const CRITERION_RANGE: [f64; 2] = [1e-9, 100.0];

/// The pre-flight's seconds per reference step per triangle (implicit Euler with Newton to
/// [`REFERENCE_TOLERANCE`], on one thread), without contact: a quarter of the cheapest
/// measured on this VM (case A's linear energy, 7.6e-7 s; its Neo-Hookean 2.9e-6 s), so the
/// estimate before anything runs refuses only what would take longer on a machine four times
/// as fast.
pub const PREFLIGHT_SECONDS_PER_STEP_TRIANGLE: f64 = 2e-7;

/// The same with contact (barrier contact, more Newton iterations a step): a quarter of case
/// D's 1.7e-5 s.
pub const PREFLIGHT_SECONDS_PER_STEP_TRIANGLE_CONTACT: f64 = 4e-6;

/// The same for a 3D scene, per tetrahedron: about a sixth of case-a-3d's Neo-Hookean and
/// StVK references on this VM (82 s for 4500 steps on 1920 tetrahedra, 9.6e-6 s), so the
/// estimate before anything runs refuses only what would take longer on a much faster machine.
pub const PREFLIGHT_SECONDS_PER_STEP_TETRAHEDRON: f64 = 1.5e-6;

/// A ladder's estimated cost in runs at the budget (`budget x frames` of stepping): it climbs
/// until a rung costs twice the budget, and the run around the stepping (recording, errors)
/// adds to it. Measured: 4.7 on case D (16 ladders, 27 s), where the ladders are cut by cost.
pub const LADDER_BUDGET_RUNS: f64 = 5.0;

/// The ladders' estimated cost of one energy over its reference's, when the ladders are not
/// cut by cost (a small mesh, a large budget). Measured on case A: 1.4 to 2.6 (Neo-Hookean
/// 14.3 s against 8.4 s).
pub const LADDERS_OVER_REFERENCE: f64 = 3.0;

/// What a budget runs, its settings checked.
struct Plan {
    energies: Vec<EnergyKind>,
    frame_dt: f64,
    frames: u64,
    /// Steps per frame of the (finer) reference.
    reference_per_frame: u64,
}

/// Where the simulated duration came from, for messages.
enum DurationFrom {
    Flag,
    Scene(&'static str),
}

impl Plan {
    /// Check every setting of `spec` on `base`, naming the flag (or the scene key) and the
    /// value of the first that is wrong.
    fn new<S: Subject>(base: &S, spec: &BudgetSpec) -> Result<Plan, SceneError> {
        use fem_core::math::readable as r;
        let usage = |m: String| Err(SceneError::Usage(m));
        if !(spec.fps.is_finite() && spec.fps > 0.0) {
            return usage(format!(
                "--fps {}: must be a finite number > 0",
                r(spec.fps)
            ));
        }
        if spec.fps > MAX_FPS {
            return usage(format!(
                "--fps {}: must be at most {MAX_FPS:e} (a frame of at least 1 ns)",
                r(spec.fps)
            ));
        }
        let frame_dt = 1.0 / spec.fps;
        if !frame_dt.is_finite() {
            return usage(format!(
                "--fps {}: its frame, 1/fps = {} s, is not a finite number of seconds",
                r(spec.fps),
                r(frame_dt)
            ));
        }
        if !(spec.budget_ms.is_finite() && spec.budget_ms > 0.0) {
            return usage(format!(
                "--budget-ms {}: must be a finite number > 0",
                r(spec.budget_ms)
            ));
        }
        if !(BUDGET_MS_RANGE[0]..=BUDGET_MS_RANGE[1]).contains(&spec.budget_ms) {
            return usage(format!(
                "--budget-ms {}: must be from {:e} ms (1 ns) to {:e} ms (1000 s) per frame",
                r(spec.budget_ms),
                BUDGET_MS_RANGE[0],
                BUDGET_MS_RANGE[1]
            ));
        }
        if !(spec.settle > 0.0 && spec.settle < 1.0) {
            return usage(format!(
                "--settle {}: must be in the open interval (0, 1)",
                r(spec.settle)
            ));
        }
        if spec.settle < MIN_SETTLE {
            return usage(format!(
                "--settle {}: must be at least {MIN_SETTLE:e} (a smaller fraction of the peak \
                 kinetic energy is round-off)",
                r(spec.settle)
            ));
        }
        if !(spec.criterion.is_finite() && spec.criterion > 0.0) {
            return usage(format!(
                "--criterion {}: must be a finite number > 0",
                r(spec.criterion)
            ));
        }
        if !(CRITERION_RANGE[0]..=CRITERION_RANGE[1]).contains(&spec.criterion) {
            return usage(format!(
                "--criterion {}: must be from {:e} to {} (a relative error: 0.05 is 5 %)",
                r(spec.criterion),
                CRITERION_RANGE[0],
                CRITERION_RANGE[1]
            ));
        }
        if !(spec.cost_cap.is_finite() && spec.cost_cap >= 1.0) {
            return usage(format!(
                "cost cap {}: must be a finite number >= 1",
                r(spec.cost_cap)
            ));
        }
        if !(spec.max_minutes.is_finite() && spec.max_minutes > 0.0) {
            return usage(format!(
                "--max-minutes {}: must be a finite number > 0",
                r(spec.max_minutes)
            ));
        }
        if spec.frameworks.is_empty() {
            return usage("--frameworks: names no framework".into());
        }
        for (k, f) in spec.frameworks.iter().enumerate() {
            if spec.frameworks[..k].contains(f) {
                return usage(format!("--frameworks: {} is listed twice", f.name()));
            }
        }
        for (k, e) in spec.energies.iter().enumerate() {
            if spec.energies[..k].contains(e) {
                return usage(format!("--energies: {} is listed twice", e.name()));
            }
        }
        let defaults = base.defaults();
        let energies: Vec<EnergyKind> = if !spec.energies.is_empty() {
            spec.energies.clone()
        } else if !defaults.energies.is_empty() {
            defaults.energies.clone()
        } else {
            EnergyKind::ALL.to_vec()
        };
        let reference_steps = spec.reference_steps.or(defaults.reference_steps);
        if let Some(n) = reference_steps
            && !(2..=10_000).contains(&n)
        {
            return usage(format!(
                "--reference-steps {n}: must be an integer from 2 to 10000"
            ));
        }
        let contact = base.contact();
        let reference_per_frame = reference_steps.unwrap_or(if contact { 10 } else { 100 });
        let (duration, from) = match (spec.duration, defaults.duration) {
            (Some(d), _) => (d, DurationFrom::Flag),
            (None, Some(d)) => (d, DurationFrom::Scene("budget.duration")),
            (None, None) => (
                base.scene_duration(),
                DurationFrom::Scene("solver.steps x solver.dt"),
            ),
        };
        let fps = r(spec.fps);
        match from {
            DurationFrom::Flag if !(duration.is_finite() && duration > 0.0) => {
                return usage(format!(
                    "--duration {}: must be a finite number > 0",
                    r(duration)
                ));
            }
            DurationFrom::Scene(key) if !(duration.is_finite() && duration > 0.0) => {
                return usage(format!(
                    "{}: {key} = {} s: must be a finite number > 0; set --duration",
                    base.origin(),
                    r(duration)
                ));
            }
            _ => {}
        }
        // A whole number of frames, at least one: a duration shorter than a frame is refused,
        // not stretched to one.
        if duration < frame_dt * (1.0 - 1e-9) {
            return usage(match from {
                DurationFrom::Flag => format!(
                    "--duration {}: shorter than one frame at --fps {fps} ({} s); make it at \
                     least one frame or raise --fps",
                    r(duration),
                    r(frame_dt)
                ),
                DurationFrom::Scene(key) => format!(
                    "--fps {fps}: one frame ({} s) is longer than the scene's duration ({key} = \
                     {} s); raise --fps or set --duration to at least one frame",
                    r(frame_dt),
                    r(duration)
                ),
            });
        }
        let count = (duration / frame_dt).round();
        if count > MAX_FRAMES as f64 {
            let n = if count.is_finite() {
                r(count)
            } else {
                "more than 1e308".into()
            };
            return usage(match from {
                DurationFrom::Flag => format!(
                    "--duration {}: {n} frames at --fps {fps}; at most {MAX_FRAMES}",
                    r(duration)
                ),
                DurationFrom::Scene(key) => format!(
                    "--fps {fps}: {n} frames over the scene's duration ({key} = {} s); at \
                     most {MAX_FRAMES} (set --duration)",
                    r(duration)
                ),
            });
        }
        Ok(Plan {
            energies,
            frame_dt,
            frames: count as u64,
            reference_per_frame,
        })
    }
}

/// The wall-time estimate of a budget, to stop one that would run for hours before it does
/// (`--max-minutes`, [`BudgetSpec::max_minutes`]). Work is proportional to simulated steps x
/// triangles, and per energy it is the reference and the ladders:
///
/// - the reference: its steps x the mesh's triangles x a cost per step and triangle, before
///   anything runs [`PREFLIGHT_SECONDS_PER_STEP_TRIANGLE`] (with contact
///   [`PREFLIGHT_SECONDS_PER_STEP_TRIANGLE_CONTACT`]; deterministic: counts only), after
///   the first reference the one measured (the coarse reference runs alongside on a second
///   thread and is not counted);
/// - the ladders: the smaller of [`LADDER_BUDGET_RUNS`] runs at the budget per ladder (they
///   are cut by cost) and [`LADDERS_OVER_REFERENCE`] times the reference (they are not: a
///   small mesh, a large budget).
///
/// After each energy the estimate is the time taken so far, extrapolated over the energies
/// left.
struct TimeModel {
    frames: u64,
    budget_s: f64,
    cells: usize,
    /// `triangles` or `tetrahedra`.
    cell_name: &'static str,
    reference_steps: u64,
    /// The pre-flight's cost of a reference step per cell.
    seconds_per_step_triangle: f64,
    /// Ladders per energy (none for a framework that cannot run it).
    ladders: Vec<usize>,
    max_minutes: f64,
}

impl TimeModel {
    fn new<S: Subject>(base: &S, spec: &BudgetSpec, plan: &Plan) -> Result<TimeModel, SceneError> {
        let ladders = plan
            .energies
            .iter()
            .map(|&e| {
                spec.frameworks
                    .iter()
                    .filter(|&&f| base.cannot_run(e, f).is_none())
                    .map(|&f| {
                        let mut groups: Vec<u8> = base.ladder(f).iter().map(|s| s.group).collect();
                        groups.dedup();
                        groups.len()
                    })
                    .sum()
            })
            .collect();
        Ok(TimeModel {
            frames: plan.frames,
            budget_s: spec.budget_ms * 1e-3,
            cells: base.cells()?,
            cell_name: S::Cell::PLURAL,
            reference_steps: plan.frames * plan.reference_per_frame,
            seconds_per_step_triangle: base.preflight_seconds_per_step_cell(),
            ladders,
            max_minutes: spec.max_minutes,
        })
    }

    /// Seconds of one energy's ladders.
    fn ladders(&self, ladders: usize, reference_s: f64) -> f64 {
        (ladders as f64 * LADDER_BUDGET_RUNS * self.budget_s * self.frames as f64)
            .min(LADDERS_OVER_REFERENCE * reference_s)
    }

    /// Seconds of the energies from the `from`-th on, each reference taking `reference_s`.
    fn energies(&self, from: usize, reference_s: f64) -> f64 {
        self.ladders[from.min(self.ladders.len())..]
            .iter()
            .map(|&l| reference_s + self.ladders(l, reference_s))
            .sum()
    }

    /// The estimate before anything runs.
    fn preflight(&self) -> Result<String, SceneError> {
        let reference_s =
            (self.reference_steps as f64) * self.cells as f64 * self.seconds_per_step_triangle;
        self.check(
            self.energies(0, reference_s),
            &format!(
                "estimated before running, from the step counts: {} x (a reference of {} \
                 steps on {} {} + up to {} ladders of settings over {} frames)",
                match self.ladders.len() {
                    1 => "1 energy".to_owned(),
                    n => format!("{n} energies"),
                },
                self.reference_steps,
                self.cells,
                self.cell_name,
                self.ladders.iter().max().copied().unwrap_or(0),
                self.frames
            ),
        )
    }

    /// Refuse when `seconds` pass the limit; otherwise the estimate in words, for the
    /// progress.
    fn check(&self, seconds: f64, how: &str) -> Result<String, SceneError> {
        let minutes = seconds / 60.0;
        let about = minutes_text(seconds);
        if minutes <= self.max_minutes {
            return Ok(format!(
                "about {about} in all, {how} (--max-minutes {})",
                fem_core::math::readable(self.max_minutes)
            ));
        }
        Err(self.passed(&format!("the budget would take about {about} ({how})")))
    }

    /// The error once the limit is passed: `what` happened.
    fn passed(&self, what: &str) -> SceneError {
        SceneError::Usage(format!(
            "--max-minutes {}: {what}; shorten --duration, choose fewer --frameworks or \
             --energies, or raise --max-minutes",
            fem_core::math::readable(self.max_minutes)
        ))
    }
}

/// `seconds` in minutes, for messages (`0.038 minutes (2.3 s)`, `3.1 minutes`, `107 minutes`).
fn minutes_text(seconds: f64) -> String {
    let minutes = seconds / 60.0;
    if minutes < 0.1 {
        format!("{minutes:.3} minutes ({seconds:.1} s)")
    } else if minutes < 10.0 {
        format!("{minutes:.1} minutes")
    } else if minutes < 1e6 {
        format!("{minutes:.0} minutes")
    } else {
        format!("{minutes:.1e} minutes")
    }
}

/// Run the budget comparison of `base` (see the module docs); `progress` is told what runs.
///
/// Every setting is checked first, the error naming its flag and value (`--fps 1e-320:
/// ...`). The wall time is estimated before anything runs, after each energy's reference and
/// after each energy, and the comparison stops with an error naming
/// `--max-minutes` once the estimate passes [`BudgetSpec::max_minutes`].
pub fn budget(
    base: &LoadedScene,
    spec: &BudgetSpec,
    progress: impl FnMut(&str),
) -> Result<BudgetRun, SceneError> {
    compare_frameworks(base, spec, progress)
}

/// [`budget`] on a 3D scene (`dim = 3`, [`fem_scene::solid`]): the same ladders, reference,
/// errors and ranking over tetrahedra (the von Mises field's L2 error weighted by rest
/// volume). A 3D scene has no contact or regions, so it is ranked by position RMS unless
/// `rank_by` says otherwise; a framework without a 3D path (linearly implicit Euler) is a row
/// that cannot run, and the BDF2 rungs are left out (the 3D solvers have backward Euler only).
pub fn budget3(
    base: &LoadedScene3,
    spec: &BudgetSpec,
    progress: impl FnMut(&str),
) -> Result<BudgetRun<[u32; 4]>, SceneError> {
    compare_frameworks(base, spec, progress)
}

/// The comparison of [`budget`] and [`budget3`], written once over the scene's dimension.
fn compare_frameworks<S: Subject>(
    base: &S,
    spec: &BudgetSpec,
    mut progress: impl FnMut(&str),
) -> Result<BudgetRun<S::Cell>, SceneError> {
    let started = std::time::Instant::now();
    let plan = Plan::new(base, spec)?;
    let model = TimeModel::new(base, spec, &plan)?;
    progress(&format!("wall time: {}", model.preflight()?));
    let Plan {
        energies,
        frame_dt,
        frames,
        reference_per_frame: per_frame,
        ..
    } = plan;
    let rank_by = spec.rank_by.unwrap_or_else(|| base.rank_default());
    let cap = spec.cost_cap * spec.budget_ms * 1e-3 * frames as f64;
    let mut lay = Layout::default();
    let mut trials = Vec::new();
    let mut rows = Vec::new();
    let mut kept = Vec::new();
    let mut references = Vec::new();
    let mut reference_label = String::new();
    let mut reference_seconds = Vec::new();
    for (k, &energy) in energies.iter().enumerate() {
        // The reference of this energy: implicit Euler converged to round-off, at a hundredth
        // of the frame step; with contact at a tenth (its barrier contact is the framework's
        // converged contact: the penalty of explicit FEM penetrates by a depth its stiffness
        // sets, whatever the step). Then again at twice that step, for its own error.
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
        // The reference has no cost cap, but it may not outlast what is left of
        // `--max-minutes`.
        let left = spec.max_minutes * 60.0 - started.elapsed().as_secs_f64();
        let too_long = || {
            model.passed(&format!(
                "{energy}'s reference was stopped after {} in all",
                minutes_text(started.elapsed().as_secs_f64())
            ))
        };
        // `Ok(Err(why))`: the reference did not complete.
        let run_reference = |per: u64| -> Result<Result<Recorded<S::Cell>, String>, SceneError> {
            let scene = base.variant(
                energy,
                SolverKind::Implicit,
                &values,
                frame_dt / per as f64,
                frames * per,
            )?;
            let Ok((result, trajectory, layout)) = scene.record(per, Some(left.max(0.0)))? else {
                return Err(too_long());
            };
            if result.blew_up {
                return Ok(Err(format!(
                    "the reference run ({}, {energy}) did not complete: {}",
                    label_of(per),
                    result.blow_up_message.clone().unwrap_or_default()
                )));
            }
            Ok(Ok((result, trajectory, layout)))
        };
        progress(&format!(
            "{energy}: reference ({}; and at half as many steps, alongside)",
            label_of(per_frame)
        ));
        let reference_started = std::time::Instant::now();
        // The two references are not timed: they run side by side, each on one thread.
        let (fine, coarse) = std::thread::scope(|scope| {
            let coarse = scope.spawn(|| run_reference(per_frame / 2));
            let fine = run_reference(per_frame);
            (fine, coarse.join())
        });
        let coarse =
            coarse.map_err(|_| SceneError::Scene("the coarse reference run panicked".into()))??;
        reference_label = label_of(per_frame);
        let (_, reference, fine_layout) =
            match fine? {
                Ok(fine) => fine,
                Err(why) => {
                    // Nothing to measure against: every framework of this energy says so, and
                    // none is run.
                    for &framework in &spec.frameworks {
                        rows.push(Row {
                            energy,
                            framework,
                            cannot_run: Some(base.cannot_run(energy, framework).unwrap_or_else(
                                || format!("no reference to measure against: {why}"),
                            )),
                            cheapest: None,
                            best: None,
                        });
                    }
                    continue;
                }
            };
        reference_seconds.push(reference_started.elapsed().as_secs_f64());
        lay = base.finish_layout(fine_layout, frame_dt);
        let windows = Windows::find(&lay, &reference, spec.settle);
        // A reference with a value that is not finite measures nothing.
        let reference_note =
            measure::non_finite(&lay, &reference).map(|w| format!("the reference's {w}"));
        let (error, note) = match (&reference_note, &coarse) {
            (Some(w), _) => (Errors::default(), Some(w.clone())),
            (None, Err(why)) => (Errors::default(), Some(why.clone())),
            (None, Ok((_, coarse, _))) => match measure::non_finite(&lay, coarse) {
                Some(w) => (
                    Errors::default(),
                    Some(format!("the reference at half as many steps: {w}")),
                ),
                None => {
                    let e = errors(&lay, &windows, coarse, &reference);
                    if e.is_finite() {
                        (e, None)
                    } else {
                        (
                            Errors::default(),
                            Some(
                                "its error against itself at half as many steps overflowed".into(),
                            ),
                        )
                    }
                }
            },
        };
        references.push(Reference {
            energy,
            windows,
            error,
            note,
        });
        // The estimate once this reference took what it took.
        let mean_reference = reference_seconds.iter().sum::<f64>() / reference_seconds.len() as f64;
        let estimate = model.check(
            started.elapsed().as_secs_f64()
                + model.ladders(model.ladders[k], mean_reference)
                + model.energies(k + 1, mean_reference),
            &format!(
                "estimated after {energy}'s reference, which took {:.1} s",
                reference_seconds.last().copied().unwrap_or_default()
            ),
        )?;
        progress(&format!("wall time: {estimate}"));
        let key = |t: &Trial| {
            (
                t.rank_value.unwrap_or(f64::INFINITY),
                t.errors.whole.position_rms,
            )
        };
        for &framework in &spec.frameworks {
            if let Some(why) = base.cannot_run(energy, framework) {
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
            let mut best: Option<(Trial, Trajectory<_>)> = None;
            let mut skip_group: Option<u8> = None;
            for setting in base.ladder(framework) {
                if skip_group == Some(setting.group) {
                    continue;
                }
                let per = setting.steps_per_frame;
                let scene = base.variant(
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
                    measured: false,
                    note: None,
                };
                let (trajectory, residual_note) = match scene.record(per, Some(cap))? {
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
                    Ok((s, trajectory, _)) => {
                        trial.stable = !s.blew_up;
                        trial.failure = s.blow_up_message.clone();
                        trial.ms_per_frame = 1e3 * s.step_seconds / frames as f64;
                        trial.iterations_per_frame = s.solver_iterations as f64 / frames as f64;
                        // A residual that is not finite is not written as a number.
                        trial.residual = s.max_step_residual.filter(|r| r.is_finite());
                        let note = s
                            .max_step_residual
                            .filter(|r| !r.is_finite())
                            .map(|_| "its largest step residual is not finite".to_owned());
                        (trajectory, note)
                    }
                };
                if trial.stable {
                    measure_trial(
                        &mut trial,
                        &lay,
                        &windows,
                        &trajectory,
                        &reference,
                        reference_note.as_deref(),
                        rank_by,
                    );
                }
                if let Some(r) = residual_note {
                    trial.note = Some(match trial.note.take() {
                        Some(w) => format!("{w}; {r}"),
                        None => r,
                    });
                }
                trials.push(trial.clone());
                let ms = trial.ms_per_frame;
                if trial.stable && cheapest.is_none() {
                    cheapest = Some(trial.clone());
                }
                // Only a measured rung can be a row's best: one whose error is unknown ranks
                // after every measured one.
                if trial.measured
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
        if let Ok((_, coarse, _)) = coarse {
            kept.push((format!("{}-reference-coarse", energy.name()), coarse));
        }
        // The time so far, extrapolated over the energies left.
        let done = k + 1;
        if done < energies.len() {
            let elapsed = started.elapsed().as_secs_f64();
            let estimate = model.check(
                elapsed + (energies.len() - done) as f64 * elapsed / done as f64,
                &format!(
                    "estimated after {done} of {} energies, which took {}",
                    energies.len(),
                    minutes_text(elapsed)
                ),
            )?;
            progress(&format!("wall time: {estimate}"));
        }
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
        scene: base.name().to_owned(),
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

/// Measure a stable `trial` against the reference: its errors and ranking value, or in its
/// note why they cannot be measured (a value of the reference or of the run that is not
/// finite, an error that overflowed); then it is not `measured` and its errors stay zero.
fn measure_trial<C: Cell>(
    trial: &mut Trial,
    lay: &Layout<C>,
    windows: &Windows,
    trajectory: &Trajectory<C::Point>,
    reference: &Trajectory<C::Point>,
    reference_note: Option<&str>,
    rank_by: RankBy,
) {
    let why = reference_note
        .map(str::to_owned)
        .or_else(|| measure::non_finite(lay, trajectory).map(|w| format!("its {w}")));
    if let Some(w) = why {
        trial.note = Some(w);
        return;
    }
    let e = errors(lay, windows, trajectory, reference);
    if !e.is_finite() {
        trial.note = Some("an error against the reference overflowed (is not finite)".into());
        return;
    }
    trial.rank_value = rank_by.value(&e, windows);
    trial.errors = e;
    trial.measured = true;
}

/// Scientific notation with three digits; 0 as `0` (a body at rest: no error at all).
pub(crate) fn sci(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x:.2e}")
    }
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
        Some(0.0) => "0 %".into(),
        Some(x) if x >= 0.1 => format!("{:.0} %", 100.0 * x),
        Some(x) if x >= 0.01 => format!("{:.1} %", 100.0 * x),
        Some(x) => format!("{:.2} %", 100.0 * x),
    }
}

impl<C: Cell> BudgetRun<C> {
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
        // A chart with nothing to draw (no measured setting at all) is not written.
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
            .filter(|(_, _, c)| drawable(c))
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
