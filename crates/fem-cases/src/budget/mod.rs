//! The frame-budget answer: which energy x framework combination, at which setting, fits a
//! real-time frame, and how wrong it is.
//!
//! For a scene, a frame rate `fps` (the time step every framework must advance per frame,
//! `1 / fps`) and a physics budget per frame (milliseconds on one thread), every framework
//! climbs a ladder of settings from the cheapest up ([`Framework::ladder`]: substeps for
//! explicit; substeps x iterations for PBD and XPBD, in XPBD's two schedules; sweeps for VBD;
//! iterations for Projective Dynamics and quasi-Newton; Newton's tolerance for implicit Euler),
//! each run over the scene's whole duration on one thread. Every setting's run is measured
//! (stepping time per frame) and compared frame by frame with a converged **reference** of the
//! same energy: implicit Euler at a hundredth of the frame step with Newton's tolerance 1e-10
//! (its own first-order error then a hundredth of implicit Euler's at the frame step), or, for
//! a scene with contact, at a tenth of the frame step with barrier contact (the penalty and
//! projection solvers' errors then include the barrier's cushion of up to
//! `barrier_distance`, 1 mm). Explicit FEM with penalty contact is no reference for contact:
//! its penetration is set by the penalty stiffness, not the step (on case D with rigid bones,
//! 6.5 mm at half the critical step, and its debris slides 4.6 cm further in 0.5 s than under
//! barrier friction: 1.1e-2 m RMS between the two). The errors are over the whole mesh
//! ([`Errors`]): position RMS and max over all vertices and frames, the relative error of the
//! peak von Mises stress, the largest absolute area error (the per-triangle area differences,
//! summed without cancelling, over the body's area) and the most inverted triangles in a
//! frame.
//!
//! A setting is **stable** when its run completes without a blow-up or a solver failure; a
//! framework that cannot run the scene at all (Projective Dynamics with an energy other than
//! co-rotational, PD and quasi-Newton with contact) says why. For each energy x framework the
//! table gives the cheapest stable setting and the most accurate stable setting within the
//! budget; frameworks are ranked per energy by the latter's position RMS, and one sentence per
//! energy names the best.

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use fem_scene::SceneError;
use fem_scene::run::{Frame, FrameSink, RunEnv, RunResult, run};
use fem_scene::scene::LoadedScene;
use fem_solvers::SolverKind;
use serde::{Deserialize, Serialize};

use crate::files::FileSource;
use crate::run::SystemClock;

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
    /// Implicit Euler by Newton, tolerance.
    Implicit,
}

impl Framework {
    /// Every framework, in table order.
    pub const ALL: [Framework; 8] = [
        Framework::Explicit,
        Framework::Pbd,
        Framework::Xpbd,
        Framework::XpbdSmallSteps,
        Framework::Vbd,
        Framework::Pd,
        Framework::QuasiNewton,
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

    /// Its settings from the cheapest up.
    pub fn ladder(self) -> Vec<Setting> {
        let int = |n: u64| toml::Value::Integer(n as i64);
        let sweeps = [1u64, 2, 3, 5, 10, 20, 50, 100, 200];
        match self {
            Framework::Explicit => [
                1u64, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256,
            ]
            .iter()
            .map(|&n| Setting {
                label: format!("{n} substeps"),
                values: Vec::new(),
                steps_per_frame: n,
            })
            .collect(),
            Framework::Pbd | Framework::Xpbd => sweeps
                .iter()
                .map(|&n| Setting {
                    label: format!("{n} iterations"),
                    values: vec![("substeps".into(), int(1)), ("iterations".into(), int(n))],
                    steps_per_frame: 1,
                })
                .collect(),
            // The named setting: n sweeps spent as n substeps of one.
            Framework::XpbdSmallSteps => sweeps
                .iter()
                .map(|&n| Setting {
                    label: format!("{n} substeps x 1"),
                    values: vec![
                        ("substeps".into(), int(1)),
                        ("iterations".into(), int(n)),
                        ("xpbd_schedule".into(), "small-steps".into()),
                    ],
                    steps_per_frame: 1,
                })
                .collect(),
            Framework::Vbd | Framework::Pd | Framework::QuasiNewton => sweeps
                .iter()
                .map(|&n| Setting {
                    label: format!("{n} iterations"),
                    values: vec![("iterations".into(), int(n))],
                    steps_per_frame: 1,
                })
                .collect(),
            Framework::Implicit => [1e-2, 1e-4, 1e-6, 1e-8]
                .iter()
                .map(|&t| Setting {
                    label: format!("tolerance {t:e}"),
                    values: vec![("tolerance".into(), toml::Value::Float(t))],
                    steps_per_frame: 1,
                })
                .collect(),
        }
    }
}

/// One rung of a ladder: solver parameters and how many steps make a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// Short label (`10 iterations`).
    pub label: String,
    /// `[solver]` keys and values set on the scene.
    pub values: Vec<(String, toml::Value)>,
    /// Steps per frame (explicit's substeps; 1 otherwise: the solver substeps itself).
    pub steps_per_frame: u64,
}

/// What to compare and against what.
#[derive(Clone, Debug)]
pub struct BudgetSpec {
    /// Frames per second: every framework advances `1 / fps` per frame. Default 90.
    pub fps: f64,
    /// Physics budget per frame on one thread, ms. Default 5.
    pub budget_ms: f64,
    /// Simulated seconds (default: the scene's `steps x dt`).
    pub duration: Option<f64>,
    /// Energies (default all five).
    pub energies: Vec<EnergyKind>,
    /// Frameworks (default all).
    pub frameworks: Vec<Framework>,
}

impl Default for BudgetSpec {
    fn default() -> Self {
        BudgetSpec {
            fps: 90.0,
            budget_ms: 5.0,
            duration: None,
            energies: EnergyKind::ALL.to_vec(),
            frameworks: Framework::ALL.to_vec(),
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

/// Errors of a run against the reference, over the whole mesh and every frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Errors {
    /// RMS over all vertices and frames of the distance to the reference, m.
    pub position_rms: f64,
    /// Largest distance to the reference, m.
    pub position_max: f64,
    /// `|peak von Mises - the reference's| / the reference's` (peaks over all frames).
    pub peak_von_mises: f64,
    /// Largest over frames of `sum_e |a_e - a_e,ref| / A`: the absolute area error.
    pub area: f64,
    /// Most triangles with `det F <= 0` in one frame.
    pub inverted: usize,
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
    /// Completed without a blow-up or a solver failure.
    pub stable: bool,
    /// Why not (a blow-up, a failed step).
    pub failure: Option<String>,
    /// Stepping time per frame on one thread, ms.
    pub ms_per_frame: f64,
    /// Errors against the reference (meaningful when stable).
    pub errors: Errors,
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
    /// The most accurate stable setting within the budget (smallest position RMS).
    pub best: Option<Trial>,
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
    /// How the reference was run (`implicit Euler, dt = ..., tolerance 1e-10`).
    pub reference: String,
    /// Every setting tried, ladder order.
    pub trials: Vec<Trial>,
    /// Per energy, the frameworks ranked (best within the budget first; those without one
    /// last).
    pub rows: Vec<Row>,
    /// One sentence per energy.
    pub sentences: Vec<String>,
}

/// Positions at every frame.
#[derive(Default)]
struct Recorder {
    frames: Vec<Vec<[f64; 2]>>,
    peak_von_mises: f64,
}

impl FrameSink for Recorder {
    fn frame(&mut self, f: &Frame<'_>) -> Result<(), SceneError> {
        self.frames
            .push(f.positions.iter().map(|p| [p.x, p.y]).collect());
        for &v in f.von_mises {
            if v.is_finite() {
                self.peak_von_mises = self.peak_von_mises.max(v);
            }
        }
        Ok(())
    }
}

/// A run's trajectory: positions at each frame and the peak von Mises stress over them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Positions per frame (the first at t = 0), m.
    pub frames: Vec<Vec<[f64; 2]>>,
    /// Peak per-element von Mises stress over the recorded frames, Pa.
    pub peak_von_mises: f64,
}

/// Run `scene` on one thread recording every `every`-th step; the result, its trajectory and
/// its stepping time.
fn record(scene: &LoadedScene, every: u64) -> Result<(RunResult, Trajectory), SceneError> {
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
        let mut rec = Recorder::default();
        let result = {
            let mut env = RunEnv {
                clock: &clock,
                files: &files,
                progress: None,
                sinks: vec![&mut rec],
                snapshot_every: None,
                drag: None,
            };
            run(&scene, &mut env)?
        };
        Ok((
            result,
            Trajectory {
                frames: rec.frames,
                peak_von_mises: rec.peak_von_mises,
            },
        ))
    })
}

/// The errors of `run` against `reference` on the mesh `rest`/`triangles` (see [`Errors`]);
/// frames beyond the shorter of the two are not compared.
pub fn errors(
    rest: &[[f64; 2]],
    triangles: &[[u32; 3]],
    run: &Trajectory,
    reference: &Trajectory,
) -> Errors {
    let area = |x: &[[f64; 2]], t: &[u32; 3]| {
        let (a, b, c) = (x[t[0] as usize], x[t[1] as usize], x[t[2] as usize]);
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    };
    let total: f64 = triangles.iter().map(|t| area(rest, t)).sum();
    let mut e = Errors::default();
    let (mut sum, mut count) = (0.0, 0usize);
    for (x, r) in run.frames.iter().zip(&reference.frames) {
        for (p, q) in x.iter().zip(r) {
            let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
            sum += d2;
            count += 1;
            e.position_max = e.position_max.max(d2.sqrt());
        }
        let mut frame_area = 0.0;
        let mut inverted = 0;
        for t in triangles {
            let a = area(x, t);
            frame_area += (a - area(r, t)).abs();
            inverted += usize::from(a <= 0.0);
        }
        e.area = e.area.max(frame_area / total);
        e.inverted = e.inverted.max(inverted);
    }
    e.position_rms = if count > 0 {
        (sum / count as f64).sqrt()
    } else {
        f64::NAN
    };
    e.peak_von_mises =
        (run.peak_von_mises - reference.peak_von_mises).abs() / reference.peak_von_mises;
    e
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
    /// Rest positions of the mesh, m.
    pub rest: Vec<[f64; 2]>,
    /// Its triangles.
    pub triangles: Vec<[u32; 3]>,
    /// The trajectories of each energy's reference (`ENERGY-reference`) and of each row's best
    /// setting within the budget (`ENERGY-FRAMEWORK`).
    pub trajectories: Vec<(String, Trajectory)>,
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
    let frame_dt = 1.0 / spec.fps;
    let duration = spec.duration.unwrap_or(s.solver.dt * s.solver.steps as f64);
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
    let contact = s.ground.is_some() || !s.obstacles.is_empty();
    let mut mesh = (Vec::new(), Vec::new());
    let mut trials = Vec::new();
    let mut rows = Vec::new();
    let mut kept = Vec::new();
    let mut reference_label = String::new();
    for &energy in &spec.energies {
        // The reference of this energy.
        // Implicit Euler converged to round-off, at a hundredth of the frame step; with
        // contact at a tenth (its barrier contact is the framework's converged contact: the
        // penalty of explicit FEM penetrates by a depth its stiffness sets, whatever the step).
        let per_frame: u64 = if contact { 10 } else { 100 };
        let (solver, values): (SolverKind, Vec<(String, toml::Value)>) = (
            SolverKind::Implicit,
            vec![
                ("tolerance".into(), toml::Value::Float(1e-10)),
                ("max_iterations".into(), toml::Value::Integer(200)),
            ],
        );
        let dt = frame_dt / per_frame as f64;
        reference_label = format!("{solver}, dt = {dt:e} s ({per_frame} steps per frame)");
        progress(&format!("{energy}: reference ({reference_label})"));
        let scene = variant(base, energy, solver, &values, dt, frames * per_frame)?;
        let (result, reference) = record(&scene, per_frame)?;
        if result.summary.blew_up {
            return Err(SceneError::Scene(format!(
                "{}: the reference run ({reference_label}, {energy}) did not complete: {}",
                base.origin,
                result.summary.blow_up_message.clone().unwrap_or_default()
            )));
        }
        let (rest, triangles) = (result.rest.clone(), result.triangles.clone());
        mesh = (rest.clone(), triangles.clone());
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
            for setting in framework.ladder() {
                let per = setting.steps_per_frame;
                let scene = variant(
                    base,
                    energy,
                    framework.solver(),
                    &setting.values,
                    frame_dt / per as f64,
                    frames * per,
                )?;
                let (result, trajectory) = record(&scene, per)?;
                let stable = !result.summary.blew_up;
                let ms = 1e3 * result.summary.step_seconds / frames as f64;
                let trial = Trial {
                    energy,
                    framework,
                    setting: setting.label.clone(),
                    stable,
                    failure: result.summary.blow_up_message.clone(),
                    ms_per_frame: ms,
                    errors: if stable {
                        errors(&rest, &triangles, &trajectory, &reference)
                    } else {
                        Errors::default()
                    },
                };
                trials.push(trial.clone());
                if stable && cheapest.is_none() {
                    cheapest = Some(trial.clone());
                }
                if stable
                    && ms <= spec.budget_ms
                    && best
                        .as_ref()
                        .is_none_or(|(b, _)| trial.errors.position_rms < b.errors.position_rms)
                {
                    best = Some((trial.clone(), trajectory));
                }
                // Past the budget (after a stable rung), dearer settings cannot be chosen.
                if ms > 2.0 * spec.budget_ms && cheapest.is_some() {
                    break;
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
    }
    // Rank within each energy: best position RMS within the budget first.
    rows.sort_by(|a, b| {
        let key = |r: &Row| {
            r.best
                .as_ref()
                .map_or(f64::INFINITY, |t| t.errors.position_rms)
        };
        let ea = spec.energies.iter().position(|e| *e == a.energy);
        let eb = spec.energies.iter().position(|e| *e == b.energy);
        ea.cmp(&eb)
            .then(key(a).total_cmp(&key(b)))
            .then(a.framework.cmp(&b.framework))
    });
    let sentences = spec
        .energies
        .iter()
        .map(|&e| sentence(&rows, e, spec))
        .collect();
    Ok(BudgetRun {
        budget: Budget {
            scene: s.name.clone(),
            fps: spec.fps,
            budget_ms: spec.budget_ms,
            frames,
            reference: reference_label,
            trials,
            rows,
            sentences,
        },
        rest: mesh.0,
        triangles: mesh.1,
        trajectories: kept,
    })
}

/// One sentence naming the best framework of `energy` within the budget.
fn sentence(rows: &[Row], energy: EnergyKind, spec: &BudgetSpec) -> String {
    let mine: Vec<&Row> = rows.iter().filter(|r| r.energy == energy).collect();
    let within: Vec<&Row> = mine.iter().copied().filter(|r| r.best.is_some()).collect();
    let head = format!(
        "{energy} at {} Hz within {} ms per frame",
        fmt_num(spec.fps),
        fmt_num(spec.budget_ms)
    );
    match within.first() {
        None => format!("{head}: no framework has a stable setting within the budget."),
        Some(r) => {
            let b = r.best.as_ref().expect("filtered");
            let mut out = format!(
                "{head}: {} ({}) is the most accurate, position RMS {} m, {} ms per frame",
                r.framework.name(),
                b.setting,
                sci(b.errors.position_rms),
                fmt_num(b.ms_per_frame)
            );
            if let Some(next) = within.get(1) {
                let n = next.best.as_ref().expect("filtered");
                let _ = write!(
                    out,
                    "; next {} ({}), {} m",
                    next.framework.name(),
                    n.setting,
                    sci(n.errors.position_rms)
                );
            }
            out.push('.');
            out
        }
    }
}

fn sci(x: f64) -> String {
    format!("{x:.2e}")
}

fn fmt_num(x: f64) -> String {
    if x >= 100.0 || (x.fract() == 0.0 && x.abs() < 1e15) {
        format!("{x:.0}")
    } else if x >= 1.0 {
        format!("{x:.2}")
    } else {
        format!("{x:.3}")
    }
}

impl Budget {
    /// The ranked table (one section per energy), the sentences and the reference.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "# Frame budget: {} at {} Hz, {} ms per frame (one thread)\n\n\
             {} frames; reference: {}. Errors over the whole mesh and every frame: position \
             RMS and max (m), peak von Mises (relative), absolute area error (relative), most \
             inverted triangles in a frame.\n\n",
            self.scene,
            fmt_num(self.fps),
            fmt_num(self.budget_ms),
            self.frames,
            self.reference
        );
        for sentence in &self.sentences {
            let _ = writeln!(s, "- {sentence}");
        }
        let mut energy = None;
        for r in &self.rows {
            if energy != Some(r.energy) {
                energy = Some(r.energy);
                let _ = write!(
                    s,
                    "\n## {}\n\n| rank | framework | best within budget | ms/frame | position RMS | position max | peak von Mises | area | inverted | cheapest stable | its ms/frame | its position RMS |\n|---:|---|---|---:|---:|---:|---:|---:|---:|---|---:|---:|\n",
                    r.energy
                );
            }
            let rank = self
                .rows
                .iter()
                .filter(|o| o.energy == r.energy)
                .position(|o| o.framework == r.framework)
                .unwrap_or(0)
                + 1;
            if let Some(why) = &r.cannot_run {
                let _ = writeln!(
                    s,
                    "| - | {} | cannot run: {why} | | | | | | | | | |",
                    r.framework.name()
                );
                continue;
            }
            let (b, bm, br, bx, bv, ba, bi) = match &r.best {
                Some(t) => (
                    t.setting.clone(),
                    fmt_num(t.ms_per_frame),
                    sci(t.errors.position_rms),
                    sci(t.errors.position_max),
                    sci(t.errors.peak_von_mises),
                    sci(t.errors.area),
                    t.errors.inverted.to_string(),
                ),
                None => (
                    "none within the budget".into(),
                    String::new(),
                    String::new(),
                    String::new(),
                    String::new(),
                    String::new(),
                    String::new(),
                ),
            };
            let (c, cm, cr) = match &r.cheapest {
                Some(t) => (
                    t.setting.clone(),
                    fmt_num(t.ms_per_frame),
                    sci(t.errors.position_rms),
                ),
                None => ("none stable".into(), String::new(), String::new()),
            };
            let _ = writeln!(
                s,
                "| {rank} | {} | {b} | {bm} | {br} | {bx} | {bv} | {ba} | {bi} | {c} | {cm} | {cr} |",
                r.framework.name()
            );
        }
        s
    }

    /// Every trial, one CSV row each.
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "energy,framework,setting,stable,ms_per_frame,position_rms,position_max,peak_von_mises,area,inverted\n",
        );
        for t in &self.trials {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{}",
                t.energy,
                t.framework.name(),
                t.setting,
                t.stable,
                t.ms_per_frame,
                t.errors.position_rms,
                t.errors.position_max,
                t.errors.peak_von_mises,
                t.errors.area,
                t.errors.inverted
            );
        }
        s
    }

    /// One chart per energy: position RMS against ms per frame for every stable setting, a
    /// curve per framework (log-log), and the budget as a vertical line.
    pub fn charts(&self) -> Vec<(EnergyKind, fem_render::chart::LineChart)> {
        use fem_render::chart::{LineChart, Scale, Series};
        let mut energies: Vec<EnergyKind> = Vec::new();
        for t in &self.trials {
            if !energies.contains(&t.energy) {
                energies.push(t.energy);
            }
        }
        energies
            .into_iter()
            .map(|e| {
                let mut series = Vec::new();
                let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
                for f in Framework::ALL {
                    let points: Vec<(f64, f64)> = self
                        .trials
                        .iter()
                        .filter(|t| t.energy == e && t.framework == f && t.stable)
                        .map(|t| (t.ms_per_frame, t.errors.position_rms))
                        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
                        .collect();
                    for p in &points {
                        lo = lo.min(p.1);
                        hi = hi.max(p.1);
                    }
                    if !points.is_empty() {
                        series.push(Series {
                            label: f.name().into(),
                            points,
                        });
                    }
                }
                if lo.is_finite() {
                    series.push(Series {
                        label: "budget".into(),
                        points: vec![(self.budget_ms, lo), (self.budget_ms, hi)],
                    });
                }
                (
                    e,
                    LineChart {
                        title: format!(
                            "{}: {e} at {} Hz, error against cost per frame",
                            self.scene,
                            fmt_num(self.fps)
                        ),
                        x_label: "ms per frame (one thread)".into(),
                        y_label: "position RMS against the reference [m]".into(),
                        x_scale: Scale::Log,
                        y_scale: Scale::Log,
                        series,
                        markers: true,
                        ..LineChart::default()
                    },
                )
            })
            .collect()
    }
}

impl BudgetRun {
    /// Write `budget.md`, `budget.csv`, `budget.json`, one `pareto-ENERGY.svg` and `.png` per
    /// energy, and `trajectories.json` (the mesh, and every trajectory the table's errors come
    /// from) into `dir`.
    pub fn write(&self, dir: &std::path::Path) -> Result<Vec<String>, SceneError> {
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
        for (energy, chart) in self.budget.charts() {
            let svg = chart.to_svg().map_err(render)?;
            put(&format!("pareto-{}.svg", energy.name()), svg.as_bytes())?;
            let png = chart.to_png().map_err(render)?.to_png().map_err(render)?;
            put(&format!("pareto-{}.png", energy.name()), &png)?;
        }
        let value = serde_json::json!({
            "rest": self.rest,
            "triangles": self.triangles,
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
