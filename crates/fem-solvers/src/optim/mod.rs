//! What the implicit family solves with: Newton on a potential over the free degrees of freedom
//! ([`newton`]: projected Hessians, a line search, faer's sparse Cholesky with the symbolic
//! analysis done once), used by implicit Euler and the static solver, and Projective Dynamics'
//! constant global matrix `M / h^2 + L` (`pd_system`: assembled and factorised once), used by
//! Projective Dynamics and the quasi-Newton solver.
//!
//! It reads the model and barrier contact (whose terms Newton's potential adds); it knows no
//! stepper.

pub mod newton;
pub(crate) mod pd_system;
