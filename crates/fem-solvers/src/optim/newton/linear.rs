//! The linearly implicit Euler step (Baraff & Witkin, "Large Steps in Cloth Simulation",
//! SIGGRAPH 1998; SOFA's `EulerImplicitSolver`): one linear solve of the Newton system of
//! implicit Euler per step, from the start of the step, and no Newton loop.
//!
//! **The step.** Implicit Euler minimises `Phi(x) = 1/(2 h^2) |x - x_hat|_M^2 + Psi(x) - f . x`
//! with `x_hat = x_n + h v_n` ([`super`]). At `x_n`, `grad Phi(x_n) = -M v_n / h - f(x_n)`
//! (`f(x_n)` the elastic and external forces), and one Newton step from there,
//! `(M / h^2 + K) dx = -grad Phi(x_n)`, multiplied by `h` with `dx = h v_{n+1}` is
//! `(M + h^2 K) v_{n+1} = M v_n + h f(x_n)`: Baraff and Witkin's step
//! `(M - h df/dv - h^2 df/dx) dv = h (f_n + h df/dx v_n)` with `df/dx = -K`, `df/dv = 0`. Rayleigh
//! damping `D = alpha M + beta K` (the force `-D v`, implicit in `v`: `df/dv = -D`) adds `h D`
//! to the left and `-h D v_n` to the right; with `dv = v_{n+1} - v_n` the terms in `v_n`
//! cancel and, divided by `h^2`,
//!
//! `(M (1/h^2 + alpha/h) + K (1 + beta/h)) dx = M v_n / h + f(x_n)`,
//! `x_{n+1} = x_n + dx`, `v_{n+1} = dx / h`.
//!
//! The right-hand side is `-grad Phi(x_n)` whatever the damping.
//!
//! **The matrix** is the Newton solver's own, assembled by the same code
//! (`NewtonSolver::assemble`): lumped masses, the **per-element PSD-projected** stiffness
//! (`Tangent::Projected`, what Newton uses, so the matrix is symmetric positive definite and
//! a step never climbs the potential's saddle; SOFA assembles the plain tangent, indefinite
//! under compression for StVK and Neo-Hookean), free rigid bodies' `J^T K J`, inertia and
//! rotational curvature in reduced coordinates ([`super::RigidUnknowns`]), grab springs,
//! barrier and friction Hessians and the moving obstacles' poses. With `s = 1 + beta/h` it is
//! assembled divided by `s`: `w M + K` with the inertia weight `w = (1/h^2 + alpha/h) / s`,
//! and the right-hand side is divided by `s` too, so no assembly needs another parameter.
//! `beta` scales every stiffness term (elastic, springs, barrier, friction) and `alpha` the
//! soft body's and its rigid regions' inertia; the obstacles' inertia and kinematic tethers
//! are kept undamped ([`BarrierContact::scale_weights`] divides them by `s` for the
//! assembly).
//!
//! **Linear solvers** ([`LinearSolver`]): faer's sparse Cholesky with the symbolic analysis
//! of the Newton solver (done once); or conjugate gradients on the assembled matrix (the upper
//! triangle in the factorisation's order, products summed in a fixed order, sequentially:
//! bit-identical for any number of threads) preconditioned by its diagonal (Jacobi) or by a
//! Cholesky factor refreshed every `refresh` steps (SOFA's `ShewchukPCGLinearSolver` with
//! `update_step`): between refreshes the factor of an older matrix preconditions the current
//! one. CG starts from zero and stops at `cg_iterations` or when the residual's 2-norm is at
//! most `cg_tolerance` times the right-hand side's.
//!
//! **Contact** (barrier, [`BarrierContact`]) enters as in implicit Euler's first Newton
//! iteration: its gradient and projected Hessian at `x_n` in the system, the moving obstacles'
//! poses as unknowns; the step is then shortened to the CCD bound
//! ([`BarrierContact::max_step`]), so every candidate pair stays apart.
//!
//! **Feasibility.** A step whose end has non-finite forces (an element inverted under an
//! energy that forbids it, such as Neo-Hookean's `log J`) or a touching contact pair is halved
//! (at most `max_halvings` times): there is no line search on the potential, only on the
//! energy's domain.
//!
//! **Report.** [`LinearReport::residual`] is the norm of `grad Phi(x_{n+1})` over the free
//! unknowns, N: the residual of the nonlinear implicit Euler step that was not solved (as
//! SOFA's `computeResidual`), so a budget can show what skipping Newton costs. It is the
//! undamped potential's gradient: with Rayleigh damping it also holds the damping force.
//!
//! A step allocates nothing (the buffers are [`LinearWork`] and the Newton solver's), except
//! the barrier Hessian's small point Jacobians, as in Newton.

use faer::dyn_stack::MemStack;
use faer::sparse::linalg::cholesky::LltRef;
use faer::{Conj, MatMut, Par};
use fem_core::clock::Stopwatch;
use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use super::{NewtonReport, NewtonSolver, Potential, RigidUnknowns};
use crate::contact::barrier::BarrierContact;
use crate::error::SolverError;
use crate::kernel::Inversion;

/// The linear solver of a linearly implicit step. Serde names: `direct`, `cg-jacobi`,
/// `cg-cholesky`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
pub enum LinearSolver {
    /// Sparse Cholesky (faer, AMD ordering, symbolic analysis once per stepper): the exact
    /// solve, one numeric factorisation a step. Default.
    #[default]
    Direct,
    /// Conjugate gradients preconditioned by the matrix's diagonal.
    CgJacobi,
    /// Conjugate gradients preconditioned by a Cholesky factor of the matrix, refreshed every
    /// `refresh` steps.
    CgCholesky,
}

/// The settings of one linearly implicit step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinearSettings {
    /// Time step `h`, s.
    pub h: Real,
    /// Rayleigh damping's mass factor `alpha`, 1/s.
    pub rayleigh_mass: Real,
    /// Rayleigh damping's stiffness factor `beta`, s.
    pub rayleigh_stiffness: Real,
    pub solver: LinearSolver,
    /// Most CG iterations.
    pub cg_iterations: usize,
    /// CG's relative residual tolerance (0: exactly `cg_iterations`).
    pub cg_tolerance: Real,
    /// Steps between refreshes of CG's Cholesky preconditioner (>= 1).
    pub refresh: usize,
    /// Most halvings of a step that leaves the energy's domain or touches.
    pub max_halvings: usize,
}

/// What one linearly implicit step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinearReport {
    /// CG iterations; 1 for the direct solver.
    pub iterations: usize,
    /// CG's relative residual `|b - A dx| / |b|` at its end (its recurrence's); 0 for the
    /// direct solver (not measured).
    pub cg_residual: Real,
    /// Whether the step factorised the matrix (the direct solver always; CG with the Cholesky
    /// preconditioner on refresh steps).
    pub factorised: bool,
    /// The norm of `grad Phi` over the free unknowns at the start of the step, N.
    pub start_residual: Real,
    /// The norm of `grad Phi` over the free unknowns at the end of the step, N: the residual
    /// of the implicit Euler step.
    pub residual: Real,
    /// The fraction of the linear solve's step taken: below 1 when the CCD, a rotating
    /// obstacle or the energy's domain shortened it.
    pub step_fraction: Real,
    /// Smallest `det F` at the end of the step.
    pub min_det_f: Real,
    /// Inverted elements at the end of the step.
    pub inverted: usize,
    /// Wall time of the gradient at the start and the matrix assembly, s (zero on
    /// `wasm32-unknown-unknown` without a host clock, as Newton's).
    pub assembly_seconds: Real,
    /// Wall time of the numeric Cholesky factorisation, s.
    pub factorisation_seconds: Real,
    /// Wall time of the linear solve (triangular solves or CG), s.
    pub solve_seconds: Real,
}

/// The buffers of the linearly implicit step beyond the Newton solver's, sized once.
#[derive(Clone, Debug, Default)]
pub(crate) struct LinearWork {
    /// CG's vectors, in the factorisation's order: right-hand side, solution, residual,
    /// preconditioned residual, direction and its product with the matrix.
    b: Vec<Real>,
    u: Vec<Real>,
    r: Vec<Real>,
    z: Vec<Real>,
    p: Vec<Real>,
    ap: Vec<Real>,
    /// Jacobi: the inverse diagonal.
    inv_diag: Vec<Real>,
    /// Steps since the Cholesky preconditioner was computed (`None`: never).
    since_refresh: Option<usize>,
}

impl LinearWork {
    /// Buffers for `solver` (its free unknowns).
    pub(crate) fn new(solver: &NewtonSolver) -> Self {
        let n = solver.n_free();
        LinearWork {
            b: vec![0.0; n],
            u: vec![0.0; n],
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            ap: vec![0.0; n],
            inv_diag: vec![0.0; n],
            since_refresh: None,
        }
    }
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl NewtonSolver {
    /// One linearly implicit Euler step (see the module docs): `x` holds the start `x_n` with
    /// the kinematic vertices already at their new positions and ends at `x_{n+1}`; the free
    /// rigid bodies start at the poses [`RigidUnknowns::begin`] recorded as the step's start
    /// (not its prediction) and end where [`RigidUnknowns::poses`] reads them; with `contact`
    /// (begun for this step, its pairs apart at `x`) the obstacles' poses `q` end at theirs.
    /// `p.weight` is `1/h^2` and `p.target` the inertial prediction.
    pub(crate) fn linear_step<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &mut [Vec2],
        settings: &LinearSettings,
        work: &mut LinearWork,
        contact: Option<&mut BarrierContact>,
    ) -> Result<LinearReport, SolverError> {
        let mut rq = std::mem::take(&mut self.rigid.q);
        let mut rtrial = std::mem::take(&mut self.rigid.trial);
        let rigid = std::mem::take(&mut self.rigid);
        let out = self.linear_step_with(
            p,
            x,
            settings,
            work,
            contact,
            (&rigid, &mut rq, &mut rtrial),
        );
        self.rigid = RigidUnknowns {
            q: rq,
            trial: rtrial,
            ..rigid
        };
        out
    }

    #[allow(clippy::type_complexity)]
    fn linear_step_with<E: Energy>(
        &mut self,
        p: &Potential<'_, E>,
        x: &mut [Vec2],
        settings: &LinearSettings,
        work: &mut LinearWork,
        mut contact: Option<&mut BarrierContact>,
        (rigid, rq, rtrial): (&RigidUnknowns, &mut Vec<[Real; 3]>, &mut Vec<[Real; 3]>),
    ) -> Result<LinearReport, SolverError> {
        let mut report = LinearReport::default();
        let h = settings.h;
        // Rayleigh's stiffness factor `s`: the system is assembled and solved divided by it.
        let scale = 1.0 + settings.rayleigh_stiffness / h;
        // The bodies linearise at the start of the step.
        rq.clone_from(&rigid.start);
        rigid.place(rq, x);
        let start = Stopwatch::start();
        if let Some(c) = contact.as_deref_mut() {
            c.prepare(x, None);
        }
        let first = self.gradient(
            p,
            x,
            contact.as_deref().map(|c| (c, &c.q[..])),
            (rigid, &rq[..]),
        );
        report.start_residual = first;
        if !first.is_finite() {
            return Err(SolverError::invalid(
                format!("{}.start", self.prefix),
                first,
                "the forces are not finite at the start of the step (an element inverted under an energy that forbids it)",
            ));
        }
        let matrix = Potential {
            mesh: p.mesh,
            energy: p.energy,
            masses: p.masses,
            weight: (p.weight + settings.rayleigh_mass / h) / scale,
            target: p.target,
            load: p.load,
            springs: p.springs,
        };
        if scale != 1.0
            && let Some(c) = contact.as_deref_mut()
        {
            c.scale_weights(1.0 / scale);
        }
        self.assemble(
            &matrix,
            x,
            contact.as_deref().map(|c| (c, &c.q[..])),
            (rigid, &rq[..]),
        );
        if scale != 1.0
            && let Some(c) = contact.as_deref_mut()
        {
            c.scale_weights(scale);
        }
        report.assembly_seconds = start.seconds();
        // The direction `-A^-1 grad Phi` into `self.direction`.
        let mut newton = NewtonReport::default();
        match settings.solver {
            LinearSolver::Direct => {
                self.factorise_assembled(&mut newton)?;
                report.factorised = true;
                let start = Stopwatch::start();
                self.solve();
                report.solve_seconds = start.seconds();
                report.iterations = 1;
            }
            LinearSolver::CgJacobi | LinearSolver::CgCholesky => {
                if settings.solver == LinearSolver::CgCholesky {
                    let due = work.since_refresh.is_none_or(|k| k + 1 >= settings.refresh);
                    if due {
                        self.factorise_assembled(&mut newton)?;
                        report.factorised = true;
                        work.since_refresh = Some(0);
                    } else {
                        work.since_refresh = work.since_refresh.map(|k| k + 1);
                    }
                }
                let start = Stopwatch::start();
                self.conjugate_gradients(settings, work, &mut report)?;
                report.solve_seconds = start.seconds();
            }
        }
        report.factorisation_seconds = newton.factorisation_seconds;
        if scale != 1.0 {
            for d in &mut self.direction {
                *d /= scale;
            }
        }
        // The step's largest fraction: the CCD bound with contact.
        let (mut alpha, mut bound) = (1.0, 1.0);
        let first_rigid = rigid.first;
        if let Some(c) = contact.as_deref_mut() {
            // A rotating obstacle turns little enough in one step for the CCD on its corners'
            // chords to hold: shorten the whole direction (as Newton does).
            c.dq.copy_from_slice(&self.direction[self.n_soft..first_rigid]);
            let limit = c.rotation_limit(x);
            if limit < 1.0 {
                for d in self.direction.iter_mut() {
                    *d *= limit;
                }
                alpha = limit;
            }
            c.dq.copy_from_slice(&self.direction[self.n_soft..first_rigid]);
            for (v, t) in self.trial.iter_mut().enumerate() {
                *t = Vec2::zeros();
                for d in 0..2 {
                    let j = self.free[2 * v + d];
                    if j != u32::MAX {
                        t[d] = self.direction[j as usize];
                    }
                }
            }
            c.prepare(x, Some(&self.trial));
            bound = c.max_step(x, &self.trial);
        }
        // From the CCD bound, halve while the end leaves the energy's domain or a pair
        // touches.
        let mut trial_q = std::mem::take(&mut self.trial_q);
        let mut trial = std::mem::take(&mut self.trial);
        let mut fraction = bound;
        let mut residual = Real::NAN;
        let mut accepted = false;
        for _ in 0..=settings.max_halvings {
            trial.copy_from_slice(x);
            for (v, t) in trial.iter_mut().enumerate() {
                for d in 0..2 {
                    let j = self.free[2 * v + d];
                    if j != u32::MAX {
                        t[d] += fraction * self.direction[j as usize];
                    }
                }
            }
            if let Some(c) = contact.as_deref() {
                c.trial_poses(fraction, &mut trial_q);
            }
            for (k, (t, q)) in rtrial.iter_mut().zip(rq.iter()).enumerate() {
                for d in 0..3 {
                    t[d] = q[d] + fraction * self.direction[first_rigid + 3 * k + d];
                }
            }
            rigid.place(rtrial, &mut trial);
            let apart = contact
                .as_deref()
                .is_none_or(|c| c.value(&trial, &trial_q).0.is_finite());
            if apart {
                // The pairs of the whole step include those near its end.
                residual = self.gradient(
                    p,
                    &trial,
                    contact.as_deref().map(|c| (c, &trial_q[..])),
                    (rigid, &rtrial[..]),
                );
                if residual.is_finite() {
                    accepted = true;
                    break;
                }
            }
            fraction *= 0.5;
        }
        if accepted {
            x.copy_from_slice(&trial);
            rq.clone_from(rtrial);
            if let Some(c) = contact {
                c.q.clone_from(&trial_q);
            }
        }
        self.trial = trial;
        self.trial_q = trial_q;
        if !accepted {
            return Err(SolverError::invalid(
                format!("{}.step", self.prefix),
                alpha * bound,
                format!(
                    "this fraction of the linear step and its {} halvings all leave the energy's domain (an inverted element) or touch an obstacle: lower dt",
                    settings.max_halvings
                ),
            ));
        }
        report.residual = residual;
        report.step_fraction = alpha * fraction;
        let inv = Inversion::of_mesh(p.mesh, x);
        report.min_det_f = inv.min_det_f;
        report.inverted = inv.inverted;
        Ok(report)
    }

    /// Conjugate gradients on the assembled matrix for `-grad Phi` (in `self.gradient`),
    /// preconditioned as `settings.solver` says (the Cholesky factor in `self.l_values`),
    /// into `self.direction`.
    fn conjugate_gradients(
        &mut self,
        settings: &LinearSettings,
        work: &mut LinearWork,
        report: &mut LinearReport,
    ) -> Result<(), SolverError> {
        let LinearWork {
            b,
            u,
            r,
            z,
            p,
            ap,
            inv_diag,
            ..
        } = work;
        for (&k, g) in self.position.iter().zip(&self.gradient) {
            b[k] = -g;
        }
        let jacobi = settings.solver == LinearSolver::CgJacobi;
        if jacobi {
            for (&k, &slot) in self.position.iter().zip(&self.diag) {
                inv_diag[k] = 1.0 / self.values[slot];
            }
        }
        u.fill(0.0);
        let b_norm = dot(b, b).sqrt();
        let (mut iterations, mut r_norm) = (0, b_norm);
        if b_norm > 0.0 {
            r.copy_from_slice(b);
            self.precondition(jacobi, inv_diag, r, z);
            p.copy_from_slice(z);
            let mut rz = dot(r, z);
            let target = settings.cg_tolerance * b_norm;
            while iterations < settings.cg_iterations {
                self.multiply(p, ap);
                let pap = dot(p, ap);
                if !pap.is_finite() {
                    return Err(SolverError::invalid(
                        format!("{}.hessian", self.prefix),
                        pap,
                        "is not finite (conjugate gradients)",
                    ));
                }
                if pap <= 0.0 {
                    break;
                }
                let a = rz / pap;
                for ((ui, ri), (pi, api)) in u.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&*ap))
                {
                    *ui += a * pi;
                    *ri -= a * api;
                }
                iterations += 1;
                r_norm = dot(r, r).sqrt();
                if r_norm <= target {
                    break;
                }
                self.precondition(jacobi, inv_diag, r, z);
                let rz_new = dot(r, z);
                let beta = rz_new / rz;
                rz = rz_new;
                for (pi, zi) in p.iter_mut().zip(&*z) {
                    *pi = zi + beta * *pi;
                }
            }
        }
        for (&k, d) in self.position.iter().zip(&mut self.direction) {
            *d = u[k];
        }
        report.iterations = iterations;
        report.cg_residual = if b_norm > 0.0 { r_norm / b_norm } else { 0.0 };
        Ok(())
    }

    /// `z = P^-1 r`: the inverse diagonal `inv_diag` (Jacobi) or the last Cholesky factor.
    fn precondition(&mut self, jacobi: bool, inv_diag: &[Real], r: &[Real], z: &mut [Real]) {
        if jacobi {
            for ((zi, ri), di) in z.iter_mut().zip(r).zip(inv_diag) {
                *zi = ri * di;
            }
            return;
        }
        z.copy_from_slice(r);
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        let rhs = MatMut::from_column_major_slice_mut(z, self.n_free, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut self.mem));
    }

    /// `y = A x` with the assembled symmetric matrix (its upper triangle stored, in the
    /// factorisation's order), summed in a fixed order.
    fn multiply(&self, x: &[Real], y: &mut [Real]) {
        y.fill(0.0);
        for j in 0..self.n_free {
            let xj = x[j];
            let mut column = 0.0;
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (i, a) = (self.row_idx[k], self.values[k]);
                if i == j {
                    column += a * xj;
                } else {
                    y[i] += a * xj;
                    column += a * x[i];
                }
            }
            y[j] += column;
        }
    }
}
