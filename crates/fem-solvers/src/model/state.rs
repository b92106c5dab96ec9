//! The state a stepper advances: vertex positions and velocities, rigid-body poses, clock.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use crate::error::SolverError;
use crate::model::Model;
use crate::rigid::BodyState;

/// Positions, velocities and time of one simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Vertex positions, m.
    pub x: Vec<Vec2>,
    /// Vertex velocities, m/s.
    pub v: Vec<Vec2>,
    /// One pose per obstacle of the model (static and kinematic ones too), in obstacle order.
    pub bodies: Vec<BodyState>,
    /// One pose per rigid body of the rigid regions
    /// ([`Model::rigid_bodies`](crate::Model::rigid_bodies)), in their order; its vertices'
    /// positions follow it.
    pub rigid: Vec<BodyState>,
    /// The clock ([`Clock`](crate::Clock)): time, s; for the static solver the load factor
    /// (0 at rest, 1 under the full load).
    pub t: Real,
    /// Number of steps taken (static solver: converged load increments).
    pub step: u64,
}

impl State {
    /// The model at rest in its reference configuration at `t = 0`.
    pub fn at_rest<E: Energy>(model: &Model<E>) -> Self {
        State {
            x: model.mesh().vertices().to_vec(),
            v: vec![Vec2::zeros(); model.mesh().n_vertices()],
            bodies: model.obstacles().iter().map(BodyState::initial).collect(),
            rigid: (model.rigid_bodies().iter())
                .map(|b| b.initial_state())
                .collect(),
            t: 0.0,
            step: 0,
        }
    }

    /// A state with the given positions and velocities at `t = 0` (bodies at rest at their
    /// initial poses; the vertices of rigid regions are placed on their bodies). Fails when the lengths do not match the model or a value is not finite.
    pub fn new<E: Energy>(
        model: &Model<E>,
        x: Vec<Vec2>,
        v: Vec<Vec2>,
    ) -> Result<Self, SolverError> {
        let mut s = State {
            x,
            v,
            ..State::at_rest(model)
        };
        s.check_matches(model)?;
        for (body, b) in model.rigid_bodies().iter().zip(&s.rigid) {
            body.place(b, &mut s.x, &mut s.v);
        }
        for (name, data) in [("x", &s.x), ("v", &s.v)] {
            if let Some(i) = data
                .iter()
                .position(|p| !(p.x.is_finite() && p.y.is_finite()))
            {
                return Err(SolverError::invalid(
                    format!("state.{name}[{i}]"),
                    format!("[{}, {}]", data[i].x, data[i].y),
                    "components must be finite",
                ));
            }
        }
        Ok(s)
    }

    /// Displacements `x - X` from the model's rest positions, m.
    pub fn displacement<E: Energy>(&self, model: &Model<E>, vertex: usize) -> Vec2 {
        self.x[vertex] - model.mesh().vertices()[vertex]
    }

    /// A 64-bit fingerprint of the state (FNV-1a of the bits of positions, velocities,
    /// rigid-body poses, time and step count): equal fingerprints mean bit-identical states
    /// with overwhelming probability.
    pub fn digest(&self) -> u64 {
        // 64-bit FNV-1a over the bits, in a fixed order: a stable fingerprint to compare
        // states across builds (native and WebAssembly), not for security.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bits: u64| {
            for b in bits.to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        for p in self.x.iter().chain(&self.v) {
            eat(p.x.to_bits());
            eat(p.y.to_bits());
        }
        for b in self.bodies.iter().chain(&self.rigid) {
            for r in [
                b.position.x,
                b.position.y,
                b.angle,
                b.velocity.x,
                b.velocity.y,
                b.angular_velocity,
            ] {
                eat(r.to_bits());
            }
        }
        eat(self.t.to_bits());
        eat(self.step);
        h
    }

    /// `Ok` when the state's sizes match the model.
    pub fn check_matches<E: Energy>(&self, model: &Model<E>) -> Result<(), SolverError> {
        let n = model.mesh().n_vertices();
        for (what, got) in [("vertices", self.x.len()), ("velocities", self.v.len())] {
            if got != n {
                return Err(SolverError::StateMismatch {
                    what,
                    got,
                    expected: n,
                });
            }
        }
        if self.bodies.len() != model.obstacles().len() {
            return Err(SolverError::StateMismatch {
                what: "bodies",
                got: self.bodies.len(),
                expected: model.obstacles().len(),
            });
        }
        if self.rigid.len() != model.rigid_bodies().len() {
            return Err(SolverError::StateMismatch {
                what: "rigid bodies",
                got: self.rigid.len(),
                expected: model.rigid_bodies().len(),
            });
        }
        Ok(())
    }
}
