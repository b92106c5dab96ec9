//! Implicit (backward) Euler in either dimension: the 2D [`crate::implicit`] step on a simplex
//! mesh, `x' = argmin 1/(2 h^2) |x - x_hat|_M^2 + Psi(x) - f_ext . x` with `x_hat = x + h v`,
//! `v' = (x' - x) / h`, then `v' <- v' exp(-c h)`, by the Newton solver of [`super::newton`].
//!
//! Newton starts from `x_hat` when the potential is finite there, else from `x`. Its stopping
//! test is the 2D solver's: the residual against `tolerance` times the force scale, or a full
//! step that moved no degree of freedom by more than `velocity_tolerance * h`. Backward Euler
//! only: BDF2 (`integrator = "bdf2"`) is refused in one line.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::exp;

use super::newton::{Inertia, NdNewton};
use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::steppers::implicit::ImplicitParams;
use crate::steppers::integrator::Integrator;
use crate::steppers::report::StepReport;

/// Implicit Euler on a [`NdModel`].
pub struct NdImplicit<D: Dim> {
    params: ImplicitParams,
    newton: NdNewton<D>,
    x_hat: Vec<D::Vector>,
    x_new: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
}

impl<D: Dim> NdImplicit<D> {
    /// With validated parameters, for `model` (the factorisation's symbolic analysis).
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: ImplicitParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        if params.integrator != Integrator::BackwardEuler {
            return Err(SolverError::invalid(
                format!("{prefix}.integrator"),
                "bdf2",
                format!("is not available in {} yet (use backward-euler)", D::NAME),
            ));
        }
        Ok(NdImplicit {
            params,
            newton: NdNewton::new(model, "implicit")?,
            x_hat: Vec::new(),
            x_new: Vec::new(),
            v_new: Vec::new(),
        })
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdImplicit<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let h = self.params.dt;
        let n = model.mesh().n_vertices();
        let fixed = model.fixed();
        self.x_hat.clear();
        for v in 0..n {
            let mut p = state.x[v] + state.v[v] * h;
            for i in 0..D::D {
                if fixed[D::D * v + i] {
                    p.set_at(i, state.x[v].at(i));
                }
            }
            self.x_hat.push(p);
        }
        let step = step_number(state.t, h);
        let inertia = Inertia {
            w: 1.0 / (h * h),
            x_hat: &self.x_hat,
        };
        // Start at the prediction where the energy is defined, else where the body is.
        self.x_new.clear();
        self.x_new.extend_from_slice(&self.x_hat);
        let mut x = std::mem::take(&mut self.x_new);
        let solved = match self.newton.minimise(
            model,
            &inertia,
            1.0,
            &mut x,
            &self.params.newton,
            self.params.velocity_tolerance * h,
            step,
        ) {
            Err(SolverError::InvalidParameter { .. }) if x == self.x_hat => {
                x.copy_from_slice(&state.x);
                self.newton.minimise(
                    model,
                    &inertia,
                    1.0,
                    &mut x,
                    &self.params.newton,
                    self.params.velocity_tolerance * h,
                    step,
                )
            }
            other => other,
        };
        self.x_new = x;
        let newton = solved?;
        let decay = exp(-self.params.damping * h);
        self.v_new.clear();
        for v in 0..n {
            self.v_new.push((self.x_new[v] - state.x[v]) * (decay / h));
        }
        let forces = newton
            .forces
            .unwrap_or(fem_core::simplex::assembly::ForceReport {
                min_det_f: 1.0,
                inverted: 0,
            });
        let report = StepReport {
            min_det_f: forces.min_det_f,
            inverted: forces.inverted,
            iterations: newton.iterations,
            residual: newton.residual,
            contacts: 0,
        };
        check_finite::<D>(&self.x_new, &self.v_new, step, state.t, &report)?;
        std::mem::swap(&mut state.x, &mut self.x_new);
        std::mem::swap(&mut state.v, &mut self.v_new);
        state.t += h;
        Ok(report)
    }
}
