//! Quasi-static equilibrium (no inertia): the positions that minimise
//! `Psi(x) - f_ext . x` with the kinematic vertices held where the state has them.
//!
//! Large loads are applied in load steps: the load factor goes from 0 to 1 in
//! [`StaticParams::load_steps`] equal increments, each solved by Newton from the previous
//! equilibrium ([`crate::newton`]); an increment whose Newton solve fails is halved, up to
//! [`StaticParams::max_bisections`] times. Contact is not handled (a model with contact
//! geometry is rejected).

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use crate::error::SolverError;
use crate::implicit::external_load;
use crate::model::Model;
use crate::newton::{NewtonParams, NewtonReport, NewtonSolver, Potential};
use crate::state::State;

/// Parameters of [`StaticSolver`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticParams {
    /// Equal load increments from 0 to the full load (>= 1). Default 1.
    pub load_steps: usize,
    /// Most halvings of an increment whose Newton solve fails. Default 10.
    pub max_bisections: usize,
    /// Newton settings.
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

/// What a static solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StaticReport {
    /// The load factors of the converged increments, ending at 1.
    pub load_factors: Vec<Real>,
    /// The Newton report of each converged increment.
    pub increments: Vec<NewtonReport>,
    /// Increments that failed and were halved.
    pub bisections: usize,
    /// Newton iterations of the failed attempts.
    pub failed_iterations: usize,
}

impl StaticReport {
    /// Newton iterations over the converged increments.
    pub fn iterations(&self) -> usize {
        self.increments.iter().map(|r| r.iterations).sum()
    }

    /// The final residual, N.
    pub fn residual(&self) -> Real {
        self.increments
            .last()
            .and_then(|r| r.residuals.last().copied())
            .unwrap_or(Real::NAN)
    }
}

/// Quasi-static solver.
#[derive(Debug)]
pub struct StaticSolver {
    params: StaticParams,
    solver: NewtonSolver,
    load: Vec<Vec2>,
    scaled: Vec<Vec2>,
    backup: Vec<Vec2>,
    report: StaticReport,
}

impl StaticSolver {
    /// A solver for `model` (symbolic analysis done here).
    pub fn new<E: Energy>(model: &Model<E>, params: StaticParams) -> Result<Self, SolverError> {
        params.newton.validate("static.newton")?;
        if params.load_steps == 0 {
            return Err(SolverError::invalid("static.load_steps", 0, "must be >= 1"));
        }
        if model.has_contact() {
            return Err(SolverError::invalid(
                "static.contact",
                "ground or obstacles",
                "contact is handled by the explicit, PBD and XPBD steppers only",
            ));
        }
        let kinematic: Vec<usize> = model.kinematics().vertices().collect();
        let n = model.mesh().n_vertices();
        Ok(StaticSolver {
            params,
            solver: NewtonSolver::new(model.mesh(), &kinematic, "static")?,
            load: vec![Vec2::zeros(); n],
            scaled: vec![Vec2::zeros(); n],
            backup: vec![Vec2::zeros(); n],
            report: StaticReport::default(),
        })
    }

    /// Move the free vertices of `state` to equilibrium under the model's full load (gravity
    /// and nodal forces); velocities are set to zero. On error the state is unchanged.
    pub fn solve<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StaticReport, SolverError> {
        state.check_matches(model)?;
        self.backup.copy_from_slice(&state.x);
        match self.solve_with(model, state, &[], |_, _, _| {}) {
            Ok(report) => Ok(report),
            Err(e) => {
                state.x.copy_from_slice(&self.backup);
                Err(e)
            }
        }
    }

    /// [`StaticSolver::solve`], also moving kinematic vertices: vertex `v` of `displacements`
    /// goes from its starting position to that plus the displacement in proportion to the load
    /// factor (a prescribed stretch applied with the load). `on_increment(factor, state,
    /// report)` is called after every converged increment, the state at that equilibrium. On
    /// error the state holds the last converged increment; [`StaticSolver::last_report`] tells
    /// what was done, failed attempts included.
    pub fn solve_with<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
        displacements: &[(usize, Vec2)],
        mut on_increment: impl FnMut(Real, &State, &NewtonReport),
    ) -> Result<StaticReport, SolverError> {
        state.check_matches(model)?;
        if let Some(&(v, _)) = displacements.iter().find(|(v, _)| *v >= state.x.len()) {
            return Err(SolverError::VertexOutOfRange {
                field: "static.displacements".into(),
                index: v,
                n_vertices: state.x.len(),
            });
        }
        external_load(model, &mut self.load);
        let start: Vec<Vec2> = displacements.iter().map(|&(v, _)| state.x[v]).collect();
        let place = |x: &mut [Vec2], factor: Real| {
            for (&(v, u), x0) in displacements.iter().zip(&start) {
                x[v] = x0 + factor * u;
            }
        };
        self.report = StaticReport::default();
        let mut x = state.x.clone();
        let mut factor = 0.0;
        let mut increment = 1.0 / self.params.load_steps as Real;
        while factor < 1.0 {
            // The last increment lands on 1 exactly, whatever the rounding of the sum.
            let next = if factor + increment > 1.0 - 1e-12 {
                1.0
            } else {
                factor + increment
            };
            for (s, l) in self.scaled.iter_mut().zip(&self.load) {
                *s = next * l;
            }
            let potential = Potential {
                mesh: model.mesh(),
                energy: model.energy(),
                masses: model.masses(),
                weight: 0.0,
                target: &[],
                load: &self.scaled,
            };
            place(&mut x, next);
            let outcome = self
                .solver
                .minimise(&potential, &mut x, &self.params.newton, None);
            match outcome {
                Ok(r) if r.converged && r.min_det_f.is_finite() => {
                    factor = next;
                    state.x.copy_from_slice(&x);
                    state.v.iter_mut().for_each(|v| *v = Vec2::zeros());
                    on_increment(factor, state, &r);
                    self.report.load_factors.push(factor);
                    self.report.increments.push(r);
                }
                other => {
                    x.copy_from_slice(&state.x);
                    let reason = match other {
                        Err(e) => e.to_string(),
                        Ok(r) => {
                            self.report.failed_iterations += r.iterations;
                            format!(
                                "Newton did not converge in {} iterations (residual {:.4e} N)",
                                r.iterations,
                                r.residuals.last().copied().unwrap_or(Real::NAN)
                            )
                        }
                    };
                    if self.report.bisections >= self.params.max_bisections {
                        return Err(SolverError::LoadIncrement {
                            increment: self.report.load_factors.len() + 1,
                            from: factor,
                            to: next,
                            halvings: self.report.bisections,
                            reason,
                        });
                    }
                    self.report.bisections += 1;
                    increment *= 0.5;
                }
            }
        }
        Ok(self.report.clone())
    }

    /// What the last solve did (also after an error).
    pub fn last_report(&self) -> &StaticReport {
        &self.report
    }
}
