//! Rigid bodies: the pose and velocity of a rigid body ([`BodyState`]), its frame (the
//! rotation precomputed), the wrench contact puts on it, and the rigid world the soft body
//! meets ([`obstacle`]: the ground half-space and polygonal obstacles that are static,
//! kinematic on a schedule of velocity windows, or dynamic).
//!
//! A rigid body's pose is its centroid and an angle from its initial pose (counter-clockwise);
//! its velocity is the centroid's and an angular velocity. What moves a body is the stepper's
//! choice: a kinematic obstacle follows its schedule (`scheduled_pose` and
//! `advance_kinematic`), a dynamic one is integrated by the stepper that pushes it (penalty
//! forces, projection impulses or barrier contact, see [`crate::contact`]).
//!
//! [`body`] holds the rigid regions: bones inside the soft body, whose vertices follow them.
//!
//! Apart from [`body`], this module knows nothing of the soft body or its mesh; it answers the polygon queries
//! (inside, nearest boundary point, penetration depth) that contact detection asks.

use fem_core::math::{Real, Vec2, sin_cos};

pub mod body;
pub mod obstacle;

pub use body::{BodyMotion, RigidBody};
pub use obstacle::{Ground, Obstacle, ObstacleMotion, ObstacleMove, first_crossing};

/// Pose and velocity of a rigid body (an obstacle's, today): the centroid's position and
/// velocity and the rotation from the initial pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// Centroid position, m.
    pub position: Vec2,
    /// Rotation angle from the initial pose, rad (counter-clockwise).
    pub angle: Real,
    /// Centroid velocity, m/s.
    pub velocity: Vec2,
    /// Angular velocity, rad/s.
    pub angular_velocity: Real,
}

impl BodyState {
    /// At rest at the obstacle's initial pose.
    pub fn initial(obstacle: &Obstacle) -> Self {
        BodyState {
            position: obstacle.initial_centroid(),
            angle: 0.0,
            velocity: Vec2::zeros(),
            angular_velocity: 0.0,
        }
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.position.iter().all(|c| c.is_finite())
            && self.velocity.iter().all(|c| c.is_finite())
            && self.angle.is_finite()
            && self.angular_velocity.is_finite()
    }

    /// Velocity of the body's material point at world position `p`.
    #[inline]
    pub(crate) fn point_velocity(&self, p: Vec2) -> Vec2 {
        let r = p - self.position;
        self.velocity + Vec2::new(-r.y, r.x) * self.angular_velocity
    }
}

/// A body pose with its rotation precomputed.
pub(crate) struct Frame {
    /// The centroid, m.
    pub position: Vec2,
    /// Cosine of the rotation angle.
    pub c: Real,
    /// Sine of the rotation angle.
    pub s: Real,
}

impl Frame {
    /// The frame of the pose `b`.
    pub(crate) fn of(b: &BodyState) -> Self {
        let (s, c) = sin_cos(b.angle);
        Frame {
            position: b.position,
            c,
            s,
        }
    }

    /// The world position of the body-frame point `q`.
    #[inline]
    pub(crate) fn apply(&self, q: Vec2) -> Vec2 {
        self.position + Vec2::new(self.c * q.x - self.s * q.y, self.s * q.x + self.c * q.y)
    }
}

/// The 2D cross product `a x b` (a torque from a lever arm and a force).
#[inline]
pub(crate) fn cross(a: Vec2, b: Vec2) -> Real {
    a.x * b.y - a.y * b.x
}

/// Net force and torque on a rigid body from contact, N and N m per unit thickness.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Wrench {
    pub force: Vec2,
    pub torque: Real,
}

/// Length of `[t, t + dt] ∩ [start, end]`: how long a scheduled window (a kinematic obstacle's
/// move, a prescribed motion) acts during a step.
#[inline]
pub(crate) fn window_overlap(t: Real, dt: Real, start: Real, end: Real) -> Real {
    let a = t.max(start);
    let b = (t + dt).min(end);
    (b - a).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_overlap_covers_partial_steps() {
        assert_eq!(window_overlap(0.0, 1.0, 0.25, 0.5), 0.25);
        assert_eq!(window_overlap(0.4, 0.2, 0.25, 0.5), 0.09999999999999998);
        assert_eq!(window_overlap(1.0, 1.0, 0.0, 0.5), 0.0);
        assert_eq!(window_overlap(0.0, 1.0, 0.0, Real::INFINITY), 1.0);
    }
}
