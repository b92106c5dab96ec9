//! The time integrator of the solvers that minimise an incremental potential (implicit Euler
//! by Newton, VBD, Projective Dynamics, quasi-Newton): backward Euler (first order, the
//! default) or BDF2 (second order).
//!
//! **Both as one minimisation.** Each step of length `h` minimises
//! `w/2 |x - x_hat|_M^2 + Psi(x) - f . x` and then sets the velocity from the positions:
//! - backward Euler: `w = 1/h^2`, `x_hat = x_n + h v_n`, `v_{n+1} = (x_{n+1} - x_n) / h`;
//! - BDF2: `w = 9/(4 h^2)` (an effective step `2h/3`),
//!   `x_hat = 4/3 x_n - 1/3 x_{n-1} + 8/9 h v_n - 2/9 h v_{n-1}`,
//!   `v_{n+1} = (3 x_{n+1} - 4 x_n + x_{n-1}) / (2h)`.
//!
//! BDF2 applied to `x' = v`, `M v' = f(x)`: `x_{n+1} - 4/3 x_n + 1/3 x_{n-1} = 2h/3 v_{n+1}` and
//! `v_{n+1} - 4/3 v_n + 1/3 v_{n-1} = 2h/3 M^-1 f(x_{n+1})`. The first gives the velocity update;
//! putting it into the second and multiplying by `2h/3` gives
//! `M (x_{n+1} - x_hat) = (2h/3)^2 f(x_{n+1})`, the stationarity condition of the potential
//! above with `f = -grad Psi + f_ext`. The sums are evaluated as
//! `x_n + (x_n - x_{n-1}) / 3 + h (8 v_n - 2 v_{n-1}) / 9` and
//! `(3 (x_{n+1} - x_n) - (x_n - x_{n-1})) / (2h)`, in differences, so round-off is that of the
//! motion, not of the absolute coordinates.
//!
//! Free rigid bodies (their centroid and angle) and dynamic obstacles in barrier contact take
//! the same target, weight and velocity update on their poses; kinematic vertices and
//! obstacles follow their schedules. Velocity damping is `v <- v exp(-c h)` after the update,
//! as under backward Euler (a first-order splitting: with `c > 0` the error has an `O(c h)`
//! part).
//!
//! BDF2 is L-stable like backward Euler but damps less; it stays stable with barrier contact
//! (`tests/suite/integrator.rs`: a block dropped on the ground and a slab dropped on a strip at
//! 90 Hz stay apart, of bounded energy, and come to rest on their weight). An unconverged solve
//! (VBD with few sweeps) leaves a position error that BDF2's velocity update weighs 1.5 times
//! as much as backward Euler's, and damps less: give it the iterations to converge. Measured
//! orders and costs are in `docs/implicit.md` (BDF2).
//!
//! **History and fall-back.** BDF2 needs the previous step's state `(x_{n-1}, v_{n-1})`. A
//! stepper keeps it (`History`) and takes a BDF2 step only when the incoming state is, bit
//! for bit (positions, velocities, rigid bodies, obstacles, clock and step counter), the
//! state it committed last, with the same step length and model layout. Otherwise (the first
//! step, a state modified or restored by the caller between steps, a step that failed, a
//! changed time step, a grab started or ended) that step is backward Euler, and BDF2 resumes
//! on the next. A step with substeps (VBD) treats each substep as a step.

use std::fmt;
use std::str::FromStr;

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;

use crate::error::SolverError;
use crate::model::Model;
use crate::model::grab::Spring;
use crate::model::state::State;
use crate::optim::pd_system::PdSystem;
use crate::rigid::{BodyState, ObstacleMotion};

/// The time integrator of a solver that minimises an incremental potential (scene key
/// `integrator`; serde names `backward-euler`, `bdf2`). See the module docs for the formulas.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
#[non_exhaustive]
pub enum Integrator {
    /// Backward (implicit) Euler: first order, strongly damping at large steps. Default.
    #[default]
    BackwardEuler,
    /// The second-order backward differentiation formula, started (and restarted whenever the
    /// previous step's state is not the one the stepper committed) by a backward Euler step.
    Bdf2,
}

impl Integrator {
    /// Every integrator, default first.
    pub const ALL: [Integrator; 2] = [Integrator::BackwardEuler, Integrator::Bdf2];

    /// The name on the command line and in files (`backward-euler`, `bdf2`).
    pub fn name(self) -> &'static str {
        match self {
            Integrator::BackwardEuler => "backward-euler",
            Integrator::Bdf2 => "bdf2",
        }
    }
}

impl fmt::Display for Integrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Integrator {
    type Err = SolverError;
    /// The integrator of that name; an unknown name is a one-line error naming the field
    /// `integrator` and the valid names.
    fn from_str(s: &str) -> Result<Self, SolverError> {
        Integrator::ALL
            .into_iter()
            .find(|i| i.name() == s)
            .ok_or_else(|| {
                SolverError::invalid(
                    "integrator",
                    s,
                    format!(
                        "unknown integrator (expected one of: {})",
                        Integrator::ALL.map(Integrator::name).join(", ")
                    ),
                )
            })
    }
}

/// BDF2's inertia weight `9 / (4 h^2)` (backward Euler's is `1 / h^2`).
#[inline]
pub(crate) fn bdf2_weight(h: Real) -> Real {
    9.0 / (4.0 * h * h)
}

/// BDF2's inertial target `4/3 x - 1/3 x_prev + 8/9 h v - 2/9 h v_prev`, in differences.
#[inline(always)]
pub(crate) fn bdf2_target(x: Vec2, x_prev: Vec2, v: Vec2, v_prev: Vec2, h: Real) -> Vec2 {
    x + (x - x_prev) / 3.0 + (v * 8.0 - v_prev * 2.0) * (h / 9.0)
}

/// [`bdf2_target`] of a scalar coordinate (an angle).
#[inline(always)]
pub(crate) fn bdf2_target_scalar(x: Real, x_prev: Real, v: Real, v_prev: Real, h: Real) -> Real {
    x + (x - x_prev) / 3.0 + (8.0 * v - 2.0 * v_prev) * (h / 9.0)
}

/// BDF2's velocity `(3 x_new - 4 x + x_prev) / (2h)`, in differences.
#[inline(always)]
pub(crate) fn bdf2_velocity(x_new: Vec2, x: Vec2, x_prev: Vec2, h: Real) -> Vec2 {
    ((x_new - x) * 3.0 - (x - x_prev)) / (2.0 * h)
}

/// [`bdf2_velocity`] of a scalar coordinate (an angle).
#[inline(always)]
pub(crate) fn bdf2_velocity_scalar(x_new: Real, x: Real, x_prev: Real, h: Real) -> Real {
    (3.0 * (x_new - x) - (x - x_prev)) / (2.0 * h)
}

/// BDF2's target pose of a body (`[x, y, theta]`) from its state and its previous state.
#[inline]
pub(crate) fn bdf2_pose_target(b: &BodyState, prev: &BodyState, h: Real) -> [Real; 3] {
    let p = bdf2_target(b.position, prev.position, b.velocity, prev.velocity, h);
    let a = bdf2_target_scalar(
        b.angle,
        prev.angle,
        b.angular_velocity,
        prev.angular_velocity,
        h,
    );
    [p.x, p.y, a]
}

/// BDF2's targets of the dynamic obstacles: overwrite their entries of `targets` (from
/// `contact::barrier::step_targets`, backward Euler's `pose + h velocity`) with BDF2's from
/// the obstacles' states `state` and `prev` (at the start of the previous step). Kinematic and
/// static obstacles keep theirs (their schedule's pose, their pose).
pub(crate) fn bdf2_obstacle_targets<E: Energy>(
    model: &Model<E>,
    state: &[BodyState],
    prev: &[BodyState],
    h: Real,
    targets: &mut [[Real; 3]],
) {
    for (o, obs) in model.obstacles().iter().enumerate() {
        if let ObstacleMotion::Dynamic { .. } = obs.motion() {
            targets[o] = bdf2_pose_target(&state[o], &prev[o], h);
        }
    }
}

/// BDF2's velocities of the dynamic obstacles: overwrite those of `new` (their poses at the
/// end of the step, from `contact::barrier::end_poses`) from the poses of `state` (the step's
/// start) and `prev` (the previous step's). Kinematic obstacles keep their schedule's.
pub(crate) fn bdf2_obstacle_velocities<E: Energy>(
    model: &Model<E>,
    state: &[BodyState],
    prev: &[BodyState],
    h: Real,
    new: &mut [BodyState],
) {
    for (o, obs) in model.obstacles().iter().enumerate() {
        if let ObstacleMotion::Dynamic { .. } = obs.motion() {
            bdf2_body_velocity(&mut new[o], &state[o], &prev[o], h);
        }
    }
}

/// BDF2's velocity and angular velocity of a body whose new pose is in `new`, from its poses
/// `state` (the step's start) and `prev` (the previous step's start).
#[inline]
pub(crate) fn bdf2_body_velocity(
    new: &mut BodyState,
    state: &BodyState,
    prev: &BodyState,
    h: Real,
) {
    new.velocity = bdf2_velocity(new.position, state.position, prev.position, h);
    new.angular_velocity = bdf2_velocity_scalar(new.angle, state.angle, prev.angle, h);
}

/// A copy of a [`State`], bit for bit.
#[derive(Clone, Debug, Default)]
pub(crate) struct Snapshot {
    pub x: Vec<Vec2>,
    pub v: Vec<Vec2>,
    pub bodies: Vec<BodyState>,
    pub rigid: Vec<BodyState>,
    t: Real,
    step: u64,
}

/// Whether two vectors are equal bit for bit.
fn same_vectors(a: &[Vec2], b: &[Vec2]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(p, q)| p.x.to_bits() == q.x.to_bits() && p.y.to_bits() == q.y.to_bits())
}

/// Whether two body states are equal bit for bit.
fn same_bodies(a: &[BodyState], b: &[BodyState]) -> bool {
    let bits = |s: &BodyState| {
        [
            s.position.x,
            s.position.y,
            s.angle,
            s.velocity.x,
            s.velocity.y,
            s.angular_velocity,
        ]
        .map(Real::to_bits)
    };
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| bits(p) == bits(q))
}

impl Snapshot {
    /// Copy `state` (reusing the buffers).
    fn copy_from(&mut self, state: &State) {
        self.x.clone_from(&state.x);
        self.v.clone_from(&state.v);
        self.bodies.clone_from(&state.bodies);
        self.rigid.clone_from(&state.rigid);
        self.t = state.t;
        self.step = state.step;
    }

    /// Whether `state` equals this copy bit for bit.
    fn matches(&self, state: &State) -> bool {
        self.step == state.step
            && self.t.to_bits() == state.t.to_bits()
            && same_vectors(&self.x, &state.x)
            && same_vectors(&self.v, &state.v)
            && same_bodies(&self.bodies, &state.bodies)
            && same_bodies(&self.rigid, &state.rigid)
    }
}

/// The previous step's state a BDF2 stepper keeps, and the check that it still applies (see
/// the module docs). Under backward Euler it holds nothing and costs nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct History {
    bdf2: bool,
    /// The state the last committed step started from (`x_{n-1}`, ...): read by a BDF2 step.
    pub prev: Snapshot,
    /// The state the last committed step ended at (`x_n`, ...), or during a step the state
    /// it started from.
    last: Snapshot,
    /// Whether `last` and `prev` are two consecutive states this stepper committed.
    valid: bool,
    /// The step length and model layout of the last step.
    h: Real,
    layout: u64,
}

impl History {
    /// An empty history for `integrator` (the first step is backward Euler).
    pub(crate) fn new(integrator: Integrator) -> Self {
        History {
            bdf2: integrator == Integrator::Bdf2,
            ..History::default()
        }
    }

    /// Start a step of length `h` on a model of layout `layout` from `state`: whether it is a
    /// BDF2 step (BDF2 chosen, and `state` is bit for bit what this stepper committed last
    /// with the same `h` and layout; then [`History::prev`] holds the state before it). The
    /// history is invalid until [`History::commit`], so a step that fails leaves the next one
    /// backward Euler.
    pub(crate) fn begin(&mut self, state: &State, h: Real, layout: u64) -> bool {
        if !self.bdf2 {
            return false;
        }
        let ok = self.valid
            && self.h.to_bits() == h.to_bits()
            && self.layout == layout
            && self.last.matches(state);
        self.valid = false;
        if !ok {
            self.last.copy_from(state);
        }
        self.h = h;
        self.layout = layout;
        ok
    }

    /// After a step committed `state`: the step's start becomes the previous state, and
    /// `state` the one the next step must start from.
    pub(crate) fn commit(&mut self, state: &State) {
        if !self.bdf2 {
            return;
        }
        std::mem::swap(&mut self.prev, &mut self.last);
        self.last.copy_from(state);
        self.valid = true;
    }

    /// The inertial targets of a step of length `h` from `state` into `target` (backward
    /// Euler's `x + h v`, or with `bdf2` BDF2's from [`History::prev`]), and the inertia weight
    /// `w` with its inverse `1 / w` (backward Euler's `h^2` as such, bit for bit).
    pub(crate) fn targets(
        &self,
        bdf2: bool,
        state: &State,
        h: Real,
        target: &mut [Vec2],
    ) -> (Real, Real) {
        if bdf2 {
            let prev = &self.prev;
            for (i, xh) in target.iter_mut().enumerate() {
                *xh = bdf2_target(state.x[i], prev.x[i], state.v[i], prev.v[i], h);
            }
            (bdf2_weight(h), 1.0 / bdf2_weight(h))
        } else {
            for ((xh, x), v) in target.iter_mut().zip(&state.x).zip(&state.v) {
                *xh = x + h * v;
            }
            (1.0 / (h * h), h * h)
        }
    }

    /// Forget the history: the next step is backward Euler.
    pub(crate) fn clear(&mut self) {
        self.valid = false;
    }
}

/// The matrices of a step of length `h` under `integrator`: backward Euler's (inertia
/// weight `1 / h^2`), and under BDF2 BDF2's too (`9 / (4 h^2)`; its first step and
/// fall-backs are backward Euler's). Arguments and errors as `PdSystem::new`'s.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pd_systems(
    mesh: &Mesh,
    masses: &[Real],
    weights: &[Real],
    h: Real,
    integrator: Integrator,
    springs: &[Spring],
    kinematic: &[bool],
    prefix: &str,
) -> Result<(PdSystem, Option<PdSystem>), SolverError> {
    let build = |w| PdSystem::new(mesh, masses, weights, w, springs, kinematic, prefix);
    let backward_euler = build(1.0 / (h * h))?;
    let bdf2 = match integrator {
        Integrator::Bdf2 => Some(build(bdf2_weight(h))?),
        Integrator::BackwardEuler => None,
    };
    Ok((backward_euler, bdf2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_an_unknown_name_lists_the_valid_ones() {
        for i in Integrator::ALL {
            assert_eq!(i.name().parse::<Integrator>().unwrap(), i);
            assert_eq!(i.to_string(), i.name());
        }
        assert_eq!(Integrator::default(), Integrator::BackwardEuler);
        assert_eq!(
            "rk4".parse::<Integrator>().unwrap_err().to_string(),
            "integrator = rk4: unknown integrator (expected one of: backward-euler, bdf2)"
        );
    }

    /// The target and velocity are exact for a quadratic motion `x = a t^2 / 2` (BDF2 is exact
    /// on polynomials of degree 2): from `t = h` and `t = 2h`, the step to `3h` satisfies
    /// `x_3 = x_hat + (2h/3)^2 a` and its velocity is `3 a h`.
    #[test]
    fn bdf2_is_exact_on_constant_acceleration() {
        let (a, h) = (Vec2::new(0.3, -9.8), 0.01);
        let x = |n: Real| a * (0.5 * (n * h) * (n * h));
        let v = |n: Real| a * (n * h);
        let target = bdf2_target(x(2.0), x(1.0), v(2.0), v(1.0), h);
        let x3 = target + a / bdf2_weight(h);
        assert!((x3 - x(3.0)).norm() < 1e-15, "{x3:?}");
        let v3 = bdf2_velocity(x(3.0), x(2.0), x(1.0), h);
        assert!((v3 - v(3.0)).norm() < 1e-13, "{v3:?}");
        let s = bdf2_target_scalar(x(2.0).y, x(1.0).y, v(2.0).y, v(1.0).y, h);
        assert_eq!(s, target.y);
        let w = bdf2_velocity_scalar(x(3.0).y, x(2.0).y, x(1.0).y, h);
        assert_eq!(w, v3.y);
    }

    /// A one-vertex state at `x`, time `t`, step `step`.
    fn state(x: Real, t: Real, step: u64) -> State {
        State {
            x: vec![Vec2::new(x, 0.0)],
            v: vec![Vec2::zeros()],
            bodies: Vec::new(),
            rigid: Vec::new(),
            t,
            step,
        }
    }

    /// BDF2 only from the state committed last, with the same step and layout; a step that
    /// is not committed (failed) leaves the next one backward Euler; backward Euler keeps
    /// nothing.
    #[test]
    fn the_history_applies_to_the_state_committed_last_only() {
        let (h, layout) = (0.1, 7);
        let mut history = History::new(Integrator::Bdf2);
        let s0 = state(0.0, 0.0, 0);
        assert!(!history.begin(&s0, h, layout), "the first step");
        let s1 = state(1.0, 0.1, 1);
        history.commit(&s1);
        assert!(history.begin(&s1, h, layout));
        assert_eq!(history.prev.x, s0.x);
        // That step failed (no commit): the retry is backward Euler, then BDF2 resumes.
        assert!(!history.begin(&s1, h, layout));
        let s2 = state(2.0, 0.2, 2);
        history.commit(&s2);
        assert!(history.begin(&s2, h, layout));
        assert_eq!(history.prev.x, s1.x);
        let s3 = state(3.0, 0.3, 3);
        history.commit(&s3);
        // Another state (a restored one, a moved vertex, -0.0 for 0.0, another clock).
        for other in [
            s2.clone(),
            state(3.0 + 1e-15, 0.3, 3),
            state(3.0, 0.3, 4),
            state(3.0, 0.30000000000000004, 3),
            State {
                v: vec![Vec2::new(-0.0, 0.0)],
                ..s3.clone()
            },
        ] {
            let mut h2 = history.clone();
            assert!(!h2.begin(&other, h, layout), "{other:?}");
        }
        // Another step length or layout.
        assert!(!history.clone().begin(&s3, 0.05, layout));
        assert!(!history.clone().begin(&s3, h, layout + 1));
        assert!(history.clone().begin(&s3, h, layout));
        history.clear();
        assert!(!history.begin(&s3, h, layout));
        // Backward Euler: never BDF2.
        let mut be = History::new(Integrator::BackwardEuler);
        assert!(!be.begin(&s0, h, layout));
        be.commit(&s1);
        assert!(!be.begin(&s1, h, layout));
    }
}
