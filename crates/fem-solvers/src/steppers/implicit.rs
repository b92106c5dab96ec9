//! Implicit (backward) Euler as the minimisation of the incremental potential:
//!
//! `x' = argmin  1/(2 h^2) |x - x_hat|_M^2 + Psi(x) - f_ext . x`,  `x_hat = x + h v`,
//! `v' = (x' - x) / h`, then `v' <- v' exp(-c h)` (optional damping, as in the other steppers),
//!
//! where `f_ext` holds gravity (`M g`) and the nodal loads (tractions included). Newton with
//! SPD-projected element Hessians, a backtracking line search that rejects states of infinite
//! energy (inverted elements under energies that forbid them), a sparse Cholesky factorisation
//! whose symbolic analysis is done once at construction and reused by every iteration of every
//! step ([`crate::newton`]). Each step reports the Newton iterations and the final residual.
//!
//! The paper names an implicit solver as future work. Implicit Euler is unconditionally stable
//! and dissipates energy (more at larger `h`): at a time step where explicit FEM blows up it
//! stays bounded, and without external load the total energy never increases.
//!
//! Kinematic vertices follow their schedule exactly as in the explicit stepper. With a ground
//! or obstacles, barrier contact joins the potential (IPC-style, built on [`crate::ipc`]; see
//! `docs/solvers.md`, Contact): dynamic and kinematic obstacles are unknowns of the same Newton system, every line search
//! starts at the largest step the CCD allows, and the starting guess is the prediction only as
//! far as it stays free of contact. The body must start apart from the ground and the
//! obstacles (a step that starts touching is an error naming the pair). After each step
//! [`ImplicitStepper::min_distance`] and [`Stepper::contacts`] report the gaps and forces.
//!
//! The starting guess is `x_hat` when its potential is finite, else the current positions (always
//! valid), so a large step never starts from an inverted configuration.
//!
//! **BDF2** (`integrator = "bdf2"`, [`crate::integrator`]): the same minimisation with the
//! inertia weight `9 / (4 h^2)`, BDF2's target `x_hat = 4/3 x_n - 1/3 x_{n-1} + 8/9 h v_n -
//! 2/9 h v_{n-1}` and velocity `(3 x_{n+1} - 4 x_n + x_{n-1}) / (2h)`, for the vertices, the free
//! rigid bodies' poses and the dynamic obstacles' poses alike; the first step, and any step from
//! a state the stepper did not commit, is backward Euler ([`ImplicitStepper::last_step_bdf2`]).
//!
//! Registered as `implicit` ([`Solver`]); scene keys `dt`, `damping`, `integrator` and Newton's
//! `tolerance`, `max_iterations`, `max_halvings`.

use fem_core::energy::Energy;
use fem_core::energy::EnergyOf as _;
use fem_core::math::{Real, Vec2, exp};

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::barrier::{BarrierContact, end_poses, step_targets};
use crate::error::{SolverError, check_non_negative, check_positive};
use crate::model::Model;
use crate::model::state::State;
use crate::optim::newton::{NewtonParams, NewtonReport, NewtonSolver, Potential};
use crate::rigid::BodyState;
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::integrator::{
    History, Integrator, bdf2_body_velocity, bdf2_obstacle_targets, bdf2_obstacle_velocities,
    bdf2_pose_target, bdf2_velocity,
};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// The default of [`ImplicitParams::velocity_tolerance`], m/s.
pub const VELOCITY_TOLERANCE: Real = 1e-3;

/// Parameters of [`ImplicitStepper`] (scene keys `dt`, `damping`, `velocity_tolerance`,
/// `integrator`, `tolerance`,
/// `max_iterations`, `max_halvings`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct ImplicitParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c dt)`; finite, >= 0). Default 0.
    pub damping: Real,
    /// Newton also stops after a full step that moved no vertex by more than
    /// `velocity_tolerance * dt`, m/s (finite, >= 0; 0: only the residual `tolerance` stops
    /// it). Newton converges quadratically there, so each vertex's position is within about
    /// that distance of the step's exact minimiser, its velocity within about
    /// `velocity_tolerance` of the converged step's: the real-time stopping rule
    /// (docs/implicit.md). Default `VELOCITY_TOLERANCE`.
    pub velocity_tolerance: Real,
    /// The time integrator: backward Euler (default) or BDF2 (second order; see
    /// [`crate::integrator`]).
    pub integrator: Integrator,
    /// Newton settings (serde: flattened into this table).
    #[cfg_attr(feature = "serde", serde(flatten))]
    pub newton: NewtonParams,
}

impl Default for ImplicitParams {
    fn default() -> Self {
        ImplicitParams {
            dt: 1e-3,
            damping: 0.0,
            velocity_tolerance: VELOCITY_TOLERANCE,
            integrator: Integrator::BackwardEuler,
            newton: NewtonParams::default(),
        }
    }
}

impl ImplicitParams {
    /// Check every field; errors name `implicit.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(ImplicitStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>` (Newton's too: `<prefix>.tolerance`).
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        check_positive(&format!("{prefix}.dt"), self.dt)?;
        check_non_negative(&format!("{prefix}.damping"), self.damping)?;
        check_non_negative(
            &format!("{prefix}.velocity_tolerance"),
            self.velocity_tolerance,
        )?;
        self.newton.validate_as(prefix)
    }
}

/// Implicit Euler by Newton on the incremental potential.
#[derive(Debug)]
pub struct ImplicitStepper {
    params: ImplicitParams,
    decay: Real,
    n_triangles: usize,
    solver: NewtonSolver,
    target: Vec<Vec2>,
    load: Vec<Vec2>,
    x_new: Vec<Vec2>,
    v_new: Vec<Vec2>,
    last: NewtonReport,
    /// The model layout the free degrees of freedom were analysed for.
    layout: u64,
    /// Barrier contact, when the model has a ground or obstacles.
    contact: Option<BarrierContact>,
    /// The obstacles' target poses of the step and their new states.
    targets: Vec<[Real; 3]>,
    bodies_new: Vec<BodyState>,
    /// The rigid regions' new poses.
    rigid_new: Vec<BodyState>,
    /// The lumped masses, zero on the vertices of free rigid bodies (whose inertia is the
    /// body's).
    masses: Vec<Real>,
    /// The smallest distance over the candidate pairs at the end of the last step, m.
    min_distance: Real,
    /// The previous step's state (BDF2).
    history: History,
    /// The free rigid bodies' BDF2 targets (one per body of the model).
    rigid_targets: Vec<[Real; 3]>,
    /// Whether the last step was a BDF2 step.
    last_bdf2: bool,
}

impl ImplicitStepper {
    /// A stepper for `model`: validates the parameters, sets up barrier contact when the model
    /// has a ground or obstacles, and does the symbolic analysis of the Hessian's pattern.
    pub fn new<E: Energy>(model: &Model<E>, params: ImplicitParams) -> Result<Self, SolverError> {
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
            "implicit",
            n_extra,
            coupled,
            model.rigid_bodies(),
        )?;
        let n = model.mesh().n_vertices();
        Ok(ImplicitStepper {
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
            last: NewtonReport::default(),
            history: History::new(params.integrator),
            rigid_targets: Vec::new(),
            last_bdf2: false,
        })
    }

    /// Whether the last step was a BDF2 step (false under backward Euler, and for a BDF2
    /// stepper's first step and every step that fell back to backward Euler; see
    /// [`crate::integrator`]).
    pub fn last_step_bdf2(&self) -> bool {
        self.last_bdf2
    }

    /// The parameters.
    pub fn params(&self) -> &ImplicitParams {
        &self.params
    }

    /// The Newton report of the last step (residual and potential after every iteration).
    pub fn last_newton(&self) -> &NewtonReport {
        &self.last
    }

    /// Free degrees of freedom of the linear systems.
    pub fn unknowns(&self) -> usize {
        self.solver.n_free()
    }

    /// The smallest distance between the soft body and the ground or an obstacle over the
    /// candidate pairs at the end of the last step, m (infinite when nothing is near, or
    /// without contact). Barrier contact keeps it positive.
    pub fn min_distance(&self) -> Real {
        self.min_distance
    }
}

/// The lumped masses with those of free rigid bodies' vertices set to zero: Newton's vertex
/// inertia, the bodies' own being theirs ([`crate::optim::newton::RigidUnknowns`]).
pub(crate) fn inertial_masses<E: Energy>(model: &Model<E>) -> Vec<Real> {
    let mut m = model.masses().to_vec();
    for body in model.rigid_bodies().iter().filter(|b| b.is_free()) {
        for &v in &body.vertices {
            m[v as usize] = 0.0;
        }
    }
    m
}

/// The external load per vertex: gravity `m g` plus the nodal forces.
pub(crate) fn external_load<E: Energy>(model: &Model<E>, load: &mut [Vec2]) {
    for (l, m) in load.iter_mut().zip(model.masses()) {
        *l = *m * model.gravity();
    }
    for &(v, f) in model.external_forces() {
        load[v as usize] += f;
    }
}

impl Stepper for ImplicitStepper {
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
            *self = ImplicitStepper::new(model, self.params)?;
        }
        let (h, t) = (self.params.dt, state.t);
        let bdf2 = self.history.begin(state, h, model.layout());
        self.last_bdf2 = false;
        // The inertia weight: backward Euler's `1/h^2` or BDF2's `9/(4 h^2)`.
        let (weight, _) = self.history.targets(bdf2, state, h, &mut self.target);
        external_load(model, &mut self.load);
        // Kinematic vertices go to their scheduled positions, both in the target and in the
        // unknowns (where they stay fixed).
        model
            .kinematics()
            .apply(t, h, t + h, &state.x, &mut self.target, &mut self.v_new);
        self.x_new.copy_from_slice(&self.target);
        if bdf2 {
            let prev = &self.history.prev.rigid;
            self.rigid_targets.clear();
            self.rigid_targets
                .extend((state.rigid.iter().zip(prev)).map(|(b, p)| bdf2_pose_target(b, p, h)));
            self.solver
                .rigid()
                .begin_towards(&state.rigid, &self.rigid_targets, &mut self.x_new);
        } else {
            self.solver
                .rigid()
                .begin(&state.rigid, Some(h), &mut self.x_new);
        }
        let potential = Potential {
            mesh: model.elastic_mesh(),
            energy: model.elastic_energies(),
            masses: &self.masses,
            weight,
            target: &self.target,
            load: &self.load,
            springs: model.springs(),
        };
        // When the prediction inverts an element the energy forbids, start from the current
        // positions (valid), kinematic vertices moved.
        let kinematics = model.kinematics();
        let current = |x: &mut [Vec2]| {
            x.copy_from_slice(&state.x);
            for (k, v) in kinematics.vertices().enumerate() {
                x[v] = state.x[v] + h * kinematics.velocity(k, state.x[v], t, h, t + h);
            }
        };
        if let Some(c) = self.contact.as_mut() {
            step_targets(model, state, h, &mut self.targets);
            if bdf2 {
                let prev = &self.history.prev.bodies;
                bdf2_obstacle_targets(model, &state.bodies, prev, h, &mut self.targets);
            }
            c.begin(
                &state.x,
                &state.bodies,
                &self.targets,
                weight,
                model.gravity(),
            );
            if let Some(at) = c.start_overlap(&state.x) {
                return Err(SolverError::invalid(
                    "implicit.contact",
                    at,
                    "barrier contact needs every soft vertex and obstacle apart at the start of a step (start the body above the ground and clear of obstacles)",
                ));
            }
            // Start from the prediction as far as it stays free of contact.
            for (d, (xh, x)) in self.v_new.iter_mut().zip(self.x_new.iter().zip(&state.x)) {
                *d = xh - x;
            }
            c.dq.fill(0.0);
            c.prepare(&state.x, Some(&self.v_new));
            let alpha = c.max_step(&state.x, &self.v_new);
            if alpha < 1.0 {
                for ((xn, x), d) in self.x_new.iter_mut().zip(&state.x).zip(&self.v_new) {
                    *xn = x + d * alpha;
                }
                for v in model.kinematics().vertices() {
                    self.x_new[v] = self.target[v];
                }
            }
        }
        let report = self.solver.minimise(
            &potential,
            &mut self.x_new,
            &self.params.newton,
            self.params.velocity_tolerance * h,
            Some(&current),
            self.contact.as_mut(),
        )?;
        if bdf2 {
            let prev = &self.history.prev.x;
            for (i, v) in self.v_new.iter_mut().enumerate() {
                *v = bdf2_velocity(self.x_new[i], state.x[i], prev[i], h) * self.decay;
            }
        } else {
            for ((v, xn), x) in self.v_new.iter_mut().zip(&self.x_new).zip(&state.x) {
                *v = (xn - x) / h * self.decay;
            }
        }
        self.rigid_new.clone_from(&state.rigid);
        for (k, q) in self.solver.rigid().poses() {
            let b = &mut self.rigid_new[k];
            let (p, angle) = (Vec2::new(q[0], q[1]), q[2]);
            if bdf2 {
                let start = *b;
                b.position = p;
                b.angle = angle;
                bdf2_body_velocity(b, &start, &self.history.prev.rigid[k], h);
                b.velocity *= self.decay;
                b.angular_velocity *= self.decay;
            } else {
                b.velocity = (p - b.position) / h * self.decay;
                b.angular_velocity = (angle - b.angle) / h * self.decay;
                b.position = p;
                b.angle = angle;
            }
        }
        let mut contacts = 0;
        if let Some(c) = self.contact.as_mut() {
            end_poses(c, model, state, h, &mut self.bodies_new);
            if bdf2 {
                let prev = &self.history.prev.bodies;
                bdf2_obstacle_velocities(model, &state.bodies, prev, h, &mut self.bodies_new);
            }
            self.min_distance = c.record(&self.x_new);
            contacts = c.contacts().len();
        }
        // Kinematic velocities are their schedule's (undamped): the commit moves them.
        let step = state.step;
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
        .commit(model, state, || {
            if report.converged {
                Ok(())
            } else {
                Err(SolverError::NotConverged {
                    step,
                    iterations: report.iterations,
                    residual: *report.residuals.last().unwrap_or(&Real::NAN),
                })
            }
        })?;
        self.history.commit(state);
        self.last_bdf2 = bdf2;
        let out = StepReport {
            min_det_f: report.min_det_f,
            inverted: report.inverted,
            iterations: report.iterations,
            residual: *report.residuals.last().unwrap_or(&0.0),
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

impl Solver for ImplicitStepper {
    type Params = ImplicitParams;
    const NAME: &'static str = "implicit";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Implicit Euler",
        summary: "implicit (backward) Euler: Newton on the incremental potential, sparse Cholesky",
        paper: false,
        contact: true,
        rigid_regions: true,
        averaged_pressure: true,
        dims: 3,
        implicit: true,
        iterations: false,
        substeps: false,
        factorisation: true,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "the exact solution as dt -> 0 (first order; second order with integrator = bdf2); each step to its Newton tolerance",
    };

    fn validate_params(p: &ImplicitParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &ImplicitParams) -> Result<Self, SolverError> {
        ImplicitStepper::new(model, *p)
    }

    fn dt_mut(p: &mut ImplicitParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }

    fn integrator_mut(p: &mut ImplicitParams) -> Option<&mut Integrator> {
        Some(&mut p.integrator)
    }
}
