//! The interactive app's state and API, in plain Rust (tested natively; `crate::wasm` only
//! exports it): a scene built by `fem-scene`, stepped by any solver of the registry, in real
//! time, with a hand that grabs and drags the body.
//!
//! **Real time.** The page calls [`App::begin_frame`] with the wall time since the last frame;
//! the app owes that much simulated time (capped at [`MAX_FRAME_SECONDS`], so a tab that was
//! hidden does not come back to minutes of work) and answers how many steps it needs. The page
//! then steps in chunks ([`App::step`]) while its physics budget lasts, and reports what it did
//! ([`App::end_frame`]). Steps not taken are dropped, not carried over: when the physics
//! cannot keep up, simulated time runs slower than wall time and the heads-up display says so
//! ([`Hud::slowed`], [`Hud::real_time_factor`]); there is no spiral of death.
//!
//! **Changing settings** ([`App::set`], any scene key as `--set` takes it) rebuilds the model
//! and the stepper through `fem-scene` and keeps the current positions and velocities when the
//! mesh, the boundary conditions and the initial shape are unchanged; otherwise the scene
//! restarts. A value the scene rejects leaves everything as it was and returns the one-line
//! message the command line prints.
//!
//! **A blow-up** stops the stepping with the command line's one-line message
//! ([`Hud::error`]); [`App::reset`] recovers.

use std::collections::BTreeMap;

use fem_core::energy::{AnyEnergy, Energy};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::stress::{ElementStress, VonMisesFormula, populate_element_stress};
use fem_scene::build::{MeshSource, build_mesh, build_simulation, von_mises_formula};
use fem_scene::cases::{case_text, load_case};
use fem_scene::drag::{DragAction, DragEvent, DragPlayer, DragTrajectory, Hand, Held};
use fem_scene::scene::{LoadedScene, MaterialRegionSpec, Scene, parse_scene};
use fem_solvers::{AnyStepper, BodyState, Clock, ContactPressure, Model, State, Stepper};

/// The most simulated time one frame may owe, s: a frame after a long pause (a hidden tab,
/// a breakpoint) does not ask for more.
pub const MAX_FRAME_SECONDS: Real = 0.1;

/// The field the page colours the body with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// Von Mises stress per triangle, Pa.
    VonMises,
    /// Displacement magnitude per vertex, m.
    Displacement,
    /// `det F` per triangle.
    DetF,
}

impl Field {
    /// By index, as the page numbers them (0 von Mises, 1 displacement, 2 det F).
    pub fn from_index(i: u32) -> Option<Field> {
        match i {
            0 => Some(Field::VonMises),
            1 => Some(Field::Displacement),
            2 => Some(Field::DetF),
            _ => None,
        }
    }

    /// Whether the field has one value per vertex (else one per triangle).
    pub fn per_vertex(self) -> bool {
        self == Field::Displacement
    }
}

/// What the heads-up display shows after a frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hud {
    /// Simulated time, s (the load factor for the static solver).
    pub t: Real,
    /// Steps taken since the start.
    pub step: u64,
    /// Steps taken in the last frame.
    pub steps_last_frame: u64,
    /// Steps the last frame wanted (more than it took when the physics could not keep up).
    pub steps_wanted: u64,
    /// Physics wall time of the last frame, ms (as the page measured it).
    pub physics_ms: Real,
    /// Simulated seconds per wall second over the last frame.
    pub real_time_factor: Real,
    /// The last frame dropped steps: simulated time runs slower than wall time.
    pub slowed: bool,
    /// Largest von Mises stress over the triangles, Pa.
    pub peak_von_mises: Real,
    /// Largest von Mises stress over the base material's triangles, Pa: the soft tissue of a
    /// body with bones (`[[regions]]`), whose own peak the bones' would hide; the same as
    /// `peak_von_mises` for a body of one material.
    pub peak_von_mises_base: Real,
    /// Triangles with `det F <= 0`.
    pub inverted: usize,
    /// Smallest `det F`.
    pub min_det_f: Real,
    /// Sum over the triangles of `|a_e - A_e|` over the rest area (errors do not cancel).
    pub area_error: Real,
    /// Signed change of the total area over the rest area.
    pub area_change: Real,
    /// The force the hand exerts on the body, N per unit thickness.
    pub grab_force: Option<[Real; 2]>,
    /// Contacts after the last step (the stepper's: penetrating pairs for penalty and
    /// projection, pairs within the barrier's reach for barrier contact).
    pub contacts: usize,
    /// Their smallest gap, m (negative: penetration; infinite without contacts).
    pub min_gap: Real,
    /// Their total force on the body, N per unit thickness.
    pub contact_force: [Real; 2],
    /// The largest normal contact pressure at a boundary vertex, Pa (0 without contact;
    /// `fem_solvers::pressure`).
    pub contact_pressure_peak: Real,
    /// The contact length, m: the tributary boundary length of the loaded vertices.
    pub contact_length: Real,
    /// The run stopped on this one-line message (a blow-up); reset recovers.
    pub error: Option<String>,
}

/// Files the user gave the page (a mesh JSON, a 3D model), by name.
#[derive(Clone, Debug, Default)]
pub struct MemoryFiles(BTreeMap<String, Vec<u8>>);

impl MemoryFiles {
    /// Add (or replace) a file.
    pub fn insert(&mut self, name: &str, bytes: Vec<u8>) {
        self.0.insert(name.to_owned(), bytes);
    }
}

impl MeshSource for MemoryFiles {
    fn read(&self, name: &str) -> Result<Vec<u8>, String> {
        let key = name.rsplit(['/', '\\']).next().unwrap_or(name);
        self.0
            .get(name)
            .or_else(|| self.0.get(key))
            .cloned()
            .ok_or_else(|| "not among the files given to the page; drop it too".to_owned())
    }
}

/// The running app: one scene, one model, one stepper, one state.
pub struct App {
    text: String,
    origin: String,
    overrides: Vec<String>,
    files: MemoryFiles,
    scene: LoadedScene,
    mesh: Mesh,
    model: Model<AnyEnergy>,
    stepper: AnyStepper,
    state: State,
    formula: VonMisesFormula,
    stress: Vec<ElementStress>,
    rest_area: Vec<Real>,
    pressure: ContactPressure,
    hud: Hud,
    /// Steps the current frame wants.
    wanted: u64,
    /// The hand's events since recording started.
    recording: Option<DragTrajectory>,
    /// A drag being replayed.
    player: Option<DragPlayer>,
    /// The pointer's hand.
    hand: Hand,
    /// The obstacles' poses at the start of the current step.
    before: Vec<BodyState>,
}

/// The scene keys whose change restarts the scene (the mesh, what holds it, where it starts).
fn restarts(old: &Scene, new: &Scene) -> bool {
    old.mesh != new.mesh
        || old.pinned != new.pinned
        || old.prescribed != new.prescribed
        || old.initial != new.initial
        || old.obstacles != new.obstacles
        || old.ground != new.ground
        // Rigid regions are bodies of the state: making one rigid or elastic restarts.
        || rigid_regions(old) != rigid_regions(new)
}

/// The `[[regions]]` entries made rigid.
fn rigid_regions(s: &Scene) -> Vec<&MaterialRegionSpec> {
    s.regions.iter().filter(|r| r.rigid).collect()
}

impl App {
    /// The app on a built-in case (`case-a` .. `case-d`).
    pub fn case(name: &str) -> Result<App, String> {
        // `load_case` gives the command line's message for an unknown name.
        let origin = load_case(name, &[]).map_err(|e| e.to_string())?.origin;
        let text = case_text(name).unwrap_or_default();
        App::scene(text, &origin, MemoryFiles::default())
    }

    /// The app on a scene file's text (its origin names it in messages), with the files it
    /// names given in memory.
    pub fn scene(text: &str, origin: &str, files: MemoryFiles) -> Result<App, String> {
        let scene = parse(text, origin, &[])?;
        let mesh = build_mesh(&scene, &files).map_err(|e| e.to_string())?;
        let (model, stepper, state) = build(&scene, mesh.clone())?;
        let mut app = App {
            text: text.to_owned(),
            origin: origin.to_owned(),
            overrides: Vec::new(),
            files,
            formula: von_mises_formula(&scene),
            rest_area: mesh.elements().iter().map(|e| e.area).collect(),
            scene,
            mesh,
            model,
            stepper,
            state,
            stress: Vec::new(),
            pressure: ContactPressure::new(),
            hud: Hud::default(),
            wanted: 0,
            recording: None,
            player: None,
            hand: Hand::default(),
            before: Vec::new(),
        };
        app.refresh();
        Ok(app)
    }

    /// Set a scene key (`energy`, `solver.kind`, `solver.dt`, `solver.iterations`,
    /// `material.youngs_modulus`, ...; the value in TOML syntax, strings quoted) without a
    /// reload: see the module docs. Returns whether the scene restarted.
    pub fn set(&mut self, key: &str, value: &str) -> Result<bool, String> {
        let assignment = format!("{key}={value}");
        let mut overrides: Vec<String> = self
            .overrides
            .iter()
            .filter(|o| o.split('=').next() != Some(key))
            .cloned()
            .collect();
        overrides.push(assignment);
        let scene = parse(&self.text, &self.origin, &overrides)?;
        let restart = restarts(&self.scene.scene, &scene.scene);
        let mesh = if scene.scene.mesh == self.scene.scene.mesh {
            self.mesh.clone()
        } else {
            build_mesh(&scene, &self.files).map_err(|e| e.to_string())?
        };
        let (mut model, stepper, fresh) = build(&scene, mesh.clone())?;
        let state = if restart {
            fresh
        } else {
            let mut kept = self.state.clone();
            // A solver with another clock starts its own (load factor from 0).
            if self.stepper.kind().capabilities().clock != stepper.kind().capabilities().clock {
                kept.t = 0.0;
            }
            kept
        };
        // The old model's grab (the pointer's or a replay's) holds the rebuilt one too.
        if !restart {
            if let Some(g) = self.model.active_grab() {
                model.grab(&g, &state.x).map_err(|e| e.to_string())?;
            }
        } else {
            self.hand = Hand::default();
        }
        self.overrides = overrides;
        self.formula = von_mises_formula(&scene);
        self.rest_area = mesh.elements().iter().map(|e| e.area).collect();
        self.scene = scene;
        self.mesh = mesh;
        self.model = model;
        self.stepper = stepper;
        self.state = state;
        self.hud.error = None;
        self.refresh();
        Ok(restart)
    }

    /// Back to `t = 0` with the current settings (and no grab).
    pub fn reset(&mut self) {
        // The scene built before, so it builds again; keep the old app if it somehow fails.
        if let Ok((model, stepper, state)) = build(&self.scene, self.mesh.clone()) {
            self.model = model;
            self.stepper = stepper;
            self.state = state;
        }
        self.player = None;
        self.hand = Hand::default();
        self.hud = Hud::default();
        self.refresh();
    }

    /// Start a frame `wall_seconds` after the last one; the steps it wants (see the module
    /// docs). Zero after a blow-up.
    pub fn begin_frame(&mut self, wall_seconds: Real) -> u64 {
        // NaN and non-positive frame times want nothing.
        if self.hud.error.is_some()
            || wall_seconds.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        {
            self.wanted = 0;
            return 0;
        }
        let owed = wall_seconds.min(MAX_FRAME_SECONDS);
        self.wanted = if self.stepper.kind().capabilities().clock == Clock::LoadFactor {
            1
        } else {
            // Round to the nearest step: the clock stays within half a step of wall time.
            ((owed / self.stepper.dt()).round() as u64).max(1)
        };
        self.hud.real_time_factor = owed / wall_seconds;
        self.wanted
    }

    /// Take up to `n` steps; the number taken. A failure stops the run with the command
    /// line's message (also in [`Hud::error`]).
    pub fn step(&mut self, n: u64) -> Result<u64, String> {
        if let Some(e) = &self.hud.error {
            return Err(e.clone());
        }
        for k in 0..n {
            if let Some(p) = self.player.as_mut()
                && let Err(e) = p.apply(&mut self.model, &self.state)
            {
                self.hud.error = Some(e.to_string());
                return Err(e.to_string());
            }
            self.before.clone_from(&self.state.bodies);
            let t = self.state.t;
            let stepped = self.stepper.step(&self.model, &mut self.state);
            if stepped.is_ok() {
                let dt = self.state.t - t;
                self.hand.after_step(&mut self.state, &self.before, dt);
                if let Some(p) = self.player.as_ref() {
                    p.after_step(&mut self.state, dt);
                }
            }
            if let Err(e) = stepped {
                let message = format!("{}: {e}", self.scene.origin);
                self.hud.error = Some(message.clone());
                self.refresh();
                return if k == 0 { Err(message) } else { Ok(k) };
            }
        }
        Ok(n)
    }

    /// End the frame: `steps` were taken in `physics_ms` of wall time over a frame of
    /// `wall_seconds`. Updates the heads-up display.
    pub fn end_frame(&mut self, steps: u64, physics_ms: Real, wall_seconds: Real) {
        self.hud.steps_last_frame = steps;
        self.hud.steps_wanted = self.wanted;
        self.hud.physics_ms = physics_ms;
        self.hud.slowed = steps < self.wanted;
        let simulated = if self.stepper.kind().capabilities().clock == Clock::Time {
            steps as Real * self.stepper.dt()
        } else {
            0.0
        };
        self.hud.real_time_factor = if wall_seconds > 0.0 {
            simulated / wall_seconds
        } else {
            0.0
        };
        self.refresh();
    }

    /// Grab what is at the world point `(x, y)` ([`Hand::grab`]): a rigid obstacle there
    /// (held by the hand), else the body ([`fem_scene::drag::pick`]: inside a triangle, its
    /// three vertices weighted by the point's barycentric coordinates; else the nearest vertex
    /// within 5 % of the body's size). `stiffness` > 0 makes a spring grab of the body (N/m),
    /// else a pin. Whether something was grabbed. Recorded when recording.
    pub fn grab_at(&mut self, x: Real, y: Real, stiffness: Real) -> Result<bool, String> {
        let grabbed = self
            .hand
            .grab(&mut self.model, &self.state, Vec2::new(x, y), stiffness)
            .map_err(|e| e.to_string())?;
        self.record(DragAction::Grab { x, y, stiffness });
        self.refresh();
        Ok(grabbed)
    }

    /// Move the hand to `(x, y)`. Recorded when recording.
    pub fn drag_to(&mut self, x: Real, y: Real) -> Result<(), String> {
        if self.hand.held == Held::Nothing {
            return Ok(());
        }
        self.record(DragAction::Move { x, y });
        self.hand
            .move_to(&mut self.model, Vec2::new(x, y))
            .map_err(|e| e.to_string())?;
        Ok(())
    }

    /// Let go. Recorded when recording.
    pub fn release(&mut self) {
        if self.hand.held != Held::Nothing {
            self.record(DragAction::Release);
        }
        self.hand.release(&mut self.model);
        self.hud.grab_force = None;
    }

    /// What the hand holds.
    pub fn held(&self) -> Held {
        self.hand.held
    }

    /// Start recording the hand (a new recording; the clock as it is).
    pub fn start_recording(&mut self) {
        self.recording = Some(DragTrajectory::default());
    }

    /// Stop recording; the drag recorded (empty when none was).
    pub fn stop_recording(&mut self) -> DragTrajectory {
        self.recording.take().unwrap_or_default()
    }

    /// Restart the scene and replay `drag` into it as the steps reach its events' times
    /// (the pointer is still free to grab). Replays are repeatable: the same settings and the
    /// same drag give the same states, as `fem2d run --drag` does offline.
    pub fn replay(&mut self, drag: &DragTrajectory) {
        self.reset();
        self.player = Some(DragPlayer::new(drag));
    }

    fn record(&mut self, action: DragAction) {
        let t = self.state.t;
        if let Some(r) = self.recording.as_mut() {
            r.events.push(DragEvent { t, action });
        }
    }

    /// Recompute the stress and the display numbers of the current state.
    fn refresh(&mut self) {
        populate_element_stress(
            &self.mesh,
            self.model.energies(),
            &self.state.x,
            self.formula,
            &mut self.stress,
        );
        // Rigid regions carry no stress (their F is a rotation, up to round-off).
        for body in self.model.rigid_bodies() {
            for &t in &body.triangles {
                self.stress[t as usize] = ElementStress::UNSTRESSED;
            }
        }
        let hud = &mut self.hud;
        let contacts = self.stepper.contacts();
        hud.contacts = contacts.len();
        hud.min_gap = contacts
            .iter()
            .map(|c| c.gap)
            .fold(Real::INFINITY, Real::min);
        let force: Vec2 = contacts.iter().map(|c| c.normal * c.force).sum();
        hud.contact_force = [force.x, force.y];
        self.pressure
            .update(&self.model, &self.state.x, self.stepper.contacts());
        hud.contact_pressure_peak = self.pressure.peak().map_or(0.0, |p| p.pressure);
        hud.contact_length = self.pressure.contact_length();
        hud.t = self.state.t;
        hud.step = self.state.step;
        hud.peak_von_mises = self
            .stress
            .iter()
            .map(|s| s.von_mises)
            .filter(|v| v.is_finite())
            .fold(0.0, Real::max);
        let energies = self.model.energies();
        hud.peak_von_mises_base = self
            .stress
            .iter()
            .enumerate()
            .filter(|&(t, s)| energies.tag(t) == 0 && s.von_mises.is_finite())
            .map(|(_, s)| s.von_mises)
            .fold(0.0, Real::max);
        // NaN counts as inverted.
        hud.inverted = self
            .stress
            .iter()
            .filter(|s| s.det_f.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
            .count();
        hud.min_det_f = self
            .stress
            .iter()
            .map(|s| s.det_f)
            .fold(Real::INFINITY, Real::min);
        let rest: Real = self.rest_area.iter().sum();
        let (mut abs, mut signed) = (0.0, 0.0);
        for (s, a) in self.stress.iter().zip(&self.rest_area) {
            // det F is the area ratio of a linear triangle.
            let d = a * (s.det_f - 1.0);
            abs += d.abs();
            signed += d;
        }
        hud.area_error = abs / rest;
        hud.area_change = signed / rest;
        hud.grab_force = self.model.grab_force(&self.state.x).map(|f| [f.x, f.y]);
    }

    /// The heads-up display's numbers.
    pub fn hud(&self) -> &Hud {
        &self.hud
    }

    /// Current vertex positions, m.
    pub fn positions(&self) -> &[Vec2] {
        &self.state.x
    }

    /// The triangles (counter-clockwise vertex indices).
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.mesh.triangles()
    }

    /// The normal contact pressure per vertex after the last step, Pa (0 off contact).
    pub fn contact_pressure(&self) -> &[Real] {
        self.pressure.vertex_pressure()
    }

    /// The body's boundary edges (counter-clockwise, the body on the left of `a -> b`).
    pub fn boundary_edges(&self) -> &[[u32; 2]] {
        self.model.boundary_edges()
    }

    /// The material region of each triangle: 0 for the base material (`[material]`), `k` for
    /// the `k`-th `[[regions]]` entry (all 0 for a body of one material).
    pub fn material_regions(&self) -> Vec<u32> {
        let energies = self.model.energies();
        (0..self.mesh.n_triangles())
            .map(|t| energies.tag(t))
            .collect()
    }

    /// The material regions' names, by tag: `material.name` (default `body`), then each
    /// `[[regions]]` entry's.
    pub fn material_region_names(&self) -> Vec<String> {
        let s = &self.scene.scene;
        std::iter::once(s.material.name.clone().unwrap_or_else(|| "body".into()))
            .chain(s.regions.iter().map(|r| r.name.clone()))
            .collect()
    }

    /// The field's values: one per triangle, or one per vertex for the displacement.
    pub fn field(&self, field: Field) -> Vec<Real> {
        match field {
            Field::VonMises => self.stress.iter().map(|s| s.von_mises).collect(),
            Field::DetF => self.stress.iter().map(|s| s.det_f).collect(),
            Field::Displacement => self
                .state
                .x
                .iter()
                .zip(self.mesh.vertices())
                .map(|(x, x0)| (x - x0).norm())
                .collect(),
        }
    }

    /// The obstacles' polygons at their current poses, m.
    pub fn obstacles(&self) -> Vec<Vec<Vec2>> {
        self.model
            .obstacles()
            .iter()
            .zip(&self.state.bodies)
            .map(|(o, b)| o.world_polygon(b))
            .collect()
    }

    /// The ground line, as a point on it and its normal, if the scene has one.
    pub fn ground(&self) -> Option<(Vec2, Vec2)> {
        self.model.ground().map(|g| (g.point, g.normal))
    }

    /// Bounds of the rest mesh, m: `(lo, hi)`.
    pub fn bounds(&self) -> ([Real; 2], [Real; 2]) {
        let v = self.mesh.vertices();
        let mut lo = [Real::INFINITY; 2];
        let mut hi = [Real::NEG_INFINITY; 2];
        for p in v {
            lo = [lo[0].min(p.x), lo[1].min(p.y)];
            hi = [hi[0].max(p.x), hi[1].max(p.y)];
        }
        (lo, hi)
    }

    /// The state (for tests and the state hash).
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The scene as currently set.
    pub fn loaded_scene(&self) -> &LoadedScene {
        &self.scene
    }

    /// The current value of a scene key as TOML (`energy`, `material.youngs_modulus`,
    /// `solver.<key>` of the current solver), or `None` when the scene does not set it.
    pub fn get(&self, key: &str) -> Option<String> {
        let s = &self.scene.scene;
        let m = &s.material;
        let number = |v: Option<Real>| v.map(|v| format!("{v:e}"));
        match key {
            "energy" => Some(format!("\"{}\"", s.energy.name())),
            "solver.kind" => Some(format!("\"{}\"", s.solver.kind.name())),
            "solver.dt" => number(Some(s.solver.dt)),
            "material.youngs_modulus" => number(Some(m.youngs_modulus)),
            "material.poisson_ratio" => number(Some(m.poisson_ratio)),
            // Whether the first `[[regions]]` entry (the bones of the built-in cases) is rigid.
            "regions.0.rigid" => s.regions.first().map(|r| r.rigid.to_string()),
            _ => key
                .strip_prefix("solver.")
                .and_then(|k| s.solver.get(k))
                .map(|v| v.to_string()),
        }
    }

    /// The energy's name and the solver's name.
    pub fn names(&self) -> (&'static str, &'static str) {
        (self.model.energy().name(), self.stepper.kind().name())
    }
}

/// Parse a scene with overrides; the command line's one-line message on error.
fn parse(text: &str, origin: &str, overrides: &[String]) -> Result<LoadedScene, String> {
    parse_scene(text, origin, std::path::Path::new("."), overrides).map_err(|e| e.to_string())
}

/// The model, stepper and initial state of `scene` on `mesh`; the command line's message on
/// error.
fn build(scene: &LoadedScene, mesh: Mesh) -> Result<(Model<AnyEnergy>, AnyStepper, State), String> {
    build_simulation(scene, mesh).map_err(|e| e.to_string())
}
