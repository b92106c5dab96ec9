//! The end of every step, in one place: it owns the invariant **a step never writes a
//! non-finite state**.
//!
//! Steppers compute the new positions, velocities and rigid-body poses into their own buffers;
//! [`StepEnd::commit`] then moves the kinematic vertices, checks that every new value is finite
//! (else [`SolverError::NonFinite`] naming the step and the first bad vertex, or
//! [`SolverError::NonFiniteBody`], with the state untouched), swaps the buffers into the state
//! and advances its clock. No floating-point operation happens here beyond the kinematic
//! update every stepper already made, so results are those of the hand-written ends it
//! replaces, bit for bit.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use crate::error::SolverError;
use crate::model::Model;
use crate::model::state::State;
use crate::rigid::BodyState;

/// How the kinematic (pinned and prescribed) vertices reach their new positions.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kinematic {
    /// Move them along their schedules over `[t, t + dt]` from the state's positions
    /// (overwriting what the stepper wrote there).
    Schedule {
        /// Start of the (sub)step, s.
        t: Real,
        /// Length of the (sub)step, s.
        dt: Real,
        /// End of the whole step, s (where grabbed vertices reach their goals).
        until: Real,
    },
    /// The stepper has placed them itself (the static solver, by load factor).
    Placed,
}

/// A proposed new state and how to commit it.
pub(crate) struct StepEnd<'a> {
    /// How kinematic vertices are moved.
    pub kinematics: Kinematic,
    /// New positions (swapped with the state's on success).
    pub x: &'a mut Vec<Vec2>,
    /// New velocities (swapped with the state's on success).
    pub v: &'a mut Vec<Vec2>,
    /// New rigid-body poses, when the stepper advances obstacles.
    pub bodies: Option<&'a mut Vec<BodyState>>,
    /// New poses of the rigid regions' bodies, when the model has free ones (the entries of
    /// pinned and scheduled bodies are ignored: their poses follow their vertices). The
    /// bodies' vertices are placed on them before the finite check.
    pub rigid: Option<&'a mut Vec<BodyState>>,
    /// The stepper has proven every new vertex value finite (a fast running check), so the
    /// per-vertex scan can be skipped; `false` always scans.
    pub known_finite: bool,
    /// Inverted elements seen by the step, for the error message.
    pub inverted: usize,
    /// Smallest `det F` seen by the step, for the error message.
    pub min_det_f: Real,
    /// The state's clock after the step (time, or load factor).
    pub t_end: Real,
    /// Whether this counts as a step ([`State::step`] + 1); substeps do not.
    pub count_step: bool,
}

impl StepEnd<'_> {
    /// Move kinematic vertices, check finiteness, run `accept` (a last check of the stepper,
    /// e.g. Newton's convergence), then swap the buffers into `state` and advance its clock.
    /// On any error the state is unchanged.
    pub(crate) fn commit<E: Energy>(
        self,
        model: &Model<E>,
        state: &mut State,
        accept: impl FnOnce() -> Result<(), SolverError>,
    ) -> Result<(), SolverError> {
        if let Kinematic::Schedule { t, dt, until } = self.kinematics {
            model
                .kinematics()
                .apply(t, dt, until, &state.x, self.x, self.v);
        }
        if let Some(rigid) = &self.rigid {
            for (body, b) in model.rigid_bodies().iter().zip(rigid.iter()) {
                if body.is_free() {
                    body.place(b, self.x, self.v);
                }
            }
            if let Some(k) = (model.rigid_bodies().iter().zip(rigid.iter()))
                .position(|(body, b)| body.is_free() && !b.is_finite())
            {
                return Err(SolverError::NonFiniteRigid {
                    step: state.step,
                    body: k,
                });
            }
        } else {
            debug_assert!(
                model.rigid_bodies().iter().all(|b| !b.is_free()),
                "a stepper without rigid poses ran a model with free rigid bodies"
            );
        }
        if !self.known_finite {
            check_finite(
                state.step,
                state.t,
                self.x,
                self.v,
                self.inverted,
                self.min_det_f,
            )?;
        }
        if let Some(bodies) = &self.bodies
            && let Some(body) = bodies.iter().position(|b| !b.is_finite())
        {
            return Err(SolverError::NonFiniteBody {
                step: state.step,
                body,
            });
        }
        accept()?;
        std::mem::swap(&mut state.x, self.x);
        std::mem::swap(&mut state.v, self.v);
        if let Some(bodies) = self.bodies {
            std::mem::swap(&mut state.bodies, bodies);
        }
        for (k, body) in model.rigid_bodies().iter().enumerate() {
            if body.is_free() {
                if let Some(rigid) = &self.rigid {
                    state.rigid[k] = rigid[k];
                }
            } else {
                // Pinned or scheduled: the body translates with its vertices.
                let (v0, r0) = (body.vertices[0] as usize, body.offsets[0]);
                state.rigid[k] = BodyState {
                    position: state.x[v0] - r0,
                    angle: 0.0,
                    velocity: state.v[v0],
                    angular_velocity: 0.0,
                };
            }
        }
        state.t = self.t_end;
        if self.count_step {
            state.step += 1;
        }
        Ok(())
    }
}

/// The first vertex whose position or velocity is not finite.
fn first_non_finite(x: &[Vec2], v: &[Vec2]) -> Option<usize> {
    x.iter().zip(v).position(|(p, q)| {
        !(p.x.is_finite() && p.y.is_finite() && q.x.is_finite() && q.y.is_finite())
    })
}

/// [`SolverError::NonFinite`] for the first bad vertex of a proposed new state, if any; the
/// step number, time and inversion statistics go into the message.
fn check_finite(
    step: u64,
    time: Real,
    x: &[Vec2],
    v: &[Vec2],
    inverted: usize,
    min_det_f: Real,
) -> Result<(), SolverError> {
    match first_non_finite(x, v) {
        None => Ok(()),
        Some(vertex) => Err(SolverError::NonFinite {
            step,
            time,
            vertex,
            x: x[vertex].x,
            y: x[vertex].y,
            vx: v[vertex].x,
            vy: v[vertex].y,
            inverted,
            min_det_f,
        }),
    }
}
