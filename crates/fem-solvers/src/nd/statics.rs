//! Quasi-static equilibrium in either dimension, over the load factor, as the 2D
//! [`crate::statics`]: each step solves the increment from `t` to `min(t + inc, 1)` of
//! `min Psi(x) - t f_ext . x` by Newton from the previous equilibrium, `inc` starting at
//! `1 / load_steps` (the increment that would end within `1e-12` of 1 ends at 1 exactly). A
//! failed increment is halved and retried within the same call (the halved size is kept); after
//! `max_bisections` halvings over the run the step returns [`SolverError::LoadIncrement`] with
//! the state at the last equilibrium. Velocities stay zero. A step at load factor 1 does
//! nothing.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::Real;

use super::newton::{Inertia, NdNewton};
use super::{NdModel, NdState, NdStepper};
use crate::error::SolverError;
use crate::steppers::report::StepReport;
use crate::steppers::statics::StaticParams;

/// The quasi-static solver on a [`NdModel`].
pub struct NdStatic<D: Dim> {
    params: StaticParams,
    newton: NdNewton<D>,
    increment: Real,
    halvings: usize,
    steps: u64,
    x_new: Vec<D::Vector>,
}

impl<D: Dim> NdStatic<D> {
    /// With validated parameters, for `model`.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: StaticParams,
        _prefix: &str,
    ) -> Result<Self, SolverError> {
        Ok(NdStatic {
            params,
            newton: NdNewton::new(model, "static")?,
            increment: 1.0 / params.load_steps as Real,
            halvings: 0,
            steps: 0,
            x_new: Vec::new(),
        })
    }

    /// Step until the load factor reaches 1; the report of the last step, with the iterations
    /// summed.
    pub fn solve<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let mut total = 0;
        loop {
            let mut report = self.step(model, state)?;
            total += report.iterations;
            if state.t >= 1.0 {
                report.iterations = total;
                return Ok(report);
            }
        }
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdStatic<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let from = state.t;
        if from >= 1.0 {
            return Ok(StepReport {
                min_det_f: Real::NAN,
                inverted: 0,
                iterations: 0,
                residual: 0.0,
                contacts: 0,
            });
        }
        let no_inertia = Inertia::<D> { w: 0.0, x_hat: &[] };
        loop {
            let to = if from + self.increment > 1.0 - 1e-12 {
                1.0
            } else {
                from + self.increment
            };
            self.x_new.clear();
            self.x_new.extend_from_slice(&state.x);
            let mut x = std::mem::take(&mut self.x_new);
            let solved = self.newton.minimise(
                model,
                &no_inertia,
                to,
                &mut x,
                &self.params.newton,
                0.0,
                self.steps + 1,
            );
            self.x_new = x;
            let failure = match solved {
                Ok(r) => match r.forces {
                    Some(f)
                        if f.min_det_f.is_finite() && self.x_new.iter().all(|p| p.all_finite()) =>
                    {
                        std::mem::swap(&mut state.x, &mut self.x_new);
                        state.v.iter_mut().for_each(|v| *v = D::Vector::zeros());
                        state.t = to;
                        self.steps += 1;
                        return Ok(StepReport {
                            min_det_f: f.min_det_f,
                            inverted: f.inverted,
                            iterations: r.iterations,
                            residual: r.residual,
                            contacts: 0,
                        });
                    }
                    _ => "the equilibrium is not finite".to_owned(),
                },
                Err(SolverError::NotConverged {
                    iterations,
                    residual,
                    ..
                }) => format!(
                    "Newton did not converge in {iterations} iterations (residual {residual:.4e} N)"
                ),
                Err(e) => e.to_string(),
            };
            if self.halvings >= self.params.max_bisections {
                return Err(SolverError::LoadIncrement {
                    increment: self.steps as usize + 1,
                    from,
                    to,
                    halvings: self.halvings,
                    reason: failure,
                });
            }
            self.halvings += 1;
            self.increment *= 0.5;
        }
    }
}
