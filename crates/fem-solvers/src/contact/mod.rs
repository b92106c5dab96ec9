//! Contact between the soft body and the rigid world ([`crate::rigid`]: a ground half-space and
//! polygonal obstacles, static, kinematic or dynamic): the contact records every stepper
//! reports ([`Contact`]), the two families that produce them, and what is read from them.
//!
//! - [`penalty`]: penalty forces (explicit stepper) and position projection (PBD, XPBD):
//!   vertex-in-obstacle and obstacle-corner-in-edge detection, Coulomb friction;
//! - barrier contact (implicit Euler, the static solver, VBD): IPC-style, never penetrating,
//!   built on the primitives of [`ipc`] (see `docs/solvers.md`, Contact);
//! - [`pressure`]: the normal contact pressure on the body's boundary from a step's records.
//!
//! Every family finds its candidate pairs through one broad phase (a uniform grid over the
//! boundary edges' boxes), never by testing all pairs.
//!
//! The obstacles, the ground and the contact parameters are re-exported here, where contact
//! users look for them; they are defined with the rigid bodies and the model.

use fem_core::math::{Real, Vec2};

pub(crate) mod barrier;
pub(crate) mod broad_phase;
pub mod ipc;
pub mod penalty;
pub mod pressure;

pub use crate::model::contact_params::ContactParams;
pub use crate::rigid::{BodyState, Ground, Obstacle, ObstacleMotion, ObstacleMove, first_crossing};
pub use penalty::CORNER_DEPTH_FRACTION;

/// Which two features touch in a [`Contact`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ContactKind {
    /// A soft boundary vertex on (or in) the ground.
    VertexGround {
        /// The soft vertex.
        vertex: u32,
    },
    /// A soft boundary vertex against an edge of an obstacle (edge `k` runs from polygon
    /// vertex `k` to `k + 1`).
    VertexObstacle {
        /// The soft vertex.
        vertex: u32,
        /// The obstacle's index.
        obstacle: u32,
        /// The obstacle's edge.
        edge: u32,
    },
    /// An obstacle's corner against a soft boundary edge `[a, b]`.
    CornerEdge {
        /// The obstacle's index.
        obstacle: u32,
        /// The obstacle's corner (polygon vertex).
        corner: u32,
        /// The soft boundary edge's vertices.
        edge: [u32; 2],
    },
}

/// One contact at the end of a step: the stepper's own measure of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The features in contact.
    pub kind: ContactKind,
    /// The contact point on the soft body's side, m.
    pub point: Vec2,
    /// Unit normal pointing from the obstacle (or ground) into the soft body.
    pub normal: Vec2,
    /// Distance between the two features, m; negative means penetration (depth).
    pub gap: Real,
    /// Normal force on the soft body, N per unit thickness (>= 0).
    pub force: Real,
}
