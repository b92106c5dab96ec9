//! The contact parameters a model carries ([`ContactParams`]): the penalty spring of the
//! explicit stepper, Coulomb friction, and the barrier of the implicit family. The laws that
//! use them are in [`crate::contact`].

use fem_core::math::Real;

use crate::error::{SolverError, check_non_negative, check_positive};

/// Penalty contact parameters (explicit stepper). Projection contact has none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactParams {
    /// Penalty stiffness per unit vertex mass, 1/s^2 (`sqrt` of it is the contact frequency in
    /// rad/s). Default `1e6` (stable for `dt` below about 1.2 ms with the default damping).
    pub stiffness: Real,
    /// Damping ratio of the penalty spring, dimensionless (1 = critically damped for a lone
    /// vertex). Default `0.5`.
    pub damping_ratio: Real,
    /// Coulomb friction coefficient `mu`, dimensionless (>= 0; 0 = frictionless). Used by both
    /// penalty, projection and barrier contact. Default `0.5`.
    pub friction: Real,
    /// Barrier contact (implicit and static solvers): the activation distance `d_hat`, m
    /// (> 0): pairs closer than this repel. Default `1e-3`.
    pub barrier_distance: Real,
    /// Barrier contact: the stiffness `kappa` of the log barrier, N/m^4 per unit thickness
    /// (>= 0; 0 = automatic, `M / (8 d_hat^2)` with `M` the body's P-wave modulus). Default 0.
    pub barrier_stiffness: Real,
    /// Barrier contact in implicit Euler: the slip speed below which friction sticks
    /// (IPC's `eps_v`), m/s (> 0). Default `1e-3`.
    pub friction_velocity: Real,
}

impl Default for ContactParams {
    fn default() -> Self {
        ContactParams {
            stiffness: 1e6,
            damping_ratio: 0.5,
            friction: 0.5,
            barrier_distance: 1e-3,
            barrier_stiffness: 0.0,
            friction_velocity: 1e-3,
        }
    }
}

impl ContactParams {
    pub(crate) fn validate(&self) -> Result<(), SolverError> {
        check_positive("contact.stiffness", self.stiffness)?;
        check_non_negative("contact.damping_ratio", self.damping_ratio)?;
        check_non_negative("contact.friction", self.friction)?;
        check_positive("contact.barrier_distance", self.barrier_distance)?;
        check_non_negative("contact.barrier_stiffness", self.barrier_stiffness)?;
        check_positive("contact.friction_velocity", self.friction_velocity)
    }

    /// The largest explicit time step for which the penalty spring is stable, s.
    pub fn critical_time_step(&self) -> Real {
        let z = self.damping_ratio;
        2.0 * ((1.0 + z * z).sqrt() - z) / self.stiffness.sqrt()
    }
}
