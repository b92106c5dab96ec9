//! Explicit FEM in either dimension: the 2D [`crate::explicit`] update on a simplex mesh.
//!
//! With `a = M^-1 (f + f_ext)` and `decay = exp(-c dt)`, per free degree of freedom:
//! symplectic Euler `v' = (v + dt a) decay`, `x' = x + dt v'` (default), or forward Euler
//! `x' = x + dt v`, `v' = (v + dt a) decay`. Fixed degrees of freedom keep their positions and
//! zero velocity. A step whose new state is not finite is an error and leaves the state as it
//! was.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::exp;
use fem_core::simplex::assembly::{Scratch, populate_forces};

use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::steppers::explicit::{ExplicitParams, ExplicitScheme};
use crate::steppers::report::StepReport;

/// Explicit FEM on a [`NdModel`].
pub struct NdExplicit<D: Dim> {
    params: ExplicitParams,
    scratch: Scratch<D>,
    f: Vec<D::Vector>,
    x_new: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
}

impl<D: Dim> NdExplicit<D> {
    /// With validated parameters.
    pub fn new(params: ExplicitParams) -> Self {
        NdExplicit {
            params,
            scratch: Scratch::new(),
            f: Vec::new(),
            x_new: Vec::new(),
            v_new: Vec::new(),
        }
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdExplicit<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let n = model.mesh().n_vertices();
        self.f.resize(n, D::Vector::zeros());
        self.x_new.resize(n, D::Vector::zeros());
        self.v_new.resize(n, D::Vector::zeros());
        let dt = self.params.dt;
        let decay = exp(-self.params.damping * dt);
        let forces = populate_forces(
            model.mesh(),
            model.energy(),
            &state.x,
            &mut self.scratch,
            &mut self.f,
        );
        let fixed = model.fixed();
        for v in 0..n {
            let a = (self.f[v] + model.external_force(v)) / model.masses()[v];
            let (x, vel) = (state.x[v], state.v[v]);
            let mut v_new = (vel + a * dt) * decay;
            let mut x_new = match self.params.scheme {
                ExplicitScheme::ForwardEuler => x + vel * dt,
                _ => x + v_new * dt,
            };
            for i in 0..D::D {
                if fixed[D::D * v + i] {
                    v_new.set_at(i, 0.0);
                    x_new.set_at(i, x.at(i));
                }
            }
            self.v_new[v] = v_new;
            self.x_new[v] = x_new;
        }
        let report = StepReport {
            min_det_f: forces.min_det_f,
            inverted: forces.inverted,
            iterations: 0,
            residual: 0.0,
            contacts: 0,
        };
        check_finite::<D>(
            &self.x_new,
            &self.v_new,
            step_number(state.t, dt),
            state.t,
            &report,
        )?;
        std::mem::swap(&mut state.x, &mut self.x_new);
        std::mem::swap(&mut state.v, &mut self.v_new);
        state.t += dt;
        Ok(report)
    }
}
