//! Quasi-static equilibrium (no inertia) as a stepper over the load factor: the positions that
//! minimise `Psi(x) - lambda f_ext . x` for a load factor `lambda` going from 0 to 1, with the
//! kinematic vertices moved in proportion to `lambda`.
//!
//! [`StaticStepper`] runs on [`Clock::LoadFactor`]: [`State::t`] is the load factor (0 at rest,
//! exactly 1 at the end) and [`State::step`] counts converged increments. Each
//! [`Stepper::step`] solves one increment from `t` to `min(t + inc, 1)` by Newton from the
//! previous equilibrium ([`crate::newton`]); `inc` starts at `1 / load_steps`
//! ([`StaticParams::load_steps`]), and the increment that would end within `1e-12` of 1 ends at
//! exactly 1. An increment whose Newton solve fails (an error, no convergence, or a non-finite
//! `det F`) is halved and retried within the same call; the halved increment is kept for the
//! following steps. Halvings are counted over the run (from `t = 0`): after
//! [`StaticParams::max_bisections`] of them the step returns [`SolverError::LoadIncrement`]
//! with the state left at the last equilibrium. Velocities are zero after every step.
//!
//! Boundary conditions: pinned vertices stay where the state has them. A prescribed vertex
//! moves from its position at `t = 0` by its schedule's whole displacement
//! `velocity * (end - start)` ([`PrescribedMotion`](crate::PrescribedMotion)) times the load
//! factor, so its window must be finite (an infinite `end` on a moving vertex is rejected at
//! construction, naming the field). With a ground or obstacles, barrier contact joins the
//! potential as in [`crate::implicit`] (friction smoothed over `d_hat` instead of `eps_v h`):
//! dynamic obstacles are unknowns held up by contact alone (no inertia), and kinematic ones move
//! by their schedule's whole motion times the load factor (their windows must end).
//!
//! A step on a state whose load factor is already 1 (or more) does nothing and returns `Ok`
//! with 0 iterations (and the state's inversion statistics), so a loop of a fixed number of
//! steps may run past the end.
//!
//! [`StaticSolver`] is a convenience that steps until the load factor reaches 1.
//!
//! Registered as `static` ([`Solver`]); scene keys `load_steps`, `max_bisections` and Newton's
//! `tolerance`, `max_iterations`, `max_halvings`.

use fem_core::energy::Energy;
use fem_core::energy::EnergyOf as _;
use fem_core::math::{Real, Vec2};

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::barrier::BarrierContact;
use crate::error::{SolverError, check_at_most, check_count};
use crate::kernel::Inversion;
use crate::model::Model;
use crate::model::bc::Motion;
use crate::model::limits;
use crate::model::state::State;
use crate::optim::newton::{NewtonParams, NewtonReport, NewtonSolver, Potential};
use crate::rigid::BodyState;
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::implicit::external_load;
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// Parameters of [`StaticStepper`] (scene keys `load_steps`, `max_bisections`, `tolerance`,
/// `max_iterations`, `max_halvings`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct StaticParams {
    /// Equal load increments from 0 to the full load (>= 1). Default 1.
    pub load_steps: usize,
    /// Most halvings of failed increments over a run. Default 10.
    pub max_bisections: usize,
    /// Newton settings (serde: flattened into this table).
    #[cfg_attr(feature = "serde", serde(flatten))]
    pub newton: NewtonParams,
}

impl Default for StaticParams {
    fn default() -> Self {
        StaticParams {
            load_steps: 1,
            max_bisections: 10,
            newton: NewtonParams::default(),
        }
    }
}

impl StaticParams {
    /// Check every field; errors name `static.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(StaticStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>` (Newton's too: `<prefix>.tolerance`).
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        check_count(
            &format!("{prefix}.load_steps"),
            self.load_steps,
            limits::MAX_LOAD_STEPS,
        )?;
        check_at_most(
            &format!("{prefix}.max_bisections"),
            self.max_bisections,
            limits::MAX_BISECTIONS,
        )?;
        self.newton.validate_as(prefix)
    }
}

/// The quasi-static solver as a stepper over the load factor (see the module docs).
#[derive(Debug)]
pub struct StaticStepper {
    params: StaticParams,
    n_triangles: usize,
    solver: NewtonSolver,
    /// Kinematic vertices, increasing.
    kinematic: Vec<usize>,
    /// Whole displacement of each kinematic vertex at load factor 1, m (zero when pinned).
    displacement: Vec<Vec2>,
    /// Position of each kinematic vertex at load factor 0, m.
    origin: Vec<Vec2>,
    load: Vec<Vec2>,
    scaled: Vec<Vec2>,
    x_new: Vec<Vec2>,
    v_new: Vec<Vec2>,
    /// The current load increment.
    increment: Real,
    /// Halvings so far in this run.
    halvings: usize,
    last: NewtonReport,
    /// The model layout the free degrees of freedom were analysed for.
    layout: u64,
    /// Barrier contact, when the model has a ground or obstacles.
    contact: Option<BarrierContact>,
    /// The obstacles' target poses and new states.
    targets: Vec<[Real; 3]>,
    bodies_new: Vec<BodyState>,
    /// The rigid regions' new poses.
    rigid_new: Vec<BodyState>,
    /// The smallest distance over the candidate pairs at the last equilibrium, m.
    min_distance: Real,
}

impl StaticStepper {
    /// A stepper for `model`: validates the parameters, sets up barrier contact, rejects
    /// prescribed motions (of vertices or obstacles) without an end, and does the symbolic analysis of the Hessian's pattern.
    pub fn new<E: Energy>(model: &Model<E>, params: StaticParams) -> Result<Self, SolverError> {
        params.validate()?;
        for (o, obs) in model.obstacles().iter().enumerate() {
            if let Some((_, end)) = obs.schedule()
                && !end.is_finite()
            {
                let field = match obs.moves().len() {
                    0 => format!("obstacles[{o}].end"),
                    n => format!("obstacles[{o}].moves[{}].end", n - 1),
                };
                return Err(SolverError::invalid(
                    field,
                    end,
                    "must be finite for the static solver (the load factor scales the whole motion velocity * (end - start))",
                ));
            }
        }
        let kin = model.kinematics();
        let kinematic: Vec<usize> = kin.vertices().collect();
        let mut displacement = Vec::with_capacity(kinematic.len());
        for k in 0..kinematic.len() {
            let u = match kin.motion[k] {
                Motion::Pinned | Motion::Held(_) | Motion::Rigid(_) => Vec2::zeros(),
                Motion::Scheduled(m) => {
                    let motion = &kin.motions[m as usize];
                    if motion.velocity == Vec2::zeros() {
                        Vec2::zeros()
                    } else if motion.end.is_finite() {
                        motion.velocity * (motion.end - motion.start)
                    } else {
                        return Err(SolverError::invalid(
                            format!("prescribed_motion[{m}].end"),
                            motion.end,
                            "must be finite for the static solver (the load factor scales the whole displacement velocity * (end - start))",
                        ));
                    }
                }
            };
            displacement.push(u);
        }
        let contact = model
            .has_contact()
            .then(|| BarrierContact::new(model, model.contact_params().barrier_distance));
        let (n_extra, coupled) = match &contact {
            Some(c) => (c.n_extra(), c.coupled_vertices()),
            None => (0, &[][..]),
        };
        let solver = NewtonSolver::with_extra(
            model.elastic_mesh(),
            model.elastic_energies().nodal_pressure(),
            &kinematic,
            "static",
            n_extra,
            coupled,
            model.rigid_bodies(),
        )?;
        let n = model.mesh().n_vertices();
        Ok(StaticStepper {
            contact,
            targets: Vec::new(),
            bodies_new: Vec::new(),
            rigid_new: Vec::new(),
            min_distance: Real::INFINITY,
            layout: model.layout(),
            increment: 1.0 / params.load_steps as Real,
            params,
            n_triangles: model.mesh().n_triangles(),
            solver,
            origin: vec![Vec2::zeros(); kinematic.len()],
            kinematic,
            displacement,
            load: vec![Vec2::zeros(); n],
            scaled: vec![Vec2::zeros(); n],
            x_new: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            halvings: 0,
            last: NewtonReport::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &StaticParams {
        &self.params
    }

    /// The Newton report of the last converged increment.
    pub fn last_newton(&self) -> &NewtonReport {
        &self.last
    }

    /// Increments halved so far in this run.
    pub fn halvings(&self) -> usize {
        self.halvings
    }

    /// The load increment the next step will try (the nominal `1 / load_steps` until a
    /// failed increment halves it).
    pub fn increment(&self) -> Real {
        self.increment
    }

    /// Free degrees of freedom of the linear systems.
    pub fn unknowns(&self) -> usize {
        self.solver.n_free()
    }

    /// The smallest distance between the soft body and the ground or an obstacle over the
    /// candidate pairs at the last equilibrium, m (infinite when nothing is near, or without
    /// contact). Barrier contact keeps it positive.
    pub fn min_distance(&self) -> Real {
        self.min_distance
    }

    /// Where the kinematic vertices were at load factor 0: taken from the state at `t = 0`
    /// (a new run also resets the increment and the halvings), and recovered from its
    /// positions when the state is not one this stepper produced.
    fn sync_origin(&mut self, state: &State) {
        let t = state.t;
        if t == 0.0 {
            self.increment = 1.0 / self.params.load_steps as Real;
            self.halvings = 0;
        }
        for ((o, &v), u) in self
            .origin
            .iter_mut()
            .zip(&self.kinematic)
            .zip(&self.displacement)
        {
            if t == 0.0 {
                *o = state.x[v];
            } else if *o + t * u != state.x[v] {
                *o = state.x[v] - t * u;
            }
        }
    }
}

impl Stepper for StaticStepper {
    /// The nominal load increment `1 / load_steps` (dimensionless).
    fn dt(&self) -> Real {
        1.0 / self.params.load_steps as Real
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        if model.layout() != self.layout {
            let (increment, halvings) = (self.increment, self.halvings);
            *self = StaticStepper::new(model, self.params)?;
            (self.increment, self.halvings) = (increment, halvings);
        }
        // At full load the equilibrium is reached; with a grab it is solved again at every
        // step, following the hand.
        if state.t >= 1.0 && !model.is_grabbed() {
            let Inversion {
                min_det_f,
                inverted,
            } = Inversion::of_mesh(model.mesh(), &state.x);
            return Ok(StepReport {
                min_det_f,
                inverted,
                iterations: 0,
                residual: 0.0,
                contacts: 0,
            });
        }
        self.sync_origin(state);
        external_load(model, &mut self.load);
        let from = state.t;
        let mut failed_iterations = 0;
        loop {
            // The last increment lands on 1 exactly, whatever the rounding of the sum.
            let next = if from + self.increment > 1.0 - 1e-12 {
                1.0
            } else {
                from + self.increment
            };
            for (s, l) in self.scaled.iter_mut().zip(&self.load) {
                *s = next * l;
            }
            self.x_new.copy_from_slice(&state.x);
            let kin = model.kinematics();
            for (k, ((&v, o), u)) in self
                .kinematic
                .iter()
                .zip(&self.origin)
                .zip(&self.displacement)
                .enumerate()
            {
                self.x_new[v] = match kin.motion[k] {
                    // A grabbed vertex goes from where it is to its goal over the rest of
                    // the load, in proportion (on it exactly at load factor 1).
                    Motion::Held(goal) if next < 1.0 => {
                        let here = state.x[v];
                        here + (goal - here) * ((next - from) / (1.0 - from))
                    }
                    Motion::Held(goal) => goal,
                    _ => o + next * u,
                };
            }
            self.solver
                .rigid()
                .begin(&state.rigid, None, &mut self.x_new);
            let potential = Potential {
                mesh: model.elastic_mesh(),
                energy: model.elastic_energies(),
                masses: model.masses(),
                weight: 0.0,
                target: &[],
                load: &self.scaled,
                springs: model.springs(),
            };
            if let Some(c) = self.contact.as_mut() {
                // A kinematic obstacle is where its schedule is at the same fraction `next` of
                // its window (its whole motion times the load factor); the others start where
                // they are.
                self.targets.clear();
                for (obs, body) in model.obstacles().iter().zip(&state.bodies) {
                    let target = obs
                        .schedule()
                        .and_then(|(start, end)| obs.scheduled_pose(start + next * (end - start)));
                    self.targets.push(target.unwrap_or([
                        body.position.x,
                        body.position.y,
                        body.angle,
                    ]));
                }
                c.begin(
                    &state.x,
                    &state.bodies,
                    &self.targets,
                    0.0,
                    model.gravity() * next,
                );
                if let Some(at) = c.start_overlap(&state.x) {
                    return Err(SolverError::invalid(
                        "static.contact",
                        at,
                        "barrier contact needs every soft vertex and obstacle apart at the start of an increment (start the body above the ground and clear of obstacles)",
                    ));
                }
                // Kinematic vertices jump to their new places; the free ones start where they
                // are (free of contact).
                let kinematic = &self.kinematic;
                for (v, (xn, x)) in self.x_new.iter_mut().zip(&state.x).enumerate() {
                    if kinematic.binary_search(&v).is_err() {
                        *xn = *x;
                    }
                }
            }
            let outcome = self.solver.minimise(
                &potential,
                &mut self.x_new,
                &self.params.newton,
                0.0,
                None,
                self.contact.as_mut(),
            );
            let reason = match outcome {
                Ok(r) if r.converged && r.min_det_f.is_finite() => {
                    self.v_new.fill(Vec2::zeros());
                    self.rigid_new.clone_from(&state.rigid);
                    for (k, q) in self.solver.rigid().poses() {
                        let b = &mut self.rigid_new[k];
                        b.position = Vec2::new(q[0], q[1]);
                        b.angle = q[2];
                        b.velocity = Vec2::zeros();
                        b.angular_velocity = 0.0;
                    }
                    let mut contacts = 0;
                    if let Some(c) = self.contact.as_mut() {
                        self.bodies_new.clone_from(&state.bodies);
                        for (b, q) in self.bodies_new.iter_mut().zip(&c.q) {
                            b.position = Vec2::new(q[0], q[1]);
                            b.angle = q[2];
                            b.velocity = Vec2::zeros();
                            b.angular_velocity = 0.0;
                        }
                        self.min_distance = c.record(&self.x_new);
                        contacts = c.contacts().len();
                    }
                    StepEnd {
                        kinematics: Kinematic::Placed,
                        x: &mut self.x_new,
                        v: &mut self.v_new,
                        bodies: self.contact.is_some().then_some(&mut self.bodies_new),
                        rigid: Some(&mut self.rigid_new),
                        known_finite: false,
                        inverted: r.inverted,
                        min_det_f: r.min_det_f,
                        t_end: next,
                        count_step: true,
                    }
                    .commit(model, state, || Ok(()))?;
                    let out = StepReport {
                        min_det_f: r.min_det_f,
                        inverted: r.inverted,
                        iterations: r.iterations + failed_iterations,
                        residual: r.residuals.last().copied().unwrap_or(Real::NAN),
                        contacts,
                    };
                    self.last = r;
                    return Ok(out);
                }
                // Halving the load only lowers it further below the floors.
                Err(e @ SolverError::BeyondPrecision { .. }) => return Err(e),
                Err(e) => e.to_string(),
                Ok(r) => {
                    failed_iterations += r.iterations;
                    if r.converged {
                        format!("the solution is not finite (min det F = {:e})", r.min_det_f)
                    } else {
                        format!(
                            "Newton did not converge in {} iterations (residual {:.4e} N)",
                            r.iterations,
                            r.residuals.last().copied().unwrap_or(Real::NAN)
                        )
                    }
                }
            };
            if self.halvings >= self.params.max_bisections {
                return Err(SolverError::LoadIncrement {
                    increment: state.step as usize + 1,
                    from,
                    to: next,
                    halvings: self.halvings,
                    reason,
                });
            }
            self.halvings += 1;
            self.increment *= 0.5;
        }
    }

    fn contacts(&self) -> &[Contact] {
        match &self.contact {
            Some(c) => c.contacts(),
            None => &[],
        }
    }
}

impl Solver for StaticStepper {
    type Params = StaticParams;
    const NAME: &'static str = "static";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Static",
        summary: "quasi-static equilibrium (no inertia): Newton per load increment, halved on failure, sparse Cholesky",
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
        clock: Clock::LoadFactor,
        converges_to: "the equilibrium under the full load, to the Newton tolerance",
    };

    fn validate_params(p: &StaticParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &StaticParams) -> Result<Self, SolverError> {
        StaticStepper::new(model, *p)
    }

    fn dt_mut(_: &mut StaticParams) -> Option<&mut Real> {
        None
    }
}

/// What [`StaticSolver::solve`] did: one entry per converged increment.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StaticReport {
    /// The load factor after each converged increment, ending at 1.
    pub load_factors: Vec<Real>,
    /// The step report of each converged increment (iterations include failed attempts).
    pub steps: Vec<StepReport>,
    /// Increments halved over the run.
    pub halvings: usize,
}

impl StaticReport {
    /// Newton iterations over the run, failed attempts included.
    pub fn iterations(&self) -> usize {
        self.steps.iter().map(|r| r.iterations).sum()
    }

    /// The final residual, N (NaN when nothing was solved).
    pub fn residual(&self) -> Real {
        self.steps.last().map_or(Real::NAN, |r| r.residual)
    }
}

/// A convenience over [`StaticStepper`]: step until the load factor reaches 1.
#[derive(Debug)]
pub struct StaticSolver {
    stepper: StaticStepper,
}

impl StaticSolver {
    /// A solver for `model` (see [`StaticStepper::new`]).
    pub fn new<E: Energy>(model: &Model<E>, params: StaticParams) -> Result<Self, SolverError> {
        Ok(StaticSolver {
            stepper: StaticStepper::new(model, params)?,
        })
    }

    /// Step `state` from its load factor to 1 (the full load). On error the state is at the
    /// last equilibrium reached.
    pub fn solve<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StaticReport, SolverError> {
        let mut report = StaticReport::default();
        while state.t < 1.0 {
            let r = self.stepper.step(model, state)?;
            report.load_factors.push(state.t);
            report.steps.push(r);
        }
        report.halvings = self.stepper.halvings();
        Ok(report)
    }

    /// The stepper.
    pub fn stepper(&self) -> &StaticStepper {
        &self.stepper
    }
}
