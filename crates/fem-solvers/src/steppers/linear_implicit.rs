//! Linearly implicit Euler (Baraff & Witkin, "Large Steps in Cloth Simulation", SIGGRAPH 1998;
//! SOFA's `EulerImplicitSolver`): one linear solve per step, no Newton loop.
//!
//! With `x_hat = x_n + h v_n` and implicit Euler's incremental potential
//! `Phi(x) = 1/(2 h^2) |x - x_hat|_M^2 + Psi(x) - f . x` ([`crate::implicit`]), each step is
//! one Newton iteration on `Phi` from the start of the step, with Rayleigh damping
//! `D = alpha M + beta K`:
//!
//! `(M (1/h^2 + alpha/h) + K(x_n) (1 + beta/h)) dx = -grad Phi(x_n) = M v_n / h + f(x_n)`,
//! `x_{n+1} = x_n + dx`, `v_{n+1} = dx / h` (then `v <- v exp(-c h)` with `damping`),
//!
//! with the per-element PSD-projected stiffness `K` (Newton's, so the matrix is symmetric
//! positive definite; SOFA uses the plain tangent). The derivation, the matrix (assembled by
//! the Newton solver's own code: masses, stiffness, free rigid bodies in reduced coordinates,
//! grab springs, barrier contact) and the linear solvers (sparse Cholesky, or conjugate
//! gradients preconditioned by the diagonal or by a Cholesky factor refreshed every `refresh`
//! steps) are in `optim/newton/linear.rs` ([`crate::newton::LinearSolver`]).
//!
//! Kinematic vertices follow their schedule: they stand at their new positions where the
//! system is linearised, so the free vertices feel their motion in the same step. With a
//! ground or obstacles, barrier contact's gradient and Hessian at the start join the system,
//! the moving obstacles' poses are unknowns, and the step is shortened to the CCD bound so every
//! pair stays apart; the body must start apart from them, as for implicit Euler. A step
//! whose end would invert an element under an energy that forbids it (or touch) is halved.
//!
//! The report's iterations are CG's (1 for the direct solver); its residual is the norm of
//! `grad Phi(x_{n+1})` over the free unknowns, the residual of the implicit Euler step it did
//! not solve. It converges to the exact solution as `dt -> 0` at first order, as implicit
//! Euler does (`tests/suite/linear_implicit.rs`).
//!
//! Registered as `linear-implicit` ([`Solver`]); scene keys `dt`, `damping`, `rayleigh_mass`,
//! `rayleigh_stiffness`, `linear_solver`, `cg_iterations`, `cg_tolerance`, `refresh`,
//! `max_halvings`.

use fem_core::energy::Energy;
use fem_core::energy::EnergyOf as _;
use fem_core::math::{Real, Vec2, exp};

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::barrier::{BarrierContact, end_poses, step_targets};
use crate::error::{
    SolverError, check_at_most, check_count, check_non_negative, check_positive,
    check_residual_tolerance,
};
use crate::model::Model;
use crate::model::limits;
use crate::model::state::State;
use crate::optim::newton::{
    LinearReport, LinearSettings, LinearSolver, LinearWork, NewtonSolver, Potential,
};
use crate::rigid::BodyState;
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::implicit::{external_load, inertial_masses};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// Parameters of [`LinearImplicitStepper`] (scene keys: the field names).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct LinearImplicitParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c dt)` each step; finite, >= 0). Default 0.
    pub damping: Real,
    /// Rayleigh damping's mass factor `alpha`, 1/s (`D = alpha M + beta K`; finite, >= 0).
    /// Default 0.
    pub rayleigh_mass: Real,
    /// Rayleigh damping's stiffness factor `beta`, s (finite, >= 0). Default 0.
    pub rayleigh_stiffness: Real,
    /// The linear solver: `direct` (sparse Cholesky), `cg-jacobi` or `cg-cholesky`. Default
    /// `direct`.
    pub linear_solver: LinearSolver,
    /// Most conjugate-gradient iterations per step (1 to 100,000; CG only). Default 25, as in
    /// SOFA's tutorials.
    pub cg_iterations: usize,
    /// CG stops once its residual's 2-norm is at most this fraction of the right-hand side's;
    /// in `[0, 1)`, 0 runs exactly `cg_iterations`. Default `1e-5`.
    pub cg_tolerance: Real,
    /// `cg-cholesky`: steps between refreshes of the Cholesky preconditioner (1 to 100,000;
    /// 1 refactorises every step, when CG needs a single iteration). Default 10.
    pub refresh: usize,
    /// Most halvings of a step whose end leaves the energy's domain or touches (at most 200).
    /// Default 40.
    pub max_halvings: usize,
}

impl Default for LinearImplicitParams {
    fn default() -> Self {
        LinearImplicitParams {
            dt: 1e-3,
            damping: 0.0,
            rayleigh_mass: 0.0,
            rayleigh_stiffness: 0.0,
            linear_solver: LinearSolver::Direct,
            cg_iterations: 25,
            cg_tolerance: 1e-5,
            refresh: 10,
            max_halvings: 40,
        }
    }
}

impl LinearImplicitParams {
    /// Check every field; errors name `linear-implicit.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(LinearImplicitStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_non_negative(&field("damping"), self.damping)?;
        check_non_negative(&field("rayleigh_mass"), self.rayleigh_mass)?;
        check_non_negative(&field("rayleigh_stiffness"), self.rayleigh_stiffness)?;
        check_count(
            &field("cg_iterations"),
            self.cg_iterations,
            limits::MAX_ITERATIONS,
        )?;
        check_residual_tolerance(&field("cg_tolerance"), self.cg_tolerance)?;
        check_count(&field("refresh"), self.refresh, limits::MAX_ITERATIONS)?;
        check_at_most(
            &field("max_halvings"),
            self.max_halvings,
            limits::MAX_HALVINGS,
        )
    }

    fn settings(&self) -> LinearSettings {
        LinearSettings {
            h: self.dt,
            rayleigh_mass: self.rayleigh_mass,
            rayleigh_stiffness: self.rayleigh_stiffness,
            solver: self.linear_solver,
            cg_iterations: self.cg_iterations,
            cg_tolerance: self.cg_tolerance,
            refresh: self.refresh,
            max_halvings: self.max_halvings,
        }
    }
}

/// Linearly implicit Euler: one linear solve of implicit Euler's Newton system per step.
#[derive(Debug)]
pub struct LinearImplicitStepper {
    params: LinearImplicitParams,
    decay: Real,
    n_triangles: usize,
    solver: NewtonSolver,
    work: LinearWork,
    target: Vec<Vec2>,
    load: Vec<Vec2>,
    x_new: Vec<Vec2>,
    v_new: Vec<Vec2>,
    last: LinearReport,
    /// The model layout the free degrees of freedom were analysed for.
    layout: u64,
    /// Barrier contact, when the model has a ground or obstacles.
    contact: Option<BarrierContact>,
    /// The obstacles' target poses of the step and their new states.
    targets: Vec<[Real; 3]>,
    bodies_new: Vec<BodyState>,
    /// The rigid regions' new poses.
    rigid_new: Vec<BodyState>,
    /// The lumped masses, zero on the vertices of free rigid bodies.
    masses: Vec<Real>,
    /// The smallest distance over the candidate pairs at the end of the last step, m.
    min_distance: Real,
}

impl LinearImplicitStepper {
    /// A stepper for `model`: validates the parameters, sets up barrier contact when the model
    /// has a ground or obstacles, and does the symbolic analysis of the matrix's pattern.
    pub fn new<E: Energy>(
        model: &Model<E>,
        params: LinearImplicitParams,
    ) -> Result<Self, SolverError> {
        params.validate()?;
        let kinematic: Vec<usize> = model.kinematics().vertices().collect();
        let contact = model.has_contact().then(|| {
            BarrierContact::new(model, model.contact_params().friction_velocity * params.dt)
        });
        let (n_extra, coupled) = match &contact {
            Some(c) => (c.n_extra(), c.coupled_vertices()),
            None => (0, &[][..]),
        };
        let solver = NewtonSolver::with_extra(
            model.elastic_mesh(),
            model.elastic_energies().nodal_pressure(),
            &kinematic,
            Self::NAME,
            n_extra,
            coupled,
            model.rigid_bodies(),
        )?;
        let n = model.mesh().n_vertices();
        Ok(LinearImplicitStepper {
            work: LinearWork::new(&solver),
            contact,
            targets: Vec::new(),
            bodies_new: Vec::new(),
            rigid_new: Vec::new(),
            masses: inertial_masses(model),
            min_distance: Real::INFINITY,
            layout: model.layout(),
            decay: exp(-params.damping * params.dt),
            params,
            n_triangles: model.mesh().n_triangles(),
            solver,
            target: vec![Vec2::zeros(); n],
            load: vec![Vec2::zeros(); n],
            x_new: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            last: LinearReport::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &LinearImplicitParams {
        &self.params
    }

    /// What the last step did (CG iterations and residual, whether it factorised, the step
    /// fraction taken, the implicit Euler residuals at its start and end, the time split).
    pub fn last_linear(&self) -> &LinearReport {
        &self.last
    }

    /// Free unknowns of the linear systems.
    pub fn unknowns(&self) -> usize {
        self.solver.n_free()
    }

    /// The smallest distance between the soft body and the ground or an obstacle over the
    /// candidate pairs at the end of the last step, m (infinite when nothing is near, or
    /// without contact).
    pub fn min_distance(&self) -> Real {
        self.min_distance
    }
}

impl Stepper for LinearImplicitStepper {
    fn dt(&self) -> Real {
        self.params.dt
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        if model.layout() != self.layout {
            *self = LinearImplicitStepper::new(model, self.params)?;
        }
        let (h, t) = (self.params.dt, state.t);
        external_load(model, &mut self.load);
        for ((xh, x), v) in self.target.iter_mut().zip(&state.x).zip(&state.v) {
            *xh = x + h * v;
        }
        // Kinematic vertices go to their scheduled positions (in the target, where they are
        // ignored, and in the start of the linearisation, where they are held).
        model
            .kinematics()
            .apply(t, h, t + h, &state.x, &mut self.target, &mut self.v_new);
        self.x_new.copy_from_slice(&state.x);
        for v in model.kinematics().vertices() {
            self.x_new[v] = self.target[v];
        }
        self.solver
            .rigid()
            .begin(&state.rigid, Some(h), &mut self.x_new);
        let potential = Potential {
            mesh: model.elastic_mesh(),
            energy: model.elastic_energies(),
            masses: &self.masses,
            weight: 1.0 / (h * h),
            target: &self.target,
            load: &self.load,
            springs: model.springs(),
        };
        if let Some(c) = self.contact.as_mut() {
            step_targets(model, state, h, &mut self.targets);
            c.begin(
                &state.x,
                &state.bodies,
                &self.targets,
                1.0 / (h * h),
                model.gravity(),
            );
            if let Some(at) = c.start_overlap(&state.x) {
                return Err(SolverError::invalid(
                    "linear-implicit.contact",
                    at,
                    "barrier contact needs every soft vertex and obstacle apart at the start of a step (start the body above the ground and clear of obstacles)",
                ));
            }
        }
        let report = self.solver.linear_step(
            &potential,
            &mut self.x_new,
            &self.params.settings(),
            &mut self.work,
            self.contact.as_mut(),
        )?;
        for ((v, xn), x) in self.v_new.iter_mut().zip(&self.x_new).zip(&state.x) {
            *v = (xn - x) / h * self.decay;
        }
        self.rigid_new.clone_from(&state.rigid);
        for (k, q) in self.solver.rigid().poses() {
            let b = &mut self.rigid_new[k];
            let (p, angle) = (Vec2::new(q[0], q[1]), q[2]);
            b.velocity = (p - b.position) / h * self.decay;
            b.angular_velocity = (angle - b.angle) / h * self.decay;
            b.position = p;
            b.angle = angle;
        }
        let mut contacts = 0;
        if let Some(c) = self.contact.as_mut() {
            end_poses(c, model, state, h, &mut self.bodies_new);
            self.min_distance = c.record(&self.x_new);
            contacts = c.contacts().len();
        }
        StepEnd {
            kinematics: Kinematic::Schedule {
                t,
                dt: h,
                until: t + h,
            },
            x: &mut self.x_new,
            v: &mut self.v_new,
            bodies: self.contact.is_some().then_some(&mut self.bodies_new),
            rigid: Some(&mut self.rigid_new),
            known_finite: false,
            inverted: report.inverted,
            min_det_f: report.min_det_f,
            t_end: t + h,
            count_step: true,
        }
        .commit(model, state, || Ok(()))?;
        let out = StepReport {
            min_det_f: report.min_det_f,
            inverted: report.inverted,
            iterations: report.iterations,
            residual: report.residual,
            contacts,
        };
        self.last = report;
        Ok(out)
    }

    fn contacts(&self) -> &[Contact] {
        match &self.contact {
            Some(c) => c.contacts(),
            None => &[],
        }
    }
}

impl Solver for LinearImplicitStepper {
    type Params = LinearImplicitParams;
    const NAME: &'static str = "linear-implicit";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Linearly implicit Euler",
        summary: "linearly implicit Euler (Baraff & Witkin 1998, SOFA's EulerImplicitSolver): one linear solve of implicit Euler's Newton system per step (sparse Cholesky or preconditioned CG), Rayleigh damping",
        paper: false,
        contact: true,
        rigid_regions: true,
        averaged_pressure: true,
        dims: 2,
        implicit: true,
        iterations: false,
        substeps: false,
        factorisation: true,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "the exact solution as dt -> 0 (first order); each step one Newton iteration of implicit Euler's, not its solution",
    };

    fn validate_params(p: &LinearImplicitParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &LinearImplicitParams) -> Result<Self, SolverError> {
        LinearImplicitStepper::new(model, *p)
    }

    fn dt_mut(p: &mut LinearImplicitParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }
}
