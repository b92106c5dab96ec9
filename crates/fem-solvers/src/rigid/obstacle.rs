//! The rigid world the soft body meets: a ground half-space ([`Ground`]) and polygonal
//! obstacles ([`Obstacle`]) that are static, kinematic (velocity windows: lowered, held,
//! lifted) or dynamic rigid bodies (mass, gravity, two-way coupling), with the polygon queries
//! contact detection and the overlap checks at `t = 0` use.
//!
//! Polygons are given counter-clockwise in world coordinates at `t = 0`, with at least three
//! vertices and positive area; their pose is then tracked as the centroid position and an angle
//! in [`BodyState`].

use fem_core::math::{Real, Vec2};

use super::{BodyState, Frame, window_overlap};
use crate::error::{SolverError, check_finite_vec, check_positive};

/// The half-space `(p - point) . normal >= 0` is free; points below it penetrate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// A point on the ground surface, m.
    pub point: Vec2,
    /// Outward normal (pointing into the free side); normalised when the model takes it.
    pub normal: Vec2,
}

impl Ground {
    /// The horizontal ground `y >= height` (m).
    pub fn horizontal(height: Real) -> Self {
        Ground {
            point: Vec2::new(0.0, height),
            normal: Vec2::new(0.0, 1.0),
        }
    }

    pub(crate) fn validated(self) -> Result<Self, SolverError> {
        check_finite_vec("ground.point", self.point)?;
        check_finite_vec("ground.normal", self.normal)?;
        let n = self.normal.norm();
        if n == 0.0 || !n.is_finite() {
            return Err(SolverError::invalid(
                "ground.normal",
                format!("[{}, {}]", self.normal.x, self.normal.y),
                "must be a non-zero vector",
            ));
        }
        Ok(Ground {
            point: self.point,
            normal: self.normal / n,
        })
    }
}

/// How an obstacle moves.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ObstacleMotion {
    /// Never moves.
    Static,
    /// Moves with a prescribed velocity during `[start, end]` (s) and is still otherwise. The
    /// rotation is about the polygon's centroid.
    Kinematic {
        /// Translational velocity of the centroid, m/s.
        velocity: Vec2,
        /// Angular velocity, rad/s (counter-clockwise positive).
        angular_velocity: Real,
        /// Window start, s.
        start: Real,
        /// Window end, s (may be infinite).
        end: Real,
    },
    /// A rigid body with mass, under the model's gravity and pushed by the soft body.
    Dynamic {
        /// Mass per unit thickness, kg. The moment of inertia is that of the polygon with this
        /// mass spread uniformly.
        mass: Real,
        /// Whether the body may rotate (`false`: translation only).
        rotates: bool,
    },
}

/// One more move of a kinematic obstacle after the window of its [`ObstacleMotion::Kinematic`]
/// (see [`Obstacle::set_moves`]): a velocity held during `[start, end]`, e.g. debris lowered
/// onto a leg and later lifted off it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstacleMove {
    /// Translational velocity of the centroid, m/s.
    pub velocity: Vec2,
    /// Angular velocity, rad/s (counter-clockwise positive), about the centroid.
    pub angular_velocity: Real,
    /// Window start, s.
    pub start: Real,
    /// Window end, s (may be infinite for the last move).
    pub end: Real,
}

/// A rigid polygonal obstacle.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// Polygon vertices relative to the centroid, in the body frame.
    local: Vec<Vec2>,
    /// Centroid at `t = 0`, m.
    centroid: Vec2,
    /// Largest distance of a polygon vertex from the centroid, m.
    radius: Real,
    motion: ObstacleMotion,
    /// A kinematic obstacle's moves after its first window, in time order.
    then: Vec<ObstacleMove>,
    /// Moment of inertia about the centroid, kg m^2 (dynamic bodies only, else 0).
    inertia: Real,
}

/// `(b - a) x (c - a)`.
fn orient(a: Vec2, b: Vec2, c: Vec2) -> Real {
    (b - a).perp(&(c - a))
}

/// The first pair of non-adjacent edges `(i, j)`, `i < j`, of a closed polygon that intersect
/// (touching counts), or `None` for a simple polygon. Edge `k` runs from vertex `k` to `k + 1`.
/// Quadratic in the vertex count, which is small for obstacles.
pub fn first_crossing(polygon: &[Vec2]) -> Option<(usize, usize)> {
    let n = polygon.len();
    let scale = polygon.iter().map(|p| p.norm()).fold(1.0, Real::max);
    let eps = 1e-12 * scale * scale;
    let sign = |v: Real| {
        if v > eps {
            1
        } else if v < -eps {
            -1
        } else {
            0
        }
    };
    let on_segment = |a: Vec2, b: Vec2, p: Vec2| {
        p.x >= a.x.min(b.x) && p.x <= a.x.max(b.x) && p.y >= a.y.min(b.y) && p.y <= a.y.max(b.y)
    };
    for i in 0..n {
        let (a, b) = (polygon[i], polygon[(i + 1) % n]);
        for j in i + 1..n {
            // Adjacent edges share a vertex by construction.
            if j == i + 1 || (i == 0 && j == n - 1) {
                continue;
            }
            let (c, d) = (polygon[j], polygon[(j + 1) % n]);
            let (d1, d2) = (sign(orient(a, b, c)), sign(orient(a, b, d)));
            let (d3, d4) = (sign(orient(c, d, a)), sign(orient(c, d, b)));
            let proper = d1 * d2 < 0 && d3 * d4 < 0;
            let touching = (d1 == 0 && on_segment(a, b, c))
                || (d2 == 0 && on_segment(a, b, d))
                || (d3 == 0 && on_segment(c, d, a))
                || (d4 == 0 && on_segment(c, d, b));
            if proper || touching {
                return Some((i, j));
            }
        }
    }
    None
}

/// Whether `q` lies inside the closed polygon (even-odd rule), the squared distance to its
/// nearest boundary point, that point and the edge it lies on (edge `k` runs from vertex `k`
/// to `k + 1`; the first on a tie). The one polygon query of contact detection
/// ([`Obstacle`]'s penetration) and of the overlap checks at `t = 0`.
#[inline(always)]
fn polygon_query(polygon: &[Vec2], q: Vec2) -> (bool, Real, Vec2, usize) {
    let n = polygon.len();
    let mut inside = false;
    let mut best = Real::INFINITY;
    let mut closest = Vec2::zeros();
    let mut edge = 0;
    for k in 0..n {
        let a = polygon[k];
        let b = polygon[(k + 1) % n];
        if (a.y > q.y) != (b.y > q.y) {
            let xc = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if q.x < xc {
                inside = !inside;
            }
        }
        let e = b - a;
        let t = ((q - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0);
        let c = a + e * t;
        let dist2 = (c - q).norm_squared();
        if dist2 < best {
            best = dist2;
            closest = c;
            edge = k;
        }
    }
    (inside, best, closest, edge)
}

/// Whether `p` lies inside the closed polygon by more than `margin` (its distance to the
/// boundary): what contact would push out, as opposed to a point touching the boundary.
pub(crate) fn strictly_inside(polygon: &[Vec2], p: Vec2, margin: Real) -> bool {
    let (inside, dist2, _, _) = polygon_query(polygon, p);
    inside && dist2 > margin * margin
}

impl Obstacle {
    /// From a counter-clockwise polygon in world coordinates at `t = 0`. Fails (naming
    /// `obstacles[index]`) on fewer than 3 vertices, non-finite coordinates, clockwise order,
    /// zero area or crossing edges, and on a non-positive dynamic mass.
    pub fn new(
        index: usize,
        polygon: &[Vec2],
        motion: ObstacleMotion,
    ) -> Result<Self, SolverError> {
        let err = |reason: String| SolverError::Obstacle { index, reason };
        if polygon.len() < 3 {
            return Err(err(format!(
                "polygon has {} vertices, at least 3 are needed",
                polygon.len()
            )));
        }
        if let Some(k) = polygon
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(err(format!("polygon[{k}] is not finite")));
        }
        if let Some((i, j)) = first_crossing(polygon) {
            return Err(err(format!(
                "polygon edges {i} ([{}, {}] to [{}, {}]) and {j} ([{}, {}] to [{}, {}]) cross: the polygon must be simple",
                polygon[i].x,
                polygon[i].y,
                polygon[(i + 1) % polygon.len()].x,
                polygon[(i + 1) % polygon.len()].y,
                polygon[j].x,
                polygon[j].y,
                polygon[(j + 1) % polygon.len()].x,
                polygon[(j + 1) % polygon.len()].y,
            )));
        }
        // Shoelace area, centroid and polar second moment about the origin.
        let mut a2 = 0.0;
        let mut c = Vec2::zeros();
        let n = polygon.len();
        for k in 0..n {
            let (p, q) = (polygon[k], polygon[(k + 1) % n]);
            let cross = p.x * q.y - q.x * p.y;
            a2 += cross;
            c += (p + q) * cross;
        }
        let scale = polygon
            .iter()
            .map(|p| p.norm())
            .fold(0.0, Real::max)
            .max(1.0);
        if a2 <= 1e-12 * scale * scale {
            return Err(err(if a2 < 0.0 {
                format!(
                    "polygon is clockwise (signed area {:e}); list it counter-clockwise",
                    0.5 * a2
                )
            } else {
                format!("polygon has zero area ({:e})", 0.5 * a2)
            }));
        }
        let area = 0.5 * a2;
        let centroid = c / (3.0 * a2);
        let local: Vec<Vec2> = polygon.iter().map(|p| p - centroid).collect();
        let radius = local.iter().map(|p| p.norm()).fold(0.0, Real::max);
        let mut inertia = 0.0;
        match motion {
            ObstacleMotion::Static => {}
            ObstacleMotion::Kinematic {
                velocity,
                angular_velocity,
                start,
                end,
            } => {
                check_finite_vec(&format!("obstacles[{index}].velocity"), velocity)?;
                if !angular_velocity.is_finite() {
                    return Err(SolverError::invalid(
                        format!("obstacles[{index}].angular_velocity"),
                        angular_velocity,
                        "must be finite (rad/s)",
                    ));
                }
                if !(start.is_finite() && start >= 0.0) {
                    return Err(SolverError::invalid(
                        format!("obstacles[{index}].start"),
                        start,
                        "must be a finite number >= 0 (s)",
                    ));
                }
                if end.is_nan() || end < start {
                    return Err(SolverError::invalid(
                        format!("obstacles[{index}].end"),
                        end,
                        "must be >= start (s)",
                    ));
                }
            }
            ObstacleMotion::Dynamic { mass, .. } => {
                check_positive(&format!("obstacles[{index}].mass"), mass)?;
                // Polar second moment about the centroid of a uniform polygon.
                let mut j = 0.0;
                for k in 0..n {
                    let (p, q) = (local[k], local[(k + 1) % n]);
                    let cross = p.x * q.y - q.x * p.y;
                    j += cross * (p.dot(&p) + p.dot(&q) + q.dot(&q));
                }
                inertia = mass * (j / 12.0) / area;
            }
        }
        Ok(Obstacle {
            local,
            centroid,
            radius,
            motion,
            then: Vec::new(),
            inertia,
        })
    }

    /// Give a kinematic obstacle further moves after the window of its
    /// [`ObstacleMotion::Kinematic`], in time order: each starts at or after the end of the one
    /// before (so at most one velocity holds at a time; between windows the obstacle stands
    /// still). Replaces earlier ones; an empty list leaves the one window. Fails, naming
    /// `obstacles[index].moves[k]`, for an obstacle that is not kinematic, a non-finite
    /// velocity, or a window that is not ordered or not after the previous one.
    pub fn set_moves(&mut self, index: usize, moves: &[ObstacleMove]) -> Result<(), SolverError> {
        let ObstacleMotion::Kinematic { end: first_end, .. } = self.motion else {
            return Err(SolverError::invalid(
                format!("obstacles[{index}].moves"),
                moves.len(),
                "only a kinematic obstacle has moves",
            ));
        };
        let mut previous = first_end;
        for (k, m) in moves.iter().enumerate() {
            let f = format!("obstacles[{index}].moves[{k}]");
            check_finite_vec(&format!("{f}.velocity"), m.velocity)?;
            if !m.angular_velocity.is_finite() {
                return Err(SolverError::invalid(
                    format!("{f}.angular_velocity"),
                    m.angular_velocity,
                    "must be finite (rad/s)",
                ));
            }
            if !(m.start.is_finite() && m.start >= previous) {
                return Err(SolverError::invalid(
                    format!("{f}.start"),
                    m.start,
                    format!(
                        "must be finite and at or after the end of the window before it ({previous} s)"
                    ),
                ));
            }
            if m.end.is_nan() || m.end < m.start {
                return Err(SolverError::invalid(
                    format!("{f}.end"),
                    m.end,
                    "must be >= start (s)",
                ));
            }
            previous = m.end;
        }
        self.then = moves.to_vec();
        Ok(())
    }

    /// A kinematic obstacle's moves after its first window (empty for the others).
    pub fn moves(&self) -> &[ObstacleMove] {
        &self.then
    }

    /// A kinematic obstacle's windows: the first, then its [`moves`](Self::moves).
    fn windows(&self) -> impl Iterator<Item = ObstacleMove> + '_ {
        let first = match self.motion {
            ObstacleMotion::Kinematic {
                velocity,
                angular_velocity,
                start,
                end,
            } => Some(ObstacleMove {
                velocity,
                angular_velocity,
                start,
                end,
            }),
            _ => None,
        };
        first.into_iter().chain(self.then.iter().copied())
    }

    /// A kinematic obstacle's schedule `[start, end]`: from its first window's start to its
    /// last window's end (`None` for other obstacles).
    pub fn schedule(&self) -> Option<(Real, Real)> {
        let start = self.windows().next()?.start;
        let end = self.windows().last()?.end;
        Some((start, end))
    }

    /// How the obstacle moves.
    pub fn motion(&self) -> ObstacleMotion {
        self.motion
    }

    /// Centroid at `t = 0`, m.
    pub fn initial_centroid(&self) -> Vec2 {
        self.centroid
    }

    /// Largest distance of a polygon vertex from the centroid, m.
    pub fn radius(&self) -> Real {
        self.radius
    }

    /// Moment of inertia about the centroid, kg m^2 (0 unless dynamic).
    pub fn inertia(&self) -> Real {
        self.inertia
    }

    /// Polygon vertices in the body frame (relative to the centroid).
    pub fn local_polygon(&self) -> &[Vec2] {
        &self.local
    }

    /// The polygon's world vertices at the pose `body`.
    pub fn world_polygon(&self, body: &BodyState) -> Vec<Vec2> {
        let frame = Frame::of(body);
        self.local.iter().map(|p| frame.apply(*p)).collect()
    }

    /// Inverse mass and inverse inertia (zero for static and kinematic obstacles).
    pub(crate) fn inverse_mass(&self) -> (Real, Real) {
        match self.motion {
            ObstacleMotion::Dynamic { mass, rotates } => {
                (1.0 / mass, if rotates { 1.0 / self.inertia } else { 0.0 })
            }
            _ => (0.0, 0.0),
        }
    }

    /// A kinematic obstacle's pose `[x, y, angle]` at time `t` on its schedule from its
    /// initial pose (`None` for other obstacles).
    pub(crate) fn scheduled_pose(&self, t: Real) -> Option<[Real; 3]> {
        if !matches!(self.motion, ObstacleMotion::Kinematic { .. }) {
            return None;
        }
        let (mut c, mut angle) = (self.centroid, 0.0);
        for m in self.windows() {
            let moved = window_overlap(0.0, t, m.start, m.end);
            c += m.velocity * moved;
            angle += m.angular_velocity * moved;
        }
        Some([c.x, c.y, angle])
    }

    /// Advance a kinematic obstacle's pose over `[t, t + dt]` (velocity = mean over the step).
    pub(crate) fn advance_kinematic(&self, body: &mut BodyState, t: Real, dt: Real) {
        if !matches!(self.motion, ObstacleMotion::Kinematic { .. }) {
            return;
        }
        body.velocity = Vec2::zeros();
        body.angular_velocity = 0.0;
        for m in self.windows() {
            let frac = window_overlap(t, dt, m.start, m.end) / dt;
            body.velocity += m.velocity * frac;
            body.angular_velocity += m.angular_velocity * frac;
        }
        body.position += body.velocity * dt;
        body.angle += body.angular_velocity * dt;
    }

    /// Penetration of the world point `p` into the obstacle at pose `(position, cos, sin)`:
    /// `(depth, outward unit normal, nearest polygon edge)` or `None` when outside or on the
    /// boundary.
    #[inline]
    pub(crate) fn penetration(&self, frame: &Frame, p: Vec2) -> Option<(Real, Vec2, usize)> {
        let d = p - frame.position;
        if d.norm_squared() > self.radius * self.radius {
            return None;
        }
        // To the body frame.
        let q = Vec2::new(
            frame.c * d.x + frame.s * d.y,
            -frame.s * d.x + frame.c * d.y,
        );
        let (inside, best, closest, edge) = polygon_query(&self.local, q);
        if !inside || best == 0.0 {
            return None;
        }
        let depth = best.sqrt();
        let nl = (closest - q) / depth;
        Some((
            depth,
            Vec2::new(
                frame.c * nl.x - frame.s * nl.y,
                frame.s * nl.x + frame.c * nl.y,
            ),
            edge,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(index: usize, motion: ObstacleMotion) -> Result<Obstacle, SolverError> {
        Obstacle::new(
            index,
            &[
                Vec2::new(0.0, 0.0),
                Vec2::new(2.0, 0.0),
                Vec2::new(2.0, 2.0),
                Vec2::new(0.0, 2.0),
            ],
            motion,
        )
    }

    #[test]
    fn centroid_and_inertia_of_a_square() {
        let o = square(
            0,
            ObstacleMotion::Dynamic {
                mass: 3.0,
                rotates: true,
            },
        )
        .unwrap();
        assert!((o.initial_centroid() - Vec2::new(1.0, 1.0)).norm() < 1e-15);
        // I = m (a^2 + b^2) / 12 for an a x b rectangle.
        assert!((o.inertia() - 3.0 * 8.0 / 12.0).abs() < 1e-14);
    }

    #[test]
    fn bad_polygons_are_rejected_with_their_index() {
        let cw = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 0.0),
        ];
        let e = Obstacle::new(4, &cw, ObstacleMotion::Static).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("obstacles[4]: polygon is clockwise")
        );
        let e = Obstacle::new(1, &cw[..2], ObstacleMotion::Static).unwrap_err();
        assert_eq!(
            e.to_string(),
            "obstacles[1]: polygon has 2 vertices, at least 3 are needed"
        );
        let e = square(
            2,
            ObstacleMotion::Dynamic {
                mass: -1.0,
                rotates: true,
            },
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("obstacles[2].mass = -1"));
    }

    #[test]
    fn penetration_pushes_to_the_nearest_side() {
        let o = square(0, ObstacleMotion::Static).unwrap();
        let frame = Frame::of(&BodyState::initial(&o));
        let (d, n, e) = o.penetration(&frame, Vec2::new(1.0, 0.1)).unwrap();
        assert!((d - 0.1).abs() < 1e-15 && (n - Vec2::new(0.0, -1.0)).norm() < 1e-15);
        assert_eq!(e, 0);
        let (d, n, e) = o.penetration(&frame, Vec2::new(1.95, 1.0)).unwrap();
        assert!((d - 0.05).abs() < 1e-14 && (n - Vec2::new(1.0, 0.0)).norm() < 1e-15);
        assert_eq!(e, 1);
        assert!(o.penetration(&frame, Vec2::new(2.5, 1.0)).is_none());
        assert!(o.penetration(&frame, Vec2::new(2.0, 1.0)).is_none());
    }
}
