//! What the budget compares frameworks on: a 2D scene ([`LoadedScene`]) or a 3D one
//! ([`LoadedScene3`]). The comparison itself ([`super::compare_frameworks`]) is written once
//! over [`Subject`]; each dimension says how its scene is edited, run and recorded, and what
//! it cannot run.

use fem_core::energy::EnergyKind;
use fem_scene::SceneError;
use fem_scene::run::{RunEnv, run};
use fem_scene::scene::{BudgetDefaults, LoadedScene};
use fem_scene::solid::{LoadedScene3, RunEnv3, run3_with};
use fem_solvers::SolverKind;

use super::measure::{Cell, Layout, Recorder, Recorder3, Trajectory};
use super::{BDF2_GROUP, Framework, RankBy, Setting};
use crate::files::FileSource;
use crate::run::SystemClock;

/// Why a recorded run ended early, when the budget stopped it.
pub(super) struct OverCap;

/// What the budget reads of a run's summary.
pub(super) struct Outcome {
    /// It blew up or a step failed.
    pub blew_up: bool,
    /// What happened, when it did.
    pub blow_up_message: Option<String>,
    /// Wall time of the solver's steps, s.
    pub step_seconds: f64,
    /// Solver iterations over the run.
    pub solver_iterations: u64,
    /// The largest final residual of a step (`None` for explicit).
    pub max_step_residual: Option<f64>,
}

/// A run's outcome, its trajectory and the layout of its mesh.
pub(super) type Recorded<C> = (Outcome, Trajectory<<C as Cell>::Point>, Layout<C>);

/// A scene of either dimension, as the budget uses it.
pub(super) trait Subject: Sized + Sync {
    /// Its cell: a triangle or a tetrahedron.
    type Cell: Cell;
    /// The scene's name.
    fn name(&self) -> &str;
    /// Its file, for messages.
    fn origin(&self) -> &str;
    /// Its `[budget]` table.
    fn defaults(&self) -> BudgetDefaults;
    /// `solver.steps x solver.dt`, s.
    fn scene_duration(&self) -> f64;
    /// It has a ground or obstacles.
    fn contact(&self) -> bool;
    /// [`RankBy::default_for`].
    fn rank_default(&self) -> RankBy;
    /// Its cell count.
    fn cells(&self) -> Result<usize, SceneError>;
    /// The pre-flight's seconds per reference step and cell ([`super::TimeModel`]).
    fn preflight_seconds_per_step_cell(&self) -> f64;
    /// Why `framework` cannot run it with `energy`, if it cannot.
    fn cannot_run(&self, energy: EnergyKind, framework: Framework) -> Option<String>;
    /// The settings `framework` climbs on it.
    fn ladder(&self, framework: Framework) -> Vec<Setting>;
    /// It with `energy`, `solver` and `values`, `steps` steps of `dt`; validated.
    fn variant(
        &self,
        energy: EnergyKind,
        solver: SolverKind,
        values: &[(String, toml::Value)],
        dt: f64,
        steps: u64,
    ) -> Result<Self, SceneError>;
    /// Run it on one thread recording every `every`-th step; `Ok(Err(OverCap))` once the
    /// run passed `cap` seconds.
    fn record(
        &self,
        every: u64,
        cap: Option<f64>,
    ) -> Result<Result<Recorded<Self::Cell>, OverCap>, SceneError>;
    /// `layout` with the scene's contact targets and the frame step.
    fn finish_layout(&self, layout: Layout<Self::Cell>, frame_dt: f64) -> Layout<Self::Cell>;
}

/// A pool of one thread, for timings on one thread.
fn one_thread() -> Result<rayon::ThreadPool, SceneError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| SceneError::Usage(format!("thread pool: {e}")))
}

impl Subject for LoadedScene {
    type Cell = [u32; 3];

    fn name(&self) -> &str {
        &self.scene.name
    }

    fn origin(&self) -> &str {
        &self.origin
    }

    fn defaults(&self) -> BudgetDefaults {
        self.scene.budget.clone().unwrap_or_default()
    }

    fn scene_duration(&self) -> f64 {
        self.scene.solver.dt * self.scene.solver.steps as f64
    }

    fn contact(&self) -> bool {
        self.scene.ground.is_some() || !self.scene.obstacles.is_empty()
    }

    fn rank_default(&self) -> RankBy {
        RankBy::default_for(self)
    }

    fn cells(&self) -> Result<usize, SceneError> {
        let mesh = fem_scene::build::build_mesh(self, &FileSource::for_scene(self))?;
        Ok(mesh.triangles().len())
    }

    fn preflight_seconds_per_step_cell(&self) -> f64 {
        if self.contact() {
            super::PREFLIGHT_SECONDS_PER_STEP_TRIANGLE_CONTACT
        } else {
            super::PREFLIGHT_SECONDS_PER_STEP_TRIANGLE
        }
    }

    fn cannot_run(&self, energy: EnergyKind, framework: Framework) -> Option<String> {
        let s = &self.scene;
        if self.contact() && !framework.solver().capabilities().contact {
            return Some(format!(
                "{} does not handle contact, and the scene has a ground or obstacles",
                framework.name()
            ));
        }
        if s.material.formulation == fem_scene::scene::Formulation::AveragedPressure
            && !framework.solver().capabilities().averaged_pressure
        {
            return Some(format!(
                "{} does not support the averaged nodal pressure triangle (material.formulation = averaged-pressure)",
                framework.name()
            ));
        }
        pd_energy(energy, framework)
    }

    fn ladder(&self, framework: Framework) -> Vec<Setting> {
        framework.ladder()
    }

    fn variant(
        &self,
        energy: EnergyKind,
        solver: SolverKind,
        values: &[(String, toml::Value)],
        dt: f64,
        steps: u64,
    ) -> Result<Self, SceneError> {
        crate::compare::variant_scene(self, energy, solver, &settings(values, dt, steps))
    }

    fn record(
        &self,
        every: u64,
        cap: Option<f64>,
    ) -> Result<Result<Recorded<[u32; 3]>, OverCap>, SceneError> {
        let mut scene = self.clone();
        scene.scene.output.frame_every = every;
        scene.scene.output.frames = false;
        one_thread()?.install(|| {
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
            if rec.cap.over {
                return Ok(Err(OverCap));
            }
            let s = result?.summary;
            let outcome = Outcome {
                blew_up: s.blew_up,
                blow_up_message: s.blow_up_message,
                step_seconds: s.step_seconds,
                solver_iterations: s.solver_iterations,
                max_step_residual: s.max_step_residual,
            };
            Ok(Ok((outcome, rec.trajectory, rec.layout)))
        })
    }

    fn finish_layout(&self, mut layout: Layout, frame_dt: f64) -> Layout {
        let s = &self.scene;
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
}

/// Projective Dynamics runs the co-rotational energy only.
fn pd_energy(energy: EnergyKind, framework: Framework) -> Option<String> {
    (framework == Framework::Pd && energy != EnergyKind::Corotational)
        .then(|| "Projective Dynamics runs the co-rotational energy only".into())
}

/// A rung's `[solver]` settings with its step and step count.
fn settings(values: &[(String, toml::Value)], dt: f64, steps: u64) -> Vec<(String, toml::Value)> {
    let mut settings = vec![
        ("dt".to_owned(), toml::Value::Float(dt)),
        ("steps".to_owned(), toml::Value::Integer(steps as i64)),
    ];
    settings.extend_from_slice(values);
    settings
}

/// A 3D scene: no contact, regions or `[budget]` table; a framework needs a 3D path, and
/// BDF2, which the 3D solvers do not have yet, is left out of the ladders.
impl Subject for LoadedScene3 {
    type Cell = [u32; 4];

    fn name(&self) -> &str {
        &self.scene.name
    }

    fn origin(&self) -> &str {
        &self.origin
    }

    fn defaults(&self) -> BudgetDefaults {
        BudgetDefaults::default()
    }

    fn scene_duration(&self) -> f64 {
        self.scene.solver.dt * self.scene.solver.steps as f64
    }

    fn contact(&self) -> bool {
        false
    }

    fn rank_default(&self) -> RankBy {
        RankBy::Position
    }

    fn cells(&self) -> Result<usize, SceneError> {
        let m = &self.scene.mesh;
        Ok(6 * m.nx * m.ny * m.nz)
    }

    fn preflight_seconds_per_step_cell(&self) -> f64 {
        super::PREFLIGHT_SECONDS_PER_STEP_TETRAHEDRON
    }

    fn cannot_run(&self, energy: EnergyKind, framework: Framework) -> Option<String> {
        if framework.solver().capabilities().dims < 3 {
            return Some(format!(
                "{} has no 3D path yet (docs/solvers.md#3d)",
                framework.name()
            ));
        }
        pd_energy(energy, framework)
    }

    fn ladder(&self, framework: Framework) -> Vec<Setting> {
        framework
            .ladder()
            .into_iter()
            .filter(|s| s.group != BDF2_GROUP)
            .collect()
    }

    fn variant(
        &self,
        energy: EnergyKind,
        solver: SolverKind,
        values: &[(String, toml::Value)],
        dt: f64,
        steps: u64,
    ) -> Result<Self, SceneError> {
        crate::compare::variant_scene3(self, energy, solver, &settings(values, dt, steps))
    }

    fn record(
        &self,
        every: u64,
        cap: Option<f64>,
    ) -> Result<Result<Recorded<[u32; 4]>, OverCap>, SceneError> {
        let mut scene = self.clone();
        scene.scene.output.frame_every = every as usize;
        one_thread()?.install(|| {
            let clock = SystemClock::new();
            let mut rec = Recorder3::new(cap);
            let result = run3_with(
                &scene,
                RunEnv3 {
                    clock: &clock,
                    threads: 1,
                    keep_frames: false,
                    progress: None,
                    sinks: vec![&mut rec],
                },
            );
            if rec.cap.over {
                return Ok(Err(OverCap));
            }
            let s = result?.summary;
            let outcome = Outcome {
                blew_up: s.blew_up,
                blow_up_message: s.blow_up_message,
                step_seconds: s.step_seconds,
                solver_iterations: s.iterations,
                max_step_residual: s.max_step_residual,
            };
            Ok(Ok((outcome, rec.trajectory, rec.layout)))
        })
    }

    fn finish_layout(&self, mut layout: Layout<[u32; 4]>, frame_dt: f64) -> Layout<[u32; 4]> {
        layout.frame_dt = frame_dt;
        layout
    }
}
