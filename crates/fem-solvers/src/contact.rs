//! Contact between the soft body's vertices and rigid obstacles: a ground half-space and
//! polygons that are static, kinematic (prescribed motion) or dynamic rigid bodies (mass,
//! gravity, two-way coupling).
//!
//! Only **vertex-in-obstacle** contact is detected: a mesh vertex inside the ground half-space or
//! inside a polygon is pushed out along the shortest way to the obstacle's surface (the closest
//! point on the polygon boundary; corners push radially). Obstacle corners poking into the
//! interior of a soft edge are not detected, so obstacles should be at least as coarse as the
//! mesh near the contact (a flat slab on a strip is the intended use). Friction is Coulomb's
//! with coefficient `mu` = [`ContactParams::friction`] (0 for frictionless).
//!
//! - **Penalty** (explicit stepper): a penetrating vertex of mass `m` at depth `d`, approaching
//!   the surface with normal speed `v_n < 0`, gets the force
//!   `m * max(0, k d - 2 zeta sqrt(k) v_n)` along the outward normal, with `k` =
//!   [`ContactParams::stiffness`] (1/s^2: force per unit vertex mass per metre of penetration) and
//!   `zeta` = [`ContactParams::damping_ratio`]. Scaling by the vertex mass makes `k` independent
//!   of the mesh resolution and gives a vertex-level natural frequency `sqrt(k)` (rad/s), so the
//!   explicit step must satisfy `dt < 2 (sqrt(1 + zeta^2) - zeta) / sqrt(k)` (the stability guard
//!   includes this bound). At rest a vertex carrying the weight of a column `r` times its own
//!   mass sinks by about `r g / k`. Friction: the tangential force `-m sqrt(k) v_t` (a viscous
//!   regularisation of sticking at the contact frequency), capped at `mu` times the normal
//!   force. A dynamic body receives the opposite force at the vertex.
//! - **Projection** (PBD and XPBD): after every constraint sweep each penetrating vertex is moved
//!   to the surface; with a dynamic body the correction is shared by the generalised inverse
//!   masses `1/m` and `1/M + (r x n)^2 / I`, so momentum is exchanged both ways. Friction
//!   (static, position level, as in Macklin et al. 2014): the tangential motion of the vertex
//!   relative to the obstacle over the (sub)step is cancelled up to `mu` times the
//!   penetration depth.
//!
//! Polygons are given counter-clockwise in world coordinates at `t = 0`, with at least three
//! vertices and positive area; their pose is then tracked as the centroid position and an angle
//! in [`BodyState`].

use fem_core::math::{Real, Vec2, sin_cos};

use crate::bc::window_overlap;
use crate::error::{SolverError, check_finite_vec, check_non_negative, check_positive};

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

/// Penalty contact parameters (explicit stepper). Projection contact has none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactParams {
    /// Penalty stiffness per unit vertex mass, 1/s^2 (`sqrt` of it is the contact frequency in
    /// rad/s). Default `1e6` (stable for `dt` below about 1.2 ms with the default damping).
    pub stiffness: Real,
    /// Damping ratio of the penalty spring, dimensionless (1 = critically damped for a lone
    /// vertex). Default `0.5`.
    pub damping_ratio: Real,
    /// Coulomb friction coefficient `mu`, dimensionless (>= 0; 0 = frictionless). Used by both
    /// penalty, projection and barrier contact. Default `0.5`.
    pub friction: Real,
    /// Barrier contact (implicit and static solvers): the activation distance `d_hat`, m
    /// (> 0): pairs closer than this repel. Default `1e-3`.
    pub barrier_distance: Real,
    /// Barrier contact: the stiffness `kappa` of the log barrier, N/m^4 per unit thickness
    /// (>= 0; 0 = automatic, `M / (8 d_hat^2)` with `M` the body's P-wave modulus). Default 0.
    pub barrier_stiffness: Real,
    /// Barrier contact in implicit Euler: the slip speed below which friction sticks
    /// (IPC's `eps_v`), m/s (> 0). Default `1e-3`.
    pub friction_velocity: Real,
}

impl Default for ContactParams {
    fn default() -> Self {
        ContactParams {
            stiffness: 1e6,
            damping_ratio: 0.5,
            friction: 0.5,
            barrier_distance: 1e-3,
            barrier_stiffness: 0.0,
            friction_velocity: 1e-3,
        }
    }
}

impl ContactParams {
    pub(crate) fn validate(&self) -> Result<(), SolverError> {
        check_positive("contact.stiffness", self.stiffness)?;
        check_non_negative("contact.damping_ratio", self.damping_ratio)?;
        check_non_negative("contact.friction", self.friction)?;
        check_positive("contact.barrier_distance", self.barrier_distance)?;
        check_non_negative("contact.barrier_stiffness", self.barrier_stiffness)?;
        check_positive("contact.friction_velocity", self.friction_velocity)
    }

    /// The largest explicit time step for which the penalty spring is stable, s.
    pub fn critical_time_step(&self) -> Real {
        let z = self.damping_ratio;
        2.0 * ((1.0 + z * z).sqrt() - z) / self.stiffness.sqrt()
    }
}

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
/// nearest boundary point, and that point. The one polygon query of contact detection
/// ([`Obstacle`]'s penetration) and of the overlap checks at `t = 0`.
#[inline(always)]
fn polygon_query(polygon: &[Vec2], q: Vec2) -> (bool, Real, Vec2) {
    let n = polygon.len();
    let mut inside = false;
    let mut best = Real::INFINITY;
    let mut closest = Vec2::zeros();
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
        }
    }
    (inside, best, closest)
}

/// Whether `p` lies inside the closed polygon by more than `margin` (its distance to the
/// boundary): what contact would push out, as opposed to a point touching the boundary.
pub(crate) fn strictly_inside(polygon: &[Vec2], p: Vec2, margin: Real) -> bool {
    let (inside, dist2, _) = polygon_query(polygon, p);
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
            inertia,
        })
    }

    /// How the obstacle moves.
    pub fn motion(&self) -> ObstacleMotion {
        self.motion
    }

    /// Centroid at `t = 0`, m.
    pub fn initial_centroid(&self) -> Vec2 {
        self.centroid
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
        let (s, c) = sin_cos(body.angle);
        self.local
            .iter()
            .map(|p| body.position + Vec2::new(c * p.x - s * p.y, s * p.x + c * p.y))
            .collect()
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
        if let ObstacleMotion::Kinematic {
            velocity,
            angular_velocity,
            start,
            end,
        } = self.motion
        {
            let moved = window_overlap(0.0, t, start, end);
            let c = self.centroid + velocity * moved;
            Some([c.x, c.y, angular_velocity * moved])
        } else {
            None
        }
    }

    /// Advance a kinematic obstacle's pose over `[t, t + dt]` (velocity = mean over the step).
    pub(crate) fn advance_kinematic(&self, body: &mut BodyState, t: Real, dt: Real) {
        if let ObstacleMotion::Kinematic {
            velocity,
            angular_velocity,
            start,
            end,
        } = self.motion
        {
            let frac = window_overlap(t, dt, start, end) / dt;
            body.velocity = velocity * frac;
            body.angular_velocity = angular_velocity * frac;
            body.position += body.velocity * dt;
            body.angle += body.angular_velocity * dt;
        }
    }

    /// Penetration of the world point `p` into the obstacle at pose `(position, cos, sin)`:
    /// `(depth, outward unit normal)` or `None` when outside or on the boundary.
    #[inline]
    fn penetration(&self, frame: &Frame, p: Vec2) -> Option<(Real, Vec2)> {
        let d = p - frame.position;
        if d.norm_squared() > self.radius * self.radius {
            return None;
        }
        // To the body frame.
        let q = Vec2::new(
            frame.c * d.x + frame.s * d.y,
            -frame.s * d.x + frame.c * d.y,
        );
        let (inside, best, closest) = polygon_query(&self.local, q);
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
        ))
    }
}

/// Pose and velocity of an obstacle's rigid body.
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
            position: obstacle.centroid,
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
    fn point_velocity(&self, p: Vec2) -> Vec2 {
        let r = p - self.position;
        self.velocity + Vec2::new(-r.y, r.x) * self.angular_velocity
    }
}

/// A body pose with its rotation precomputed.
struct Frame {
    position: Vec2,
    c: Real,
    s: Real,
}

impl Frame {
    fn of(b: &BodyState) -> Self {
        let (s, c) = sin_cos(b.angle);
        Frame {
            position: b.position,
            c,
            s,
        }
    }
}

#[inline]
fn cross(a: Vec2, b: Vec2) -> Real {
    a.x * b.y - a.y * b.x
}

/// Net force and torque on a rigid body from contact, N and N m per unit thickness.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Wrench {
    pub force: Vec2,
    pub torque: Real,
}

/// Add penalty contact forces for positions `x`, velocities `v` into `f` and the reactions
/// into `wrenches` (one per obstacle, zeroed here). Serial, in vertex order (deterministic).
/// Returns the number of penetrating vertex-obstacle pairs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn accumulate_penalty_forces(
    ground: Option<&Ground>,
    obstacles: &[Obstacle],
    params: &ContactParams,
    masses: &[Real],
    x: &[Vec2],
    v: &[Vec2],
    bodies: &[BodyState],
    f: &mut [Vec2],
    wrenches: &mut [Wrench],
) -> usize {
    wrenches.fill(Wrench::default());
    let k = params.stiffness;
    let c = 2.0 * params.damping_ratio * k.sqrt();
    let gamma = k.sqrt();
    let mu = params.friction;
    let mut contacts = 0;
    // Normal plus capped viscous friction force on a vertex of mass m.
    let force = |m: Real, depth: Real, n: Vec2, v_rel: Vec2| {
        let vn = v_rel.dot(&n);
        let fn_ = m * (k * depth - c * vn).max(0.0);
        let vt = v_rel - n * vn;
        let mut ft = vt * (-m * gamma);
        let cap = mu * fn_;
        let ftn = ft.norm();
        if ftn > cap {
            ft *= cap / ftn;
        }
        n * fn_ + ft
    };
    if let Some(g) = ground {
        for (i, p) in x.iter().enumerate() {
            let h = (p - g.point).dot(&g.normal);
            if h < 0.0 {
                contacts += 1;
                f[i] += force(masses[i], -h, g.normal, v[i]);
            }
        }
    }
    for (o, (obs, body)) in obstacles.iter().zip(bodies).enumerate() {
        let frame = Frame::of(body);
        for (i, p) in x.iter().enumerate() {
            if let Some((depth, n)) = obs.penetration(&frame, *p) {
                contacts += 1;
                let fi = force(masses[i], depth, n, v[i] - body.point_velocity(*p));
                f[i] += fi;
                wrenches[o].force -= fi;
                wrenches[o].torque -= cross(p - body.position, fi);
            }
        }
    }
    contacts
}

/// The tangential correction that cancels the relative tangential motion `rel` (normal `n`)
/// up to `mu * depth`.
#[inline]
fn friction_correction(rel: Vec2, n: Vec2, mu: Real, depth: Real) -> Vec2 {
    let t = rel - n * rel.dot(&n);
    let len = t.norm();
    let limit = mu * depth;
    if len <= limit { -t } else { t * (-limit / len) }
}

/// Project penetrating vertices of `x` (inverse masses `w`, positions at the start of the
/// (sub)step `x_old`) out of the ground and the obstacles at the poses `bodies` (start-of-step
/// poses `bodies_old`), with static Coulomb friction `mu`; dynamic bodies are moved back in
/// proportion to their generalised inverse mass. Serial, in obstacle then vertex order.
/// Returns the number of corrected vertex-obstacle pairs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn project_contacts(
    ground: Option<&Ground>,
    obstacles: &[Obstacle],
    mu: Real,
    w: &[Real],
    x_old: &[Vec2],
    x: &mut [Vec2],
    bodies_old: &[BodyState],
    bodies: &mut [BodyState],
) -> usize {
    let mut contacts = 0;
    if let Some(g) = ground {
        for (i, p) in x.iter_mut().enumerate() {
            let h = (*p - g.point).dot(&g.normal);
            if h < 0.0 && w[i] > 0.0 {
                contacts += 1;
                *p -= g.normal * h;
                if mu > 0.0 {
                    *p += friction_correction(*p - x_old[i], g.normal, mu, -h);
                }
            }
        }
    }
    for ((obs, body), old) in obstacles.iter().zip(bodies.iter_mut()).zip(bodies_old) {
        let (im, ii) = obs.inverse_mass();
        let mut frame = Frame::of(body);
        for (i, p) in x.iter_mut().enumerate() {
            if let Some((depth, n)) = obs.penetration(&frame, *p) {
                let r = *p - body.position;
                let rn = cross(r, n);
                let wb = im + ii * rn * rn;
                let denom = w[i] + wb;
                if denom <= 0.0 {
                    continue;
                }
                contacts += 1;
                let dl = depth / denom;
                *p += n * (w[i] * dl);
                if wb > 0.0 {
                    body.position -= n * (im * dl);
                    body.angle -= ii * rn * dl;
                }
                if mu > 0.0 {
                    // Motion of the body's material point under the vertex over the step.
                    let r = *p - body.position;
                    let dtheta = body.angle - old.angle;
                    let body_motion =
                        (body.position - old.position) + Vec2::new(-r.y, r.x) * dtheta;
                    let corr = friction_correction(*p - x_old[i] - body_motion, n, mu, depth);
                    let cl = corr.norm();
                    if cl > 0.0 {
                        let t = corr / cl;
                        let rt = cross(r, t);
                        let wbt = im + ii * rt * rt;
                        let den = w[i] + wbt;
                        let dl = if den > 0.0 { cl / den } else { 0.0 };
                        *p += t * (w[i] * dl);
                        if wbt > 0.0 {
                            body.position -= t * (im * dl);
                            body.angle -= ii * rt * dl;
                        }
                    }
                }
                if wb > 0.0 || mu > 0.0 {
                    frame = Frame::of(body);
                }
            }
        }
    }
    contacts
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
        let (d, n) = o.penetration(&frame, Vec2::new(1.0, 0.1)).unwrap();
        assert!((d - 0.1).abs() < 1e-15 && (n - Vec2::new(0.0, -1.0)).norm() < 1e-15);
        let (d, n) = o.penetration(&frame, Vec2::new(1.95, 1.0)).unwrap();
        assert!((d - 0.05).abs() < 1e-14 && (n - Vec2::new(1.0, 0.0)).norm() < 1e-15);
        assert!(o.penetration(&frame, Vec2::new(2.5, 1.0)).is_none());
        assert!(o.penetration(&frame, Vec2::new(2.0, 1.0)).is_none());
    }
}
