//! The quasi-Newton stepper with barrier contact and free rigid bodies (the parent module's
//! docs, **Contact and rigid regions**): Newton's unknowns, potential and gradient
//! ([`NewtonSolver::gradient`]), the barrier's terms and CCD, and L-BFGS with an initial
//! Hessian that adds the bodies and the moving obstacles to the Projective Dynamics matrix.
//!
//! **Unknowns**, packed: the free soft vertices' x, then their y (the PD matrix's two
//! right-hand sides), then the moving obstacles' pose components (the barrier's extra
//! unknowns), then three per free rigid body `q = (p_x, p_y, theta)` (Newton's
//! [`RigidUnknowns`]).
//!
//! **Initial Hessian** `H0`, symmetric positive definite:
//! - soft block: `A = M / h^2 + L` (factorised once, as without contact);
//! - rigid bodies: the same quadratic model in the reduced coordinates, `J^T (M' / h^2 + L) J +
//!   diag(M, M, I) / h^2`, with the slaved vertices' `x_v = p + R(theta) r_v`,
//!   `J_v = [I | perp(R r_v)]` at the poses the step starts from and `M'` the lumped masses
//!   without the bodies' vertices (their inertia is the body's). Its soft-body block is
//!   `C(theta) = C_x, C_y, cos(theta) U + sin(theta) V` per body, `U`, `V` the rotation column
//!   at `theta = 0` and `pi / 2`, so `A^-1 C` is four columns per body solved once, when the
//!   stepper is built, and the bodies' block is solved each step through the Schur complement
//!   `S = D - C^T A^-1 C` (a dense `3 n_b` square, Cholesky), which is at least
//!   `diag(M, M, I) / h^2`;
//! - moving obstacles: their diagonal weights (inertia `M / h^2`, `I / h^2`, or a kinematic
//!   obstacle's tether), exact without contact.
//!
//! A direction costs the PD solve, a dot product and an update per body column, and a
//! `3 n_b` triangular solve. The [`NewtonSolver`] is built as implicit Euler's is (the symbolic
//! analysis of its Hessian's pattern, unused here, done once with it): its unknowns, gradient
//! and rigid bodies are what this path shares with Newton instead of copying them.

use fem_core::assembly::Scratch;
use fem_core::energy::Energy;
use fem_core::energy::EnergyOf as _;
use fem_core::math::{Real, Vec2, sin_cos};

use super::{
    QuasiNewtonParams, QuasiNewtonReport, QuasiNewtonStepper, dot, overflowing_start, stalled,
};
use crate::contact::Contact;
use crate::contact::barrier::{BarrierContact, end_poses, step_targets};
use crate::error::SolverError;
use crate::model::Model;
use crate::model::state::State;
use crate::optim::newton::{NewtonSolver, Potential, RigidUnknowns, force_scale};
use crate::optim::pd_system::PdSystem;
use crate::rigid::BodyState;
use crate::steppers::implicit::{external_load, inertial_masses};
use crate::steppers::integrator::{
    Integrator, bdf2_body_velocity, bdf2_obstacle_targets, bdf2_obstacle_velocities,
    bdf2_pose_target,
};
use crate::steppers::report::StepReport;
use crate::steppers::vbd::{commit_positions, inversion};

/// The free rigid bodies' part of the initial Hessian (see the module docs).
#[derive(Debug, Default)]
struct Bodies {
    /// Each free body's index in the model's rigid bodies, its mass and its inertia.
    index: Vec<usize>,
    mass: Vec<Real>,
    inertia: Vec<Real>,
    /// Each body's coupling columns `C_x, C_y, U, V`, sparse over the packed soft unknowns.
    columns: Vec<[Vec<(u32, Real)>; 4]>,
    /// The PD weights `L_ab` between two vertices of free bodies: (body of `a`, body of `b`,
    /// rest offsets `r_a`, `r_b`, `L_ab`).
    inner: Vec<(u32, u32, Vec2, Vec2, Real)>,
    /// This step: each body's `(cos, sin)` of its angle, the Cholesky factor of the bodies'
    /// block (`3 n_b` square, row-major lower triangle), the block `D` itself (the bodies'
    /// vertices' PD weights through their Jacobians and the inertia), whether the factor is the
    /// Schur complement's (else `D`'s alone: the coupling left out when round-off made `S`
    /// indefinite), and a right-hand side.
    cs: Vec<(Real, Real)>,
    factor: Vec<Real>,
    block: Vec<Real>,
    coupled: bool,
    rhs: Vec<Real>,
}

/// `A^-1` of the bodies' coupling columns for one PD matrix, and their Gram matrix
/// `C_{k,a} . A^-1 C_{l,b}` (`4 n_b` square, row-major).
#[derive(Debug, Default)]
struct Solved {
    columns: Vec<[Vec<Real>; 4]>,
    gram: Vec<Real>,
}

/// The initial Hessian beyond the PD matrix (see the module docs).
#[derive(Debug)]
struct InitialHessian {
    /// Free soft vertices and contact unknowns.
    n: usize,
    n_c: usize,
    /// Each contact unknown's weight in this step.
    extra_weight: Vec<Real>,
    bodies: Bodies,
    /// For backward Euler's matrix and BDF2's.
    solved: Solved,
    bdf2_solved: Option<Solved>,
}

impl InitialHessian {
    /// Set up the bodies' block for a step from the poses `q` with inertia weight `w`
    /// (`bdf2`: for BDF2's matrix).
    fn begin(&mut self, q: &[[Real; 3]], w: Real, bdf2: bool) {
        let solved = match (&self.bdf2_solved, bdf2) {
            (Some(s), true) => s,
            _ => &self.solved,
        };
        self.bodies.begin(q, w, solved);
    }

    /// `H0^-1` of the packed vector `d`, in place; `system` solves the soft block, `bdf2`
    /// says which matrix it is.
    fn apply(&mut self, d: &mut [Real], system: &mut PdSystem, bdf2: bool) {
        let two_n = 2 * self.n;
        system.solve(&mut d[..two_n]);
        let solved = match (&self.bdf2_solved, bdf2) {
            (Some(s), true) => s,
            _ => &self.solved,
        };
        self.bodies.apply(d, two_n, two_n + self.n_c, solved);
        for (d, w) in d[two_n..two_n + self.n_c]
            .iter_mut()
            .zip(&self.extra_weight)
        {
            *d /= w;
        }
    }
}

/// The coupled path's unknowns, contact and buffers.
#[derive(Debug)]
pub(super) struct Coupled {
    /// Newton's unknowns (soft, contact, rigid), gradient and rigid bodies.
    newton: NewtonSolver,
    /// Barrier contact, when the model has a ground or obstacles.
    contact: Option<BarrierContact>,
    /// The lumped masses, zero on the free rigid bodies' vertices.
    masses: Vec<Real>,
    /// Free soft vertices, contact unknowns, free rigid bodies.
    n: usize,
    n_c: usize,
    n_b: usize,
    /// Each contact unknown's obstacle and pose component.
    extras: Vec<(usize, usize)>,
    h0: InitialHessian,
    /// Buffers: a move per vertex (the CCD's), the move of every unknown (L-BFGS's `s`), the
    /// bodies' poses and trial poses, the obstacles' trial poses and targets, the bodies'
    /// BDF2 targets, the new obstacle and body states.
    dx: Vec<Vec2>,
    s: Vec<Real>,
    rq: Vec<[Real; 3]>,
    rtrial: Vec<[Real; 3]>,
    trial_q: Vec<[Real; 3]>,
    targets: Vec<[Real; 3]>,
    rigid_targets: Vec<[Real; 3]>,
    bodies_new: Vec<BodyState>,
    rigid_new: Vec<BodyState>,
    min_distance: Real,
}

/// `R l` for `R` the rotation with cosine `c` and sine `s`.
#[inline]
fn rotate((c, s): (Real, Real), l: Vec2) -> Vec2 {
    Vec2::new(c * l.x - s * l.y, s * l.x + c * l.y)
}

/// `a . b` with `a` sparse.
#[inline]
fn sparse_dot(a: &[(u32, Real)], b: &[Real]) -> Real {
    a.iter().map(|&(i, v)| v * b[i as usize]).sum()
}

/// Cholesky `a = L L^T` in place (`m` square, row-major, the lower triangle read and
/// written); false when a pivot falls below `floor[j]` (or is not finite).
fn cholesky(a: &mut [Real], m: usize, floor: impl Fn(usize) -> Real) -> bool {
    for j in 0..m {
        let mut d = a[j * m + j];
        for k in 0..j {
            d -= a[j * m + k] * a[j * m + k];
        }
        if !(d.is_finite() && d >= floor(j)) {
            return false;
        }
        let d = d.sqrt();
        a[j * m + j] = d;
        for i in j + 1..m {
            let mut s = a[i * m + j];
            for k in 0..j {
                s -= a[i * m + k] * a[j * m + k];
            }
            a[i * m + j] = s / d;
        }
    }
    true
}

/// Solve `L L^T z = b` in place with the factor of [`cholesky`].
fn cholesky_solve(l: &[Real], m: usize, b: &mut [Real]) {
    for i in 0..m {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * m + k] * b[k];
        }
        b[i] = s / l[i * m + i];
    }
    for i in (0..m).rev() {
        let mut s = b[i];
        for k in i + 1..m {
            s -= l[k * m + i] * b[k];
        }
        b[i] = s / l[i * m + i];
    }
}

impl Solved {
    /// Solve the coupling columns `dense` with `system`.
    fn new(
        dense: &[[Vec<Real>; 4]],
        sparse: &[[Vec<(u32, Real)>; 4]],
        system: &mut PdSystem,
    ) -> Self {
        let columns: Vec<[Vec<Real>; 4]> = dense
            .iter()
            .map(|cols| {
                let mut out = cols.clone();
                for c in out.iter_mut() {
                    system.solve(c);
                }
                out
            })
            .collect();
        let m = 4 * columns.len();
        let mut gram = vec![0.0; m * m];
        for (k, ck) in sparse.iter().enumerate() {
            for (a, c) in ck.iter().enumerate() {
                for (l, wl) in columns.iter().enumerate() {
                    for (b, w) in wl.iter().enumerate() {
                        gram[(4 * k + a) * m + 4 * l + b] = sparse_dot(c, w);
                    }
                }
            }
        }
        Solved { columns, gram }
    }
}

impl Bodies {
    /// The bodies' block of the initial Hessian at the poses `q` with inertia weight `w`,
    /// factorised (see the module docs).
    fn begin(&mut self, q: &[[Real; 3]], w: Real, solved: &Solved) {
        let nb = self.index.len();
        if nb == 0 {
            return;
        }
        let m = 3 * nb;
        for (cs, q) in self.cs.iter_mut().zip(q) {
            let (s, c) = sin_cos(q[2]);
            *cs = (c, s);
        }
        // D: the PD weights between the bodies' vertices through their Jacobians, and the
        // bodies' inertia.
        self.block.fill(0.0);
        for &(k, l, ra, rb, lab) in &self.inner {
            let (k, l) = (k as usize, l as usize);
            let pa = rotate(self.cs[k], ra);
            let pb = rotate(self.cs[l], rb);
            let jj = [
                [1.0, 0.0, -pb.y],
                [0.0, 1.0, pb.x],
                [-pa.y, pa.x, pa.dot(&pb)],
            ];
            for (i, row) in jj.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    self.block[(3 * k + i) * m + 3 * l + j] += lab * v;
                }
            }
        }
        for k in 0..nb {
            let (mass, inertia) = (w * self.mass[k], w * self.inertia[k]);
            self.block[3 * k * m + 3 * k] += mass;
            self.block[(3 * k + 1) * m + 3 * k + 1] += mass;
            self.block[(3 * k + 2) * m + 3 * k + 2] += inertia;
        }
        // Pivots of S are at least the inertia's (S = S0 + diag, S0 positive semi-definite):
        // half of it is the floor below which round-off has taken over.
        let (mass, inertia) = (&self.mass, &self.inertia);
        let floor = |j: usize| {
            0.5 * w
                * match j % 3 {
                    2 => inertia[j / 3],
                    _ => mass[j / 3],
                }
        };
        // S = D - E G E^T, E_k mapping (C_x, C_y, U, V) to (x, y, theta): rows (1, 0, 0, 0),
        // (0, 1, 0, 0), (0, 0, cos, sin).
        let g = &solved.gram;
        let mg = 4 * nb;
        self.factor.copy_from_slice(&self.block);
        for k in 0..nb {
            let ek = [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, self.cs[k].0, self.cs[k].1],
            ];
            for l in 0..nb {
                let el = [
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0, 0.0],
                    [0.0, 0.0, self.cs[l].0, self.cs[l].1],
                ];
                for (i, eki) in ek.iter().enumerate() {
                    for (j, elj) in el.iter().enumerate() {
                        let mut v = 0.0;
                        for (a, &ea) in eki.iter().enumerate() {
                            for (b, &eb) in elj.iter().enumerate() {
                                if ea != 0.0 && eb != 0.0 {
                                    v += ea * g[(4 * k + a) * mg + 4 * l + b] * eb;
                                }
                            }
                        }
                        self.factor[(3 * k + i) * m + 3 * l + j] -= v;
                    }
                }
            }
        }
        self.coupled = cholesky(&mut self.factor, m, floor);
        if !self.coupled {
            self.factor.copy_from_slice(&self.block);
            if !cholesky(&mut self.factor, m, floor) {
                // The inertia alone.
                self.factor.fill(0.0);
                for j in 0..m {
                    self.factor[j * m + j] = (2.0 * floor(j)).sqrt();
                }
            }
        }
    }

    /// Complete `H0^-1 r` for the bodies: `d[..2n]` holds `y = A^-1 r_soft`, `d[off..]` the
    /// bodies' `r`; writes `z = S^-1 (r - C^T y)` there and `y - A^-1 C z` into the soft part.
    fn apply(&mut self, d: &mut [Real], two_n: usize, off: usize, solved: &Solved) {
        let nb = self.index.len();
        if nb == 0 {
            return;
        }
        let m = 3 * nb;
        for k in 0..nb {
            let (c, s) = self.cs[k];
            let mut ct = [0.0; 3];
            if self.coupled {
                let y = &d[..two_n];
                let cols = &self.columns[k];
                ct = [
                    sparse_dot(&cols[0], y),
                    sparse_dot(&cols[1], y),
                    c * sparse_dot(&cols[2], y) + s * sparse_dot(&cols[3], y),
                ];
            }
            for i in 0..3 {
                self.rhs[3 * k + i] = d[off + 3 * k + i] - ct[i];
            }
        }
        cholesky_solve(&self.factor, m, &mut self.rhs);
        d[off..off + m].copy_from_slice(&self.rhs);
        if self.coupled {
            for k in 0..nb {
                let (c, s) = self.cs[k];
                let z = &self.rhs[3 * k..3 * k + 3];
                let coefficients = [z[0], z[1], z[2] * c, z[2] * s];
                for (w, a) in solved.columns[k].iter().zip(coefficients) {
                    for (d, w) in d[..two_n].iter_mut().zip(w) {
                        *d -= a * w;
                    }
                }
            }
        }
    }
}

/// The potential Newton minimises at the soft positions `x`, the obstacles' poses in
/// `contact` and the bodies' poses `rq`, and the sum of its terms' magnitudes.
fn value<E: Energy>(
    p: &Potential<'_, E>,
    rigid: &RigidUnknowns,
    contact: Option<(&BarrierContact, &[[Real; 3]])>,
    x: &[Vec2],
    rq: &[[Real; 3]],
    scratch: &mut Scratch,
) -> (Real, Real) {
    let (e, m) = p.value(x, scratch);
    let inertia = rigid.inertia(p.weight, rq);
    let (e, m) = (e + inertia, m + inertia);
    match contact {
        Some((c, q)) => {
            let (ce, cm) = c.value(x, q);
            (e + ce, m + cm)
        }
        None => (e, m),
    }
}

impl Coupled {
    /// The coupled path for `model` (a ground, obstacles or free rigid bodies): Newton's
    /// unknowns and barrier contact as implicit Euler sets them up, and the bodies' part of
    /// the initial Hessian for `system` (backward Euler's) and `bdf2_system`. `free` are the
    /// free soft vertices (increasing), `weights` the PD weights of the elastic mesh's
    /// elements.
    pub(super) fn new<E: Energy>(
        model: &Model<E>,
        params: &QuasiNewtonParams,
        free: &[u32],
        weights: &[Real],
        system: &mut PdSystem,
        bdf2_system: Option<&mut PdSystem>,
    ) -> Result<Self, SolverError> {
        let kinematic: Vec<usize> = model.kinematics().vertices().collect();
        let contact = model.has_contact().then(|| {
            BarrierContact::new(model, model.contact_params().friction_velocity * params.dt)
        });
        let (n_c, coupled) = match &contact {
            Some(c) => (c.n_extra(), c.coupled_vertices()),
            None => (0, &[][..]),
        };
        let newton = NewtonSolver::with_extra(
            model.elastic_mesh(),
            model.elastic_energies().nodal_pressure(),
            &kinematic,
            "quasi-newton",
            n_c,
            coupled,
            model.rigid_bodies(),
        )?;
        let mesh = model.elastic_mesh();
        let n_vertices = mesh.n_vertices();
        let n = free.len();
        debug_assert_eq!(
            newton.n_free(),
            2 * n + n_c + 3 * free_bodies(model).count()
        );
        let mut rank = vec![u32::MAX; n_vertices];
        for (k, &v) in free.iter().enumerate() {
            rank[v as usize] = k as u32;
        }
        // Each free body's vertices with their rest offsets.
        let mut slave = vec![(u32::MAX, Vec2::zeros()); n_vertices];
        let mut bodies = Bodies::default();
        for (k, (index, body)) in free_bodies(model).enumerate() {
            for (&v, &r) in body.vertices.iter().zip(&body.offsets) {
                slave[v as usize] = (k as u32, r);
            }
            bodies.index.push(index);
            bodies.mass.push(body.mass);
            bodies.inertia.push(body.inertia);
        }
        let n_b = bodies.index.len();
        // The coupling columns, dense (the right-hand sides of the solves), then sparse.
        let mut dense: Vec<[Vec<Real>; 4]> = (0..n_b)
            .map(|_| std::array::from_fn(|_| vec![0.0; 2 * n]))
            .collect();
        for ((tri, el), &we) in mesh.triangles().iter().zip(mesh.elements()).zip(weights) {
            let g = el.gradients();
            for a in 0..3 {
                for b in 0..3 {
                    let (va, vb) = (tri[a] as usize, tri[b] as usize);
                    let (kb, rb) = slave[vb];
                    if kb == u32::MAX {
                        continue;
                    }
                    // As the PD matrix's `L_ab` (`pd_system.rs`).
                    let l = we * g[a].dot(&g[b]);
                    let (ka, ra) = slave[va];
                    if ka != u32::MAX {
                        bodies.inner.push((ka, kb, ra, rb, l));
                        continue;
                    }
                    let f = rank[va];
                    if f == u32::MAX {
                        continue;
                    }
                    let (ix, iy) = (f as usize, n + f as usize);
                    let cols = &mut dense[kb as usize];
                    cols[0][ix] += l;
                    cols[1][iy] += l;
                    cols[2][ix] -= l * rb.y;
                    cols[2][iy] += l * rb.x;
                    cols[3][ix] -= l * rb.x;
                    cols[3][iy] -= l * rb.y;
                }
            }
        }
        bodies.columns = dense
            .iter()
            .map(|cols| {
                cols.each_ref().map(|c| {
                    (c.iter().enumerate())
                        .filter(|(_, v)| **v != 0.0)
                        .map(|(i, &v)| (i as u32, v))
                        .collect()
                })
            })
            .collect();
        let m = 3 * n_b;
        bodies.cs = vec![(1.0, 0.0); n_b];
        bodies.factor = vec![0.0; m * m];
        bodies.block = vec![0.0; m * m];
        bodies.rhs = vec![0.0; m];
        let solved = Solved::new(&dense, &bodies.columns, system);
        let bdf2_solved = match (params.integrator, bdf2_system) {
            (Integrator::Bdf2, Some(s)) => Some(Solved::new(&dense, &bodies.columns, s)),
            _ => None,
        };
        Ok(Coupled {
            newton,
            contact,
            masses: inertial_masses(model),
            n,
            n_c,
            n_b,
            extras: vec![(0, 0); n_c],
            h0: InitialHessian {
                n,
                n_c,
                extra_weight: vec![1.0; n_c],
                bodies,
                solved,
                bdf2_solved,
            },
            dx: vec![Vec2::zeros(); n_vertices],
            s: vec![0.0; 2 * n + n_c + m],
            rq: vec![[0.0; 3]; n_b],
            rtrial: vec![[0.0; 3]; n_b],
            trial_q: Vec::new(),
            targets: Vec::new(),
            rigid_targets: Vec::new(),
            bodies_new: Vec::new(),
            rigid_new: Vec::new(),
            min_distance: Real::INFINITY,
        })
    }

    /// Unknowns beyond the soft ones: the moving obstacles' and the free rigid bodies'.
    pub(super) fn n_extra(&self) -> usize {
        self.n_c + 3 * self.n_b
    }

    /// See [`QuasiNewtonStepper::min_distance`].
    pub(super) fn min_distance(&self) -> Real {
        self.min_distance
    }

    /// The contacts at the end of the last step.
    pub(super) fn contacts(&self) -> &[Contact] {
        match &self.contact {
            Some(c) => c.contacts(),
            None => &[],
        }
    }

    /// Newton's last gradient, packed.
    fn pack(&self, out: &mut [Real]) {
        let g = self.newton.last_gradient();
        let n = self.n;
        for k in 0..n {
            out[k] = g[2 * k];
            out[n + k] = g[2 * k + 1];
        }
        out[2 * n..].copy_from_slice(&g[2 * n..]);
    }
}

/// The model's free rigid bodies with their indices.
fn free_bodies<E: Energy>(
    model: &Model<E>,
) -> impl Iterator<Item = (usize, &crate::rigid::RigidBody)> {
    (model.rigid_bodies().iter().enumerate()).filter(|(_, b)| b.is_free())
}

impl QuasiNewtonStepper {
    /// One step with contact or free rigid bodies (see the module docs).
    pub(super) fn step_coupled<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        let QuasiNewtonStepper {
            params,
            decay,
            els,
            system,
            bdf2_system,
            history,
            bdf2: step_bdf2,
            forbids_inversion,
            psi_scale,
            free,
            target,
            load,
            x,
            trial,
            v_new,
            scratch,
            g,
            g_new,
            d,
            lbfgs,
            last,
            coupled,
            ..
        } = self;
        let cp = coupled.as_mut().expect("the coupled path");
        let (h, t) = (params.dt, state.t);
        let bdf2 = history.begin(state, h, model.layout());
        *step_bdf2 = bdf2;
        let (w, hh) = history.targets(bdf2, state, h, target);
        external_load(model, load);
        // Kinematic vertices go to their scheduled positions in the target and the unknowns;
        // the start is the target plus the external load's acceleration over the step.
        let kinematics = model.kinematics();
        kinematics.apply(t, h, t + h, &state.x, target, v_new);
        let masses = model.masses();
        for (i, xh) in target.iter().enumerate() {
            x[i] = *xh + load[i] * (hh / masses[i]);
        }
        kinematics.apply(t, h, t + h, &state.x, x, v_new);
        // The bodies aim at their inertial targets and start there plus their load's
        // acceleration (so free fall is exact from the start).
        {
            let rigid = cp.newton.rigid();
            if bdf2 {
                let prev = &history.prev.rigid;
                cp.rigid_targets.clear();
                cp.rigid_targets
                    .extend((state.rigid.iter().zip(prev)).map(|(b, p)| bdf2_pose_target(b, p, h)));
                rigid.begin_towards(&state.rigid, &cp.rigid_targets, x);
            } else {
                rigid.begin(&state.rigid, Some(h), x);
            }
            cp.rq.clone_from(&rigid.q);
        }
        let bodies = &cp.h0.bodies;
        for ((q, &index), (mass, inertia)) in
            (cp.rq.iter_mut().zip(&bodies.index)).zip(bodies.mass.iter().zip(&bodies.inertia))
        {
            let body = &model.rigid_bodies()[index];
            let (mut f, mut torque) = (Vec2::zeros(), 0.0);
            for &v in &body.vertices {
                let (l, r) = (load[v as usize], x[v as usize] - Vec2::new(q[0], q[1]));
                f += l;
                torque += r.x * l.y - r.y * l.x;
            }
            q[0] += hh * f.x / mass;
            q[1] += hh * f.y / mass;
            q[2] += hh * torque / inertia;
        }
        let rigid = std::mem::take(cp.newton.rigid());
        rigid.place(&cp.rq, x);
        if let Some(c) = cp.contact.as_mut() {
            step_targets(model, state, h, &mut cp.targets);
            if bdf2 {
                let prev = &history.prev.bodies;
                bdf2_obstacle_targets(model, &state.bodies, prev, h, &mut cp.targets);
            }
            c.begin(&state.x, &state.bodies, &cp.targets, w, model.gravity());
            if let Some(at) = c.start_overlap(&state.x) {
                *cp.newton.rigid() = rigid;
                return Err(SolverError::invalid(
                    "quasi-newton.contact",
                    at,
                    "barrier contact needs every soft vertex and obstacle apart at the start of a step (start the body above the ground and clear of obstacles)",
                ));
            }
            for ((e, weight), (o, k, w)) in
                (cp.extras.iter_mut().zip(&mut cp.h0.extra_weight)).zip(c.extra_unknowns())
            {
                *e = (o, k);
                *weight = w;
            }
            // Start from the guess as far as it stays free of contact (the bodies' poses
            // too, along the way to theirs).
            for (dv, (xn, x0)) in cp.dx.iter_mut().zip(x.iter().zip(&state.x)) {
                *dv = xn - x0;
            }
            c.dq.fill(0.0);
            c.prepare(&state.x, Some(&cp.dx));
            let alpha = c.max_step(&state.x, &cp.dx);
            if alpha < 1.0 {
                for ((xn, x0), dv) in x.iter_mut().zip(&state.x).zip(&cp.dx) {
                    *xn = x0 + dv * alpha;
                }
                for v in kinematics.vertices() {
                    x[v] = target[v];
                }
                for (q, s) in cp.rq.iter_mut().zip(&rigid.start) {
                    for i in 0..3 {
                        q[i] = s[i] + alpha * (q[i] - s[i]);
                    }
                }
                rigid.place(&cp.rq, x);
            }
            c.prepare(x, None);
        }
        let potential = Potential {
            mesh: model.elastic_mesh(),
            energy: model.elastic_energies(),
            masses: &cp.masses,
            weight: w,
            target: &target[..],
            load: &load[..],
            springs: model.springs(),
        };
        let mut report = QuasiNewtonReport::default();
        let (mut phi, mut magnitude) = value(
            &potential,
            &rigid,
            cp.contact.as_ref().map(|c| (c, &c.q[..])),
            x,
            &cp.rq,
            scratch,
        );
        if !phi.is_finite() || (*forbids_inversion && inversion(els, x).inverted > 0) {
            // The current positions (valid), kinematic vertices moved, bodies where they are.
            x.copy_from_slice(&state.x);
            kinematics.apply(t, h, t + h, &state.x, x, v_new);
            cp.rq.clone_from(&rigid.start);
            rigid.place(&cp.rq, x);
            if let Some(c) = cp.contact.as_mut() {
                c.prepare(x, None);
            }
            (phi, magnitude) = value(
                &potential,
                &rigid,
                cp.contact.as_ref().map(|c| (c, &c.q[..])),
                x,
                &cp.rq,
                scratch,
            );
            report.fallback_guess = true;
        }
        if !phi.is_finite() {
            *cp.newton.rigid() = rigid;
            let cause = crate::optim::newton::start_cause(&potential, x, cp.contact.as_ref());
            return Err(SolverError::invalid(
                "quasi-newton.initial_guess",
                phi,
                format!("the potential is not finite at the starting positions: {cause}"),
            ));
        }
        let (n, n_c) = (cp.n, cp.n_c);
        let off = 2 * n + n_c;
        let mut gnorm = cp.newton.gradient(
            &potential,
            x,
            cp.contact.as_ref().map(|c| (c, &c.q[..])),
            (&rigid, &cp.rq),
        );
        cp.pack(g);
        // Newton's force scale: the body's own unknowns' first gradient (soft vertices and
        // rigid bodies; an obstacle's tether would dwarf them), the load, and the elastic
        // forces on the free degrees of freedom at the start.
        let own = (g[..2 * n].iter().chain(&g[off..]))
            .map(|g| g * g)
            .sum::<Real>()
            .sqrt();
        let scale = force_scale(own, load, cp.newton.elastic_force());
        if let Err(e) = overflowing_start(gnorm, scale) {
            *cp.newton.rigid() = rigid;
            return Err(e);
        }
        // Whether any trial of the step had a finite potential, and whether any was taken.
        let (mut finite_trial, mut moved) = (false, false);
        report.force_scale = scale;
        report.residuals.push(gnorm);
        cp.h0.begin(&cp.rq, w, bdf2);
        lbfgs.clear();
        let soft = match (bdf2_system.as_mut(), bdf2) {
            (Some(s), true) => s,
            _ => system,
        };
        while report.iterations < params.iterations {
            if gnorm <= params.tolerance * scale {
                report.converged = true;
                break;
            }
            let mut slope = 0.0;
            for restart in [false, true] {
                if restart {
                    // Not a descent direction (round-off in the history): restart from H0.
                    lbfgs.clear();
                }
                lbfgs.direction(g, d, |d| cp.h0.apply(d, soft, bdf2));
                if let Some(c) = cp.contact.as_mut() {
                    // A rotating obstacle turns little enough in one line search for the CCD
                    // on its corners' chords to hold: shorten the whole direction.
                    c.dq.copy_from_slice(&d[2 * n..off]);
                    let limit = c.rotation_limit(x);
                    if limit < 1.0 {
                        for d in d.iter_mut() {
                            *d *= limit;
                        }
                    }
                }
                slope = dot(g, d);
                if slope < 0.0 && slope.is_finite() {
                    break;
                }
            }
            // The line search starts at the largest step the CCD allows.
            let mut alpha = 1.0;
            if let Some(c) = cp.contact.as_mut() {
                cp.dx.fill(Vec2::zeros());
                for (k, &v) in free.iter().enumerate() {
                    cp.dx[v as usize] = Vec2::new(d[k], d[n + k]);
                }
                c.dq.copy_from_slice(&d[2 * n..off]);
                c.prepare(x, Some(&cp.dx));
                alpha = c.max_step(x, &cp.dx);
            }
            let mut accepted = false;
            for _ in 0..=params.max_halvings {
                trial.copy_from_slice(x);
                for (k, &v) in free.iter().enumerate() {
                    trial[v as usize] += Vec2::new(d[k], d[n + k]) * alpha;
                }
                if let Some(c) = cp.contact.as_ref() {
                    c.trial_poses(alpha, &mut cp.trial_q);
                }
                for (k, (t, q)) in cp.rtrial.iter_mut().zip(&cp.rq).enumerate() {
                    for i in 0..3 {
                        t[i] = q[i] + alpha * d[off + 3 * k + i];
                    }
                }
                rigid.place(&cp.rtrial, trial);
                let cq = cp.contact.as_ref().map(|c| (c, &cp.trial_q[..]));
                let (e, m) = value(&potential, &rigid, cq, trial, &cp.rtrial, scratch);
                report.evaluations += 1;
                if !e.is_finite() {
                    alpha *= 0.5;
                    continue;
                }
                finite_trial = true;
                // Within the potential's round-off a trial that lowers the gradient is taken
                // instead, keeping the lower potential as the reference (no cycling), as in
                // Newton's line search.
                let armijo = e <= phi + 1e-4 * alpha * slope;
                let in_round_off = (e - phi).abs() <= 1e-12 * (magnitude + m + *psi_scale);
                let lowers_gradient = !armijo
                    && in_round_off
                    && cp
                        .newton
                        .gradient(&potential, trial, cq, (&rigid, &cp.rtrial))
                        < gnorm;
                if armijo || lowers_gradient {
                    phi = if armijo { e } else { phi.min(e) };
                    magnitude = m;
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            report.iterations += 1;
            moved |= accepted;
            if !accepted {
                if lbfgs.pairs > 0 {
                    // The pairs' curvature misled the direction (the barrier's changes fast):
                    // start again from H0 before giving up.
                    lbfgs.clear();
                    report.residuals.push(gnorm);
                    continue;
                }
                break;
            }
            // The move of every unknown, then the new state and its gradient.
            for (k, &v) in free.iter().enumerate() {
                let ds = trial[v as usize] - x[v as usize];
                cp.s[k] = ds.x;
                cp.s[n + k] = ds.y;
            }
            if let Some(c) = cp.contact.as_mut() {
                for (s, &(o, i)) in cp.s[2 * n..off].iter_mut().zip(&cp.extras) {
                    *s = cp.trial_q[o][i] - c.q[o][i];
                }
                c.q.clone_from(&cp.trial_q);
            }
            for (k, (t, q)) in cp.rtrial.iter().zip(&cp.rq).enumerate() {
                for i in 0..3 {
                    cp.s[off + 3 * k + i] = t[i] - q[i];
                }
            }
            std::mem::swap(x, trial);
            std::mem::swap(&mut cp.rq, &mut cp.rtrial);
            if let Some(c) = cp.contact.as_mut() {
                c.prepare(x, None);
            }
            gnorm = cp.newton.gradient(
                &potential,
                x,
                cp.contact.as_ref().map(|c| (c, &c.q[..])),
                (&rigid, &cp.rq),
            );
            cp.pack(g_new);
            lbfgs.remember(&cp.s, g_new, g);
            std::mem::swap(g, g_new);
            report.residuals.push(gnorm);
        }
        if gnorm <= params.tolerance * scale {
            report.converged = true;
        }
        if !moved && (report.fallback_guess || !finite_trial) && !report.converged {
            let halvings = params.max_halvings;
            if let Err(e) = stalled(x, trial, els, *forbids_inversion, halvings, gnorm) {
                *cp.newton.rigid() = rigid;
                return Err(e);
            }
        }
        *cp.newton.rigid() = rigid;
        // The bodies' new poses and velocities, as implicit Euler's.
        cp.rigid_new.clone_from(&state.rigid);
        for (q, &k) in cp.rq.iter().zip(&cp.h0.bodies.index) {
            let b = &mut cp.rigid_new[k];
            let (p, angle) = (Vec2::new(q[0], q[1]), q[2]);
            if bdf2 {
                let start = *b;
                b.position = p;
                b.angle = angle;
                bdf2_body_velocity(b, &start, &history.prev.rigid[k], h);
                b.velocity *= *decay;
                b.angular_velocity *= *decay;
            } else {
                b.velocity = (p - b.position) / h * *decay;
                b.angular_velocity = (angle - b.angle) / h * *decay;
                b.position = p;
                b.angle = angle;
            }
        }
        let mut contacts = 0;
        if let Some(c) = cp.contact.as_mut() {
            end_poses(c, model, state, h, &mut cp.bodies_new);
            if bdf2 {
                let prev = &history.prev.bodies;
                bdf2_obstacle_velocities(model, &state.bodies, prev, h, &mut cp.bodies_new);
            }
            cp.min_distance = c.record(x);
            contacts = c.contacts().len();
        }
        let inv = commit_positions(
            model,
            state,
            els,
            x,
            v_new,
            cp.contact.is_some().then_some(&mut cp.bodies_new),
            Some(&mut cp.rigid_new),
            h,
            t + h,
            *decay,
            true,
            bdf2.then_some(&history.prev.x[..]),
        )?;
        history.commit(state);
        let out = StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations: report.iterations,
            residual: gnorm,
            contacts,
        };
        *last = report;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::bc::Region;
    use crate::optim::pd_system::element_lame;
    use fem_core::energy::{ElementEnergies, NeoHookean};
    use fem_core::material::Lame;
    use fem_core::structured::{RectangleParams, rectangle};
    use nalgebra::{DMatrix, DVector};

    /// A 4 m x 1 m beam (8 x 2 cells, Neo-Hookean) whose cells between x = 1 and 1.5 m and
    /// between 2.5 and 3 m are two free rigid bodies, its left end pinned.
    fn beam_with_two_bodies() -> Model<NeoHookean> {
        let mesh = rectangle(&RectangleParams::new(4.0, 1.0, 8, 2)).unwrap();
        let tags: Vec<u32> = (0..mesh.n_triangles())
            .map(|t| {
                let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
                u32::from((c.x > 1.0 && c.x < 1.5) || (c.x > 2.5 && c.x < 3.0))
            })
            .collect();
        let energy = NeoHookean::new(Lame::new(3e3, 5e3).unwrap()).unwrap();
        let energies = ElementEnergies::new(vec![energy, energy], tags).unwrap();
        let masses = mesh.lumped_masses_from_density(2.0).unwrap();
        let mut model = Model::with_regions(mesh, energies, masses).unwrap();
        model.make_rigid(1, 2.0).unwrap();
        model
            .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
            .unwrap();
        model
    }

    /// The Schur complement applies the inverse of the PD quadratic model in the reduced
    /// coordinates at the bodies' poses, `J^T (M' w + L) J + w diag(M, M, I)`, assembled here
    /// densely over every vertex and its Jacobian: `H0 z = r` to round-off, at turned poses,
    /// for backward Euler's weight and BDF2's.
    #[test]
    fn the_initial_hessian_is_the_pd_model_in_reduced_coordinates() {
        let model = beam_with_two_bodies();
        assert_eq!(model.rigid_bodies().len(), 2);
        for integrator in [Integrator::BackwardEuler, Integrator::Bdf2] {
            let h = 1e-2;
            let p = QuasiNewtonParams {
                dt: h,
                integrator,
                ..QuasiNewtonParams::default()
            };
            let mut qn = QuasiNewtonStepper::new(&model, p).unwrap();
            let bdf2 = integrator == Integrator::Bdf2;
            let w = if bdf2 { 2.25 / (h * h) } else { 1.0 / (h * h) };
            let QuasiNewtonStepper {
                system,
                bdf2_system,
                coupled,
                free,
                ..
            } = &mut qn;
            let cp = coupled.as_mut().unwrap();
            let (n, nb) = (cp.n, cp.n_b);
            assert_eq!(nb, 2);
            let m = 2 * n + 3 * nb;
            // Poses: moved and turned.
            let rq: Vec<[Real; 3]> = (model.rigid_bodies().iter().zip([0.3, -0.7]))
                .map(|(b, a)| [b.centroid.x + 0.1, b.centroid.y - 0.2, a])
                .collect();
            cp.h0.begin(&rq, w, bdf2);
            assert!(cp.h0.bodies.coupled);
            // The full matrix over every vertex coordinate (x and y decouple).
            let mesh = model.elastic_mesh();
            let nv = mesh.n_vertices();
            let lame = element_lame(model.elastic_energies(), mesh.n_triangles());
            let mut a = DMatrix::<Real>::zeros(2 * nv, 2 * nv);
            for (v, m) in inertial_masses(&model).iter().enumerate() {
                for d in 0..2 {
                    a[(2 * v + d, 2 * v + d)] += w * m;
                }
            }
            for ((tri, el), &(mu, lambda)) in
                mesh.triangles().iter().zip(mesh.elements()).zip(&lame)
            {
                let g = el.gradients();
                for i in 0..3 {
                    for j in 0..3 {
                        let l = 2.0 * el.area * (mu + lambda) * g[i].dot(&g[j]);
                        for d in 0..2 {
                            a[(2 * tri[i] as usize + d, 2 * tri[j] as usize + d)] += l;
                        }
                    }
                }
            }
            // Its Jacobian in the packed reduced unknowns.
            let mut jac = DMatrix::<Real>::zeros(2 * nv, m);
            for (k, &v) in free.iter().enumerate() {
                jac[(2 * v as usize, k)] = 1.0;
                jac[(2 * v as usize + 1, n + k)] = 1.0;
            }
            let mut inertia = DMatrix::<Real>::zeros(m, m);
            for (b, (body, q)) in model.rigid_bodies().iter().zip(&rq).enumerate() {
                let base = 2 * n + 3 * b;
                for (&v, r) in body.vertices.iter().zip(&body.offsets) {
                    let (s, c) = sin_cos(q[2]);
                    let rho = rotate((c, s), *r);
                    let v = v as usize;
                    jac[(2 * v, base)] = 1.0;
                    jac[(2 * v, base + 2)] = -rho.y;
                    jac[(2 * v + 1, base + 1)] = 1.0;
                    jac[(2 * v + 1, base + 2)] = rho.x;
                }
                inertia[(base, base)] = w * body.mass;
                inertia[(base + 1, base + 1)] = w * body.mass;
                inertia[(base + 2, base + 2)] = w * body.inertia;
            }
            let hm = jac.transpose() * &a * &jac + inertia;
            let r = DVector::<Real>::from_fn(m, |i, _| (i as Real * 0.61).sin() + 0.3);
            let mut z: Vec<Real> = r.iter().copied().collect();
            let soft = match (bdf2_system.as_mut(), bdf2) {
                (Some(s), true) => s,
                _ => system,
            };
            cp.h0.apply(&mut z, soft, bdf2);
            let residual = (&hm * DVector::from_vec(z) - &r).norm() / r.norm();
            assert!(
                residual < 1e-10,
                "{integrator}: relative residual {residual:e}"
            );
            // Without the coupling the bodies' block alone is far from it.
            let mut z0: Vec<Real> = r.iter().copied().collect();
            cp.h0.bodies.coupled = false;
            cp.h0.bodies.factor.copy_from_slice(&cp.h0.bodies.block);
            assert!(cholesky(&mut cp.h0.bodies.factor, 3 * nb, |_| 0.0));
            cp.h0.apply(&mut z0, soft, bdf2);
            let uncoupled = (&hm * DVector::from_vec(z0) - &r).norm() / r.norm();
            eprintln!(
                "{integrator}: H0 z = r to {residual:.1e}; {uncoupled:.1e} without the coupling"
            );
            assert!(uncoupled > 1e-3);
        }
    }
}
