//! The one error type of the crate: bad input (named field and value) and runs that blow up
//! (named step and vertex). Every message is a single line; nothing in this crate panics on
//! bad input.

use fem_core::math::{Real, readable};

/// Why a model could not be built or a step could not be taken.
///
/// fem-core's errors convert into it (`From`), so one `?` carries a program from the material
/// to the last step. New variants may be added.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolverError {
    /// A parameter is outside its domain.
    #[error("{field} = {value}: {rule}")]
    InvalidParameter {
        /// Dotted field name (`explicit.dt`, `contact.stiffness`, ...).
        field: String,
        /// The rejected value, formatted.
        value: String,
        /// What the value must satisfy.
        rule: String,
    },
    /// A vertex index is out of range.
    #[error("{field}: vertex index {index} is out of range (mesh has {n_vertices} vertices)")]
    VertexOutOfRange {
        /// Where the index came from (`pinned`, `prescribed_motion[2]`, ...).
        field: String,
        /// The bad index.
        index: usize,
        /// Number of mesh vertices.
        n_vertices: usize,
    },
    /// The ground is unusable (the body starts below it).
    #[error("ground: {0}")]
    Ground(String),
    /// An obstacle polygon is unusable.
    #[error("obstacles[{index}]: {reason}")]
    Obstacle {
        /// Obstacle index.
        index: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// The state does not belong to the model (vertex or body count differs).
    #[error("state has {got} {what}, model has {expected}")]
    StateMismatch {
        /// `vertices` or `bodies`.
        what: &'static str,
        /// Count in the state.
        got: usize,
        /// Count in the model.
        expected: usize,
    },
    /// A stepper was built for another mesh.
    #[error("stepper was built for a mesh of {expected} triangles, model has {got}")]
    ModelMismatch {
        /// Triangles in the model passed to `step`.
        got: usize,
        /// Triangles the stepper was built for.
        expected: usize,
    },
    /// The run blew up: a position or velocity became NaN or infinite. The state is left at
    /// the last good step.
    #[error(
        "step {step} (t = {time} s): vertex {vertex} became non-finite (x = [{x:.4e}, {y:.4e}], v = [{vx:.4e}, {vy:.4e}]); {inverted} inverted elements, min det F = {min_det_f:.4e}"
    )]
    NonFinite {
        /// Index of the step that failed (0-based count of steps taken before it).
        step: u64,
        /// Time at the start of the failed step, s.
        time: Real,
        /// First vertex (lowest index) with a non-finite position or velocity.
        vertex: usize,
        /// Its would-be x coordinate.
        x: Real,
        /// Its would-be y coordinate.
        y: Real,
        /// Its would-be x velocity.
        vx: Real,
        /// Its would-be y velocity.
        vy: Real,
        /// Inverted elements seen in the failed step.
        inverted: usize,
        /// Smallest det F seen in the failed step.
        min_det_f: Real,
    },
    /// A dimension-generic solver's step produced a non-finite position or velocity; the
    /// state is left at the last good step.
    #[error(
        "step {step} (t = {time} s): vertex {vertex} became non-finite (x = {position}, v = {velocity}); {inverted} inverted elements, min det F = {min_det_f:.4e}"
    )]
    NonFiniteVertex {
        /// The step that failed (1-based).
        step: u64,
        /// Simulated time at the start of that step, s.
        time: Real,
        /// The first bad vertex.
        vertex: usize,
        /// Its would-be position, `[x, y(, z)]` with 4 decimals in exponent form.
        position: String,
        /// Its would-be velocity, likewise.
        velocity: String,
        /// Inverted elements in the last force pass.
        inverted: usize,
        /// The smallest det F in the last force pass.
        min_det_f: Real,
    },
    /// Newton's method did not reach its tolerance (implicit or static solve).
    #[error(
        "step {step}: Newton did not converge in {iterations} iterations (residual {residual:.4e} N); lower dt, add load steps or raise max_iterations"
    )]
    NotConverged {
        /// Index of the step (or load increment) that failed.
        step: u64,
        /// Iterations taken.
        iterations: usize,
        /// Final residual, N.
        residual: Real,
    },
    /// A Newton-family solve that cannot move the body although a load acts on it: the load
    /// is below the round-off of the stiffness and inertia it acts against on every free
    /// unknown (a modulus or a spring beside which it is round-off, or a step so short that it
    /// moves nothing by one unit in the last place of the coordinates), or the first Newton
    /// step is below that round-off while the residual is above it (a Hessian too
    /// ill-conditioned to solve). Raised instead of reporting a step that did not move as
    /// converged.
    #[error(
        "{prefix}: {detail}; a modulus, a spring, the time step or the load is beyond what double precision can solve"
    )]
    BeyondPrecision {
        /// The solver (`implicit`, `static`, ...).
        prefix: &'static str,
        /// What was measured (the load, the floors, the step).
        detail: String,
    },
    /// A load increment of the quasi-static solver failed after every allowed halving.
    #[error(
        "load increment {increment} (load factor {from} to {to}, after {halvings} halvings): {reason}; add load steps or raise max_iterations"
    )]
    LoadIncrement {
        /// 1-based number of the increment that failed.
        increment: usize,
        /// Load factor of the last equilibrium.
        from: Real,
        /// Load factor the increment aimed at.
        to: Real,
        /// Halvings done before giving up.
        halvings: usize,
        /// Why the last attempt failed.
        reason: String,
    },
    /// A solver name is not one of [`SolverKind::ALL`](crate::SolverKind::ALL).
    #[error("unknown solver `{name}` (expected one of: {expected})")]
    UnknownSolver {
        /// The name given.
        name: String,
        /// The solvers' names, comma-separated in table order (the registry fills them in).
        expected: String,
    },
    /// A rigid body's pose or velocity became NaN or infinite.
    #[error("step {step}: rigid body of obstacles[{body}] became non-finite")]
    NonFiniteBody {
        /// Index of the failed step.
        step: u64,
        /// Obstacle index.
        body: usize,
    },
    /// A rigid region's body became NaN or infinite.
    #[error("step {step}: rigid body {body} (of the rigid regions) became non-finite")]
    NonFiniteRigid {
        /// Index of the failed step.
        step: u64,
        /// Rigid body index ([`Model::rigid_bodies`](crate::Model::rigid_bodies)).
        body: usize,
    },
    /// The mesh was rejected ([`Mesh::new`](fem_core::mesh::Mesh::new)); `?` converts it.
    #[error("mesh: {0}")]
    Mesh(#[from] fem_core::mesh::MeshError),
    /// A material constant or Lamé parameter was rejected; `?` converts it.
    #[error(transparent)]
    Material(#[from] fem_core::MaterialError),
    /// An energy could not be chosen or built; `?` converts it.
    #[error(transparent)]
    Energy(#[from] fem_core::energy::EnergyError),
}

impl SolverError {
    /// Shorthand for [`SolverError::InvalidParameter`].
    pub fn invalid(
        field: impl Into<String>,
        value: impl ToString,
        rule: impl Into<String>,
    ) -> Self {
        SolverError::InvalidParameter {
            field: field.into(),
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

/// `Ok` when `value` is finite and > 0.
pub(crate) fn check_positive(field: &str, value: Real) -> Result<(), SolverError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            readable(value),
            "must be a finite number > 0",
        ))
    }
}

/// `Ok` when `value` is finite and >= 0.
pub(crate) fn check_non_negative(field: &str, value: Real) -> Result<(), SolverError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            readable(value),
            "must be a finite number >= 0",
        ))
    }
}

/// `Ok` when `1 <= n <= max`.
pub(crate) fn check_count(field: &str, n: usize, max: usize) -> Result<(), SolverError> {
    if n == 0 {
        Err(SolverError::invalid(field, n, "must be at least 1"))
    } else {
        check_at_most(field, n, max)
    }
}

/// `Ok` when `n <= max`.
pub(crate) fn check_at_most(field: &str, n: usize, max: usize) -> Result<(), SolverError> {
    if n <= max {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            n,
            format!("must be at most {max} (fem_solvers::limits)"),
        ))
    }
}

/// `Ok` when `value` lies in the open interval `(0, 2)` (a relaxation factor).
pub(crate) fn check_relaxation(field: &str, value: Real) -> Result<(), SolverError> {
    if value > 0.0 && value < 2.0 {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            readable(value),
            "must lie in the open interval (0, 2)",
        ))
    }
}

/// `Ok` when both components are finite.
pub(crate) fn check_finite_vec(field: &str, v: fem_core::math::Vec2) -> Result<(), SolverError> {
    if v.x.is_finite() && v.y.is_finite() {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            format!("[{}, {}]", v.x, v.y),
            "components must be finite",
        ))
    }
}

/// A relative residual tolerance of an iterative solver, in `[0, 1)` (0: a fixed count of
/// iterations).
pub(crate) fn check_residual_tolerance(field: &str, tolerance: Real) -> Result<(), SolverError> {
    if (0.0..1.0).contains(&tolerance) {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            readable(tolerance),
            "must be in [0, 1) (relative to the residual's scale; 0 runs every iteration)",
        ))
    }
}

/// A Chebyshev spectral radius estimate `rho`, in `[0, 1)` (0 turns the acceleration off).
pub(crate) fn check_rho(field: &str, rho: Real) -> Result<(), SolverError> {
    if (0.0..1.0).contains(&rho) {
        Ok(())
    } else {
        Err(SolverError::invalid(
            field,
            rho,
            "must be in [0, 1) (0 turns the acceleration off)",
        ))
    }
}
