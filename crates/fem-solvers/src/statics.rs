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
}

impl StaticReport {
    /// Newton iterations over all increments.
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
        external_load(model, &mut self.load);
        let mut x = state.x.clone();
        let mut report = StaticReport::default();
        let mut factor = 0.0;
        let mut increment = 1.0 / self.params.load_steps as Real;
        let mut halvings = 0;
        while factor < 1.0 {
            let next = (factor + increment).min(1.0);
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
            self.backup.copy_from_slice(&x);
            let outcome = self
                .solver
                .minimise(&potential, &mut x, &self.params.newton);
            match outcome {
                Ok(r) if r.converged && r.min_det_f.is_finite() => {
                    factor = next;
                    report.load_factors.push(factor);
                    report.increments.push(r);
                }
                other => {
                    x.copy_from_slice(&self.backup);
                    if halvings >= self.params.max_bisections {
                        return Err(match other {
                            Err(e) => e,
                            Ok(r) => SolverError::NotConverged {
                                step: report.load_factors.len() as u64,
                                iterations: r.iterations,
                                residual: *r.residuals.last().unwrap_or(&Real::NAN),
                            },
                        });
                    }
                    halvings += 1;
                    report.bisections += 1;
                    increment *= 0.5;
                }
            }
        }
        state.x = x;
        state.v.iter_mut().for_each(|v| *v = Vec2::zeros());
        Ok(report)
    }
}
