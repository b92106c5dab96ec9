//! Solvers for a soft body in **either dimension**: the same code steps a triangle mesh in 2D
//! and a tetrahedral mesh in 3D ([`fem_core::dim`]), on flat degree-of-freedom vectors.
//!
//! A [`NdModel<D, E>`] holds the body (a [`SimplexMesh<D>`](fem_core::simplex::SimplexMesh),
//! an energy written once over `F` ([`Hyperelastic<D>`]), lumped masses, fixed degrees of
//! freedom, gravity, nodal loads and tractions); a [`NdState<D>`] its positions, velocities
//! and clock; an [`NdStepper`] advances the state by one step and returns the same
//! [`StepReport`] the 2D steppers do.
//!
//! The 2D solvers of [`crate::steppers`] keep their own hand-specialised kernels, contact,
//! rigid regions and drag (they are what `fem2d` runs in 2D); this module is the
//! dimension-generic path the 3D scenes run. In 2D the two agree: a test runs each solver here
//! on a triangle mesh against the 2D solver of the same name.
//!
//! Which solvers have a dimension-generic path is a row of the capability table
//! ([`Capabilities::dims`](crate::Capabilities)); [`build`] builds one from the registry's
//! parameters and refuses, in one line, a solver without one or an option it does not support
//! (contact and rigid regions are 2D only).

mod explicit;
mod implicit;
mod model;
mod newton;
mod pd_system;
mod position_based;
mod projective;
mod quasi_newton;
mod statics;
mod vbd;

pub use explicit::NdExplicit;
pub use implicit::NdImplicit;
pub use model::{NdModel, NdRegion, NdState};
pub use position_based::{NdPbd, NdXpbd};
pub use projective::{NdPd, corotational_projections};
pub use quasi_newton::NdQuasiNewton;
pub use statics::NdStatic;
pub use vbd::NdVbd;

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::Real;

use crate::error::SolverError;
use crate::steppers::registry::{SolverKind, SolverParams};
use crate::steppers::report::StepReport;

/// A time stepper (or load stepper) of a [`NdModel`].
pub trait NdStepper<D: Dim, E: Hyperelastic<D>> {
    /// Advance `state` by one step. On error the state is left at the last good step.
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError>;
}

/// Any dimension-generic stepper, built from the registry's parameters by [`build`].
pub enum AnyNdStepper<D: Dim> {
    /// Explicit FEM.
    Explicit(NdExplicit<D>),
    /// Implicit Euler by Newton.
    Implicit(NdImplicit<D>),
    /// Quasi-static equilibrium by Newton.
    Static(NdStatic<D>),
    /// Energy-based PBD.
    Pbd(NdPbd<D>),
    /// Energy-based XPBD.
    Xpbd(NdXpbd<D>),
    /// Vertex Block Descent.
    Vbd(NdVbd<D>),
    /// Projective Dynamics (co-rotational energy).
    Pd(NdPd<D>),
    /// Implicit Euler by L-BFGS with the Projective Dynamics matrix.
    QuasiNewton(NdQuasiNewton<D>),
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for AnyNdStepper<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        match self {
            AnyNdStepper::Explicit(s) => s.step(model, state),
            AnyNdStepper::Implicit(s) => s.step(model, state),
            AnyNdStepper::Static(s) => s.step(model, state),
            AnyNdStepper::Pbd(s) => s.step(model, state),
            AnyNdStepper::Xpbd(s) => s.step(model, state),
            AnyNdStepper::Vbd(s) => s.step(model, state),
            AnyNdStepper::Pd(s) => s.step(model, state),
            AnyNdStepper::QuasiNewton(s) => s.step(model, state),
        }
    }
}

/// Build the dimension-generic stepper of `params` for `model`, validating the parameters
/// under `prefix` (the scene's `solver`). A solver without a dimension-generic path, or an
/// option its path does not support, is a one-line error.
pub fn build<D: Dim, E: Hyperelastic<D> + 'static>(
    model: &NdModel<D, E>,
    params: &SolverParams,
    prefix: &str,
) -> Result<AnyNdStepper<D>, SolverError> {
    params.validate_as(prefix)?;
    let kind = params.kind();
    let refuse = |what: String| {
        Err(SolverError::invalid(
            format!("{prefix}.kind"),
            kind.name(),
            what,
        ))
    };
    match params {
        SolverParams::Explicit(p) => Ok(AnyNdStepper::Explicit(NdExplicit::new(*p))),
        SolverParams::Implicit(p) => {
            Ok(AnyNdStepper::Implicit(NdImplicit::new(model, *p, prefix)?))
        }
        SolverParams::Static(p) => Ok(AnyNdStepper::Static(NdStatic::new(model, *p, prefix)?)),
        SolverParams::Pbd(p) => Ok(AnyNdStepper::Pbd(NdPbd::new(model, *p, prefix)?)),
        SolverParams::Xpbd(p) => Ok(AnyNdStepper::Xpbd(NdXpbd::new(model, *p, prefix)?)),
        SolverParams::Vbd(p) => Ok(AnyNdStepper::Vbd(NdVbd::new(model, *p, prefix)?)),
        SolverParams::Pd(p) => Ok(AnyNdStepper::Pd(NdPd::new(model, *p, prefix)?)),
        SolverParams::QuasiNewton(p) => Ok(AnyNdStepper::QuasiNewton(NdQuasiNewton::new(
            model, *p, prefix,
        )?)),
        _ => refuse(format!(
            "has no {} path yet (solvers with one: {})",
            D::NAME,
            with_nd_path().join(", ")
        )),
    }
}

/// The solvers [`build`] accepts.
pub fn with_nd_path() -> Vec<&'static str> {
    SolverKind::ALL
        .into_iter()
        .filter(|k| k.capabilities().dims >= 3)
        .map(|k| k.name())
        .collect()
}

/// Check a step's new positions and velocities; the first non-finite vertex is an error naming
/// the step (1-based, from the state's clock and `dt`) and its values.
pub(crate) fn check_finite<D: Dim>(
    x: &[D::Vector],
    v: &[D::Vector],
    step: u64,
    time: Real,
    report: &StepReport,
) -> Result<(), SolverError> {
    match (0..x.len()).find(|&i| !(x[i].all_finite() && v[i].all_finite())) {
        None => Ok(()),
        Some(i) => Err(SolverError::NonFiniteVertex {
            step,
            time,
            vertex: i,
            position: components::<D>(&x[i]),
            velocity: components::<D>(&v[i]),
            inverted: report.inverted,
            min_det_f: report.min_det_f,
        }),
    }
}

/// `[a, b(, c)]` with 4 decimals in exponent form.
fn components<D: Dim>(p: &D::Vector) -> String {
    let parts: Vec<String> = (0..D::D).map(|k| format!("{:.4e}", p.at(k))).collect();
    format!("[{}]", parts.join(", "))
}

/// The step number (1-based) of the step that starts at `t` with step `dt`.
pub(crate) fn step_number(t: Real, dt: Real) -> u64 {
    (t / dt).round() as u64 + 1
}
