//! `pyfem2d.Simulation`: one scene, one model, one stepper, one state, stepped from Python.
//!
//! A step is the command line's step (`fem_scene::run`'s loop): the stepper's step, the same
//! failure rules (an error, a residual that is not finite), then the contact pressure; so a
//! scene stepped here reaches `fem2d run`'s states bit for bit. The hand (grab, move,
//! release) is the interactive app's ([`fem_scene::drag::Hand`]).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use fem_cases::files::{FileSource, load_case_or_file};
use fem_core::energy::{AnyEnergy, Energy};
use fem_core::math::Vec2;
use fem_core::mesh::Mesh;
use fem_core::stress::{ElementStress, VonMisesFormula, populate_element_stress};
use fem_scene::build::{
    MeshSource, build_mesh, build_simulation, build_stepper, von_mises_formula,
};
use fem_scene::drag::{Hand, Held};
use fem_scene::scene::{LoadedScene, parse_scene};
use fem_solvers::contact::ContactKind;
use fem_solvers::{AnyStepper, BodyState, Clock, ContactPressure, Grab, Model, State, Stepper};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{check_threads, json_to_py, pairs, points, values};
use crate::{blow_up, guard, invalid, scene_err};

/// How long a chunk of [`Simulation::run`] may step with the GIL released before it looks for
/// signals (Ctrl-C) and lets other Python threads in, s.
const CHUNK_SECONDS: f64 = 0.05;

/// Mesh and model files: the ones given in memory by name, else read from disk relative to
/// the scene's directory (the command line's rule).
struct Files {
    disk: FileSource,
    memory: BTreeMap<String, Vec<u8>>,
}

impl MeshSource for Files {
    fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        let key = name.rsplit(['/', '\\']).next().unwrap_or(name);
        match self.memory.get(name).or_else(|| self.memory.get(key)) {
            Some(bytes) => Ok(bytes.clone()),
            None => self.disk.read(name),
        }
    }
}

/// The numbers of one step.
#[pyclass(module = "pyfem2d._native", frozen, get_all)]
#[derive(Clone, Debug)]
pub struct StepReport {
    /// Iterations of the step (0 for explicit; see docs/solvers.md for what each solver counts).
    pub iterations: usize,
    /// The residual of its last iteration (0 for explicit), in the solver's units.
    pub residual: f64,
    /// Smallest `det F` the step met.
    pub min_det_f: f64,
    /// Elements with `det F <= 0` in that pass.
    pub inverted: usize,
    /// Contact pairs after the step.
    pub contacts: usize,
}

#[pymethods]
impl StepReport {
    fn __repr__(&self) -> String {
        format!(
            "StepReport(iterations={}, residual={:e}, min_det_f={}, inverted={}, contacts={})",
            self.iterations, self.residual, self.min_det_f, self.inverted, self.contacts
        )
    }
}

impl StepReport {
    fn from(r: &fem_solvers::StepReport) -> Self {
        StepReport {
            iterations: r.iterations,
            residual: r.residual,
            min_det_f: r.min_det_f,
            inverted: r.inverted,
            contacts: r.contacts,
        }
    }
}

/// A simulation's state at one moment (`Simulation.snapshot`), restored by
/// `Simulation.restore`.
#[pyclass(module = "pyfem2d._native", frozen)]
pub struct Snapshot {
    state: State,
    hand: Hand,
    grab: Option<Grab>,
    stopped: Option<String>,
    report: Option<fem_solvers::StepReport>,
    /// The rest mesh's fingerprint ([`fingerprint`]).
    mesh: u64,
}

#[pymethods]
impl Snapshot {
    /// Simulated time of the snapshot, s (the load factor for the static solver).
    #[getter]
    fn time(&self) -> f64 {
        self.state.t
    }

    /// Steps taken when it was made.
    #[getter]
    fn step(&self) -> u64 {
        self.state.step
    }

    fn __repr__(&self) -> String {
        format!("Snapshot(time={}, step={})", self.state.t, self.state.step)
    }
}

/// A scene stepped from Python (see docs/python.md).
#[pyclass(module = "pyfem2d._native")]
pub struct Simulation {
    scene: LoadedScene,
    mesh: Mesh,
    model: Model<AnyEnergy>,
    stepper: AnyStepper,
    state: State,
    formula: VonMisesFormula,
    stress: Vec<ElementStress>,
    /// `version` when `stress` was computed.
    stress_of: Option<u64>,
    /// Bumped by every change of the state.
    version: u64,
    rigid_triangles: Vec<u32>,
    pressure: ContactPressure,
    hand: Hand,
    before: Vec<BodyState>,
    report: Option<fem_solvers::StepReport>,
    /// The message of the step that failed: stepping stops until `reset` or `restore`.
    stopped: Option<String>,
    pool: Option<rayon::ThreadPool>,
    threads: Option<usize>,
    /// The rest mesh's fingerprint: a snapshot restores only the simulation it came from.
    fingerprint: u64,
}

/// A hash of the rest mesh (positions' bits and triangles).
fn fingerprint(mesh: &Mesh) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for p in mesh.vertices() {
        p.x.to_bits().hash(&mut h);
        p.y.to_bits().hash(&mut h);
    }
    mesh.triangles().hash(&mut h);
    h.finish()
}

/// Build everything from a loaded scene.
fn build(scene: LoadedScene, files: &Files, threads: Option<usize>) -> Result<Simulation, PyErr> {
    check_threads(threads)?;
    let pool = match threads {
        None => None,
        Some(n) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| invalid(format!("threads: {n}: {e}")))?,
        ),
    };
    let mesh = build_mesh(&scene, files).map_err(scene_err)?;
    let (model, stepper, state) = build_simulation(&scene, mesh.clone()).map_err(scene_err)?;
    let rigid_triangles = model
        .rigid_bodies()
        .iter()
        .flat_map(|b| b.triangles.iter().copied())
        .collect();
    let mut pressure = ContactPressure::new();
    pressure.update(&model, &state.x, &[]);
    Ok(Simulation {
        fingerprint: fingerprint(&mesh),
        formula: von_mises_formula(&scene),
        scene,
        mesh,
        model,
        stepper,
        state,
        stress: Vec::new(),
        stress_of: None,
        version: 0,
        rigid_triangles,
        pressure,
        hand: Hand::default(),
        before: Vec::new(),
        report: None,
        stopped: None,
        pool,
        threads,
    })
}

/// In-memory files from a `{name: bytes or str}` mapping.
fn memory_files(files: Option<&Bound<'_, PyDict>>) -> PyResult<BTreeMap<String, Vec<u8>>> {
    let mut out = BTreeMap::new();
    if let Some(d) = files {
        for (k, v) in d.iter() {
            let name: String = k
                .extract()
                .map_err(|_| invalid(format!("files: the key {k} is not a file name")))?;
            let bytes: Vec<u8> = if let Ok(s) = v.extract::<String>() {
                s.into_bytes()
            } else {
                v.extract::<Vec<u8>>().map_err(|_| {
                    invalid(format!(
                        "files: {name}: expected the file's text (str) or bytes"
                    ))
                })?
            };
            out.insert(name, bytes);
        }
    }
    Ok(out)
}

impl Simulation {
    /// Run `f` on the simulation's thread pool (rayon's global one without `threads`).
    fn on_pool<T: Send>(&mut self, f: impl FnOnce(&mut Simulation) -> T + Send) -> T {
        match self.pool.take() {
            Some(pool) => {
                let out = pool.install(|| f(self));
                self.pool = Some(pool);
                out
            }
            None => f(self),
        }
    }

    /// One step, as `fem_scene::run`'s loop takes it ([`fem_scene::run::step`]), then the
    /// hand and the contact pressure; the failure's one-line message.
    fn step_once(&mut self) -> Result<(), String> {
        self.before.clone_from(&self.state.bodies);
        let t = self.state.t;
        let stepped = fem_scene::run::step(&mut self.stepper, &self.model, &mut self.state);
        self.version += 1;
        match stepped {
            Ok(report) => {
                let dt = self.state.t - t;
                self.hand.after_step(&mut self.state, &self.before, dt);
                self.pressure
                    .update(&self.model, &self.state.x, self.stepper.contacts());
                self.report = Some(report);
                Ok(())
            }
            Err(e) => {
                let message = fem_scene::scales::explain(&self.scene, &e);
                self.stopped = Some(message.clone());
                Err(message)
            }
        }
    }

    /// Up to `n` steps, stopping after `seconds` of wall time when given: the steps taken and
    /// the failure, if one stopped them.
    fn steps(&mut self, n: u64, seconds: Option<f64>) -> (u64, Option<String>) {
        self.on_pool(|sim| {
            let start = Instant::now();
            for k in 0..n {
                if let Err(e) = sim.step_once() {
                    return (k, Some(e));
                }
                if seconds.is_some_and(|s| start.elapsed().as_secs_f64() >= s) {
                    return (k + 1, None);
                }
            }
            (n, None)
        })
    }

    fn check_running(&self) -> PyResult<()> {
        match &self.stopped {
            Some(m) => Err(blow_up(format!(
                "{m} (the simulation stopped there; reset() or restore() it)"
            ))),
            None => Ok(()),
        }
    }

    /// The element stress of the current state (computed once per state).
    fn stress(&mut self) -> &[ElementStress] {
        if self.stress_of != Some(self.version) {
            let (mesh, model, x, formula) = (&self.mesh, &self.model, &self.state.x, self.formula);
            let stress = &mut self.stress;
            match self.pool.as_ref() {
                Some(pool) => pool.install(|| {
                    populate_element_stress(mesh, model.energies(), x, formula, stress)
                }),
                None => populate_element_stress(mesh, model.energies(), x, formula, stress),
            }
            // Rigid regions carry no stress (their F is a rotation, up to round-off).
            for &t in &self.rigid_triangles {
                self.stress[t as usize] = ElementStress::UNSTRESSED;
            }
            self.stress_of = Some(self.version);
        }
        &self.stress
    }

    fn steps_for(&self, seconds: f64) -> PyResult<u64> {
        if self.stepper.kind().capabilities().clock == Clock::LoadFactor {
            return Err(invalid(format!(
                "seconds: {seconds}: the {} solver steps a load factor from 0 to 1, not time; call run() without seconds to apply the full load, or step(n)",
                self.stepper.kind().name()
            )));
        }
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(invalid(format!(
                "seconds: {seconds} is not a duration; give a finite number of seconds >= 0"
            )));
        }
        let n = (seconds / self.stepper.dt()).round();
        if n > 1e12 {
            return Err(invalid(format!(
                "seconds: {seconds} is {n:e} steps of {} s; give fewer",
                self.stepper.dt()
            )));
        }
        Ok(n as u64)
    }
}

#[pymethods]
impl Simulation {
    /// A built-in case (`case-a` .. `case-d`, `lower-leg`) or a scene file (`.toml`), with
    /// the command line's flags as keywords and `--set` overrides as a dict (or a list of
    /// `KEY=VALUE` strings).
    #[new]
    #[pyo3(signature = (scene="case-a", overrides=None, *, energy=None, solver=None, dt=None, steps=None, threads=None, files=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: &str,
        overrides: Option<&Bound<'_, PyAny>>,
        energy: Option<&str>,
        solver: Option<&str>,
        dt: Option<f64>,
        steps: Option<u64>,
        threads: Option<usize>,
        files: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        guard(|| {
            let o = crate::convert::overrides(energy, solver, dt, steps, overrides)?;
            let memory = memory_files(files)?;
            let scene_name = scene.to_owned();
            let loaded = py
                .detach(move || load_case_or_file(&scene_name, &o))
                .map_err(scene_err)?;
            let files = Files {
                disk: FileSource::for_scene(&loaded),
                memory,
            };
            py.detach(move || build(loaded, &files, threads))
        })
    }

    /// A scene from its TOML text (`origin` names it in messages; files it names are read
    /// from `files`, else relative to `base_dir`).
    #[staticmethod]
    #[pyo3(signature = (text, overrides=None, *, origin="<toml>", base_dir=None, energy=None, solver=None, dt=None, steps=None, threads=None, files=None))]
    #[allow(clippy::too_many_arguments)]
    fn from_toml(
        py: Python<'_>,
        text: &str,
        overrides: Option<&Bound<'_, PyAny>>,
        origin: &str,
        base_dir: Option<PathBuf>,
        energy: Option<&str>,
        solver: Option<&str>,
        dt: Option<f64>,
        steps: Option<u64>,
        threads: Option<usize>,
        files: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        guard(|| {
            let o = crate::convert::overrides(energy, solver, dt, steps, overrides)?;
            let memory = memory_files(files)?;
            let base = base_dir.unwrap_or_else(|| PathBuf::from("."));
            let loaded = parse_scene(text, origin, &base, &o).map_err(scene_err)?;
            let files = Files {
                disk: FileSource::for_scene(&loaded),
                memory,
            };
            py.detach(move || build(loaded, &files, threads))
        })
    }

    /// Take `n` steps (load increments for the static solver) with the GIL released, looking
    /// for signals (Ctrl-C) between chunks; the last step's report. A failed step raises
    /// `StepFailedError` and stops the simulation.
    #[pyo3(signature = (n=1))]
    fn step(slf: &Bound<'_, Self>, py: Python<'_>, n: u64) -> PyResult<Option<StepReport>> {
        guard(|| {
            slf.borrow().check_running()?;
            let mut left = n;
            while left > 0 {
                let (taken, failed) = {
                    let mut guard = slf.borrow_mut();
                    let sim: &mut Simulation = &mut guard;
                    py.detach(|| sim.steps(left, Some(CHUNK_SECONDS)))
                };
                if let Some(m) = failed {
                    return Err(blow_up(m));
                }
                left -= taken;
                if left > 0 {
                    py.check_signals()?;
                }
            }
            Ok(slf.borrow().report.as_ref().map(StepReport::from))
        })
    }

    /// Step `seconds` of simulated time (`None`: to the scene's end, `solver.steps` steps from
    /// the start or the full load), calling `callback(sim)` every `every` steps (a callback that returns
    /// `False` stops the run). Checks for signals (Ctrl-C) between chunks. The steps taken.
    #[pyo3(signature = (seconds=None, callback=None, every=1))]
    fn run(
        slf: &Bound<'_, Self>,
        py: Python<'_>,
        seconds: Option<f64>,
        callback: Option<Bound<'_, PyAny>>,
        every: u64,
    ) -> PyResult<u64> {
        guard(|| {
            if every == 0 {
                return Err(invalid("every: 0 is not a step count; give 1 or more"));
            }
            let (total, load_factor) = {
                let sim = slf.borrow();
                sim.check_running()?;
                let load_factor = sim.stepper.kind().capabilities().clock == Clock::LoadFactor;
                let total = match seconds {
                    Some(s) => sim.steps_for(s)?,
                    None if load_factor => u64::MAX,
                    None => sim.scene.scene.solver.steps.saturating_sub(sim.state.step),
                };
                (total, load_factor)
            };
            let mut done = 0u64;
            let mut since_callback = 0u64;
            while done < total {
                if load_factor && slf.borrow().state.t >= 1.0 {
                    break;
                }
                let want = if callback.is_some() {
                    (every - since_callback).min(total - done)
                } else {
                    total - done
                };
                let want = if load_factor { 1 } else { want };
                let (taken, failed) = {
                    let mut guard = slf.borrow_mut();
                    let sim: &mut Simulation = &mut guard;
                    py.detach(|| sim.steps(want, Some(CHUNK_SECONDS)))
                };
                done += taken;
                since_callback += taken;
                if let Some(m) = failed {
                    return Err(blow_up(m));
                }
                if let Some(cb) = &callback
                    && since_callback >= every
                {
                    since_callback = 0;
                    let answer = cb.call1((slf.clone(),))?;
                    if answer.is_instance_of::<pyo3::types::PyBool>()
                        && !answer.extract::<bool>()?
                    {
                        break;
                    }
                }
                py.check_signals()?;
            }
            Ok(done)
        })
    }

    /// Back to the initial state (no grab; a stopped simulation runs again).
    fn reset(&mut self, py: Python<'_>) -> PyResult<()> {
        guard(|| {
            let scene = self.scene.clone();
            let mesh = self.mesh.clone();
            let (model, stepper, state) = py
                .detach(|| build_simulation(&scene, mesh))
                .map_err(scene_err)?;
            self.model = model;
            self.stepper = stepper;
            self.state = state;
            self.hand = Hand::default();
            self.report = None;
            self.stopped = None;
            self.version += 1;
            self.pressure.update(&self.model, &self.state.x, &[]);
            Ok(())
        })
    }

    /// The state now (positions, velocities, bodies, clock, the hand and its grab).
    fn snapshot(&self) -> Snapshot {
        Snapshot {
            state: self.state.clone(),
            hand: self.hand,
            grab: self.model.active_grab(),
            stopped: self.stopped.clone(),
            report: self.report,
            mesh: self.fingerprint,
        }
    }

    /// Go back to `snapshot`. The stepper is rebuilt, so a solver that carries history (BDF2's
    /// previous step, quasi-Newton's memory, warm starts) continues as from a start at that
    /// state; explicit and implicit Euler continue bit for bit.
    fn restore(&mut self, py: Python<'_>, snapshot: &Snapshot) -> PyResult<()> {
        guard(|| {
            if snapshot.mesh != self.fingerprint
                || snapshot.state.x.len() != self.mesh.n_vertices()
                || snapshot.state.bodies.len() != self.model.obstacles().len()
                || snapshot.state.rigid.len() != self.model.rigid_bodies().len()
            {
                return Err(invalid(format!(
                    "snapshot: it was taken of another mesh or scene ({} vertices; this simulation has {}); a snapshot restores the simulation it came from",
                    snapshot.state.x.len(),
                    self.mesh.n_vertices()
                )));
            }
            self.model.release();
            if let Some(g) = &snapshot.grab {
                self.model
                    .grab(g, &snapshot.state.x)
                    .map_err(|e| invalid(e.to_string()))?;
            }
            let scene = &self.scene;
            let model = &self.model;
            self.stepper = py
                .detach(|| build_stepper(scene, model))
                .map_err(scene_err)?;
            self.state = snapshot.state.clone();
            self.hand = snapshot.hand;
            self.stopped = snapshot.stopped.clone();
            self.report = snapshot.report;
            self.version += 1;
            self.pressure.update(&self.model, &self.state.x, &[]);
            Ok(())
        })
    }

    /// Grab what is at `(x, y)`: a rigid obstacle there, else the body (inside a triangle,
    /// its three vertices; else the nearest vertex within 5 % of the body's size), as the
    /// interactive app does. `stiffness > 0` holds the body by a spring (N/m), else by a pin.
    /// Whether something was grabbed.
    #[pyo3(signature = (x, y, stiffness=0.0))]
    fn grab(&mut self, x: f64, y: f64, stiffness: f64) -> PyResult<bool> {
        guard(|| {
            if !(x.is_finite() && y.is_finite()) {
                return Err(invalid(format!("grab: the point ({x}, {y}) is not finite")));
            }
            let grabbed = self
                .hand
                .grab(&mut self.model, &self.state, Vec2::new(x, y), stiffness)
                .map_err(scene_err)?;
            Ok(grabbed)
        })
    }

    /// Move the hand (and what it holds) to `(x, y)`.
    fn move_to(&mut self, x: f64, y: f64) -> PyResult<()> {
        guard(|| {
            if !(x.is_finite() && y.is_finite()) {
                return Err(invalid(format!(
                    "move_to: the point ({x}, {y}) is not finite"
                )));
            }
            self.hand
                .move_to(&mut self.model, Vec2::new(x, y))
                .map_err(scene_err)
        })
    }

    /// Let go.
    fn release(&mut self) {
        self.hand.release(&mut self.model);
    }

    /// What the hand holds: `"nothing"`, `"body"` or `"obstacle"`.
    #[getter]
    fn held(&self) -> &'static str {
        match self.hand.held {
            Held::Nothing => "nothing",
            Held::Body => "body",
            Held::Obstacle { .. } => "obstacle",
        }
    }

    /// The force the grab exerts on the body, N per unit thickness (`None` without a grab of
    /// the body).
    fn grab_force(&self) -> Option<(f64, f64)> {
        self.model.grab_force(&self.state.x).map(|f| (f.x, f.y))
    }

    /// Vertex positions, m, `(n, 2)`; into `out` when given.
    #[pyo3(signature = (out=None))]
    fn positions<'py>(
        &self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points(py, pairs(&self.state.x), out, "positions")
    }

    /// Vertex velocities, m/s, `(n, 2)`; into `out` when given.
    #[pyo3(signature = (out=None))]
    fn velocities<'py>(
        &self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points(py, pairs(&self.state.v), out, "velocities")
    }

    /// Vertex displacements from the rest mesh, m, `(n, 2)`; into `out` when given.
    #[pyo3(signature = (out=None))]
    fn displacements<'py>(
        &self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let u = self
            .state
            .x
            .iter()
            .zip(self.mesh.vertices())
            .map(|(x, x0)| [x.x - x0.x, x.y - x0.y]);
        points(py, u, out, "displacements")
    }

    /// The rest positions, m, `(n, 2)`.
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points(py, pairs(self.mesh.vertices()), None, "rest positions")
    }

    /// The triangles, `(m, 3)` int64 vertex indices, counter-clockwise.
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<i64>> {
        let t: Vec<[i64; 3]> = self
            .mesh
            .triangles()
            .iter()
            .map(|t| t.map(i64::from))
            .collect();
        PyArray2::from_owned_array(
            py,
            numpy::ndarray::Array2::from_shape_vec((t.len(), 3), t.into_iter().flatten().collect())
                .unwrap_or_default(),
        )
    }

    /// Per-triangle von Mises stress, Pa (`(m,)`, NaN for an inverted triangle, 0 in rigid
    /// regions); into `out` when given.
    #[pyo3(signature = (out=None))]
    fn von_mises<'py>(
        &mut self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray1<f64>>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guard(|| {
            let s = self.stress();
            values(py, s.iter().map(|s| s.von_mises), out, "von_mises")
        })
    }

    /// Per-triangle `det F` (`(m,)`); into `out` when given.
    #[pyo3(signature = (out=None))]
    fn det_f<'py>(
        &mut self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray1<f64>>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guard(|| {
            let s = self.stress();
            values(py, s.iter().map(|s| s.det_f), out, "det_f")
        })
    }

    /// The material region of each triangle (`(m,)` int64): 0 the base material, `k` the
    /// `k`-th `[[regions]]` entry.
    fn region_tags<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let e = self.model.energies();
        let tags: Vec<i64> = (0..self.mesh.n_triangles())
            .map(|t| i64::from(e.tag(t)))
            .collect();
        PyArray1::from_vec(py, tags)
    }

    /// The material regions' names by tag: `material.name` (default `body`), then each
    /// `[[regions]]` entry's.
    fn region_names(&self) -> Vec<String> {
        let s = &self.scene.scene;
        std::iter::once(s.material.name.clone().unwrap_or_else(|| "body".into()))
            .chain(s.regions.iter().map(|r| r.name.clone()))
            .collect()
    }

    /// Normal contact pressure per vertex after the last step, Pa (`(n,)`, 0 off contact);
    /// into `out` when given.
    #[pyo3(signature = (out=None))]
    fn contact_pressure<'py>(
        &self,
        py: Python<'py>,
        out: Option<Bound<'py, PyArray1<f64>>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = self.pressure.vertex_pressure();
        let n = self.mesh.n_vertices();
        // Before any contact the pressure field may be empty: zeros.
        values(
            py,
            (0..n).map(|i| p.get(i).copied().unwrap_or(0.0)),
            out,
            "contact_pressure",
        )
    }

    /// The contacts after the last step, as arrays of one entry per contact: `kind`
    /// (`vertex-ground`, `vertex-obstacle`, `corner-edge`), `vertex` (-1 for a corner),
    /// `obstacle` (-1 for the ground), `point` and `normal` `(k, 2)`, `gap` (m, negative:
    /// penetration) and `force` (N per unit thickness).
    fn contacts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.stepper.contacts();
        let d = PyDict::new(py);
        let (mut kind, mut vertex, mut obstacle) = (Vec::new(), Vec::new(), Vec::new());
        for contact in c {
            let (k, v, o) = match contact.kind {
                ContactKind::VertexGround { vertex } => ("vertex-ground", i64::from(vertex), -1),
                ContactKind::VertexObstacle {
                    vertex, obstacle, ..
                } => ("vertex-obstacle", i64::from(vertex), i64::from(obstacle)),
                ContactKind::CornerEdge { obstacle, .. } => {
                    ("corner-edge", -1, i64::from(obstacle))
                }
                _ => ("other", -1, -1),
            };
            kind.push(k);
            vertex.push(v);
            obstacle.push(o);
        }
        d.set_item("kind", PyList::new(py, kind)?)?;
        d.set_item("vertex", PyArray1::from_vec(py, vertex))?;
        d.set_item("obstacle", PyArray1::from_vec(py, obstacle))?;
        d.set_item(
            "point",
            points(py, c.iter().map(|c| [c.point.x, c.point.y]), None, "point")?,
        )?;
        d.set_item(
            "normal",
            points(
                py,
                c.iter().map(|c| [c.normal.x, c.normal.y]),
                None,
                "normal",
            )?,
        )?;
        d.set_item("gap", values(py, c.iter().map(|c| c.gap), None, "gap")?)?;
        d.set_item(
            "force",
            values(py, c.iter().map(|c| c.force), None, "force")?,
        )?;
        Ok(d)
    }

    /// The obstacles' polygons at their current poses, m: one `(k, 2)` array each.
    fn obstacles<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyArray2<f64>>>> {
        self.model
            .obstacles()
            .iter()
            .zip(&self.state.bodies)
            .map(|(o, b)| {
                let poly = o.world_polygon(b);
                points(py, pairs(&poly), None, "obstacle")
            })
            .collect()
    }

    /// The last step's report (`None` before the first step).
    #[getter]
    fn report(&self) -> Option<StepReport> {
        self.report.as_ref().map(StepReport::from)
    }

    /// Simulated time, s (the load factor for the static solver).
    #[getter]
    fn time(&self) -> f64 {
        self.state.t
    }

    /// Steps taken since the start (load increments for the static solver).
    #[getter]
    fn steps_taken(&self) -> u64 {
        self.state.step
    }

    /// The time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.stepper.dt()
    }

    /// The energy's name (as the command line spells it).
    #[getter]
    fn energy(&self) -> &'static str {
        self.model.energy().name()
    }

    /// The solver's name (as the command line spells it).
    #[getter]
    fn solver(&self) -> &'static str {
        self.stepper.kind().name()
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> String {
        self.scene.scene.name.clone()
    }

    /// Where the scene came from (a case name or a file), as messages name it.
    #[getter]
    fn origin(&self) -> String {
        self.scene.origin.clone()
    }

    /// The rayon threads asked for (`None`: rayon's default pool).
    #[getter]
    fn threads(&self) -> Option<usize> {
        self.threads
    }

    /// The message of the step that stopped the simulation, if one did.
    #[getter]
    fn stopped(&self) -> Option<String> {
        self.stopped.clone()
    }

    /// Number of vertices.
    #[getter]
    fn n_vertices(&self) -> usize {
        self.mesh.n_vertices()
    }

    /// Number of triangles.
    #[getter]
    fn n_triangles(&self) -> usize {
        self.mesh.n_triangles()
    }

    /// The current state as a `meshio.Mesh` (points padded with z = 0; triangles; point data
    /// `displacement`, `velocity` (z = 0) and `contact_pressure`; cell data `von_mises`,
    /// `det_f` and `region`), for `meshio.write` (VTU, XDMF, ...). Needs meshio installed.
    // The Python name the package's users expect (meshio's own convention).
    #[allow(clippy::wrong_self_convention)]
    fn to_meshio<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let meshio = py.import("meshio").map_err(|_| {
            pyo3::exceptions::PyImportError::new_err(
                "to_meshio needs the meshio package: pip install meshio",
            )
        })?;
        let pad = |v: Vec<[f64; 2]>| -> PyResult<Bound<'py, PyArray2<f64>>> {
            let flat: Vec<f64> = v.iter().flat_map(|p| [p[0], p[1], 0.0]).collect();
            PyArray1::from_vec(py, flat).reshape([v.len(), 3])
        };
        let x = pad(pairs(&self.state.x).collect())?;
        let point_data = PyDict::new(py);
        let u = (self.state.x.iter().zip(self.mesh.vertices()))
            .map(|(x, x0)| [x.x - x0.x, x.y - x0.y])
            .collect();
        point_data.set_item("displacement", pad(u)?)?;
        point_data.set_item("velocity", pad(pairs(&self.state.v).collect())?)?;
        point_data.set_item("contact_pressure", self.contact_pressure(py, None)?)?;
        let cell_data = PyDict::new(py);
        cell_data.set_item("von_mises", vec![self.von_mises(py, None)?])?;
        cell_data.set_item("det_f", vec![self.det_f(py, None)?])?;
        cell_data.set_item("region", vec![self.region_tags(py)])?;
        let cells = vec![("triangle", self.triangles(py))];
        let kwargs = PyDict::new(py);
        kwargs.set_item("point_data", point_data)?;
        kwargs.set_item("cell_data", cell_data)?;
        meshio.getattr("Mesh")?.call((x, cells), Some(&kwargs))
    }

    /// The scene as run (overrides applied), as TOML text.
    fn scene_toml(&self) -> PyResult<String> {
        toml::to_string_pretty(&self.scene.scene).map_err(|e| invalid(e.to_string()))
    }

    /// The scene as run, as Python data (the TOML's tables as dicts).
    fn scene_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(&self.scene.scene).map_err(|e| invalid(e.to_string()))?;
        json_to_py(py, &text)
    }

    fn __repr__(&self) -> String {
        format!(
            "Simulation({:?}, energy={:?}, solver={:?}, t={}, step={}, vertices={}, triangles={})",
            self.scene.origin,
            self.model.energy().name(),
            self.stepper.kind().name(),
            self.state.t,
            self.state.step,
            self.mesh.n_vertices(),
            self.mesh.n_triangles()
        )
    }
}

/// Steps `n` times in Rust, reading positions and von Mises after each step into buffers, as
/// a Python loop with `out=` arrays does: the baseline of the per-step overhead benchmark
/// (`crates/fem-py/bench/overhead.py`). The wall seconds of the loop.
#[pyfunction]
pub fn _rust_loop(py: Python<'_>, sim: &Bound<'_, Simulation>, n: u64) -> PyResult<f64> {
    guard(|| {
        let mut s = sim.borrow_mut();
        s.check_running()?;
        let sim: &mut Simulation = &mut s;
        let result = py.detach(|| {
            let mut x = vec![[0.0; 2]; sim.mesh.n_vertices()];
            let mut vm = vec![0.0; sim.mesh.n_triangles()];
            let start = Instant::now();
            for _ in 0..n {
                let (_, failed) = sim.steps(1, None);
                if let Some(m) = failed {
                    return Err(m);
                }
                for (dst, p) in x.iter_mut().zip(&sim.state.x) {
                    *dst = [p.x, p.y];
                }
                for (dst, s) in vm.iter_mut().zip(sim.stress()) {
                    *dst = s.von_mises;
                }
                std::hint::black_box((&x, &vm));
            }
            Ok(start.elapsed().as_secs_f64())
        });
        result.map_err(blow_up)
    })
}
