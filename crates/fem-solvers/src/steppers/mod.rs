//! The steppers: one file per solver, the [`Stepper`] trait they implement, the registry that
//! lists them ([`registry`]: names, parameters, capabilities, the stepper chosen at run time),
//! what a step reports ([`report`]) and the commit that ends every step (`commit`: a step
//! never writes a non-finite state).
//!
//! - [`explicit`]: Algorithm I (symplectic or the printed forward Euler);
//! - [`position_based`]: energy-based PBD and XPBD;
//! - [`implicit`]: implicit Euler by Newton on the incremental potential;
//! - [`integrator`]: backward Euler or BDF2, for the solvers that minimise an incremental
//!   potential (implicit, VBD, Projective Dynamics, quasi-Newton);
//! - [`statics`]: quasi-static equilibrium over a load factor;
//! - [`vbd`]: Vertex Block Descent;
//! - [`projective`]: Projective Dynamics (co-rotational);
//! - [`quasi_newton`]: L-BFGS with the Projective Dynamics matrix;
//! - [`linear_implicit`]: linearly implicit Euler (one linear solve per step).
//!
//! [`colour`] has the triangle and vertex colourings the Gauss-Seidel solvers run in parallel.
//! A stepper reads the [`crate::model`], resolves contact through [`crate::contact`] and
//! solves its implicit systems with [`crate::optim`]; nothing below this folder knows a
//! stepper.

use fem_core::energy::Energy;
use fem_core::math::Real;

use crate::contact::Contact;
use crate::error::SolverError;
use crate::model::Model;
use crate::model::state::State;
use report::StepReport;

pub mod colour;
pub(crate) mod commit;
pub mod explicit;
pub mod implicit;
pub mod integrator;
pub mod linear_implicit;
pub mod position_based;
pub mod projective;
pub mod quasi_newton;
pub mod registry;
#[cfg(all(test, feature = "serde"))]
mod registry_extension;
pub mod report;
pub mod statics;
pub mod vbd;

/// A stepper: advances a [`State`] of a [`Model`] by one step of its clock
/// ([`Clock`](registry::Clock)): a time step, or for the static solver a load increment.
pub trait Stepper {
    /// The time step, s; for a [`Clock::LoadFactor`](registry::Clock::LoadFactor) solver the
    /// nominal load increment (dimensionless).
    fn dt(&self) -> Real;

    /// Advance `state` by one step. On error the state is unchanged (a failed substep leaves
    /// the earlier substeps applied), and never holds a non-finite value.
    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError>;

    /// The contacts of the last step, where the stepper last evaluated them (penalty: the
    /// start of the step, where its forces are; projection: the sweeps of the last substep):
    /// where, the normal, the gap (negative: penetration) and the normal force, in a fixed
    /// order (see [`crate::contact::penalty`]). Empty for a stepper without contact and for a
    /// model without a ground or obstacles.
    fn contacts(&self) -> &[Contact] {
        &[]
    }
}

/// The checks every stepper makes before a step: the model is the one the stepper was built
/// for (same triangle count) and the state matches the model.
pub(crate) fn check_step_inputs<E: Energy>(
    model: &Model<E>,
    n_triangles: usize,
    state: &State,
) -> Result<(), SolverError> {
    if model.mesh().n_triangles() != n_triangles {
        return Err(SolverError::ModelMismatch {
            got: model.mesh().n_triangles(),
            expected: n_triangles,
        });
    }
    state.check_matches(model)
}

/// Refuse a model with a free rigid body, for a solver that does not move rigid regions
/// (`rigid_regions: false` in its capabilities): one line naming the solver and the solvers
/// that do.
pub(crate) fn refuse_free_rigid_bodies<E: Energy>(
    model: &Model<E>,
    solver: &str,
) -> Result<(), SolverError> {
    let free = model.rigid_bodies().iter().filter(|b| b.is_free()).count();
    if free == 0 {
        return Ok(());
    }
    let supported: Vec<&str> = (registry::SolverKind::ALL.iter())
        .filter(|k| k.capabilities().rigid_regions)
        .map(|k| k.name())
        .collect();
    Err(SolverError::invalid(
        "solver",
        solver,
        format!(
            "does not move rigid regions, and the model has {free} free rigid {}: use {}, or pin the bodies, or make the regions elastic (rigid = false)",
            if free == 1 { "body" } else { "bodies" },
            supported.join(", ")
        ),
    ))
}

/// Refuse a model of averaged nodal pressure triangles, for a solver that does not support
/// them (`averaged_pressure: false` in its capabilities): one line naming the solver and the
/// solvers that do.
pub(crate) fn refuse_averaged_pressure<E: Energy>(
    model: &Model<E>,
    solver: &str,
) -> Result<(), SolverError> {
    if !model.uses_averaged_pressure() {
        return Ok(());
    }
    let supported: Vec<&str> = (registry::SolverKind::ALL.iter())
        .filter(|k| k.capabilities().averaged_pressure)
        .map(|k| k.name())
        .collect();
    Err(SolverError::invalid(
        "solver",
        solver,
        format!(
            "does not support the averaged nodal pressure triangle (material.formulation = \"averaged-pressure\"): use {}, or material.formulation = \"standard\"",
            supported.join(", ")
        ),
    ))
}
