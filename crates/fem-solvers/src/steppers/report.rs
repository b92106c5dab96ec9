//! What a step reports (steppers never print).

use fem_core::math::Real;

/// Summary of one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Smallest `det F` over the elements, at the configuration the last force or constraint
    /// pass evaluated (explicit: the start of the step; PBD/XPBD: the last iteration).
    pub min_det_f: Real,
    /// Elements with `det F <= 0` in that pass.
    pub inverted: usize,
    /// Iterations performed, summed over substeps (0 for explicit): constraint sweeps (PBD,
    /// XPBD), vertex sweeps (VBD), local-global iterations (PD), L-BFGS iterations
    /// (quasi-Newton), Newton iterations (implicit, static), conjugate-gradient iterations
    /// (linearly implicit Euler with CG; 1 with its direct solver). With a residual tolerance (VBD,
    /// PD, XPBD `residual_tolerance`, quasi-Newton `tolerance`) the iterations actually done,
    /// at most the maximum; without, VBD, PD and XPBD do exactly `iterations` per substep.
    pub iterations: usize,
    /// The residual of the last iteration (0 for explicit): PBD `sqrt(sum C^2)`, XPBD
    /// `sqrt(sum (C + alpha~ lambda)^2)`, both over the constraints evaluated in that
    /// iteration, in the constraint's units; implicit, static and quasi-Newton: the gradient
    /// norm over the free degrees of freedom, N; linearly implicit Euler: that norm of implicit
    /// Euler's incremental potential at the step's end (the residual of the step it did not
    /// solve), N. VBD and PD with a positive
    /// `residual_tolerance`: that gradient norm of the incremental potential at the step's end
    /// (VBD: of its last substep), N; with tolerance 0, VBD the largest vertex gradient (or
    /// free body's net force) its last sweep met before each update, N, and PD the largest
    /// position change of its last iteration, m.
    pub residual: Real,
    /// Contact pairs detected (in the last pass): vertices in the ground or an obstacle and
    /// obstacle corners in soft boundary edges ([`crate::Stepper::contacts`] lists them).
    pub contacts: usize,
}

impl StepReport {
    pub(crate) fn explicit(min_det_f: Real, inverted: usize, contacts: usize) -> Self {
        StepReport {
            min_det_f,
            inverted,
            iterations: 0,
            residual: 0.0,
            contacts,
        }
    }
}
