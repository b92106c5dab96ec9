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
    /// Constraint iterations performed (summed over substeps; 0 for explicit), or Newton
    /// iterations (implicit).
    pub iterations: usize,
    /// Constraint residual of the last iteration (0 for explicit): PBD `sqrt(sum C^2)`, XPBD
    /// `sqrt(sum (C + alpha~ lambda)^2)`, both over the constraints evaluated in that
    /// iteration, in the constraint's units; implicit: the Newton residual (gradient norm over
    /// the free degrees of freedom, N).
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
