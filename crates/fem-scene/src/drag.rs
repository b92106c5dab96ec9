//! A recorded drag: what a hand did to the body (grab at a point, move, release), at simulated
//! times, so a drag felt in the interactive app can be replayed there and measured offline by
//! `fem2d run --drag FILE` with the same result.
//!
//! The JSON form:
//!
//! ```json
//! {"version": 1, "events": [
//!   {"t": 0.0,  "action": "grab", "x": 4.98, "y": 0.5, "stiffness": 0},
//!   {"t": 0.05, "action": "move", "x": 4.98, "y": 0.8},
//!   {"t": 0.5,  "action": "release"}
//! ]}
//! ```
//!
//! `t` is simulated time (s), non-decreasing; `x`, `y` are world coordinates (m); a grab with
//! `stiffness` 0 is a pin, with `stiffness` > 0 a spring of that stiffness (N/m) (see
//! `fem_solvers::grab`). An event applies before the first step that starts at or after its
//! time, in file order ([`DragPlayer`]). The hand ([`Hand`], shared by the app and the
//! player) grabs what is under its point: a rigid obstacle containing it (held by the hand:
//! after every step its pose is put where the hand holds it, and its velocity is the hand's,
//! so the debris of case D can be pushed onto the leg), else the body ([`pick`]: the triangle
//! containing the point, its vertices weighted by the point's barycentric coordinates, or the
//! nearest vertex within 5 % of the body's size); a grab that finds nothing holds nothing, and
//! the moves and release after it are ignored, as in the app.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};
use fem_solvers::{Grab, GrabModel, Model, State};
use serde::{Deserialize, Serialize};

use crate::error::SceneError;

/// What the hand does.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "action", rename_all = "kebab-case", deny_unknown_fields)]
pub enum DragAction {
    /// Grab the body at `(x, y)`: a pin (`stiffness` 0) or a spring (N/m).
    Grab {
        /// World x, m.
        x: Real,
        /// World y, m.
        y: Real,
        /// 0 for a pin, else the spring's stiffness, N/m.
        #[serde(default)]
        stiffness: Real,
    },
    /// Move the hand to `(x, y)`.
    Move {
        /// World x, m.
        x: Real,
        /// World y, m.
        y: Real,
    },
    /// Let go.
    Release,
}

/// One event: an action at a simulated time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DragEvent {
    /// Simulated time, s.
    pub t: Real,
    /// What happens.
    #[serde(flatten)]
    pub action: DragAction,
}

/// A recorded drag (see the module docs). `Default`: version 1, no events.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragTrajectory {
    /// Format version, 1.
    #[serde(default = "one")]
    pub version: u32,
    /// The events, by time.
    pub events: Vec<DragEvent>,
}

fn one() -> u32 {
    1
}

impl Default for DragTrajectory {
    fn default() -> Self {
        DragTrajectory {
            version: 1,
            events: Vec::new(),
        }
    }
}

/// Most events a drag may hold: an hour of hand events at 90 Hz (a VR controller's rate; the
/// app records at most one per animation frame, 60 Hz), 324,000. A run replays a drag of
/// simulated seconds, so an hour is far beyond any use; in memory the events take 40 bytes
/// each, 13 MB at the bound. [`DragTrajectory::parse`] counts them before it reads them, so a
/// text of more is refused without holding them, and a file larger than
/// [`MAX_DRAG_FILE_BYTES`] is refused before it is read.
pub const MAX_DRAG_EVENTS: usize = 324_000;

/// Most bytes a drag file may have: 256 per event of [`MAX_DRAG_EVENTS`] (83 MB). The JSON
/// [`DragTrajectory::to_json`] writes takes about 110 bytes per event, so every file of at most
/// that many events fits; a reader checks the size before it reads the text, which would
/// otherwise be held whole (a file of ten million events is 0.3 GB).
pub const MAX_DRAG_FILE_BYTES: u64 = 256 * MAX_DRAG_EVENTS as u64;

/// The number of entries of a drag's `events` array, counted without keeping them; `None`
/// when the text is not a JSON object with an `events` array (the full parse says why).
fn count_events(text: &str) -> Option<usize> {
    struct Count(usize);
    impl<'de> Deserialize<'de> for Count {
        fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct Counter;
            impl<'de> serde::de::Visitor<'de> for Counter {
                type Value = Count;
                fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                    f.write_str("an array")
                }
                fn visit_seq<A: serde::de::SeqAccess<'de>>(
                    self,
                    mut seq: A,
                ) -> Result<Count, A::Error> {
                    let mut n = 0;
                    while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                        n += 1;
                    }
                    Ok(Count(n))
                }
            }
            d.deserialize_seq(Counter)
        }
    }
    #[derive(Deserialize)]
    struct Events {
        events: Count,
    }
    serde_json::from_str::<Events>(text)
        .ok()
        .map(|e| e.events.0)
}

impl DragTrajectory {
    /// Parse and validate the JSON form; errors name `origin` and the field. A leading UTF-8
    /// byte-order mark is skipped; more than [`MAX_DRAG_EVENTS`] events are an error, found
    /// before the events are read.
    pub fn parse(text: &str, origin: &str) -> Result<Self, SceneError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if let Some(n) = count_events(text) {
            too_many(n, origin)?;
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let drag: DragTrajectory = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            let at = if path == "." {
                String::new()
            } else {
                format!("{path}: ")
            };
            SceneError::Scene(format!("{origin}: {at}{}", e.inner()))
        })?;
        drag.validate(origin)?;
        Ok(drag)
    }

    /// Check the version, that times are finite, non-negative and non-decreasing, and that
    /// coordinates and stiffnesses are finite (stiffness >= 0).
    pub fn validate(&self, origin: &str) -> Result<(), SceneError> {
        let err = |field: String, value: String, rule: &str| {
            SceneError::Scene(format!("{origin}: {field} = {value}: {rule}"))
        };
        if self.version != 1 {
            return Err(err("version".into(), self.version.to_string(), "must be 1"));
        }
        too_many(self.events.len(), origin)?;
        let mut last = 0.0;
        for (i, e) in self.events.iter().enumerate() {
            if !(e.t.is_finite() && e.t >= last) {
                return Err(err(
                    format!("events.{i}.t"),
                    e.t.to_string(),
                    "must be finite, >= 0 and not before the event above it (s)",
                ));
            }
            last = e.t;
            let (x, y, k) = match e.action {
                DragAction::Grab { x, y, stiffness } => (x, y, stiffness),
                DragAction::Move { x, y } => (x, y, 0.0),
                DragAction::Release => (0.0, 0.0, 0.0),
            };
            for (name, v) in [("x", x), ("y", y)] {
                if !v.is_finite() {
                    return Err(err(
                        format!("events.{i}.{name}"),
                        v.to_string(),
                        "must be finite (m)",
                    ));
                }
            }
            if !(k.is_finite() && k >= 0.0) {
                return Err(err(
                    format!("events.{i}.stiffness"),
                    k.to_string(),
                    "must be a finite number >= 0 (0 for a pin, N/m for a spring)",
                ));
            }
            if k > crate::scales::MAX_FORCE_SCALE {
                // Its pull over a metre would be beyond what sums of squared forces hold.
                return Err(err(
                    format!("events.{i}.stiffness"),
                    format!("{k:e}"),
                    "must be at most 1e150 N/m: its pull over a metre would overflow double precision",
                ));
            }
        }
        Ok(())
    }

    /// The JSON form.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}

/// The error of a drag of `n` events, more than [`MAX_DRAG_EVENTS`].
fn too_many(n: usize, origin: &str) -> Result<(), SceneError> {
    if n <= MAX_DRAG_EVENTS {
        return Ok(());
    }
    Err(SceneError::Scene(format!(
        "{origin}: events = ({n} events): must hold at most {MAX_DRAG_EVENTS} (fem_scene::drag::MAX_DRAG_EVENTS, an hour of hand events at 90 Hz)"
    )))
}

/// What a hand holds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Held {
    /// Nothing.
    #[default]
    Nothing,
    /// The body (the model's grab, a pin or a spring).
    Body,
    /// Obstacle `index`, whose position stays `offset` from the hand.
    Obstacle {
        /// The obstacle's index.
        index: usize,
        /// Its position minus the hand's, m.
        offset: Vec2,
    },
}

/// A hand: grabs an obstacle or the body, moves, lets go (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Hand {
    /// What it holds.
    pub held: Held,
    /// Where it is, m.
    pub target: Vec2,
}

impl Hand {
    /// Grab what is under `p` (an obstacle first, then the body; `stiffness` > 0 makes a
    /// spring grab of the body, else a pin): whether something was grabbed.
    pub fn grab<E: Energy>(
        &mut self,
        model: &mut Model<E>,
        state: &State,
        p: Vec2,
        stiffness: Real,
    ) -> Result<bool, SceneError> {
        self.release(model);
        self.target = p;
        for (index, (o, b)) in model.obstacles().iter().zip(&state.bodies).enumerate() {
            if inside(&o.world_polygon(b), p) {
                self.held = Held::Obstacle {
                    index,
                    offset: b.position - p,
                };
                return Ok(true);
            }
        }
        if grab_at(model, state, p, stiffness)? {
            self.held = Held::Body;
            return Ok(true);
        }
        Ok(false)
    }

    /// Move the hand to `p`.
    pub fn move_to<E: Energy>(&mut self, model: &mut Model<E>, p: Vec2) -> Result<(), SceneError> {
        self.target = p;
        if self.held == Held::Body {
            model
                .move_grab(p)
                .map_err(|e| SceneError::Solver(e.to_string()))?;
        }
        Ok(())
    }

    /// Let go (an obstacle keeps the hand's last velocity).
    pub fn release<E: Energy>(&mut self, model: &mut Model<E>) {
        if self.held == Held::Body {
            model.release();
        }
        self.held = Held::Nothing;
    }

    /// After a step from `before` (the obstacles' poses at its start) of length `dt`: a held
    /// obstacle is put where the hand holds it, with the hand's velocity and no rotation.
    pub fn after_step(&self, state: &mut State, before: &[fem_solvers::BodyState], dt: Real) {
        if let Held::Obstacle { index, offset } = self.held
            && let (Some(b), Some(b0)) = (state.bodies.get_mut(index), before.get(index))
        {
            let goal = self.target + offset;
            b.velocity = if dt > 0.0 {
                (goal - b0.position) / dt
            } else {
                Vec2::zeros()
            };
            b.position = goal;
            b.angle = b0.angle;
            b.angular_velocity = 0.0;
        }
    }
}

/// Whether `p` lies inside the polygon (even-odd rule).
fn inside(polygon: &[Vec2], p: Vec2) -> bool {
    let mut c = false;
    let n = polygon.len();
    for i in 0..n {
        let (a, b) = (polygon[i], polygon[(i + 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            c = !c;
        }
    }
    c
}

/// Plays a drag into a model as a run advances.
#[derive(Clone, Debug)]
pub struct DragPlayer {
    events: Vec<DragEvent>,
    next: usize,
    hand: Hand,
    before: Vec<fem_solvers::BodyState>,
}

impl DragPlayer {
    /// A player at the start of `drag`.
    pub fn new(drag: &DragTrajectory) -> Self {
        DragPlayer {
            events: drag.events.clone(),
            next: 0,
            hand: Hand::default(),
            before: Vec::new(),
        }
    }

    /// Before a step that starts at `state.t`: apply every event due.
    pub fn apply<E: Energy>(
        &mut self,
        model: &mut Model<E>,
        state: &State,
    ) -> Result<(), SceneError> {
        while let Some(e) = self.events.get(self.next) {
            // Events are due at their time, up to the round-off of a sum of steps.
            if e.t > state.t + 1e-9 * (1.0 + state.t.abs()) {
                break;
            }
            self.next += 1;
            match e.action {
                DragAction::Grab { x, y, stiffness } => {
                    self.hand.grab(model, state, Vec2::new(x, y), stiffness)?;
                }
                DragAction::Move { x, y } => {
                    if self.hand.held != Held::Nothing {
                        self.hand.move_to(model, Vec2::new(x, y))?;
                    }
                }
                DragAction::Release => self.hand.release(model),
            }
        }
        self.before.clone_from(&state.bodies);
        Ok(())
    }

    /// After the step: a held obstacle goes where the hand holds it (see [`Hand::after_step`]).
    pub fn after_step(&self, state: &mut State, dt: Real) {
        self.hand.after_step(state, &self.before, dt);
    }
}

/// Grab `model`'s body at `p` (see [`pick`]): whether something was grabbed. The target
/// starts at the anchor point, so the grab pulls nothing until the hand moves.
pub fn grab_at<E: Energy>(
    model: &mut Model<E>,
    state: &State,
    p: Vec2,
    stiffness: Real,
) -> Result<bool, SceneError> {
    let Some(anchor) = pick(model.mesh().triangles(), &state.x, p) else {
        return Ok(false);
    };
    let how = if stiffness > 0.0 {
        GrabModel::Spring { stiffness }
    } else {
        GrabModel::Pin
    };
    let grab = Grab {
        anchor,
        target: p,
        model: how,
    };
    if model.grab(&grab, &state.x).is_err() {
        // Only pinned or moved vertices there: nothing to hold.
        return Ok(false);
    }
    let point = model.grab_point(&state.x).unwrap_or(p);
    model
        .move_grab(point)
        .map_err(|e| SceneError::Solver(e.to_string()))?;
    Ok(true)
}

/// The anchor under `p` at positions `x`: the first triangle containing it (its vertices with
/// the point's barycentric weights; a point on a shared edge belongs to either), else the
/// nearest vertex within 5 % of the body's size, else `None`.
pub fn pick(triangles: &[[u32; 3]], x: &[Vec2], p: Vec2) -> Option<Vec<(usize, Real)>> {
    for tri in triangles {
        let [a, b, c] = tri.map(|i| x[i as usize]);
        let d = (b - a).perp(&(c - a));
        if d == 0.0 {
            continue;
        }
        let wb = (p - a).perp(&(c - a)) / d;
        let wc = (b - a).perp(&(p - a)) / d;
        let wa = 1.0 - wb - wc;
        let eps = -1e-12;
        if wa >= eps && wb >= eps && wc >= eps {
            return Some(vec![
                (tri[0] as usize, wa.max(0.0)),
                (tri[1] as usize, wb.max(0.0)),
                (tri[2] as usize, wc.max(0.0)),
            ]);
        }
    }
    let (mut lo, mut hi) = (
        Vec2::repeat(Real::INFINITY),
        Vec2::repeat(Real::NEG_INFINITY),
    );
    for q in x {
        lo = lo.inf(q);
        hi = hi.sup(q);
    }
    let reach = 0.05 * (hi - lo).norm();
    x.iter()
        .enumerate()
        .map(|(i, q)| (i, (q - p).norm()))
        .filter(|&(_, d)| d <= reach)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| vec![(i, 1.0)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_drags_are_one_line_errors_naming_the_field() {
        let cases = [
            (
                r#"{"events": [{"t": 0.1, "action": "release"}, {"t": 0.05, "action": "release"}]}"#,
                "d.json: events.1.t = 0.05: must be finite, >= 0 and not before the event above it (s)",
            ),
            (
                r#"{"version": 2, "events": []}"#,
                "d.json: version = 2: must be 1",
            ),
            (
                r#"{"events": [{"t": 0.0, "action": "grab", "x": 1.0, "y": 2.0, "stiffness": -3.0}]}"#,
                "d.json: events.0.stiffness = -3: must be a finite number >= 0 (0 for a pin, N/m for a spring)",
            ),
            (
                r#"{"events": [{"t": 0.0, "action": "grab", "x": 1.0, "y": 2.0, "stiffness": 1e300}]}"#,
                "d.json: events.0.stiffness = 1e300: must be at most 1e150 N/m: its pull over a metre would overflow double precision",
            ),
        ];
        for (text, want) in cases {
            assert_eq!(
                DragTrajectory::parse(text, "d.json")
                    .unwrap_err()
                    .to_string(),
                want
            );
        }
        for (text, needle) in [
            (r#"{"events": [{"t": 0.0, "action": "poke"}]}"#, "poke"),
            (
                r#"{"events": [{"t": 0.0, "action": "move", "x": 1.0}]}"#,
                "y",
            ),
            (r#"{"events": [], "speed": 3}"#, "speed"),
            ("{", "d.json"),
        ] {
            let e = DragTrajectory::parse(text, "d.json")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("d.json: ") && e.contains(needle), "{e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn a_byte_order_mark_before_the_json_is_skipped() {
        let text = r#"{"events": [{"t": 0.0, "action": "release"}]}"#;
        let with_bom = format!("\u{feff}{text}");
        assert_eq!(
            DragTrajectory::parse(&with_bom, "d.json").unwrap(),
            DragTrajectory::parse(text, "d.json").unwrap()
        );
    }

    #[test]
    fn more_events_than_the_bound_are_an_error_naming_the_file_and_the_count() {
        let event = r#"{"t":0,"action":"release"},"#;
        let file = |n: usize| {
            let mut text = String::from(r#"{"events":["#);
            text.push_str(&event.repeat(n));
            text.pop();
            text.push_str("]}");
            text
        };
        let at = DragTrajectory::parse(&file(MAX_DRAG_EVENTS), "d.json").unwrap();
        assert_eq!(at.events.len(), MAX_DRAG_EVENTS);
        let e = DragTrajectory::parse(&file(MAX_DRAG_EVENTS + 1), "d.json")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "d.json: events = (324001 events): must hold at most 324000 (fem_scene::drag::MAX_DRAG_EVENTS, an hour of hand events at 90 Hz)"
        );
        // A drag built in code is held to the same bound.
        let mut built = at;
        built.events.push(built.events[0]);
        assert!(built.validate("app").is_err());
        // The file size bound holds every file `to_json` writes: its longest event (a grab,
        // every number 17 significant digits and negative) takes less than 256 bytes.
        let long = -0.012_345_678_901_234_567;
        let one = DragTrajectory {
            version: 1,
            events: vec![
                DragEvent {
                    t: 1_234.567_890_123_456_7,
                    action: DragAction::Grab {
                        x: long,
                        y: long,
                        stiffness: 12_345.678_901_234_567,
                    },
                };
                2
            ],
        };
        let per_event = one.to_json().len() - DragTrajectory::default().to_json().len();
        assert!(
            (per_event as u64) < 2 * MAX_DRAG_FILE_BYTES / MAX_DRAG_EVENTS as u64,
            "{per_event}"
        );
    }

    #[test]
    fn the_json_form_round_trips() {
        let drag = DragTrajectory {
            version: 1,
            events: vec![
                DragEvent {
                    t: 0.0,
                    action: DragAction::Grab {
                        x: 1.0,
                        y: 0.5,
                        stiffness: 0.0,
                    },
                },
                DragEvent {
                    t: 0.25,
                    action: DragAction::Move { x: 1.5, y: 0.75 },
                },
                DragEvent {
                    t: 0.5,
                    action: DragAction::Release,
                },
            ],
        };
        assert_eq!(DragTrajectory::parse(&drag.to_json(), "x").unwrap(), drag);
    }

    #[test]
    fn a_point_on_a_shared_edge_picks_a_triangle() {
        let x = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        let tris = [[0, 1, 2], [0, 2, 3]];
        let a = pick(&tris, &x, Vec2::new(0.5, 0.5)).unwrap();
        assert_eq!(a.len(), 3);
        let total: Real = a.iter().map(|w| w.1).sum();
        assert!((total - 1.0).abs() < 1e-15);
        // Off the body but near a corner: that vertex; far off: nothing.
        assert_eq!(pick(&tris, &x, Vec2::new(1.02, 1.02)), Some(vec![(2, 1.0)]));
        assert_eq!(pick(&tris, &x, Vec2::new(3.0, 3.0)), None);
    }
}
