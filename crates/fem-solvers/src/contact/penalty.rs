//! Penalty (explicit) and projection (PBD, XPBD) contact between the soft body and the rigid
//! world ([`crate::rigid`]: the ground half-space and polygonal obstacles). Implicit Euler, the
//! static solver and VBD use barrier contact instead (IPC-style, never penetrating; built on
//! [`crate::ipc`], see `docs/solvers.md`, Contact).
//!
//! Two kinds of penetration are detected, so neither side has to be finer than the other:
//! - **vertex in obstacle**: a mesh vertex inside the ground half-space or inside a polygon is
//!   pushed out along the shortest way to the obstacle's surface (the closest point on the
//!   polygon boundary; corners push radially);
//! - **corner in edge**: an obstacle corner that has entered the soft body through a boundary
//!   edge `[a, b]` (see below) pushes the edge, at the corner's projection
//!   `p = (1 - t) x_a + t x_b`, into the body along the edge's inward normal; the corner ends
//!   on the edge. A sharp wedge pressed onto a coarse soft edge therefore pushes it instead of
//!   passing through it.
//!
//! **Corner-edge detection.** Boundary edges are the model's ([`Model::boundary_edges`]:
//! counter-clockwise, the body to the left of `a -> b`, so the outward normal of `e = b - a`
//! is `(e.y, -e.x) / |e|`). A corner `c` penetrates edge `[a, b]` when that edge is the
//! nearest boundary edge to `c` (point-segment distance; the first in edge order on a tie),
//! `c` projects inside the segment (`0 <= t <= 1`) and lies on its inner side at a depth `d`
//! with `0 < d <= CORNER_DEPTH_FRACTION |e|` ([`CORNER_DEPTH_FRACTION`] = 1/2). The bound keeps
//! a corner that lies deep inside the body, far from any edge (one that tunnelled in, or came
//! in where no edge is near), from being yanked back out through an edge it never crossed; a
//! corner entering normally is caught within a step or a sweep, at a depth far below half an
//! edge. A corner that projects outside every nearby edge is at a convex soft vertex, which
//! vertex-in-obstacle contact already handles. The candidates come from a broad phase, not
//! from all pairs: a uniform grid (`broad_phase`) over the boxes of the boundary edges near an
//! obstacle, queried with each obstacle's box grown by the largest accepted depth (half the
//! longest boundary edge; under projection also by how far the pass's corrections may have
//! moved edges and bodies since the grid was built, and the grid is rebuilt when that exceeds
//! the room it was built with). With that growth the nearest candidate is the nearest boundary
//! edge whenever it can be accepted.
//!
//! Friction is Coulomb's with coefficient `mu` = [`ContactParams::friction`] (0 for
//! frictionless).
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
//!
//!   A corner in edge `[a, b]` at parameter `t` gets the same law with the edge point's
//!   velocity `(1 - t) v_a + t v_b` relative to the obstacle's material velocity at the corner,
//!   and the effective mass `m_e = (1 - t) m_a + t m_b`, capped at the edge point's generalised
//!   mass `1 / ((1 - t)^2 / m_a + t^2 / m_b)`. The force is split over `a` and `b` by the weights
//!   `1 - t` and `t`, so the edge point accelerates by `F ((1 - t)^2 / m_a + t^2 / m_b)`: its
//!   contact frequency is `sqrt(k m_e ((1 - t)^2 / m_a + t^2 / m_b))`, at most `sqrt(k)` thanks
//!   to the cap, and its damping ratio at most `zeta`, so the vertex contact's critical time
//!   step bounds it too. (The cap matters only for unequal masses: with `m_a = m_b` the plain
//!   interpolation gives `(1 - t)^2 + t^2 <= 1` times `k`, but with `m_b = 4 m_a` it would give
//!   up to 1.06 `k` and with `m_b = 10 m_a` up to 1.85 `k`, above the guard; that the
//!   interpolated mass is at least the lighter vertex's does not bound it.) A dynamic body
//!   receives the opposite force at the corner, and its torque about the centroid.
//! - **Projection** (PBD and XPBD): after every constraint sweep each penetrating vertex is moved
//!   to the surface; with a dynamic body the correction is shared by the generalised inverse
//!   masses `1/m` and `1/M + (r x n)^2 / I`, so momentum is exchanged both ways. Then each
//!   penetrating corner is put back on its edge by the usual point-edge correction of
//!   position-based dynamics (Müller et al. 2007; Macklin et al. 2016): with `w = 1/m` (0 for a
//!   pinned or prescribed vertex), `n` the inward normal and
//!   `lambda = d / ((1 - t)^2 w_a + t^2 w_b + 1/M + (r x n)^2 / I)` (`r` from the centroid to
//!   the corner), `x_a += (1 - t) w_a lambda n`, `x_b += t w_b lambda n`, and a dynamic body
//!   moves by `-lambda n` over its generalised inverse mass at the corner. Against a static or
//!   kinematic obstacle the corner then lies on the edge to round-off; a dynamic body's
//!   rotation is linearised, as for vertices. Friction (static, position level, as in Macklin
//!   et al. 2014): the tangential motion of the soft point relative to the obstacle's material
//!   point over the (sub)step is cancelled up to `mu` times the penetration depth (for a
//!   corner, along the corrected edge, shared by the same weights, so the edge slides along its
//!   own line and the corner stays on it).
//!
//! Vertex contacts of every obstacle are resolved before corner contacts (in obstacle, then
//! vertex or corner order): serial and deterministic. The steppers keep one [`Contact`] record
//! per detected pair ([`crate::Stepper::contacts`]), in that order: ground, vertex-obstacle,
//! corner-edge. Their `force` is the normal force on the soft body: under penalty the normal
//! part of the force applied (at the start of the step, where it is evaluated); under
//! projection the normal corrections' multipliers `lambda` summed over the sweeps of the last
//! substep, divided by `h^2` (the substep's length squared): for a free vertex that is
//! `m * correction / h^2`, the force that moves it by that much in one substep. Their `gap` is
//! minus the depth found (for projection, by the last sweep that found the pair, before its
//! correction).
//!
//! [`Model::boundary_edges`]: crate::Model::boundary_edges

use fem_core::math::{Real, Vec2};

use super::broad_phase::{Aabb, Grid};
use super::{Contact, ContactKind};
use crate::model::contact_params::ContactParams;
use crate::rigid::{BodyState, Frame, Ground, Obstacle, Wrench, cross};

/// The box of an obstacle's polygon at the pose `frame`.
fn world_box(obs: &Obstacle, frame: &Frame) -> Aabb {
    let mut b = Aabb::empty();
    for q in obs.local_polygon() {
        b.include(frame.apply(*q));
    }
    b
}

/// How deep behind a soft boundary edge an obstacle corner may lie, as a fraction of the
/// edge's length, and still be pushed back out through that edge (see the module docs).
pub const CORNER_DEPTH_FRACTION: Real = 0.5;

/// An obstacle corner found behind a soft boundary edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EdgeHit {
    /// The boundary edge's index in [`crate::Model::boundary_edges`].
    pub edge: usize,
    /// Where the corner projects on the edge: `p = (1 - t) x_a + t x_b`, `0 <= t <= 1`.
    pub t: Real,
    /// Depth of the corner behind the edge's line, m (> 0).
    pub depth: Real,
    /// The edge's inward unit normal (from the obstacle into the soft body).
    pub normal: Vec2,
    /// The corner's projection `p` on the edge.
    pub point: Vec2,
}

/// The boundary edge that the corner `c` has entered the body through, among `candidates`
/// (indices into `edges`, ascending), at positions `x`: the nearest candidate (point-segment
/// distance, the first on a tie), provided `c` projects inside it and lies behind it by more
/// than 0 and at most [`CORNER_DEPTH_FRACTION`] of its length.
#[inline]
pub(crate) fn nearest_edge(
    edges: &[[u32; 2]],
    x: &[Vec2],
    candidates: &[u32],
    c: Vec2,
) -> Option<EdgeHit> {
    let mut best = Real::INFINITY;
    let mut nearest = None;
    for &k in candidates {
        let [a, b] = edges[k as usize];
        let pa = x[a as usize];
        let e = x[b as usize] - pa;
        let l2 = e.norm_squared();
        if l2 == 0.0 {
            continue;
        }
        let t = (c - pa).dot(&e) / l2;
        let d2 = (c - (pa + e * t.clamp(0.0, 1.0))).norm_squared();
        if d2 < best {
            best = d2;
            nearest = Some((k as usize, t, pa, e, l2));
        }
    }
    let (edge, t, pa, e, l2) = nearest?;
    if !(0.0..=1.0).contains(&t) {
        return None;
    }
    let l = l2.sqrt();
    let normal = Vec2::new(-e.y, e.x) / l;
    let depth = (c - pa).dot(&normal);
    (depth > 0.0 && depth <= CORNER_DEPTH_FRACTION * l).then(|| EdgeHit {
        edge,
        t,
        depth,
        normal,
        point: pa + e * t,
    })
}

/// The penalty law's effective mass of the edge point at parameter `t` between vertices of
/// masses `ma` and `mb`: `(1 - t) ma + t mb`, capped at the point's generalised mass
/// `1 / ((1 - t)^2 / ma + t^2 / mb)`, so its contact frequency is at most `sqrt(k)`.
#[inline]
pub(crate) fn edge_mass(ma: Real, mb: Real, t: Real) -> Real {
    let s = 1.0 - t;
    let lerp = s * ma + t * mb;
    let inv = s * s / ma + t * t / mb;
    if inv > 0.0 { lerp.min(1.0 / inv) } else { lerp }
}

/// The contact scratch a stepper owns (no allocation once grown): the records of the last step
/// ([`crate::Stepper::contacts`]) and the broad phase of corner-edge detection.
#[derive(Clone, Debug, Default)]
pub(crate) struct ContactWorkspace {
    /// One record per detected pair; under projection, between passes, `force` holds the
    /// summed multipliers `lambda` (m kg) until [`ContactWorkspace::finish_substep`].
    pub records: Vec<Contact>,
    /// Projection: the pairs of the current pass, merged into `records` after it.
    pass: Vec<Contact>,
    merged: Vec<Contact>,
    /// Every boundary edge's box at the last build.
    edge_boxes: Vec<Aabb>,
    /// The boundary edges near an obstacle at the last build (grid item `k` is edge `near[k]`)
    /// and their boxes.
    near: Vec<u32>,
    near_boxes: Vec<Aabb>,
    grid: Grid,
    found: Vec<u32>,
    /// The candidate edges of the last query (indices into the boundary edges, ascending).
    candidates: Vec<u32>,
    /// The largest depth accepted behind any edge at the last build,
    /// [`CORNER_DEPTH_FRACTION`] times the longest boundary edge, m.
    reach: Real,
    /// How far the edges near an obstacle at the last build were looked for beyond `reach`, m.
    slack: Real,
}

impl ContactWorkspace {
    /// Rebuild the broad phase at positions `x` and poses `bodies`: the grid over the boundary
    /// edges whose boxes come within `reach + slack` of an obstacle's box, with `slack` =
    /// `slack_reaches` times `reach` (room for the motion of a projection pass before the next
    /// rebuild; penalty needs none).
    fn build(
        &mut self,
        edges: &[[u32; 2]],
        x: &[Vec2],
        obstacles: &[Obstacle],
        bodies: &[BodyState],
        slack_reaches: Real,
    ) {
        let mut zone = Aabb::empty();
        for (obs, body) in obstacles.iter().zip(bodies) {
            let b = world_box(obs, &Frame::of(body));
            zone.include(b.lo);
            zone.include(b.hi);
        }
        self.edge_boxes.clear();
        let mut longest2: Real = 0.0;
        for &[a, b] in edges {
            let (pa, pb) = (x[a as usize], x[b as usize]);
            longest2 = longest2.max((pb - pa).norm_squared());
            self.edge_boxes.push(Aabb::of(&[pa, pb]));
        }
        self.reach = CORNER_DEPTH_FRACTION * longest2.sqrt();
        self.slack = slack_reaches * self.reach;
        let zone = zone.inflated(self.reach + self.slack);
        self.near.clear();
        self.near_boxes.clear();
        for (k, b) in self.edge_boxes.iter().enumerate() {
            if b.overlaps(&zone) {
                self.near.push(k as u32);
                self.near_boxes.push(*b);
            }
        }
        self.grid.build(&self.near_boxes);
    }

    /// The candidate edges for the box `b` grown by `margin` (into `self.candidates`).
    fn query(&mut self, b: &Aabb, margin: Real) {
        self.grid.query(&b.inflated(margin), &mut self.found);
        self.candidates.clear();
        let near = &self.near;
        self.candidates
            .extend(self.found.iter().map(|&k| near[k as usize]));
    }

    /// Start a projection substep: no records yet.
    pub(crate) fn start_substep(&mut self) {
        self.records.clear();
    }

    /// Merge the current pass's pairs into the records (both in the detection order): a pair
    /// seen before keeps its summed multiplier plus the new one and takes the new geometry.
    fn merge_pass(&mut self) {
        fn key(c: &Contact) -> (u32, u32, u32) {
            match c.kind {
                ContactKind::VertexGround { vertex } => (0, 0, vertex),
                ContactKind::VertexObstacle {
                    vertex, obstacle, ..
                } => (1, obstacle, vertex),
                ContactKind::CornerEdge {
                    obstacle, corner, ..
                } => (2, obstacle, corner),
            }
        }
        self.merged.clear();
        let (old, new) = (&self.records, &self.pass);
        let (mut i, mut j) = (0, 0);
        while i < old.len() || j < new.len() {
            let next = match (old.get(i), new.get(j)) {
                (Some(o), Some(n)) if key(o) == key(n) => {
                    i += 1;
                    j += 1;
                    Contact {
                        force: o.force + n.force,
                        ..*n
                    }
                }
                (Some(o), Some(n)) if key(o) < key(n) => {
                    i += 1;
                    *o
                }
                (_, Some(n)) => {
                    j += 1;
                    *n
                }
                (Some(o), None) => {
                    i += 1;
                    *o
                }
                (None, None) => unreachable!(),
            };
            self.merged.push(next);
        }
        std::mem::swap(&mut self.records, &mut self.merged);
    }

    /// End a projection substep of length `h`: the summed multipliers become forces,
    /// `lambda / h^2`.
    pub(crate) fn finish_substep(&mut self, h: Real) {
        let s = 1.0 / (h * h);
        for r in &mut self.records {
            r.force *= s;
        }
    }
}

/// Add penalty contact forces for positions `x`, velocities `v` into `f` and the reactions
/// into `wrenches` (one per obstacle, zeroed here), and record every pair in
/// `ws.records` (cleared here). Vertex contacts then corner-edge contacts (`edges`: the
/// model's boundary edges), serial, in obstacle then vertex or corner order (deterministic).
/// Returns the number of penetrating pairs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn accumulate_penalty_forces(
    ground: Option<&Ground>,
    obstacles: &[Obstacle],
    params: &ContactParams,
    masses: &[Real],
    edges: &[[u32; 2]],
    x: &[Vec2],
    v: &[Vec2],
    bodies: &[BodyState],
    f: &mut [Vec2],
    wrenches: &mut [Wrench],
    ws: &mut ContactWorkspace,
) -> usize {
    wrenches.fill(Wrench::default());
    ws.records.clear();
    let k = params.stiffness;
    let c = 2.0 * params.damping_ratio * k.sqrt();
    let gamma = k.sqrt();
    let mu = params.friction;
    let mut contacts = 0;
    // Normal plus capped viscous friction force on a point of mass m, and its normal part.
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
        (n * fn_ + ft, fn_)
    };
    if let Some(g) = ground {
        for (i, p) in x.iter().enumerate() {
            let h = (p - g.point).dot(&g.normal);
            if h < 0.0 {
                contacts += 1;
                let (fi, fn_) = force(masses[i], -h, g.normal, v[i]);
                f[i] += fi;
                ws.records.push(Contact {
                    kind: ContactKind::VertexGround { vertex: i as u32 },
                    point: *p,
                    normal: g.normal,
                    gap: h,
                    force: fn_,
                });
            }
        }
    }
    for (o, (obs, body)) in obstacles.iter().zip(bodies).enumerate() {
        let frame = Frame::of(body);
        for (i, p) in x.iter().enumerate() {
            if let Some((depth, n, edge)) = obs.penetration(&frame, *p) {
                contacts += 1;
                let (fi, fn_) = force(masses[i], depth, n, v[i] - body.point_velocity(*p));
                f[i] += fi;
                wrenches[o].force -= fi;
                wrenches[o].torque -= cross(p - body.position, fi);
                ws.records.push(Contact {
                    kind: ContactKind::VertexObstacle {
                        vertex: i as u32,
                        obstacle: o as u32,
                        edge: edge as u32,
                    },
                    point: *p,
                    normal: n,
                    gap: -depth,
                    force: fn_,
                });
            }
        }
    }
    if obstacles.is_empty() || edges.is_empty() {
        return contacts;
    }
    ws.build(edges, x, obstacles, bodies, 0.0);
    for (o, (obs, body)) in obstacles.iter().zip(bodies).enumerate() {
        let frame = Frame::of(body);
        let reach = ws.reach;
        ws.query(&world_box(obs, &frame), reach);
        if ws.candidates.is_empty() {
            continue;
        }
        for (corner, q) in obs.local_polygon().iter().enumerate() {
            let cw = frame.apply(*q);
            let Some(hit) = nearest_edge(edges, x, &ws.candidates, cw) else {
                continue;
            };
            contacts += 1;
            let [a, b] = edges[hit.edge];
            let (a, b) = (a as usize, b as usize);
            let (sa, sb) = (1.0 - hit.t, hit.t);
            let v_edge = v[a] * sa + v[b] * sb;
            let (fc, fn_) = force(
                edge_mass(masses[a], masses[b], hit.t),
                hit.depth,
                hit.normal,
                v_edge - body.point_velocity(cw),
            );
            f[a] += fc * sa;
            f[b] += fc * sb;
            wrenches[o].force -= fc;
            wrenches[o].torque -= cross(cw - body.position, fc);
            ws.records.push(Contact {
                kind: ContactKind::CornerEdge {
                    obstacle: o as u32,
                    corner: corner as u32,
                    edge: [a as u32, b as u32],
                },
                point: hit.point,
                normal: hit.normal,
                gap: -hit.depth,
                force: fn_,
            });
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
/// poses `bodies_old`), then penetrating obstacle corners back onto the soft boundary edges
/// `edges` (the model's), with static Coulomb friction `mu`; dynamic bodies are moved back in
/// proportion to their generalised inverse mass. Serial, in obstacle then vertex or corner
/// order. Merges the pass's pairs into `ws.records` (see [`ContactWorkspace::merge_pass`]).
/// Returns the number of corrected pairs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn project_contacts(
    ground: Option<&Ground>,
    obstacles: &[Obstacle],
    mu: Real,
    w: &[Real],
    edges: &[[u32; 2]],
    x_old: &[Vec2],
    x: &mut [Vec2],
    bodies_old: &[BodyState],
    bodies: &mut [BodyState],
    ws: &mut ContactWorkspace,
) -> usize {
    let mut contacts = 0;
    ws.pass.clear();
    if let Some(g) = ground {
        for (i, p) in x.iter_mut().enumerate() {
            let h = (*p - g.point).dot(&g.normal);
            if h < 0.0 && w[i] > 0.0 {
                contacts += 1;
                *p -= g.normal * h;
                if mu > 0.0 {
                    *p += friction_correction(*p - x_old[i], g.normal, mu, -h);
                }
                ws.pass.push(Contact {
                    kind: ContactKind::VertexGround { vertex: i as u32 },
                    point: *p,
                    normal: g.normal,
                    gap: h,
                    force: -h / w[i],
                });
            }
        }
    }
    for (o, ((obs, body), old)) in obstacles
        .iter()
        .zip(bodies.iter_mut())
        .zip(bodies_old)
        .enumerate()
    {
        let (im, ii) = obs.inverse_mass();
        let mut frame = Frame::of(body);
        for (i, p) in x.iter_mut().enumerate() {
            if let Some((depth, n, edge)) = obs.penetration(&frame, *p) {
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
                ws.pass.push(Contact {
                    kind: ContactKind::VertexObstacle {
                        vertex: i as u32,
                        obstacle: o as u32,
                        edge: edge as u32,
                    },
                    point: *p,
                    normal: n,
                    gap: -depth,
                    force: dl,
                });
            }
        }
    }
    if !obstacles.is_empty() && !edges.is_empty() {
        contacts += project_corners(obstacles, mu, w, edges, x_old, x, bodies_old, bodies, ws);
    }
    ws.merge_pass();
    contacts
}

/// The corner-edge part of [`project_contacts`], after every vertex contact. The broad phase
/// is built once, at the positions after the vertex contacts; the corrections then move edges
/// and bodies, by at most `drift` (summed bounds), so each query grows by `drift` too, and the
/// grid is rebuilt when `drift` exceeds the slack it was built with.
#[allow(clippy::too_many_arguments)]
fn project_corners(
    obstacles: &[Obstacle],
    mu: Real,
    w: &[Real],
    edges: &[[u32; 2]],
    x_old: &[Vec2],
    x: &mut [Vec2],
    bodies_old: &[BodyState],
    bodies: &mut [BodyState],
    ws: &mut ContactWorkspace,
) -> usize {
    let mut contacts = 0;
    ws.build(edges, x, obstacles, bodies, 1.0);
    let mut drift: Real = 0.0;
    for o in 0..obstacles.len() {
        let obs = &obstacles[o];
        let (im, ii) = obs.inverse_mass();
        let old_frame = Frame::of(&bodies_old[o]);
        // The drift the current candidates were gathered with.
        let mut gathered: Option<Real> = None;
        for (corner, q) in obs.local_polygon().iter().enumerate() {
            if drift > ws.slack {
                ws.build(edges, x, obstacles, bodies, 1.0);
                drift = 0.0;
                gathered = None;
            }
            let body = &mut bodies[o];
            let frame = Frame::of(body);
            if gathered != Some(drift) {
                let reach = ws.reach;
                ws.query(&world_box(obs, &frame), reach + drift);
                gathered = Some(drift);
            }
            if ws.candidates.is_empty() {
                continue;
            }
            let cw = frame.apply(*q);
            let Some(hit) = nearest_edge(edges, x, &ws.candidates, cw) else {
                continue;
            };
            let [a, b] = edges[hit.edge];
            let (a, b) = (a as usize, b as usize);
            let (sa, sb) = (1.0 - hit.t, hit.t);
            let n = hit.normal;
            let we = sa * sa * w[a] + sb * sb * w[b];
            let r = cw - body.position;
            let rn = cross(r, n);
            let wb = im + ii * rn * rn;
            let denom = we + wb;
            if denom <= 0.0 {
                continue;
            }
            contacts += 1;
            let dl = hit.depth / denom;
            let (xa0, xb0) = (x[a], x[b]);
            let (pos0, angle0) = (body.position, body.angle);
            x[a] += n * (sa * w[a] * dl);
            x[b] += n * (sb * w[b] * dl);
            if wb > 0.0 {
                body.position -= n * (im * dl);
                body.angle -= ii * rn * dl;
            }
            let e = x[b] - x[a];
            if mu > 0.0 && e.norm_squared() > 0.0 {
                // The soft point's motion over the step relative to the body's material corner,
                // cancelled along the corrected edge's own direction: sliding a and b along
                // their line keeps the corner on it.
                let p = x[a] * sa + x[b] * sb;
                let p_old = x_old[a] * sa + x_old[b] * sb;
                let c_now = Frame::of(body).apply(*q);
                let rel = (p - p_old) - (c_now - old_frame.apply(*q));
                let n_now = Vec2::new(-e.y, e.x).normalize();
                let corr = friction_correction(rel, n_now, mu, hit.depth);
                let cl = corr.norm();
                if cl > 0.0 {
                    let t = corr / cl;
                    let r = c_now - body.position;
                    let rt = cross(r, t);
                    let wbt = im + ii * rt * rt;
                    let den = sa * sa * w[a] + sb * sb * w[b] + wbt;
                    let dl = if den > 0.0 { cl / den } else { 0.0 };
                    x[a] += t * (sa * w[a] * dl);
                    x[b] += t * (sb * w[b] * dl);
                    if wbt > 0.0 {
                        body.position -= t * (im * dl);
                        body.angle -= ii * rt * dl;
                    }
                }
            }
            // How far any edge or body point may have moved: the larger vertex motion plus the
            // body's translation and its rotation at its radius.
            drift += (x[a] - xa0).norm().max((x[b] - xb0).norm())
                + (body.position - pos0).norm()
                + (body.angle - angle0).abs() * obs.radius();
            // The corner's projection on the corrected edge.
            let e = x[b] - x[a];
            let c_now = Frame::of(body).apply(*q);
            let l2 = e.norm_squared();
            let s = if l2 > 0.0 {
                ((c_now - x[a]).dot(&e) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            ws.pass.push(Contact {
                kind: ContactKind::CornerEdge {
                    obstacle: o as u32,
                    corner: corner as u32,
                    edge: [a as u32, b as u32],
                },
                point: x[a] + e * s,
                normal: n,
                gap: -hit.depth,
                force: dl,
            });
        }
    }
    contacts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid::ObstacleMotion;

    /// A soft body `[0, 2] x [0, 1]` whose top is split into four 0.5 m edges: vertices
    /// counter-clockwise from the origin, boundary edges `k -> k + 1`. Edge 3 is
    /// `(1.5, 1) -> (1, 1)`, edge 1 the right side `(2, 0) -> (2, 1)`.
    fn comb() -> (Vec<Vec2>, Vec<[u32; 2]>) {
        let x = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(1.5, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.5, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        let edges = (0..7).map(|k| [k, (k + 1) % 7]).collect();
        (x, edges)
    }

    /// A thin static triangle with its corner 0 at `tip`, pointing along `-dir`.
    fn spike(tip: Vec2, dir: Vec2, motion: ObstacleMotion) -> Obstacle {
        let side = Vec2::new(-dir.y, dir.x) * 0.05;
        Obstacle::new(
            0,
            &[tip, tip + dir * 0.6 - side, tip + dir * 0.6 + side],
            motion,
        )
        .unwrap()
    }

    /// Corner 0's hit through the broad phase, as the steppers find it.
    fn hit_of(
        ws: &mut ContactWorkspace,
        x: &[Vec2],
        edges: &[[u32; 2]],
        o: &Obstacle,
    ) -> Option<EdgeHit> {
        let bodies = [BodyState::initial(o)];
        ws.build(edges, x, std::slice::from_ref(o), &bodies, 0.0);
        let frame = Frame::of(&bodies[0]);
        let reach = ws.reach;
        ws.query(&world_box(o, &frame), reach);
        nearest_edge(edges, x, &ws.candidates, frame.apply(o.local_polygon()[0]))
    }

    #[test]
    fn corner_detection_finds_the_edge_the_depth_and_the_parameter() {
        let (x, edges) = comb();
        let mut ws = ContactWorkspace::default();
        let up = Vec2::new(0.0, 1.0);
        // 0.2 m below the top edge (1.5, 1) -> (1, 1), a quarter of the way from its end 1.
        let h = hit_of(
            &mut ws,
            &x,
            &edges,
            &spike(Vec2::new(1.375, 0.8), up, ObstacleMotion::Static),
        )
        .unwrap();
        assert_eq!(h.edge, 3);
        assert!(
            (h.depth - 0.2).abs() < 1e-15 && (h.t - 0.25).abs() < 1e-15,
            "{h:?}"
        );
        assert!((h.normal - Vec2::new(0.0, -1.0)).norm() < 1e-15);
        assert!((h.point - Vec2::new(1.375, 1.0)).norm() < 1e-15);
        // Nearer the right side than the top: that edge, pushing left.
        let h = hit_of(
            &mut ws,
            &x,
            &edges,
            &spike(
                Vec2::new(1.9, 0.6),
                Vec2::new(1.0, 0.0),
                ObstacleMotion::Static,
            ),
        )
        .unwrap();
        assert_eq!(h.edge, 1);
        assert!(
            (h.depth - 0.1).abs() < 1e-15 && (h.t - 0.6).abs() < 1e-15,
            "{h:?}"
        );
        assert!((h.normal - Vec2::new(-1.0, 0.0)).norm() < 1e-15);
        // Deeper than half the nearest edge (0.3 m > 0.25 m): left alone.
        assert!(
            hit_of(
                &mut ws,
                &x,
                &edges,
                &spike(Vec2::new(1.25, 0.7), up, ObstacleMotion::Static)
            )
            .is_none()
        );
        // Outside the body, and exactly on an edge: no contact.
        assert!(
            hit_of(
                &mut ws,
                &x,
                &edges,
                &spike(Vec2::new(1.25, 1.1), up, ObstacleMotion::Static)
            )
            .is_none()
        );
        assert!(
            hit_of(
                &mut ws,
                &x,
                &edges,
                &spike(Vec2::new(1.25, 1.0), up, ObstacleMotion::Static)
            )
            .is_none()
        );
    }

    #[test]
    fn the_broad_phase_finds_what_all_pairs_find() {
        // A fine strip (80 top edges) and 2000 corners around it: the nearest candidate of the
        // grid is the nearest of all the edges whenever a corner is accepted.
        let n = 80;
        let mut x: Vec<Vec2> = (0..=n).map(|i| Vec2::new(i as Real * 0.05, 0.0)).collect();
        x.extend(
            (0..=n)
                .rev()
                .map(|i| Vec2::new(i as Real * 0.05, 0.3 + 0.02 * (i as Real).sin())),
        );
        let m = x.len() as u32;
        let edges: Vec<[u32; 2]> = (0..m).map(|k| [k, (k + 1) % m]).collect();
        let mut ws = ContactWorkspace::default();
        let mut seed = 11u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as Real / (1u64 << 53) as Real
        };
        let mut found = 0;
        for _ in 0..2000 {
            let tip = Vec2::new(4.2 * next() - 0.1, 0.5 * next() - 0.1);
            let angle = 6.3 * next();
            let o = spike(
                tip,
                Vec2::new(angle.cos(), angle.sin()),
                ObstacleMotion::Static,
            );
            let all: Vec<u32> = (0..m).collect();
            let corner = Frame::of(&BodyState::initial(&o)).apply(o.local_polygon()[0]);
            let brute = nearest_edge(&edges, &x, &all, corner);
            assert_eq!(hit_of(&mut ws, &x, &edges, &o), brute, "corner at {tip:?}");
            found += usize::from(brute.is_some());
        }
        assert!(found > 200, "only {found} corners inside");
    }

    #[test]
    fn the_edge_contact_frequency_never_exceeds_the_vertex_one() {
        // The edge point accelerates by F ((1 - t)^2 / m_a + t^2 / m_b) under F = m_e k d: its
        // squared frequency over k is m_e ((1 - t)^2 / m_a + t^2 / m_b), at most 1 with the cap;
        // equal masses keep the plain interpolation.
        for ratio in [1.0, 1.5, 4.0, 10.0, 1e3] {
            for i in 0..=100 {
                let t = i as Real / 100.0;
                let (ma, mb) = (0.3, 0.3 * ratio);
                for (ma, mb) in [(ma, mb), (mb, ma)] {
                    let me = edge_mass(ma, mb, t);
                    let w2 = me * ((1.0 - t).powi(2) / ma + t * t / mb);
                    assert!(w2 <= 1.0 + 1e-15, "ratio {ratio}, t {t}: {w2}");
                    assert!(me >= ma.min(mb) * (1.0 - 1e-15));
                }
            }
            let plain = |t: Real| edge_mass(0.3, 0.3, t) - 0.3;
            assert!((0..=10).all(|i| plain(i as Real / 10.0).abs() < 1e-15));
        }
    }

    /// A soft edge `(1, 0) -> (-1, 0)` (body below), vertex masses 1 and 2 kg, and a dynamic
    /// triangle (3 kg) whose corner 0 is 1 cm into the edge at x = 0.3, moving down and sideways
    /// and spinning.
    fn edge_and_dynamic_spike() -> (Vec<Vec2>, Vec<[u32; 2]>, Vec<Real>, Obstacle, BodyState) {
        let x = vec![Vec2::new(1.0, 0.0), Vec2::new(-1.0, 0.0)];
        let o = spike(
            Vec2::new(0.3, -0.01),
            Vec2::new(0.2, 1.0).normalize(),
            ObstacleMotion::Dynamic {
                mass: 3.0,
                rotates: true,
            },
        );
        let body = BodyState {
            velocity: Vec2::new(0.4, -1.0),
            angular_velocity: 2.0,
            ..BodyState::initial(&o)
        };
        (x, vec![[0, 1]], vec![1.0, 2.0], o, body)
    }

    #[test]
    fn penalty_corner_forces_are_equal_and_opposite() {
        let (x, edges, masses, o, body) = edge_and_dynamic_spike();
        let v = [Vec2::new(0.1, 0.2), Vec2::new(-0.3, 0.0)];
        for mu in [0.0, 0.5] {
            let params = ContactParams {
                friction: mu,
                ..Default::default()
            };
            let (mut f, mut wr, mut ws) = (
                [Vec2::zeros(); 2],
                [Wrench::default()],
                ContactWorkspace::default(),
            );
            let n = accumulate_penalty_forces(
                None,
                std::slice::from_ref(&o),
                &params,
                &masses,
                &edges,
                &x,
                &v,
                &[body],
                &mut f,
                &mut wr,
                &mut ws,
            );
            assert_eq!(n, 1);
            let total = f[0] + f[1];
            // Linear: what the edge gets, the body loses.
            assert!(
                (total + wr[0].force).norm() < 1e-12 * total.norm(),
                "mu {mu}"
            );
            // The split: the corner projects at t = 0.35 from vertex 0.
            assert!((f[0] - total * 0.65).norm() < 1e-12 * total.norm());
            // The normal part pushes the edge down, into the body, and is what is recorded.
            let r = ws.records[0];
            assert_eq!(
                r.kind,
                ContactKind::CornerEdge {
                    obstacle: 0,
                    corner: 0,
                    edge: [0, 1]
                }
            );
            assert!(
                (r.normal - Vec2::new(0.0, -1.0)).norm() < 1e-15 && (r.gap + 0.01).abs() < 1e-15
            );
            assert!(r.force > 0.0 && (total.dot(&r.normal) - r.force).abs() < 1e-12 * r.force);
            // Angular, about the origin: the body's torque is the reaction's at the corner; the
            // edge's forces act at its vertices, equivalent to their sum at the edge point,
            // which is the corner moved along the normal: exactly opposite without friction.
            let corner = Vec2::new(0.3, -0.01);
            assert!(
                (wr[0].torque + cross(corner - body.position, total)).abs() < 1e-12 * total.norm()
            );
            let l_soft = cross(x[0], f[0]) + cross(x[1], f[1]);
            let l_body = wr[0].torque + cross(body.position, wr[0].force);
            if mu == 0.0 {
                assert!(
                    (l_soft + l_body).abs() < 1e-12 * total.norm(),
                    "{l_soft} {l_body}"
                );
            }
        }
    }

    #[test]
    fn projected_corner_exchanges_equal_and_opposite_impulses() {
        let (x0, edges, masses, o, body) = edge_and_dynamic_spike();
        let w: Vec<Real> = masses.iter().map(|m| 1.0 / m).collect();
        let (m_body, inertia) = (3.0, o.inertia());
        for mu in [0.0, 0.5] {
            let mut x = x0.clone();
            let x_old = [x0[0] + Vec2::new(0.01, 0.0), x0[1]];
            let mut bodies = [body];
            let mut ws = ContactWorkspace::default();
            ws.start_substep();
            let n = project_contacts(
                None,
                std::slice::from_ref(&o),
                mu,
                &w,
                &edges,
                &x_old,
                &mut x,
                &[body],
                &mut bodies,
                &mut ws,
            );
            assert_eq!(n, 1);
            // Linear momentum (position level): sum m dx + M dX = 0.
            let p_soft = (x[0] - x0[0]) * masses[0] + (x[1] - x0[1]) * masses[1];
            let p_body = (bodies[0].position - body.position) * m_body;
            assert!(
                (p_soft + p_body).norm() < 1e-15,
                "mu {mu}: {p_soft:?} {p_body:?}"
            );
            if mu == 0.0 {
                // The corner ends on the edge, up to the linearised rotation of the body (the
                // correction moves the corner by r x dtheta; the rotation by dtheta differs from
                // it by |r| dtheta^2 / 2 at most). (With mu > 0 the friction correction that
                // follows turns a rotating body a little more about the corner's lever; the
                // next sweep takes that up, as for vertex contacts.)
                let c = Frame::of(&bodies[0]).apply(o.local_polygon()[0]);
                let e = x[1] - x[0];
                let off = cross(e, c - x[0]).abs() / e.norm();
                let dtheta = bodies[0].angle - body.angle;
                let chord = 0.5 * (c - bodies[0].position).norm() * dtheta * dtheta;
                assert!(dtheta != 0.0 && off <= 1.01 * chord, "{off:e} > {chord:e}");
                // Angular momentum about the origin, to first order in the correction.
                let l_soft = cross(x0[0], (x[0] - x0[0]) * masses[0])
                    + cross(x0[1], (x[1] - x0[1]) * masses[1]);
                let l_body =
                    inertia * (bodies[0].angle - body.angle) + cross(body.position, p_body);
                assert!((l_soft + l_body).abs() < 1e-15, "{l_soft} {l_body}");
            }
            // The record: lambda / h^2, with lambda the soft side's normal impulse times h (the
            // friction correction along the corrected, slightly turned edge adds a little).
            ws.finish_substep(0.01);
            let r = ws.records[0];
            let tol = if mu == 0.0 {
                1e-15
            } else {
                1e-3 * r.force * 1e-4
            };
            assert!(
                (r.force * 1e-4 - p_soft.dot(&r.normal)).abs() <= tol,
                "mu {mu}: {r:?}"
            );
        }
    }
}
