//! Barrier contact for the Newton solvers (implicit Euler and statics), in the manner of
//! Incremental Potential Contact (Li et al. 2020): contact is a term of the potential Newton
//! minimises, and a line search filtered by continuous collision detection never lets a step
//! cross, so the distance between the soft body and every obstacle stays positive at every
//! step (not only at sampled times).
//!
//! **Pairs.** Three kinds, found by the broad phase (`broad_phase`) over the soft body's
//! boundary:
//! - a soft boundary vertex and the ground (the distance is the height above it);
//! - a soft boundary vertex and an obstacle's edge;
//! - an obstacle's corner and a soft boundary edge (so a sharp corner cannot pass between two
//!   soft vertices).
//!
//! **Barrier.** Each pair at squared distance `s` below `d_hat^2` adds `kappa b(s, d_hat^2)`
//! ([`crate::ipc::barrier`]); its force grows without bound as the distance closes. The
//! activation distance `d_hat` is [`ContactParams::barrier_distance`]; the stiffness `kappa`
//! is [`ContactParams::barrier_stiffness`], or by default `M / (8 d_hat^2)` with `M` the
//! P-wave modulus of the body at rest: the barrier's normal stiffness at half the activation
//! distance then equals the modulus (about an element's stiffness), and a contact carrying the
//! force `F` (N per unit thickness) settles at the gap `M d_hat^2 / (4 F)` when that is well
//! below `d_hat`. Each pair's Hessian block is projected to positive semi-definite.
//!
//! **Friction** (Coulomb, coefficient [`ContactParams::friction`]) is lagged as in IPC: the
//! normal force, the tangent and the contact point's place on the edge are those at the start
//! of the solve, and the friction potential `mu lambda f0(|u|)` of the tangential relative
//! displacement `u` over the step is smoothed below `eps_x` (static friction within `eps_x`,
//! sliding at `mu lambda` beyond): `eps_x = eps_v h` in implicit Euler
//! ([`ContactParams::friction_velocity`] = `eps_v`), `eps_x = d_hat` in statics.
//!
//! **Rigid bodies.** A dynamic obstacle's centroid and angle are unknowns of the same Newton
//! system (two-way coupling): its inertia `M/(2h^2) |c - c_hat|^2 + I/(2h^2) (theta -
//! theta_hat)^2` and its weight join the potential (statics: its weight only). A kinematic
//! obstacle is an unknown too, tethered to its prescribed pose by a stiff spring (stiffness
//! `1e6 M_p` per metre, `M_p` the P-wave modulus, and the same times the squared radius per
//! radian), so it pushes the soft body through the barrier rather than jumping into it; it
//! lags its schedule by the contact force over that stiffness (about 1e-9 m for kN forces on
//! a MPa body). Static obstacles and the ground are fixed.
//!
//! **CCD.** Before each line search the largest step that keeps every candidate pair apart is
//! found by additive CCD ([`crate::ipc::point_segment_toi`], exact for the ground): the line
//! search starts there. The corners of a rotating body are taken to move along the chord of
//! their arc within one Newton step; a trial whose squared distance is not positive for some
//! pair is rejected like an infinite energy.

use fem_core::math::{Mat6, Real, Vec2, sin_cos};
use nalgebra::SymmetricEigen;

use super::broad_phase::{Aabb, Grid};
use super::ipc::{Grad6, Hess6, barrier, point_segment_barrier, point_segment_toi};
use super::{Contact, ContactKind};
use crate::model::Model;
use crate::model::contact_params::ContactParams;
use crate::model::state::State;
use crate::rigid::obstacle::strictly_inside;
use crate::rigid::{BodyState, Ground, ObstacleMotion};
use fem_core::energy::Energy;

/// The pairs' separation factor of the CCD: a step never closes a gap by more than 90 %.
const CCD_SEPARATION: Real = 0.1;

/// What a point of a pair is attached to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Point {
    /// A soft vertex.
    Soft(u32),
    /// An obstacle's corner (obstacle, corner).
    Corner(u32, u32),
    /// A fixed point (the ground's two reference points).
    Fixed(Vec2),
}

/// One candidate pair: the point `p` against the segment `[a, b]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pair {
    kind: ContactKind,
    p: Point,
    a: Point,
    b: Point,
    /// The ground: distance is the signed height (one-sided), not the distance to a segment.
    ground: bool,
}

/// The lagged friction data of a pair active at the start of the solve.
#[derive(Clone, Copy, Debug)]
struct Lag {
    /// The pair (its points).
    pair: Pair,
    /// Normal force magnitude at the start, N.
    lambda: Real,
    /// Unit tangent.
    tangent: Vec2,
    /// The closest point's parameter on the segment.
    beta: Real,
}

/// How a moving obstacle's unknowns are weighted.
#[derive(Clone, Copy, Debug)]
enum Role {
    /// Inertia (mass/h^2, inertia/h^2; 0 in statics) and weight.
    Dynamic { mass: Real, inertia: Real },
    /// A stiff tether to the prescribed pose.
    Kinematic,
}

/// A moving obstacle's unknowns.
#[derive(Clone, Copy, Debug)]
struct Body {
    obstacle: usize,
    role: Role,
    /// Index of its first unknown among the extra degrees of freedom.
    first: usize,
    /// Whether the angle is an unknown (else only the centroid).
    rotates: bool,
    /// Quadratic weights of `[x, y, theta]` about `target`.
    weight: [Real; 3],
    /// The pose the weights pull towards.
    target: [Real; 3],
    /// Force on the centroid (its weight), N.
    load: Vec2,
}

/// One degree of freedom of the Newton system: a soft one (`2 v + d`) or an extra one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Dof {
    Soft(usize),
    Extra(usize),
}

/// The barrier contact term of one Newton solve: settings, the obstacles' unknowns, the
/// candidate pairs and the lagged friction.
#[derive(Debug)]
pub(crate) struct BarrierContact {
    d_hat: Real,
    kappa: Real,
    mu: Real,
    eps_x: Real,
    ground: Option<Ground>,
    /// Each obstacle's local polygon.
    polygons: Vec<Vec<Vec2>>,
    /// Each obstacle's radius about its centroid, m.
    radii: Vec<Real>,
    /// The moving obstacles' unknowns, by obstacle (`None`: fixed).
    body_of: Vec<Option<usize>>,
    bodies: Vec<Body>,
    n_extra: usize,
    /// The poses of every obstacle `[x, y, theta]` (unknown for moving ones).
    pub q: Vec<[Real; 3]>,
    /// The poses at the start of the solve.
    q_start: Vec<[Real; 3]>,
    /// Soft positions at the start of the solve (friction's reference).
    x_start: Vec<Vec2>,
    boundary: Vec<[u32; 2]>,
    boundary_vertices: Vec<u32>,
    /// Extra-DOF directions of the current line search.
    pub dq: Vec<Real>,
    grid: Grid,
    boxes: Vec<Aabb>,
    found: Vec<u32>,
    pairs: Vec<Pair>,
    lags: Vec<Lag>,
    contacts: Vec<Contact>,
    tether: Real,
    /// How near (m) a pair must come to be a candidate: `d_hat`, or more for solvers that
    /// move vertices one at a time between broad phases (VBD).
    margin: Real,
    /// Per soft vertex, the candidate pairs and lagged friction pairs it belongs to, with its
    /// place in the pair (0 = p, 1 = a, 2 = b): compressed rows over the vertices.
    vertex_start: Vec<u32>,
    vertex_items: Vec<(u32, u8, bool)>,
    /// Scratch buffers (sized once, reused: no allocation per iteration or sweep).
    q_end: Vec<[Real; 3]>,
    corners: Vec<(Vec2, Vec2)>,
    fill: Vec<u32>,
    still: Vec<Vec2>,
}

/// A point's Jacobian: the degrees of freedom it moves with and `d point / d dof` for each, at
/// most three (a rotating corner's), held inline so that evaluating the derivatives allocates
/// nothing.
#[derive(Clone, Copy, Debug)]
struct Jacobian {
    len: usize,
    entries: [(Dof, Vec2); 3],
}

impl Default for Jacobian {
    fn default() -> Self {
        Jacobian {
            len: 0,
            entries: [(Dof::Extra(0), Vec2::zeros()); 3],
        }
    }
}

impl Jacobian {
    fn clear(&mut self) {
        self.len = 0;
    }

    fn push(&mut self, entry: (Dof, Vec2)) {
        self.entries[self.len] = entry;
        self.len += 1;
    }

    fn entries(&self) -> &[(Dof, Vec2)] {
        &self.entries[..self.len]
    }
}

/// `R(theta) l` and its derivative `perp(R l)`.
#[inline]
fn rotate(theta: Real, l: Vec2) -> Vec2 {
    let (s, c) = sin_cos(theta);
    Vec2::new(c * l.x - s * l.y, s * l.x + c * l.y)
}

/// IPC's friction mollifier `f0` and its first two derivatives, for `y >= 0`.
#[inline]
fn mollifier(y: Real, eps: Real) -> (Real, Real, Real) {
    if y >= eps {
        (y, 1.0, 0.0)
    } else {
        (
            -y * y * y / (3.0 * eps * eps) + y * y / eps + eps / 3.0,
            -y * y / (eps * eps) + 2.0 * y / eps,
            -2.0 * y / (eps * eps) + 2.0 / eps,
        )
    }
}

/// The positive semi-definite part of a symmetric 6x6 matrix.
fn project_psd(h: &Hess6) -> Hess6 {
    let eig = SymmetricEigen::new(Mat6::from(*h));
    let mut d = eig.eigenvalues;
    if d.iter().all(|&l| l >= 0.0) {
        return *h;
    }
    for l in d.iter_mut() {
        *l = l.max(0.0);
    }
    let q = eig.eigenvectors;
    q * Mat6::from_diagonal(&d) * q.transpose()
}

impl BarrierContact {
    /// The contact term for `model` (which has a ground or obstacles), with the friction
    /// smoothing displacement `eps_x` (m).
    pub(crate) fn new<E: Energy>(model: &Model<E>, eps_x: Real) -> Self {
        let params: &ContactParams = model.contact_params();
        let d_hat = params.barrier_distance;
        let modulus = model.p_wave_modulus();
        let kappa = if params.barrier_stiffness > 0.0 {
            params.barrier_stiffness
        } else {
            modulus / (8.0 * d_hat * d_hat)
        };
        let mut bodies = Vec::new();
        let mut body_of = Vec::new();
        let mut n_extra = 0;
        let mut q = Vec::new();
        for (o, obs) in model.obstacles().iter().enumerate() {
            let c = obs.initial_centroid();
            q.push([c.x, c.y, 0.0]);
            let (role, rotates) = match obs.motion() {
                ObstacleMotion::Static => {
                    body_of.push(None);
                    continue;
                }
                ObstacleMotion::Kinematic { .. } => (Role::Kinematic, true),
                ObstacleMotion::Dynamic { mass, rotates } => (
                    Role::Dynamic {
                        mass,
                        inertia: obs.inertia(),
                    },
                    rotates,
                ),
            };
            body_of.push(Some(bodies.len()));
            bodies.push(Body {
                obstacle: o,
                role,
                first: n_extra,
                rotates,
                weight: [0.0; 3],
                target: [c.x, c.y, 0.0],
                load: Vec2::zeros(),
            });
            n_extra += if rotates { 3 } else { 2 };
        }
        BarrierContact {
            d_hat,
            kappa,
            mu: params.friction,
            eps_x,
            ground: model.ground().copied(),
            polygons: model
                .obstacles()
                .iter()
                .map(|o| o.local_polygon().to_vec())
                .collect(),
            radii: model.obstacles().iter().map(|o| o.radius()).collect(),
            body_of,
            bodies,
            n_extra,
            q_start: q.clone(),
            q,
            x_start: Vec::new(),
            boundary: model.boundary_edges().to_vec(),
            boundary_vertices: model.boundary_vertices().to_vec(),
            dq: vec![0.0; n_extra],
            grid: Grid::default(),
            boxes: Vec::new(),
            found: Vec::new(),
            pairs: Vec::new(),
            lags: Vec::new(),
            contacts: Vec::new(),
            tether: 1e6 * modulus,
            margin: d_hat,
            vertex_start: Vec::new(),
            vertex_items: Vec::new(),
            q_end: Vec::new(),
            corners: Vec::new(),
            fill: Vec::new(),
            still: Vec::new(),
        }
    }

    /// Extra unknowns (the moving obstacles' poses).
    pub(crate) fn n_extra(&self) -> usize {
        self.n_extra
    }

    /// The soft vertices an extra unknown may couple to (the boundary).
    pub(crate) fn coupled_vertices(&self) -> &[u32] {
        &self.boundary_vertices
    }

    /// Set up a solve from the soft positions `x` and the obstacles' poses `poses` at its
    /// start: targets and weights of the moving obstacles (`inertia_weight` = `1/h^2`, 0 in
    /// statics; `target_poses` the inertial predictions of dynamic bodies and the prescribed
    /// poses of kinematic ones; `gravity` scaled by the load factor), and the lagged friction.
    pub(crate) fn begin(
        &mut self,
        x: &[Vec2],
        poses: &[BodyState],
        target_poses: &[[Real; 3]],
        inertia_weight: Real,
        gravity: Vec2,
    ) {
        self.x_start.clear();
        self.x_start.extend_from_slice(x);
        for (o, b) in poses.iter().enumerate() {
            self.q[o] = [b.position.x, b.position.y, b.angle];
        }
        self.q_start.clone_from(&self.q);
        for body in &mut self.bodies {
            body.target = target_poses[body.obstacle];
            match body.role {
                Role::Dynamic { mass, inertia } => {
                    body.weight = [
                        inertia_weight * mass,
                        inertia_weight * mass,
                        inertia_weight * inertia,
                    ];
                    body.load = gravity * mass;
                }
                Role::Kinematic => {
                    let k = self.tether;
                    let r = self.radii[body.obstacle];
                    body.weight = [k, k, k * (r * r).max(1e-12)];
                    body.load = Vec2::zeros();
                }
            }
        }
        // Lagged friction from the pairs active at the start.
        self.prepare(x, None);
        self.lags.clear();
        if self.mu > 0.0 {
            for k in 0..self.pairs.len() {
                let pair = self.pairs[k];
                let [p, a, b] = self.points(&pair, x, &self.q);
                let (s, normal, beta) = self.geometry(&pair, p, a, b);
                if s >= self.d_hat * self.d_hat || s <= 0.0 {
                    continue;
                }
                let (_, db, _) = barrier(s, self.d_hat * self.d_hat);
                let lambda = -self.kappa * db * 2.0 * s.sqrt();
                self.lags.push(Lag {
                    pair,
                    lambda,
                    tangent: Vec2::new(-normal.y, normal.x),
                    beta,
                });
            }
        }
    }

    /// The world position of an obstacle's corner at the poses `q`.
    #[inline]
    fn corner(&self, q: &[[Real; 3]], o: u32, c: u32) -> Vec2 {
        let pose = q[o as usize];
        Vec2::new(pose[0], pose[1]) + rotate(pose[2], self.polygons[o as usize][c as usize])
    }

    #[inline]
    fn point(&self, pt: Point, x: &[Vec2], q: &[[Real; 3]]) -> Vec2 {
        match pt {
            Point::Soft(v) => x[v as usize],
            Point::Corner(o, c) => self.corner(q, o, c),
            Point::Fixed(p) => p,
        }
    }

    #[inline]
    fn points(&self, pair: &Pair, x: &[Vec2], q: &[[Real; 3]]) -> [Vec2; 3] {
        [pair.p, pair.a, pair.b].map(|pt| self.point(pt, x, q))
    }

    /// Squared distance (negative heights of the ground give `-h^2`), the unit normal from the
    /// segment (or ground) towards the point, and the closest point's parameter.
    fn geometry(&self, pair: &Pair, p: Vec2, a: Vec2, b: Vec2) -> (Real, Vec2, Real) {
        if pair.ground {
            let g = self.ground.as_ref().expect("ground pair without a ground");
            let h = (p - g.point).dot(&g.normal);
            return (h.signum() * h * h, g.normal, 0.0);
        }
        let e = b - a;
        let l2 = e.norm_squared();
        let beta = if l2 > 0.0 {
            ((p - a).dot(&e) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d = p - (a + e * beta);
        let n = d.norm();
        let normal = if n > 0.0 {
            d / n
        } else {
            Vec2::new(e.y, -e.x).normalize()
        };
        (d.norm_squared(), normal, beta)
    }

    /// The candidate pairs for the motion from `(x, q)` along `(dx, self.dq)` (whole step;
    /// `None`: no motion): every pair whose boxes, swept and grown by `d_hat`, overlap.
    pub(crate) fn prepare(&mut self, x: &[Vec2], dx: Option<&[Vec2]>) {
        let mut q_end = std::mem::take(&mut self.q_end);
        if dx.is_some() {
            self.trial_poses(1.0, &mut q_end);
        } else {
            q_end.clone_from(&self.q);
        }
        let end = |v: usize| match dx {
            Some(d) => x[v] + d[v],
            None => x[v],
        };
        let margin = self.margin;
        self.pairs.clear();
        // Ground: every boundary vertex whose swept box comes within d_hat.
        if let Some(g) = self.ground {
            let (t0, t1) = (g.point, g.point + Vec2::new(g.normal.y, -g.normal.x));
            for &v in &self.boundary_vertices {
                let h0 = (x[v as usize] - g.point).dot(&g.normal);
                let h1 = (end(v as usize) - g.point).dot(&g.normal);
                if h0.min(h1) < margin {
                    self.pairs.push(Pair {
                        kind: ContactKind::VertexGround { vertex: v },
                        p: Point::Soft(v),
                        a: Point::Fixed(t0),
                        b: Point::Fixed(t1),
                        ground: true,
                    });
                }
            }
        }
        if self.polygons.is_empty() {
            self.q_end = q_end;
            return;
        }
        self.boxes.clear();
        for &[a, b] in &self.boundary {
            let (a, b) = (a as usize, b as usize);
            self.boxes
                .push(Aabb::of(&[x[a], x[b], end(a), end(b)]).inflated(margin));
        }
        self.grid.build(&self.boxes);
        for o in 0..self.polygons.len() {
            let n = self.polygons[o].len();
            let mut corners = std::mem::take(&mut self.corners);
            corners.clear();
            for k in 0..n {
                let c0 = self.corner(&self.q, o as u32, k as u32);
                let c1 = self.corner(&q_end, o as u32, k as u32);
                corners.push((c0, c1));
            }
            for k in 0..n {
                let (a0, a1) = corners[k];
                let (b0, b1) = corners[(k + 1) % n];
                let edge_box = Aabb::of(&[a0, a1, b0, b1]);
                let mut found = std::mem::take(&mut self.found);
                self.grid.query(&edge_box, &mut found);
                for &e in &found {
                    let [sa, sb] = self.boundary[e as usize];
                    // Soft vertices of the edge against the obstacle's edge k.
                    for v in [sa, sb] {
                        let vb = Aabb::of(&[x[v as usize], end(v as usize)]).inflated(margin);
                        if vb.overlaps(&edge_box) {
                            self.pairs.push(Pair {
                                kind: ContactKind::VertexObstacle {
                                    vertex: v,
                                    obstacle: o as u32,
                                    edge: k as u32,
                                },
                                p: Point::Soft(v),
                                a: Point::Corner(o as u32, k as u32),
                                b: Point::Corner(o as u32, ((k + 1) % n) as u32),
                                ground: false,
                            });
                        }
                    }
                    // The obstacle's corner k against the soft edge.
                    let cb = Aabb::of(&[a0, a1]);
                    if cb.overlaps(&self.boxes[e as usize]) {
                        self.pairs.push(Pair {
                            kind: ContactKind::CornerEdge {
                                obstacle: o as u32,
                                corner: k as u32,
                                edge: [sa, sb],
                            },
                            p: Point::Corner(o as u32, k as u32),
                            a: Point::Soft(sa),
                            b: Point::Soft(sb),
                            ground: false,
                        });
                    }
                }
                self.found = found;
            }
            self.corners = corners;
        }
        self.q_end = q_end;
        // One pair per feature couple, in a fixed order.
        self.pairs.sort_unstable_by_key(|p| key(&p.kind));
        self.pairs.dedup_by_key(|p| key(&p.kind));
    }

    /// The obstacles' poses after the step `alpha` along `self.dq`.
    pub(crate) fn trial_poses(&self, alpha: Real, out: &mut Vec<[Real; 3]>) {
        out.clone_from(&self.q);
        for b in &self.bodies {
            let p = &mut out[b.obstacle];
            p[0] += alpha * self.dq[b.first];
            p[1] += alpha * self.dq[b.first + 1];
            if b.rotates {
                p[2] += alpha * self.dq[b.first + 2];
            }
        }
    }

    /// The contact energy at `(x, q)` (barriers, friction, the moving obstacles' inertia or
    /// tether and weight) and the sum of its terms' magnitudes; infinite when a candidate
    /// pair touches or crosses.
    pub(crate) fn value(&self, x: &[Vec2], q: &[[Real; 3]]) -> (Real, Real) {
        let s_hat = self.d_hat * self.d_hat;
        let (mut e, mut mag) = (0.0, 0.0);
        for pair in &self.pairs {
            let [p, a, b] = self.points(pair, x, q);
            let (s, _, _) = self.geometry(pair, p, a, b);
            if s <= 0.0 {
                return (Real::INFINITY, Real::INFINITY);
            }
            let (bv, _, _) = barrier(s, s_hat);
            e += self.kappa * bv;
        }
        mag += e.abs();
        for lag in &self.lags {
            let d = self.friction_energy(lag, self.points(&lag.pair, x, q));
            e += d;
            mag += d.abs();
        }
        for b in &self.bodies {
            let p = q[b.obstacle];
            for ((pk, tk), wk) in p.iter().zip(&b.target).zip(&b.weight) {
                let t = 0.5 * wk * (pk - tk).powi(2);
                e += t;
                mag += t;
            }
            let s = self.q_start[b.obstacle];
            let w = b.load.x * (p[0] - s[0]) + b.load.y * (p[1] - s[1]);
            e -= w;
            mag += w.abs();
        }
        (e, mag)
    }

    /// Tangential slip of a lagged pair over the solve, its points now being `now`, and its
    /// gradient over `[p, a, b]`.
    fn slip(&self, lag: &Lag, now: [Vec2; 3]) -> (Real, Grad6) {
        let then = self.points(&lag.pair, &self.x_start, &self.q_start);
        let w = [1.0, -(1.0 - lag.beta), -lag.beta];
        let mut rel = Vec2::zeros();
        let mut g = Grad6::zeros();
        for k in 0..3 {
            rel += (now[k] - then[k]) * w[k];
            g[2 * k] = w[k] * lag.tangent.x;
            g[2 * k + 1] = w[k] * lag.tangent.y;
        }
        (rel.dot(&lag.tangent), g)
    }

    /// A lagged pair's friction energy with its points at `now`.
    fn friction_energy(&self, lag: &Lag, now: [Vec2; 3]) -> Real {
        let (u, _) = self.slip(lag, now);
        self.mu * lag.lambda * mollifier(u.abs(), self.eps_x).0
    }

    /// A lagged pair's friction gradient and Hessian over `[p, a, b]` at `(x, q)`.
    fn friction_derivatives(&self, lag: &Lag, x: &[Vec2], q: &[[Real; 3]]) -> (Grad6, Hess6) {
        let (u, du) = self.slip(lag, self.points(&lag.pair, x, q));
        let (_, f1, f2) = mollifier(u.abs(), self.eps_x);
        let scale = self.mu * lag.lambda;
        (
            du * (scale * f1 * u.signum()),
            du * du.transpose() * (scale * f2),
        )
    }

    /// A candidate pair's barrier gradient and Hessian (not projected) over `[p, a, b]` at the
    /// points `[p, a, b]`, or `None` beyond the activation distance (or touching).
    fn barrier_derivatives(&self, pair: &Pair, [p, a, b]: [Vec2; 3]) -> Option<(Grad6, Hess6)> {
        let s_hat = self.d_hat * self.d_hat;
        if !pair.ground {
            let (e, g, h) = point_segment_barrier(p, a, b, self.d_hat, self.kappa);
            return (e != 0.0 && e.is_finite()).then_some((g, h));
        }
        let gr = self.ground.as_ref().expect("ground pair");
        let hgt = (p - gr.point).dot(&gr.normal);
        let s = hgt * hgt;
        if hgt <= 0.0 || s >= s_hat {
            return None;
        }
        let (_, db, d2b) = barrier(s, s_hat);
        let ds = gr.normal * (2.0 * hgt);
        let n = gr.normal;
        let mut g = Grad6::zeros();
        g.fixed_rows_mut::<2>(0)
            .copy_from(&(ds * (self.kappa * db)));
        let mut h = Hess6::zeros();
        h.fixed_view_mut::<2, 2>(0, 0).copy_from(
            &((ds * ds.transpose() * d2b + n * n.transpose() * (2.0 * db)) * self.kappa),
        );
        Some((g, h))
    }

    /// The degrees of freedom of a point and `d point / d dof` for each; second derivative
    /// of a corner in its angle (`-R l`).
    fn jacobian(&self, pt: Point, q: &[[Real; 3]], out: &mut Jacobian) -> Vec2 {
        out.clear();
        match pt {
            Point::Soft(v) => {
                out.push((Dof::Soft(2 * v as usize), Vec2::new(1.0, 0.0)));
                out.push((Dof::Soft(2 * v as usize + 1), Vec2::new(0.0, 1.0)));
                Vec2::zeros()
            }
            Point::Corner(o, c) => {
                let Some(b) = self.body_of[o as usize] else {
                    return Vec2::zeros();
                };
                let b = &self.bodies[b];
                out.push((Dof::Extra(b.first), Vec2::new(1.0, 0.0)));
                out.push((Dof::Extra(b.first + 1), Vec2::new(0.0, 1.0)));
                let r = rotate(q[o as usize][2], self.polygons[o as usize][c as usize]);
                if b.rotates {
                    out.push((Dof::Extra(b.first + 2), Vec2::new(-r.y, r.x)));
                    -r
                } else {
                    Vec2::zeros()
                }
            }
            Point::Fixed(_) => Vec2::zeros(),
        }
    }

    /// Scatter a pair's gradient and (already projected) Hessian over `[p, a, b]` into the
    /// system through the points' Jacobians.
    #[allow(clippy::too_many_arguments)]
    fn scatter(
        &self,
        pair: &Pair,
        q: &[[Real; 3]],
        g: &Grad6,
        h: Option<&Hess6>,
        grad: &mut dyn FnMut(Dof, Real),
        hess: &mut dyn FnMut(Dof, Dof, Real),
        jac: &mut [Jacobian; 3],
    ) {
        let mut curv = [Vec2::zeros(); 3];
        for (k, pt) in [pair.p, pair.a, pair.b].into_iter().enumerate() {
            curv[k] = self.jacobian(pt, q, &mut jac[k]);
        }
        for k in 0..3 {
            let gk = Vec2::new(g[2 * k], g[2 * k + 1]);
            for &(dof, col) in jac[k].entries() {
                grad(dof, gk.dot(&col));
            }
        }
        let Some(h) = h else {
            return;
        };
        for i in 0..3 {
            for j in 0..3 {
                let block = h.fixed_view::<2, 2>(2 * i, 2 * j);
                for &(di, ci) in jac[i].entries() {
                    for &(dj, cj) in jac[j].entries() {
                        let v = ci.dot(&(block * cj));
                        if v != 0.0 {
                            hess(di, dj, v);
                        }
                    }
                }
            }
            // The corner's curvature in its angle, kept where it is convex.
            if curv[i] != Vec2::zeros() {
                let gi = Vec2::new(g[2 * i], g[2 * i + 1]);
                let c = gi.dot(&curv[i]);
                if c > 0.0 {
                    let theta = jac[i].entries().last().expect("rotating corner").0;
                    hess(theta, theta, c);
                }
            }
        }
    }

    /// Add the gradient (and, with `hess`, the projected Hessian) of the contact energy at
    /// `(x, q)` through the callbacks. Allocates nothing (the points' Jacobians are held
    /// inline).
    pub(crate) fn derivatives(
        &self,
        x: &[Vec2],
        q: &[[Real; 3]],
        grad: &mut dyn FnMut(Dof, Real),
        hess: Option<&mut dyn FnMut(Dof, Dof, Real)>,
    ) {
        let mut jac: [Jacobian; 3] = Default::default();
        self.derivatives_with(x, q, grad, hess, &mut jac);
    }

    /// The gradient of the contact energy at `(x, self.q)` through `grad`, as
    /// [`BarrierContact::derivatives`] gives it: the residual test of the solvers that
    /// iterate.
    pub(crate) fn gradient(&mut self, x: &[Vec2], grad: &mut dyn FnMut(Dof, Real)) {
        let mut jac: [Jacobian; 3] = Default::default();
        self.derivatives_with(x, &self.q, grad, None, &mut jac);
    }

    /// [`BarrierContact::derivatives`] with the points' Jacobians in `jac`.
    fn derivatives_with(
        &self,
        x: &[Vec2],
        q: &[[Real; 3]],
        grad: &mut dyn FnMut(Dof, Real),
        hess: Option<&mut dyn FnMut(Dof, Dof, Real)>,
        jac: &mut [Jacobian; 3],
    ) {
        let mut noop = |_: Dof, _: Dof, _: Real| {};
        let want_h = hess.is_some();
        let hess: &mut dyn FnMut(Dof, Dof, Real) = match hess {
            Some(h) => h,
            None => &mut noop,
        };
        for pair in &self.pairs {
            let Some((g, h)) = self.barrier_derivatives(pair, self.points(pair, x, q)) else {
                continue;
            };
            let hp = if want_h { project_psd(&h) } else { h };
            self.scatter(pair, q, &g, want_h.then_some(&hp), grad, hess, jac);
        }
        for lag in &self.lags {
            let (g, h) = self.friction_derivatives(lag, x, q);
            self.scatter(&lag.pair, q, &g, want_h.then_some(&h), grad, hess, jac);
        }
        for b in &self.bodies {
            let p = q[b.obstacle];
            let n = if b.rotates { 3 } else { 2 };
            for (k, (pk, tk)) in p.iter().zip(&b.target).enumerate().take(n) {
                let mut g = b.weight[k] * (pk - tk);
                if k < 2 {
                    g -= b.load[k];
                }
                grad(Dof::Extra(b.first + k), g);
                hess(
                    Dof::Extra(b.first + k),
                    Dof::Extra(b.first + k),
                    b.weight[k],
                );
            }
        }
    }

    /// The step fraction in `(0, 1]` along `self.dq` within which the corners of every
    /// rotating obstacle stay so close to the chords of their arcs (sagitta `r dtheta^2 / 8`
    /// at most 5 % of the smallest gap now, or of `d_hat` when nothing is that near) that the
    /// CCD on chords stays conservative. Uses the pairs of the last `prepare` at `x`.
    pub(crate) fn rotation_limit(&self, x: &[Vec2]) -> Real {
        let mut gap = self.d_hat;
        for pair in &self.pairs {
            let [p, a, b] = self.points(pair, x, &self.q);
            let (s, _, _) = self.geometry(pair, p, a, b);
            gap = gap.min(s.signum() * s.abs().sqrt());
        }
        let mut alpha: Real = 1.0;
        for b in self.bodies.iter().filter(|b| b.rotates) {
            let dtheta = self.dq[b.first + 2].abs();
            let r = self.radii[b.obstacle];
            if dtheta > 0.0 && r > 0.0 && gap > 0.0 {
                alpha = alpha.min((0.4 * gap / r).sqrt() / dtheta);
            }
        }
        alpha
    }

    /// The largest step fraction in `(0, 1]` along `(dx, self.dq)` from `(x, self.q)` that keeps
    /// every candidate pair apart (by additive CCD; 1 when nothing comes close).
    pub(crate) fn max_step(&mut self, x: &[Vec2], dx: &[Vec2]) -> Real {
        self.max_step_with(x, dx, CCD_SEPARATION)
    }

    /// As [`BarrierContact::max_step`], closing no gap to less than `separation` of itself.
    pub(crate) fn max_step_with(&mut self, x: &[Vec2], dx: &[Vec2], separation: Real) -> Real {
        let mut q_end = std::mem::take(&mut self.q_end);
        self.trial_poses(1.0, &mut q_end);
        let mut alpha: Real = 1.0;
        for pair in &self.pairs {
            let start = self.points(pair, x, &self.q);
            let x_end_pt = |pt: Point| match pt {
                Point::Soft(v) => x[v as usize] + dx[v as usize],
                Point::Corner(o, c) => self.corner(&q_end, o, c),
                Point::Fixed(p) => p,
            };
            let end = [x_end_pt(pair.p), x_end_pt(pair.a), x_end_pt(pair.b)];
            if pair.ground {
                let g = self.ground.as_ref().expect("ground pair");
                let h0 = (start[0] - g.point).dot(&g.normal);
                let h1 = (end[0] - g.point).dot(&g.normal);
                if h1 < separation * h0 {
                    alpha = alpha.min((1.0 - separation) * h0 / (h0 - h1));
                }
                continue;
            }
            let disp = [end[0] - start[0], end[1] - start[1], end[2] - start[2]];
            if let Some(t) = point_segment_toi(start, disp, separation) {
                alpha = alpha.min(t);
            }
        }
        self.q_end = q_end;
        alpha
    }

    /// The contacts (pairs within the activation distance) at `(x, q)`, with their normal
    /// forces, into `self.contacts`; returns them and the smallest distance over all
    /// candidate pairs (infinite when none).
    pub(crate) fn record(&mut self, x: &[Vec2]) -> Real {
        let s_hat = self.d_hat * self.d_hat;
        self.prepare(x, None);
        self.contacts.clear();
        let mut min = Real::INFINITY;
        for k in 0..self.pairs.len() {
            let pair = self.pairs[k];
            let [p, a, b] = self.points(&pair, x, &self.q);
            let (s, normal, beta) = self.geometry(&pair, p, a, b);
            let gap = s.signum() * s.abs().sqrt();
            min = min.min(gap);
            if s >= s_hat {
                continue;
            }
            let force = if s > 0.0 {
                -self.kappa * barrier(s, s_hat).1 * 2.0 * gap
            } else {
                Real::INFINITY
            };
            // The normal points into the soft body: from the segment to the point when the
            // point is soft, the other way when the corner is the point.
            let (point, normal) = match pair.p {
                Point::Corner(..) => (a + (b - a) * beta, -normal),
                _ => (p, normal),
            };
            self.contacts.push(Contact {
                kind: pair.kind,
                point,
                normal,
                gap,
                force,
            });
        }
        min
    }

    /// Whether the body at `x` and the obstacles at their poses are apart, as barrier contact
    /// needs at the start of a step: `None`, or what touches or overlaps (a candidate pair at
    /// distance <= 0 after [`BarrierContact::begin`] or a `prepare` without motion, a boundary
    /// vertex inside an obstacle, an obstacle corner inside the body) in words, for an error.
    /// An overlap happens when something outside the solver moved an obstacle (a hand).
    pub(crate) fn start_overlap(&self, x: &[Vec2]) -> Option<String> {
        let mut best = (0.0, None);
        for pair in &self.pairs {
            let [p, a, b] = self.points(pair, x, &self.q);
            let (s, _, _) = self.geometry(pair, p, a, b);
            let d = s.signum() * s.abs().sqrt();
            if d <= best.0 {
                best = (d, Some(pair.kind));
            }
        }
        if let (d, Some(kind)) = best {
            return Some(format!("{} at distance {d:e} m", describe(&kind)));
        }
        for (o, poly) in self.polygons.iter().enumerate() {
            // A vertex against the obstacle's own polygon, in the obstacle's frame.
            let [cx, cy, theta] = self.q[o];
            for &v in &self.boundary_vertices {
                let local = rotate(-theta, x[v as usize] - Vec2::new(cx, cy));
                if strictly_inside(poly, local, 0.0) {
                    return Some(format!("vertex {v} inside obstacles[{o}]"));
                }
            }
            // A corner against the body's boundary (even-odd over its boundary edges, which
            // may form several loops).
            for k in 0..poly.len() {
                let c = self.corner(&self.q, o as u32, k as u32);
                let mut inside = false;
                for &[a, b] in &self.boundary {
                    let (a, b) = (x[a as usize], x[b as usize]);
                    if (a.y > c.y) != (b.y > c.y)
                        && c.x < a.x + (c.y - a.y) / (b.y - a.y) * (b.x - a.x)
                    {
                        inside = !inside;
                    }
                }
                if inside {
                    return Some(format!("obstacles[{o}] corner {k} inside the body"));
                }
            }
        }
        None
    }

    /// Collect candidate pairs up to `margin` (>= `d_hat`) apart instead of `d_hat`.
    pub(crate) fn set_margin(&mut self, margin: Real) {
        self.margin = margin.max(self.d_hat);
    }

    /// The activation distance, m.
    pub(crate) fn d_hat(&self) -> Real {
        self.d_hat
    }

    /// The stiffness tethering a kinematic obstacle to its schedule, N/m per unit thickness
    /// (and times the squared radius per radian). Default `1e6` times the P-wave modulus.
    pub(crate) fn set_tether(&mut self, stiffness: Real) {
        self.tether = stiffness;
    }

    /// Scale the moving obstacles' weights (a dynamic body's inertia `M / h^2`, a kinematic
    /// one's tether) by `factor`, until the next [`BarrierContact::begin`]: the linearly
    /// implicit step assembles its matrix divided by Rayleigh's stiffness factor and keeps
    /// these terms out of the damping (`optim::newton::linear`).
    pub(crate) fn scale_weights(&mut self, factor: Real) {
        for w in self.bodies.iter_mut().flat_map(|b| b.weight.iter_mut()) {
            *w *= factor;
        }
    }

    /// Each extra unknown, in their order: its obstacle, its component of the obstacle's pose
    /// (0 and 1 the centroid's, 2 the angle) and its weight on the diagonal of the Hessian in
    /// the current solve (a dynamic body's inertia `M w`, `I w`, a kinematic one's tether):
    /// the quasi-Newton solver's initial Hessian for these unknowns.
    pub(crate) fn extra_unknowns(&self) -> impl Iterator<Item = (usize, usize, Real)> + '_ {
        self.bodies.iter().flat_map(|b| {
            let n = if b.rotates { 3 } else { 2 };
            (0..n).map(move |k| (b.obstacle, k, b.weight[k]))
        })
    }

    /// Set the obstacles' line-search direction `dq` to their targets (from their poses).
    pub(crate) fn aim_at_targets(&mut self) {
        for b in &self.bodies {
            let (p, t) = (self.q[b.obstacle], b.target);
            self.dq[b.first] = t[0] - p[0];
            self.dq[b.first + 1] = t[1] - p[1];
            if b.rotates {
                self.dq[b.first + 2] = t[2] - p[2];
            }
        }
    }

    /// Whether soft vertex `v` belongs to a candidate or lagged pair (after
    /// [`BarrierContact::index_vertices`]).
    pub(crate) fn vertex_has_pairs(&self, v: usize) -> bool {
        self.vertex_start.len() > v + 1 && self.vertex_start[v + 1] > self.vertex_start[v]
    }

    /// Whether soft vertex `v` lies on the boundary (can touch anything).
    pub(crate) fn on_boundary(&self, v: usize) -> bool {
        self.boundary_vertices.binary_search(&(v as u32)).is_ok()
    }

    /// The barrier and friction energy of soft vertex `v`'s pairs with `v` moved to `p` (the
    /// rest at `x`); infinite when a pair touches.
    pub(crate) fn vertex_energy(&self, v: usize, x: &[Vec2], p: Vec2) -> Real {
        if self.vertex_start.len() <= v + 1 {
            return 0.0;
        }
        let s_hat = self.d_hat * self.d_hat;
        let (a, b) = (
            self.vertex_start[v] as usize,
            self.vertex_start[v + 1] as usize,
        );
        let mut e = 0.0;
        for &(k, slot, lagged) in &self.vertex_items[a..b] {
            let pair = if lagged {
                self.lags[k as usize].pair
            } else {
                self.pairs[k as usize]
            };
            let mut pts = self.points(&pair, x, &self.q);
            pts[slot as usize] = p;
            if lagged {
                e += self.friction_energy(&self.lags[k as usize], pts);
            } else {
                let (sq, _, _) = self.geometry(&pair, pts[0], pts[1], pts[2]);
                if sq <= 0.0 {
                    return Real::INFINITY;
                }
                e += self.kappa * barrier(sq, s_hat).0;
            }
        }
        e
    }

    /// Index the candidate pairs (of the last `prepare`) and the lagged friction pairs by soft
    /// vertex, for [`BarrierContact::vertex_terms`] and [`BarrierContact::vertex_max_step`].
    pub(crate) fn index_vertices(&mut self, n_vertices: usize) {
        self.vertex_start.clear();
        self.vertex_start.resize(n_vertices + 1, 0);
        let each = |pairs: &mut dyn Iterator<Item = &Pair>, f: &mut dyn FnMut(u32, u32, u8)| {
            for (k, pair) in pairs.enumerate() {
                for (slot, pt) in [pair.p, pair.a, pair.b].into_iter().enumerate() {
                    if let Point::Soft(v) = pt {
                        f(v, k as u32, slot as u8);
                    }
                }
            }
        };
        let start = &mut self.vertex_start;
        each(&mut self.pairs.iter(), &mut |v, _, _| {
            start[v as usize + 1] += 1
        });
        each(&mut self.lags.iter().map(|l| &l.pair), &mut |v, _, _| {
            start[v as usize + 1] += 1
        });
        for v in 0..n_vertices {
            start[v + 1] += start[v];
        }
        self.vertex_items.clear();
        self.vertex_items
            .resize(start[n_vertices] as usize, (0, 0, false));
        let mut fill = std::mem::take(&mut self.fill);
        fill.clear();
        fill.extend_from_slice(&start[..n_vertices]);
        let items = &mut self.vertex_items;
        each(&mut self.pairs.iter(), &mut |v, k, slot| {
            items[fill[v as usize] as usize] = (k, slot, false);
            fill[v as usize] += 1;
        });
        each(&mut self.lags.iter().map(|l| &l.pair), &mut |v, k, slot| {
            items[fill[v as usize] as usize] = (k, slot, true);
            fill[v as usize] += 1;
        });
        self.fill = fill;
    }

    /// The barrier and friction terms' gradient and Hessian block (`h00, h01, h11`, not
    /// projected) with respect to soft vertex `v` at `x` (the obstacles at `self.q`).
    pub(crate) fn vertex_terms(&self, v: usize, x: &[Vec2]) -> (Vec2, [Real; 3]) {
        let mut g = Vec2::zeros();
        let mut h = [0.0; 3];
        if self.vertex_start.len() <= v + 1 {
            return (g, h);
        }
        let (a, b) = (
            self.vertex_start[v] as usize,
            self.vertex_start[v + 1] as usize,
        );
        for &(k, slot, lagged) in &self.vertex_items[a..b] {
            let i = 2 * slot as usize;
            let (g6, h6) = if lagged {
                self.friction_derivatives(&self.lags[k as usize], x, &self.q)
            } else {
                let pair = &self.pairs[k as usize];
                match self.barrier_derivatives(pair, self.points(pair, x, &self.q)) {
                    Some(d) => d,
                    None => continue,
                }
            };
            g += Vec2::new(g6[i], g6[i + 1]);
            h[0] += h6[(i, i)];
            h[1] += 0.5 * (h6[(i, i + 1)] + h6[(i + 1, i)]);
            h[2] += h6[(i + 1, i + 1)];
        }
        (g, h)
    }

    /// The largest fraction in `(0, 1]` of the move `d` of soft vertex `v` alone (the other
    /// points held) that keeps its candidate pairs apart.
    pub(crate) fn vertex_max_step(&self, v: usize, x: &[Vec2], d: Vec2) -> Real {
        let mut alpha: Real = 1.0;
        if self.vertex_start.len() <= v + 1 {
            return alpha;
        }
        let (a, b) = (
            self.vertex_start[v] as usize,
            self.vertex_start[v + 1] as usize,
        );
        for &(k, slot, lagged) in &self.vertex_items[a..b] {
            if lagged {
                continue;
            }
            let pair = &self.pairs[k as usize];
            let start = self.points(pair, x, &self.q);
            if pair.ground {
                let g = self.ground.as_ref().expect("ground pair");
                let h0 = (start[0] - g.point).dot(&g.normal);
                let h1 = h0 + d.dot(&g.normal);
                if h1 < CCD_SEPARATION * h0 {
                    alpha = alpha.min((1.0 - CCD_SEPARATION) * h0 / (h0 - h1));
                }
                continue;
            }
            let mut disp = [Vec2::zeros(); 3];
            disp[slot as usize] = d;
            if let Some(t) = point_segment_toi(start, disp, CCD_SEPARATION) {
                alpha = alpha.min(t);
            }
        }
        alpha
    }

    /// One Newton step on every moving obstacle's pose (the soft vertices held at `x`):
    /// inertia or tether, weight, and the barrier and friction of its pairs, the step limited
    /// by the CCD and to `cap` metres of motion of any corner. Uses the pairs of the last
    /// `prepare`.
    pub(crate) fn body_step(&mut self, x: &[Vec2], cap: Real) {
        if self.bodies.is_empty() {
            return;
        }
        let n = self.n_extra;
        let mut g = vec![0.0; n];
        let mut hm = nalgebra::DMatrix::<Real>::zeros(n, n);
        let q = self.q.clone();
        self.derivatives(
            x,
            &q,
            &mut |d, v| {
                if let Dof::Extra(k) = d {
                    g[k] += v;
                }
            },
            Some(&mut |a, b, v| {
                if let (Dof::Extra(i), Dof::Extra(j)) = (a, b) {
                    hm[(i, j)] += v;
                }
            }),
        );
        // Each body's block is positive definite (inertia or tether) unless it is a free body
        // in statics, which VBD never is.
        let Some(chol) = hm.cholesky() else {
            return;
        };
        let step = chol.solve(&-nalgebra::DVector::from_vec(g));
        self.dq.copy_from_slice(step.as_slice());
        // The largest corner motion, capped.
        let mut motion: Real = 0.0;
        for b in &self.bodies {
            let r = self.radii[b.obstacle];
            let mut m = (self.dq[b.first].powi(2) + self.dq[b.first + 1].powi(2)).sqrt();
            if b.rotates {
                m += r * self.dq[b.first + 2].abs();
            }
            motion = motion.max(m);
        }
        let mut alpha: Real = if motion > cap { cap / motion } else { 1.0 };
        alpha = alpha.min(self.rotation_limit(x));
        for d in self.dq.iter_mut() {
            *d *= alpha;
        }
        // Half the gap at most: the soft vertices answer in the next sweep (a vertex's Newton
        // step on the barrier can about double its gap), so the two sides keep pace; closing
        // 90 % as the Newton solvers do would pin the gap near zero, jamming both.
        let mut still = std::mem::take(&mut self.still);
        still.clear();
        still.resize(x.len(), Vec2::zeros());
        let t = self.max_step_with(x, &still, 0.5);
        self.still = still;
        let mut q_new = std::mem::take(&mut self.q_end);
        self.trial_poses(t, &mut q_new);
        std::mem::swap(&mut self.q, &mut q_new);
        self.q_end = q_new;
    }

    /// The contacts found by the last [`BarrierContact::record`].
    pub(crate) fn contacts(&self) -> &[Contact] {
        &self.contacts
    }
}

/// The obstacles' target poses of a (sub)step of length `h` from `state`: the inertial
/// prediction `pose + h velocity` of a dynamic body, the schedule's pose at `t + h` of a
/// kinematic one (so a lag behind it never accumulates), the pose of a static one.
pub(crate) fn step_targets<E: Energy>(
    model: &Model<E>,
    state: &State,
    h: Real,
    targets: &mut Vec<[Real; 3]>,
) {
    targets.clear();
    for (obs, b) in model.obstacles().iter().zip(&state.bodies) {
        let target = match obs.motion() {
            ObstacleMotion::Dynamic { .. } => {
                let p = b.position + b.velocity * h;
                [p.x, p.y, b.angle + b.angular_velocity * h]
            }
            _ => obs
                .scheduled_pose(state.t + h)
                .unwrap_or([b.position.x, b.position.y, b.angle]),
        };
        targets.push(target);
    }
}

/// The obstacles' new states at the end of a (sub)step of length `h` with barrier contact:
/// poses from the solve, velocities from the motion (dynamic) or the schedule (kinematic).
pub(crate) fn end_poses<E: Energy>(
    c: &BarrierContact,
    model: &Model<E>,
    state: &State,
    h: Real,
    bodies_new: &mut Vec<BodyState>,
) {
    bodies_new.clone_from(&state.bodies);
    for (o, (obs, body)) in model
        .obstacles()
        .iter()
        .zip(bodies_new.iter_mut())
        .enumerate()
    {
        let q = c.q[o];
        let old = &state.bodies[o];
        match obs.motion() {
            ObstacleMotion::Dynamic { .. } => {
                body.velocity = (Vec2::new(q[0], q[1]) - old.position) / h;
                body.angular_velocity = (q[2] - old.angle) / h;
            }
            ObstacleMotion::Kinematic { .. } => {
                let mut scheduled = *old;
                obs.advance_kinematic(&mut scheduled, state.t, h);
                body.velocity = scheduled.velocity;
                body.angular_velocity = scheduled.angular_velocity;
            }
            ObstacleMotion::Static => {}
        }
        body.position = Vec2::new(q[0], q[1]);
        body.angle = q[2];
    }
}

/// A pair in words, for error messages.
fn describe(kind: &ContactKind) -> String {
    match *kind {
        ContactKind::VertexGround { vertex } => format!("vertex {vertex} and the ground"),
        ContactKind::VertexObstacle {
            vertex,
            obstacle,
            edge,
        } => format!("vertex {vertex} and obstacles[{obstacle}] edge {edge}"),
        ContactKind::CornerEdge {
            obstacle,
            corner,
            edge,
        } => format!(
            "obstacles[{obstacle}] corner {corner} and the edge {}-{}",
            edge[0], edge[1]
        ),
    }
}

/// A sort key of a pair's features.
fn key(kind: &ContactKind) -> (u8, u32, u32, u32, u32) {
    match *kind {
        ContactKind::VertexGround { vertex } => (0, vertex, 0, 0, 0),
        ContactKind::VertexObstacle {
            vertex,
            obstacle,
            edge,
        } => (1, obstacle, edge, vertex, 0),
        ContactKind::CornerEdge {
            obstacle,
            corner,
            edge,
        } => (2, obstacle, corner, edge[0], edge[1]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fem_core::energy::NeoHookean;
    use fem_core::material::Lame;
    use fem_core::structured::{RectangleParams, rectangle};

    /// A 1 m x 0.25 m strip on the ground (its bottom 0.4 mm above it) and a tilted dynamic
    /// triangle whose corner hangs 0.3 mm above the strip's top edge: every pair kind is
    /// within the activation distance (1 mm).
    fn scene() -> (Model<NeoHookean>, Vec<BodyState>) {
        let mesh = rectangle(&RectangleParams {
            origin: [0.0, 4e-4],
            ..RectangleParams::new(1.0, 0.25, 4, 1)
        })
        .unwrap();
        let energy = NeoHookean::new(Lame::new(3e3, 5e3).unwrap()).unwrap();
        let mut m = Model::with_total_mass(mesh, energy, 1.0).unwrap();
        m.set_ground(Some(Ground::horizontal(0.0))).unwrap();
        let top = 0.25 + 4e-4 + 3e-4;
        m.add_obstacle(
            &[
                Vec2::new(0.4, top),
                Vec2::new(0.7, top + 0.1),
                Vec2::new(0.35, top + 0.2),
            ],
            ObstacleMotion::Dynamic {
                mass: 2.0,
                rotates: true,
            },
        )
        .unwrap();
        let bodies = m.obstacles().iter().map(BodyState::initial).collect();
        (m, bodies)
    }

    /// Gradient of the contact energy (soft DOFs then extras) by the derivatives.
    fn gradient(c: &BarrierContact, x: &[Vec2], q: &[[Real; 3]]) -> Vec<Real> {
        let n = 2 * x.len();
        let mut g = vec![0.0; n + c.n_extra()];
        c.derivatives(
            x,
            q,
            &mut |d, v| match d {
                Dof::Soft(i) => g[i] += v,
                Dof::Extra(k) => g[n + k] += v,
            },
            None,
        );
        g
    }

    /// The unknowns as one vector and back.
    fn unpack(c: &BarrierContact, x0: &[Vec2], u: &[Real]) -> (Vec<Vec2>, Vec<[Real; 3]>) {
        let n = x0.len();
        let x = (0..n).map(|v| Vec2::new(u[2 * v], u[2 * v + 1])).collect();
        let mut q = c.q.clone();
        q[0] = [u[2 * n], u[2 * n + 1], u[2 * n + 2]];
        (x, q)
    }

    #[test]
    fn contact_energy_gradient_matches_finite_differences() {
        let (model, bodies) = scene();
        let x0 = model.mesh().vertices().to_vec();
        let mut c = BarrierContact::new(&model, 1e-4);
        // Targets away from the start so inertia and weight contribute; a small motion since
        // the start so the lagged friction is in both its sticking and sliding ranges.
        let targets = [[0.49, 0.36, 0.01]];
        c.begin(&x0, &bodies, &targets, 8100.0, Vec2::new(0.0, -9.8));
        assert!(c.lags.len() >= 3, "{} lagged contacts", c.lags.len());
        let kinds: Vec<u8> = c.pairs.iter().map(|p| key(&p.kind).0).collect();
        assert!(kinds.contains(&0) && kinds.contains(&1) && kinds.contains(&2));
        let mut u: Vec<Real> = x0.iter().flat_map(|p| [p.x, p.y]).collect();
        u.extend_from_slice(&c.q[0]);
        // Move a little, keeping every gap positive: some slips below eps_x, some above.
        for (k, v) in u.iter_mut().enumerate() {
            *v += 2e-5 * ((k as Real * 0.37).sin());
        }
        let (x, q) = unpack(&c, &x0, &u);
        c.prepare(&x, None);
        let g = gradient(&c, &x, &q);
        let h = 1e-8;
        let mut worst: Real = 0.0;
        let scale = g.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
        for k in 0..u.len() {
            let mut up = u.clone();
            up[k] += h;
            let (xp, qp) = unpack(&c, &x0, &up);
            let mut dn = u.clone();
            dn[k] -= h;
            let (xd, qd) = unpack(&c, &x0, &dn);
            let fd = (c.value(&xp, &qp).0 - c.value(&xd, &qd).0) / (2.0 * h);
            worst = worst.max((fd - g[k]).abs() / scale);
        }
        // Central differences with h = 1e-8 m on gaps of about 3e-4 m: truncation and
        // round-off both stay below 1e-5 of the largest gradient entry.
        assert!(worst < 1e-5, "worst relative gradient error {worst:e}");
    }

    #[test]
    fn contact_hessian_is_symmetric_positive_semidefinite() {
        let (model, bodies) = scene();
        let x0 = model.mesh().vertices().to_vec();
        let mut c = BarrierContact::new(&model, 1e-4);
        c.begin(&x0, &bodies, &[[0.49, 0.36, 0.01]], 8100.0, Vec2::zeros());
        let n = 2 * x0.len() + c.n_extra();
        let mut hm = nalgebra::DMatrix::<Real>::zeros(n, n);
        let nsoft = 2 * x0.len();
        let idx = |d: Dof| match d {
            Dof::Soft(i) => i,
            Dof::Extra(k) => nsoft + k,
        };
        let q = c.q.clone();
        c.derivatives(
            &x0,
            &q,
            &mut |_, _| {},
            Some(&mut |a, b, v| hm[(idx(a), idx(b))] += v),
        );
        let asym = (&hm - hm.transpose()).abs().max();
        assert!(asym <= 1e-12 * hm.abs().max(), "asymmetry {asym:e}");
        let min = hm.symmetric_eigenvalues().min();
        assert!(min >= -1e-9 * hm.abs().max(), "smallest eigenvalue {min:e}");
    }

    #[test]
    fn ccd_step_keeps_every_pair_apart_when_a_corner_is_driven_through_an_edge() {
        let (model, bodies) = scene();
        let x0 = model.mesh().vertices().to_vec();
        let mut c = BarrierContact::new(&model, 1e-4);
        c.begin(&x0, &bodies, &[[0.5, 0.3, 0.0]], 0.0, Vec2::zeros());
        // The body dives 5 cm (through the strip's top) while the strip stays.
        c.dq.copy_from_slice(&[0.0, -0.05, 0.0]);
        let dx = vec![Vec2::zeros(); x0.len()];
        c.prepare(&x0, Some(&dx));
        let alpha = c.max_step(&x0, &dx);
        assert!(alpha > 0.0 && alpha < 0.3e-3 / 0.05, "alpha {alpha}");
        let mut q = Vec::new();
        c.trial_poses(alpha, &mut q);
        c.q.clone_from(&q);
        let d = c.record(&x0);
        assert!(d > 0.0 && d < 3e-4, "distance after the step {d:e}");
        assert_eq!(c.start_overlap(&x0), None);
    }

    #[test]
    fn an_obstacle_moved_into_the_body_from_outside_is_named_at_the_start() {
        // A hand (outside the solver) puts the triangle's lower corner 1 cm into the strip:
        // the unsigned pair distances are all positive, the overlap is still found.
        let (model, bodies) = scene();
        let x0 = model.mesh().vertices().to_vec();
        let mut c = BarrierContact::new(&model, 1e-4);
        c.begin(&x0, &bodies, &[[0.5, 0.3, 0.0]], 0.0, Vec2::zeros());
        assert_eq!(c.start_overlap(&x0), None);
        c.q[0][1] -= 0.0107;
        c.prepare(&x0, None);
        assert_eq!(
            c.start_overlap(&x0).as_deref(),
            Some("obstacles[0] corner 0 inside the body")
        );
    }
}
