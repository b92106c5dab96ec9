//! Energy-based PBD (Bender, Koschier, Charrier & Weber 2014; paper Eqs. 4-6) and XPBD
//! (Macklin, Müller & Chentanez 2016; paper Algorithm II and Eq. 7), one constraint per
//! triangle, sharing one prediction / projection / velocity-update loop.
//!
//! Each (sub)step of length `h`: predict `v' = v + h (g + M^-1 f_ext)`, `x* = x + h v'`
//! (Algorithm II lines 1-2); reset the multipliers; run `iterations` sweeps over the triangle
//! constraints, each followed by contact projection; then `v = (x* - x) / h`, damped by
//! `exp(-c h)` (lines 12-13).
//!
//! Per triangle with rest area `a` and vertices `j`, `grad_j psi_e = a P g_j` (the energy
//! gradient of Eq. 4, with `g_j` the shape-function gradients) and `w_j = 1/m_j`:
//! - **PBD**: `C = a psi(F)`, `s = -C / sum_j w_j |grad_j C|^2` (Eq. 5),
//!   `dx_j = k w_j s grad_j C` (Eq. 6) with the stiffness `k` in `(0, 1]`. The response depends
//!   on `dt` and on the iteration count: that is the paper's case C observation.
//! - **XPBD, consistent form** (default): `C = sqrt(2 a psi)`, whose gradient is
//!   `a P g_j / C`, and compliance `alpha~ = alpha / h^2` with `alpha` =
//!   [`XpbdParams::compliance`] (default 1, dimensionless): the constraint energy
//!   `C^2 / (2 alpha)` is then exactly the element's elastic energy `a psi`: the constraint
//!   energy is the true one, and implicit Euler of it is what XPBD approximates. It does not
//!   converge to it as iterations grow. The sweeps converge to a point where every constraint
//!   equation `C + alpha~ lambda = 0` holds, but the primal residual
//!   `M (x - x*) - sum_j grad C_j(x) lambda_j` is neglected (each correction follows the
//!   gradient where the sweep was), so the limit is one of many points satisfying the
//!   constraints and depends on the ordering. Measured on case A (20 x 4 cells, `\` diagonals,
//!   Neo-Hookean), tip after 30 steps of 10 ms: implicit Euler -0.6100 m; XPBD Gauss-Seidel
//!   -0.6156, coloured -0.6134, Jacobi -0.6116, each unchanged (to 3e-7 m) from 1000 to 8000
//!   iterations: 1.6 to 5.6 mm from implicit Euler, and ordering-dependent.
//! - **XPBD, literal form** (the paper's text): `C = a psi` with the same update. Then
//!   `C^2 / (2 alpha)` is `(a psi)^2 / (2 alpha)`, quartic in the strain: `alpha` (units 1/J
//!   per unit thickness) has no material meaning and the response depends on the mesh.
//!
//! Both: `dlambda = (-C - alpha~ lambda) / (sum_j w_j |grad_j C|^2 + alpha~)`,
//! `dx_j = w_j grad_j C dlambda`, and `lambda` accumulates over the iterations of a (sub)step
//! (reset to 0 at its start).
//!
//! **Rest threshold.** At rest `psi = 0` and `C = sqrt(2 a psi)` has no gradient direction
//! (`0/0`); rounding makes `psi` noise of order `1e-16` times the modulus there. A constraint
//! is skipped when `psi <= rest_threshold * M`, with `M` the P-wave modulus of the energy
//! ([`Model::p_wave_modulus`]) and `rest_threshold` a named parameter (default `1e-14`, i.e.
//! strains below about `1e-7`). A NaN `psi` is not skipped, so blow-ups surface.
//!
//! **Orderings** ([`Ordering`]): plain Gauss-Seidel in triangle order (serial); coloured
//! Gauss-Seidel (triangles grouped by a greedy colouring; each colour's corrections are
//! computed in parallel over its triangles, then applied in parallel over vertex chunks through
//! a per-colour vertex-sorted corner list; default); Jacobi (every constraint from the same positions, corrections summed per vertex).
//! Jacobi scales each constraint's step (its `dlambda` and so its `dx` alike) by
//! `relaxation / max_j n_j` (`relaxation` = [`PbdParams::relaxation`], [`XpbdParams::relaxation`]), with `n_j` the number of triangles at vertex `j`: unlike
//! per-vertex averaging of `dx` alone, this keeps positions and multipliers consistent, so
//! Jacobi XPBD converges (more slowly than Gauss-Seidel), to a limit of its own: like every
//! ordering's, it satisfies the constraints but not the primal equation, and it differs from
//! the Gauss-Seidel orderings' by a few tenths of a millimetre to several millimetres on case
//! A (above). Each gives bit-identical states for any thread count:
//! within a colour no two constraints share a vertex, so parallel evaluation followed by
//! application equals the in-place serial sweep, and Jacobi sums per vertex in element order.
//!
//! **Rigid regions** ([`crate::rigid::body`]; Müller, Macklin, Chentanez, Jeschke & Kim 2020,
//! "Detailed rigid body simulation with extended position based dynamics"): only the
//! deformable triangles ([`Model::elastic_mesh`]) are constraints. A free body is predicted as
//! the vertices are (gravity, and the external forces on its vertices as a force and a torque
//! about its centroid) and its vertices are placed on the predicted pose. A constraint with
//! corners on a free body reads them from the body's pose and moves the body as one particle
//! with its generalised inverse mass: with `G = sum_j grad_j C` and
//! `T = sum_j (x_j - p) x grad_j C` over those corners, the denominator gets
//! `|G|^2 / m + T^2 / I` in place of their `w_j |grad_j C|^2`, and the body moves by
//! `dp = G dlambda / m`, `dtheta = T dlambda / I` (in 2D the angle is one number: the update
//! is exact, only the constraint is linearised). All such constraints move the same body, so
//! they leave the colouring (and Jacobi) and are projected serially, in triangle order, after
//! each sweep's other constraints: states stay bit-identical on any thread count. After each
//! sweep the bodies' vertices are placed on their poses; at the end of the substep a body's
//! velocities are `(p - p_old) / h` and `(theta - theta_old) / h`, damped as the vertices', and
//! the step's end places its vertices. Linear momentum is kept to round-off (the corrections
//! are mass-weighted and the gradients sum to zero); angular momentum drifts by `O(h)`, as for
//! the vertices alone (positions-based velocities). Contact projection treats slaved vertices
//! as kinematic: it does not push a body. Without rigid regions nothing changes, bits included.
//!
//! **XPBD settings** ([`XpbdSchedule`], [`LambdaReset`]): "small steps" (Macklin et al. 2019)
//! spends the `substeps x iterations` sweeps as that many substeps of one sweep; resetting the
//! multipliers before every sweep is available only to show that it stiffens the body with the
//! iterations.
//!
//! **XPBD's residual tolerance** (`tolerance`, scene key `residual_tolerance`; 0 = off, the
//! default): with a positive tolerance a substep stops its sweeps once a sweep's constraint
//! residual `sqrt(sum (C + alpha~ lambda)^2)` (each constraint's, as its projection in that
//! sweep found it; the report's residual) is at most `tolerance` times that of the substep's
//! first sweep. The residual is a by-product of the sweep, so the test costs nothing; the
//! report gives the sweeps done, summed over substeps. It is relative to the first sweep, not
//! to a force: XPBD's sweeps converge to their own fixed point, not to implicit Euler's step
//! (above), and the primal residual they neglect is not measured.
//!
//! Registered as `pbd` and `xpbd` ([`Solver`]); scene keys: `dt`, `substeps`, `iterations`,
//! `damping`, `ordering` (`"gauss-seidel"` | `"coloured"` | `"jacobi"`), `relaxation`,
//! `rest_threshold`, and PBD's `stiffness` or XPBD's `compliance`, `xpbd_form`
//! (`"consistent"` | `"literal"`), `xpbd_schedule`, `xpbd_lambda_reset` and
//! `residual_tolerance`.

use fem_core::energy::{ElementEnergies, Energy};
use fem_core::math::{Real, Vec2, exp};
use fem_core::mesh::VertexAdjacency;
use fem_core::par::prelude::*;

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::penalty::{ContactWorkspace, project_contacts};
use crate::error::{
    SolverError, check_count, check_non_negative, check_positive, check_relaxation,
    check_residual_tolerance,
};
use crate::kernel::{
    ELEMENT_CHUNK, Inversion, PackedElement, VERTEX_CHUNK, deformation_gradient, energy_gradients,
};
use crate::model::Model;
use crate::model::grab::Spring;
use crate::model::limits;
use crate::model::state::State;
use crate::rigid::{BodyState, Frame, ObstacleMotion, RigidBody, cross};
use crate::steppers::colour::Colouring;
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// The order in which triangle constraints are projected. Serde names: `gauss-seidel`,
/// `coloured`, `jacobi`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
pub enum Ordering {
    /// Gauss-Seidel in triangle index order (serial; the paper's loop).
    GaussSeidel,
    /// Gauss-Seidel by colour classes, each class in parallel. Default.
    #[default]
    Coloured,
    /// Jacobi: all constraints from the same positions, each step scaled by
    /// `relaxation / max_j n_j` (see the module docs and the parameters' `relaxation`),
    /// corrections summed per vertex.
    Jacobi,
}

/// Parameters of [`PbdStepper`] (scene keys: the field names).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct PbdParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Substeps per step (>= 1); each substep is a full PBD step of `dt / substeps`. Default 1.
    pub substeps: usize,
    /// Constraint sweeps per substep (>= 1). Default 10.
    pub iterations: usize,
    /// PBD stiffness `k` in `(0, 1]`, dimensionless: the fraction of each projection applied.
    /// Default 1.
    pub stiffness: Real,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c h)` per substep). Default 0.
    pub damping: Real,
    /// Constraint ordering. Default coloured Gauss-Seidel.
    pub ordering: Ordering,
    /// Jacobi relaxation factor, dimensionless, in the open interval `(0, 2)` (checked
    /// whatever the ordering; used only by [`Ordering::Jacobi`]). 1 is safe; larger converges
    /// faster but can oscillate. Default 1.
    pub relaxation: Real,
    /// Skip a constraint when `psi <= rest_threshold * M` (see the module docs),
    /// dimensionless. Default `1e-14`.
    pub rest_threshold: Real,
}

impl Default for PbdParams {
    fn default() -> Self {
        PbdParams {
            dt: 1e-3,
            substeps: 1,
            iterations: 10,
            stiffness: 1.0,
            damping: 0.0,
            ordering: Ordering::default(),
            relaxation: 1.0,
            rest_threshold: 1e-14,
        }
    }
}

/// Which constraint function XPBD uses. Serde names: `consistent`, `literal`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
#[non_exhaustive]
pub enum XpbdForm {
    /// `C = sqrt(2 a psi)`: compliance 1 reproduces the elastic energy. Default.
    #[default]
    Consistent,
    /// `C = a psi`: the paper's text (compliance without material meaning).
    Literal,
}

/// How XPBD spends its `substeps x iterations` constraint sweeps per step. Serde names:
/// `iterations`, `small-steps`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
#[non_exhaustive]
pub enum XpbdSchedule {
    /// `substeps` substeps of `iterations` sweeps each, as given. Default.
    #[default]
    Iterations,
    /// "Small steps" (Macklin, Storey, Lu, Terdiman, Chentanez, Jeschke & Müller, "Small Steps
    /// in Physics Simulation", SCA 2019): the same number of sweeps spent as
    /// `substeps x iterations` substeps of one sweep each.
    SmallSteps,
}

/// When XPBD's multipliers `lambda` return to zero. Serde names: `step`, `iteration`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
pub enum LambdaReset {
    /// At the start of each (sub)step, accumulating over its sweeps (Algorithm II). Default.
    #[default]
    Step,
    /// Before every sweep. This exists only to show why it is wrong: each sweep then solves
    /// for the whole constraint force again from the current positions, so the corrections of
    /// the sweeps add up and the body gets stiffer with every extra iteration, like PBD
    /// (`tests/suite/position_based.rs` measures it).
    Iteration,
}

/// Parameters of [`XpbdStepper`] (scene keys: the field names, with `form` read as
/// `xpbd_form`, `schedule` as `xpbd_schedule` and `lambda_reset` as `xpbd_lambda_reset`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct XpbdParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Substeps per step (>= 1); each substep is a full XPBD step of `dt / substeps`. Default 1.
    pub substeps: usize,
    /// Constraint sweeps per substep (>= 1). Default 10.
    pub iterations: usize,
    /// Compliance `alpha` (finite, >= 0); `alpha~ = alpha / h^2`. Consistent form:
    /// dimensionless, 1 = the material's own stiffness, 2 = twice as soft. Literal form: 1/J per
    /// unit thickness. Default 1.
    pub compliance: Real,
    /// Constraint function (scene key `xpbd_form`). Default consistent.
    #[cfg_attr(feature = "serde", serde(rename = "xpbd_form"))]
    pub form: XpbdForm,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c h)` per substep). Default 0.
    pub damping: Real,
    /// Constraint ordering. Default coloured Gauss-Seidel.
    pub ordering: Ordering,
    /// Jacobi relaxation factor, dimensionless, in the open interval `(0, 2)` (checked
    /// whatever the ordering; used only by [`Ordering::Jacobi`]). 1 is safe; larger converges
    /// faster but can oscillate. Default 1.
    pub relaxation: Real,
    /// Skip a constraint when `psi <= rest_threshold * M` (see the module docs),
    /// dimensionless. Default `1e-14`.
    pub rest_threshold: Real,
    /// How the sweeps are spent (scene key `xpbd_schedule`). Default as given.
    #[cfg_attr(feature = "serde", serde(rename = "xpbd_schedule"))]
    pub schedule: XpbdSchedule,
    /// When the multipliers return to zero (scene key `xpbd_lambda_reset`). Default each
    /// (sub)step.
    #[cfg_attr(feature = "serde", serde(rename = "xpbd_lambda_reset"))]
    pub lambda_reset: LambdaReset,
    /// Relative residual tolerance in `[0, 1)`, dimensionless (scene key
    /// `residual_tolerance`): when positive, a substep stops its sweeps once the constraint
    /// residual of a sweep, `sqrt(sum (C + alpha~ lambda)^2)`, is at most `tolerance` times
    /// that of its first sweep; `iterations` is then the most sweeps (with `small-steps` every
    /// substep has one sweep, so nothing stops early). 0 runs exactly `iterations` sweeps.
    /// Default 0.
    #[cfg_attr(feature = "serde", serde(rename = "residual_tolerance"))]
    pub tolerance: Real,
}

impl Default for XpbdParams {
    fn default() -> Self {
        XpbdParams {
            dt: 1e-3,
            substeps: 1,
            iterations: 10,
            compliance: 1.0,
            form: XpbdForm::Consistent,
            damping: 0.0,
            ordering: Ordering::default(),
            relaxation: 1.0,
            rest_threshold: 1e-14,
            schedule: XpbdSchedule::default(),
            lambda_reset: LambdaReset::default(),
            tolerance: 0.0,
        }
    }
}

impl PbdParams {
    /// Check every field; errors name `pbd.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(PbdStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_count(&field("substeps"), self.substeps, limits::MAX_SUBSTEPS)?;
        check_count(
            &field("iterations"),
            self.iterations,
            limits::MAX_ITERATIONS,
        )?;
        if !(self.stiffness > 0.0 && self.stiffness <= 1.0) {
            return Err(SolverError::invalid(
                field("stiffness"),
                self.stiffness,
                "must lie in (0, 1]",
            ));
        }
        check_non_negative(&field("damping"), self.damping)?;
        check_relaxation(&field("relaxation"), self.relaxation)?;
        check_non_negative(&field("rest_threshold"), self.rest_threshold)
    }
}

impl XpbdParams {
    /// Check every field; errors name `xpbd.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(XpbdStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_count(&field("substeps"), self.substeps, limits::MAX_SUBSTEPS)?;
        check_count(
            &field("iterations"),
            self.iterations,
            limits::MAX_ITERATIONS,
        )?;
        check_non_negative(&field("compliance"), self.compliance)?;
        check_non_negative(&field("damping"), self.damping)?;
        check_relaxation(&field("relaxation"), self.relaxation)?;
        if self.schedule == XpbdSchedule::SmallSteps
            && self.substeps.saturating_mul(self.iterations) > limits::MAX_SUBSTEPS
        {
            return Err(SolverError::invalid(
                field("iterations"),
                self.iterations,
                format!(
                    "with xpbd_schedule = \"small-steps\", substeps x iterations must be at most {} (fem_solvers::limits::MAX_SUBSTEPS)",
                    limits::MAX_SUBSTEPS
                ),
            ));
        }
        check_non_negative(&field("rest_threshold"), self.rest_threshold)?;
        check_residual_tolerance(&field("residual_tolerance"), self.tolerance)
    }
}

/// The projection rule with its per-substep constants.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Rule {
    Pbd { stiffness: Real },
    Consistent { alpha_tilde: Real },
    Literal { alpha_tilde: Real },
}

/// What one constraint projection produced.
#[derive(Clone, Copy, Debug)]
struct Projection {
    dx: [Vec2; 3],
    active: bool,
    det: Real,
    residual2: Real,
}

/// Project one triangle constraint from positions `x` (read only); updates its multiplier.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn project_one<E: Energy>(
    energy: &ElementEnergies<E>,
    el: &PackedElement,
    x: &[Vec2],
    w: &[Real],
    rule: Rule,
    psi_threshold: Real,
    scale: Real,
    lambda: &mut Real,
) -> Projection {
    let f = deformation_gradient(el, x);
    let det = f.determinant();
    let skip = |residual2| Projection {
        dx: [Vec2::zeros(); 3],
        active: false,
        det,
        residual2,
    };
    let (psi, p) = el.energy(energy).psi_pk1(&f);
    if psi <= psi_threshold {
        return skip(0.0);
    }
    let (g1, g2) = energy_gradients(el, &p);
    let g0 = -(g1 + g2);
    let [i0, i1, i2] = el.idx;
    let (w0, w1, w2) = (w[i0 as usize], w[i1 as usize], w[i2 as usize]);
    let s = w0 * g0.norm_squared() + w1 * g1.norm_squared() + w2 * g2.norm_squared();
    let (m, residual2) = match multiplier(rule, el.area, psi, s, scale, lambda) {
        Ok(m) => m,
        Err(residual2) => return skip(residual2),
    };
    Projection {
        dx: [g0 * (w0 * m), g1 * (w1 * m), g2 * (w2 * m)],
        active: true,
        det,
        residual2,
    }
}

/// The factor `m` of a constraint's corrections `dx_j = w_j m grad_j (a psi)` and its squared
/// residual, from the element's `a`, `psi` and `s = sum_j w_j |grad_j (a psi)|^2` (a free
/// rigid body counts with its generalised inverse mass); updates the multiplier. `Err` (with
/// the residual) when the constraint has no direction to move in (`s <= 0`).
#[inline(always)]
fn multiplier(
    rule: Rule,
    area: Real,
    psi: Real,
    s: Real,
    scale: Real,
    lambda: &mut Real,
) -> Result<(Real, Real), Real> {
    match rule {
        Rule::Pbd { stiffness } => {
            let c = area * psi;
            if s <= 0.0 {
                return Err(c * c);
            }
            Ok((-stiffness * scale * c / s, c * c))
        }
        Rule::Consistent { alpha_tilde } => {
            if s <= 0.0 {
                return Err(0.0);
            }
            let c = (2.0 * area * psi).sqrt();
            let inv_c = 1.0 / c;
            let r = c + alpha_tilde * *lambda;
            let dl = -scale * r / (s * inv_c * inv_c + alpha_tilde);
            *lambda += dl;
            Ok((dl * inv_c, r * r))
        }
        Rule::Literal { alpha_tilde } => {
            if s <= 0.0 {
                return Err(0.0);
            }
            let c = area * psi;
            let r = c + alpha_tilde * *lambda;
            let dl = -scale * r / (s + alpha_tilde);
            *lambda += dl;
            Ok((dl, r * r))
        }
    }
}

/// Which corners of a constraint are slaved to a free rigid body, and their rest offsets from
/// its centroid.
#[derive(Clone, Copy, Debug)]
struct BodyLink {
    /// The free body of each corner ([`BodyLink::NONE`]: none; the corner is a vertex).
    body: [u32; 3],
    /// Each slaved corner's rest offset (zero for the others).
    offset: [Vec2; 3],
}

impl BodyLink {
    const NONE: u32 = u32::MAX;

    /// The link of `el`, or `None` when no corner is slaved to a free body.
    fn of<E: Energy>(model: &Model<E>, el: &PackedElement) -> Option<BodyLink> {
        let bodies = model.rigid_bodies();
        let mut link = BodyLink {
            body: [Self::NONE; 3],
            offset: [Vec2::zeros(); 3],
        };
        for (k, &v) in el.idx.iter().enumerate() {
            if let Some(b) = model.rigid_body_of(v as usize)
                && bodies[b].is_free()
            {
                let body = &bodies[b];
                let i = body.vertices.binary_search(&v).expect("slaved vertex");
                link.body[k] = b as u32;
                link.offset[k] = body.offsets[i];
            }
        }
        link.body.iter().any(|&b| b != Self::NONE).then_some(link)
    }
}

/// Project one constraint with corners slaved to free rigid bodies (Müller et al. 2020), in
/// place: slaved corners are read from their body's pose in `poses`, each body `b` enters the
/// denominator with its generalised inverse mass along its generalised gradient
/// (`|G|^2 / m_b + T^2 / I_b`, `G = sum grad_j`, `T = sum (x_j - p_b) x grad_j` over its
/// corners) and moves by `dp = m G / m_b`, `dtheta = m T / I_b`; the other corners move as in
/// [`project_one`].
#[allow(clippy::too_many_arguments)]
fn project_linked<E: Energy>(
    energy: &ElementEnergies<E>,
    el: &PackedElement,
    link: &BodyLink,
    x: &mut [Vec2],
    w: &[Real],
    bodies: &[RigidBody],
    poses: &mut [BodyState],
    rule: Rule,
    psi_threshold: Real,
    lambda: &mut Real,
) -> Projection {
    let idx = el.idx.map(|i| i as usize);
    let mut xs = idx.map(|i| x[i]);
    for k in 0..3 {
        if link.body[k] != BodyLink::NONE {
            xs[k] = Frame::of(&poses[link.body[k] as usize]).apply(link.offset[k]);
        }
    }
    let local = PackedElement {
        idx: [0, 1, 2],
        ..*el
    };
    let f = deformation_gradient(&local, &xs);
    let det = f.determinant();
    let skip = |residual2| Projection {
        dx: [Vec2::zeros(); 3],
        active: false,
        det,
        residual2,
    };
    let (psi, p) = el.energy(energy).psi_pk1(&f);
    if psi <= psi_threshold {
        return skip(0.0);
    }
    let (g1, g2) = energy_gradients(el, &p);
    let g = [-(g1 + g2), g1, g2];
    // The generalised gradients (G, T) of the (at most three) bodies, by first corner.
    let mut wk = [0.0; 3];
    let mut moved = [(BodyLink::NONE, Vec2::zeros(), 0.0); 3];
    let mut s = 0.0;
    for k in 0..3 {
        let b = link.body[k];
        if b == BodyLink::NONE {
            wk[k] = w[idx[k]];
            s += wk[k] * g[k].norm_squared();
        } else {
            let slot = moved
                .iter()
                .position(|e| e.0 == b || e.0 == BodyLink::NONE)
                .expect("three corners");
            let arm = xs[k] - poses[b as usize].position;
            let e = &mut moved[slot];
            e.0 = b;
            e.1 += g[k];
            e.2 += cross(arm, g[k]);
        }
    }
    for &(b, gf, gt) in moved.iter().take_while(|e| e.0 != BodyLink::NONE) {
        let (im, ii) = bodies[b as usize].inverse_mass();
        s += gf.norm_squared() * im + gt * gt * ii;
    }
    let (m, residual2) = match multiplier(rule, el.area, psi, s, 1.0, lambda) {
        Ok(m) => m,
        Err(residual2) => return skip(residual2),
    };
    let dx = [g[0] * (wk[0] * m), g[1] * (wk[1] * m), g[2] * (wk[2] * m)];
    for (&i, d) in idx.iter().zip(&dx) {
        x[i] += d;
    }
    for &(b, gf, gt) in moved.iter().take_while(|e| e.0 != BodyLink::NONE) {
        let (im, ii) = bodies[b as usize].inverse_mass();
        let pose = &mut poses[b as usize];
        pose.position += gf * (m * im);
        pose.angle += gt * (m * ii);
    }
    Projection {
        dx,
        active: true,
        det,
        residual2,
    }
}

/// Statistics of one sweep, accumulated per fixed chunk so sums do not depend on threads.
#[derive(Clone, Copy, Debug)]
struct SweepStats {
    inv: Inversion,
    residual2: Real,
}

impl SweepStats {
    const EMPTY: SweepStats = SweepStats {
        inv: Inversion::EMPTY,
        residual2: 0.0,
    };

    #[inline(always)]
    fn add(&mut self, p: &Projection) {
        self.inv.add(p.det);
        self.residual2 += p.residual2;
    }

    fn merge(&mut self, other: &SweepStats) {
        self.inv = Inversion::merge(self.inv, other.inv);
        self.residual2 += other.residual2;
    }
}

#[inline(always)]
fn apply(x: &mut [Vec2], el: &PackedElement, p: &Projection) {
    if p.active {
        let [i0, i1, i2] = el.idx;
        x[i0 as usize] += p.dx[0];
        x[i1 as usize] += p.dx[1];
        x[i2 as usize] += p.dx[2];
    }
}

/// The shared position-based engine.
#[derive(Clone, Debug)]
struct Engine {
    dt: Real,
    substeps: usize,
    iterations: usize,
    damping: Real,
    rest_threshold: Real,
    ordering: Ordering,
    /// Kind of rule with the compliance / stiffness before scaling by `h`.
    rule: Rule,
    n_triangles: usize,
    /// Elements in sweep order (coloured order for [`Ordering::Coloured`], else triangle
    /// order) and the colour ranges into it (one range for the other orderings); the elements
    /// touching a free rigid body follow, from `linked_start` on, in triangle order.
    elements: Vec<PackedElement>,
    ranges: Vec<(usize, usize)>,
    n_colours: usize,
    /// Where the elements touching free rigid bodies start in `elements`, and their links.
    linked_start: usize,
    links: Vec<BodyLink>,
    /// Jacobi with rigid bodies only: the vertex adjacency of the elements before
    /// `linked_start` (the elastic mesh's is used otherwise).
    jacobi_adjacency: Option<VertexAdjacency>,
    lambda: Vec<Real>,
    /// Zero the multipliers before every sweep ([`LambdaReset::Iteration`]).
    reset_lambda_each_sweep: bool,
    /// Stop a substep's sweeps once the constraint residual is at most this fraction of its
    /// first sweep's (XPBD's `residual_tolerance`; 0: every sweep, and always for PBD).
    tolerance: Real,
    x_pred: Vec<Vec2>,
    v_new: Vec<Vec2>,
    corrections: Vec<Projection>,
    chunk_stats: Vec<SweepStats>,
    /// Per element (Jacobi only): `relaxation / max_j n_j`, with `n_j` the number of
    /// triangles at vertex `j`.
    jacobi_scale: Vec<Real>,
    /// Coloured ordering only: the parallel application of a colour's corrections as a
    /// per-vertex gather (see [`ColourScatter`]).
    colour_scatter: ColourScatter,
    bodies_pred: Vec<BodyState>,
    /// The rigid regions' predicted and projected poses (entries of bodies that are not free
    /// are unused).
    rigid_pred: Vec<BodyState>,
    /// The multipliers of the grab's springs (one vector per spring), zeroed every substep.
    grab_lambda: Vec<Vec2>,
    /// Contact scratch and the last substep's contact records.
    contact: ContactWorkspace,
}

/// For each colour, the corners of its triangles sorted by vertex, so a colour's corrections
/// can be applied by disjoint vertex chunks in parallel. Within a colour every vertex belongs
/// to at most one triangle, so each vertex receives at most one correction per colour and the
/// order of application cannot change the result: it equals the serial in-place sweep.
#[derive(Clone, Debug, Default)]
struct ColourScatter {
    /// `(vertex, 3 * t + corner)` with `t` the triangle's position within its colour, sorted
    /// by vertex within each colour.
    corners: Vec<(u32, u32)>,
    /// Per colour, `n_vertex_chunks + 1` offsets into `corners`: chunk `c` of the colour's
    /// corners holds the vertices in `[c * VERTEX_CHUNK, (c + 1) * VERTEX_CHUNK)`.
    offsets: Vec<Vec<usize>>,
}

impl ColourScatter {
    fn new(elements: &[PackedElement], ranges: &[(usize, usize)], n_vertices: usize) -> Self {
        let n_chunks = n_vertices.div_ceil(VERTEX_CHUNK);
        let mut corners = Vec::with_capacity(3 * elements.len());
        let mut offsets = Vec::with_capacity(ranges.len());
        for &(a, b) in ranges {
            let start = corners.len();
            for (t, el) in elements[a..b].iter().enumerate() {
                for (k, &v) in el.idx.iter().enumerate() {
                    corners.push((v, (3 * t + k) as u32));
                }
            }
            let colour = &mut corners[start..];
            colour.sort_unstable();
            debug_assert!(
                colour.windows(2).all(|w| w[0].0 < w[1].0),
                "colour shares a vertex"
            );
            let colour = &corners[start..];
            offsets.push(
                (0..=n_chunks)
                    .map(|c| {
                        start + colour.partition_point(|&(v, _)| (v as usize) < c * VERTEX_CHUNK)
                    })
                    .collect(),
            );
        }
        ColourScatter { corners, offsets }
    }

    /// Add colour `colour`'s corrections `corr` (indexed by position within the colour) to
    /// `x`, in parallel over vertex chunks.
    fn apply(&self, colour: usize, corr: &[Projection], x: &mut [Vec2]) {
        let offs = &self.offsets[colour];
        x.par_chunks_mut(VERTEX_CHUNK)
            .enumerate()
            .for_each(|(c, xs)| {
                let base = c * VERTEX_CHUNK;
                for &(v, slot) in &self.corners[offs[c]..offs[c + 1]] {
                    let p = &corr[(slot / 3) as usize];
                    if p.active {
                        xs[v as usize - base] += p.dx[(slot % 3) as usize];
                    }
                }
            });
    }
}

impl Engine {
    #[allow(clippy::too_many_arguments)]
    fn new<E: Energy>(
        model: &Model<E>,
        dt: Real,
        substeps: usize,
        iterations: usize,
        damping: Real,
        rest_threshold: Real,
        ordering: Ordering,
        relaxation: Real,
        rule: Rule,
    ) -> Self {
        let mesh = model.elastic_mesh();
        // Elements touching a free rigid body leave the sweep order and are projected
        // serially after it (in triangle order): they all move the body.
        let links: Vec<Option<BodyLink>> = if model.rigid_bodies().iter().any(|b| b.is_free()) {
            model
                .elements
                .iter()
                .map(|el| BodyLink::of(model, el))
                .collect()
        } else {
            Vec::new()
        };
        let linked = |t: usize| links.get(t).is_some_and(|l| l.is_some());
        let (mut elements, ranges) = match ordering {
            Ordering::Coloured => {
                let c = Colouring::greedy(mesh);
                let mut els = Vec::with_capacity(model.elements.len());
                let mut ranges = Vec::with_capacity(c.n_colours());
                for w in c.offsets.windows(2) {
                    let start = els.len();
                    els.extend(
                        (c.order[w[0]..w[1]].iter())
                            .filter(|&&t| !linked(t as usize))
                            .map(|&t| model.elements[t as usize]),
                    );
                    if els.len() > start {
                        ranges.push((start, els.len()));
                    }
                }
                (els, ranges)
            }
            _ => {
                let els: Vec<PackedElement> = (model.elements.iter().enumerate())
                    .filter(|&(t, _)| !linked(t))
                    .map(|(_, el)| *el)
                    .collect();
                let n = els.len();
                (els, vec![(0, n)])
            }
        };
        let n_colours = match ordering {
            Ordering::Coloured => ranges.len(),
            _ => 1,
        };
        let linked_start = elements.len();
        elements.extend(
            (model.elements.iter().enumerate())
                .filter(|&(t, _)| linked(t))
                .map(|(_, el)| *el),
        );
        let jacobi_adjacency = (ordering == Ordering::Jacobi && linked_start < elements.len())
            .then(|| {
                let pure: Vec<bool> = (0..model.elements.len()).map(|t| !linked(t)).collect();
                mesh.restricted(&pure).adjacency().clone()
            });
        let links: Vec<BodyLink> = links.into_iter().flatten().collect();
        let jacobi_scale = match ordering {
            Ordering::Jacobi => elements[..linked_start]
                .iter()
                .map(|el| {
                    let n = el
                        .idx
                        .iter()
                        .map(|&v| mesh.adjacency().of(v as usize).len())
                        .max()
                        .unwrap_or(1);
                    relaxation / n as Real
                })
                .collect(),
            _ => Vec::new(),
        };
        Engine {
            dt,
            substeps,
            iterations,
            damping,
            rest_threshold,
            ordering,
            rule,
            n_triangles: model.mesh().n_triangles(),
            n_colours,
            lambda: Vec::new(),
            reset_lambda_each_sweep: false,
            tolerance: 0.0,
            x_pred: Vec::new(),
            v_new: Vec::new(),
            corrections: Vec::new(),
            chunk_stats: Vec::new(),
            colour_scatter: match ordering {
                Ordering::Coloured => ColourScatter::new(&elements, &ranges, mesh.n_vertices()),
                _ => ColourScatter::default(),
            },
            jacobi_scale,
            elements,
            ranges,
            linked_start,
            links,
            jacobi_adjacency,
            bodies_pred: Vec::new(),
            rigid_pred: Vec::new(),
            grab_lambda: Vec::new(),
            contact: ContactWorkspace::default(),
        }
    }

    fn rule_for(&self, h: Real) -> Rule {
        match self.rule {
            Rule::Pbd { stiffness } => Rule::Pbd { stiffness },
            Rule::Consistent { alpha_tilde } => Rule::Consistent {
                alpha_tilde: alpha_tilde / (h * h),
            },
            Rule::Literal { alpha_tilde } => Rule::Literal {
                alpha_tilde: alpha_tilde / (h * h),
            },
        }
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        let h = self.dt / self.substeps as Real;
        let until = state.t + self.dt;
        let mut report = StepReport::explicit(Real::INFINITY, 0, 0);
        for _ in 0..self.substeps {
            let r = self.substep(model, state, h, until)?;
            report = StepReport {
                iterations: report.iterations + r.iterations,
                ..r
            };
        }
        state.step += 1;
        Ok(report)
    }

    fn substep<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
        h: Real,
        until: Real,
    ) -> Result<StepReport, SolverError> {
        let n = state.x.len();
        let w = model.inverse_masses();
        let g = model.gravity();
        let t = state.t;
        self.x_pred.resize(n, Vec2::zeros());
        self.v_new.resize(n, Vec2::zeros());
        self.lambda.clear();
        self.lambda.resize(self.elements.len(), 0.0);

        // Prediction (Algorithm II, lines 1-2).
        for ((vn, v), &wi) in self.v_new.iter_mut().zip(&state.v).zip(w) {
            *vn = if wi > 0.0 { v + g * h } else { *v };
        }
        for &(v, fe) in model.external_forces() {
            let v = v as usize;
            self.v_new[v] += fe * (w[v] * h);
        }
        for ((xp, x), v) in self.x_pred.iter_mut().zip(&state.x).zip(&self.v_new) {
            *xp = x + v * h;
        }
        model
            .kinematics()
            .apply(t, h, until, &state.x, &mut self.x_pred, &mut self.v_new);
        self.predict_rigid(model, state, h);
        self.bodies_pred.clone_from(&state.bodies);
        for (obs, body) in model.obstacles().iter().zip(self.bodies_pred.iter_mut()) {
            match obs.motion() {
                ObstacleMotion::Static => {}
                ObstacleMotion::Kinematic { .. } => obs.advance_kinematic(body, t, h),
                ObstacleMotion::Dynamic { .. } => {
                    body.velocity += g * h;
                    body.position += body.velocity * h;
                    body.angle += body.angular_velocity * h;
                }
            }
        }

        // Constraint sweeps (lines 3-11).
        let rule = self.rule_for(h);
        let psi_threshold = self.rest_threshold * model.p_wave_modulus();
        let mut stats = SweepStats::EMPTY;
        let mut contacts = 0;
        let springs = model.springs();
        self.grab_lambda.clear();
        self.grab_lambda.resize(springs.len(), Vec2::zeros());
        self.contact.start_substep();
        let (mut sweeps, mut first) = (0, 0.0);
        for k in 0..self.iterations {
            if self.reset_lambda_each_sweep && k > 0 {
                self.lambda.fill(0.0);
                self.grab_lambda.fill(Vec2::zeros());
            }
            stats = self.sweep(
                model.elastic_energies(),
                model.elastic_mesh().adjacency(),
                model.rigid_bodies(),
                w,
                rule,
                psi_threshold,
            );
            project_springs(springs, w, h, &mut self.x_pred, &mut self.grab_lambda);
            for (body, b) in model.rigid_bodies().iter().zip(&self.rigid_pred) {
                if body.is_free() {
                    body.place_positions(b, &mut self.x_pred);
                }
            }
            if model.has_contact() {
                contacts = project_contacts(
                    model.ground(),
                    model.obstacles(),
                    model.contact_params().friction,
                    w,
                    model.boundary_edges(),
                    &state.x,
                    &mut self.x_pred,
                    &state.bodies,
                    &mut self.bodies_pred,
                    &mut self.contact,
                );
            }
            sweeps += 1;
            if self.tolerance > 0.0 {
                // The residual each constraint had when its sweep projected it.
                let r = stats.residual2.sqrt();
                if k == 0 {
                    first = r;
                }
                if r <= self.tolerance * first {
                    break;
                }
            }
        }
        self.contact.finish_substep(h);

        // Velocities (lines 12-13).
        let decay = exp(-self.damping * h);
        let mut known_finite = true;
        for ((vn, xp), x) in self.v_new.iter_mut().zip(&self.x_pred).zip(&state.x) {
            let v = (xp - x) * (decay / h);
            known_finite &= (v.x + v.y + xp.x + xp.y).is_finite();
            *vn = v;
        }
        for (obs, (pred, body)) in model
            .obstacles()
            .iter()
            .zip(self.bodies_pred.iter_mut().zip(&state.bodies))
        {
            if let ObstacleMotion::Dynamic { .. } = obs.motion() {
                pred.velocity = (pred.position - body.position) / h;
                pred.angular_velocity = (pred.angle - body.angle) / h;
            }
        }
        for (body, (pred, old)) in
            (model.rigid_bodies().iter()).zip(self.rigid_pred.iter_mut().zip(&state.rigid))
        {
            if body.is_free() {
                pred.velocity = (pred.position - old.position) * (decay / h);
                pred.angular_velocity = (pred.angle - old.angle) * (decay / h);
            }
        }
        // A substep advances the time; the step counter moves once per step (in `step`).
        StepEnd {
            kinematics: Kinematic::Schedule { t, dt: h, until },
            x: &mut self.x_pred,
            v: &mut self.v_new,
            bodies: Some(&mut self.bodies_pred),
            rigid: Some(&mut self.rigid_pred),
            known_finite,
            inverted: stats.inv.inverted,
            min_det_f: stats.inv.min_det_f,
            t_end: t + h,
            count_step: false,
        }
        .commit(model, state, || Ok(()))?;
        Ok(StepReport {
            min_det_f: stats.inv.min_det_f,
            inverted: stats.inv.inverted,
            iterations: sweeps,
            residual: stats.residual2.sqrt(),
            contacts,
        })
    }

    /// One sweep over all constraints in the configured order.
    #[allow(clippy::too_many_arguments)]
    fn sweep<E: Energy>(
        &mut self,
        energy: &ElementEnergies<E>,
        adjacency: &VertexAdjacency,
        bodies: &[RigidBody],
        w: &[Real],
        rule: Rule,
        psi_threshold: Real,
    ) -> SweepStats {
        let parallel = fem_core::par::current_num_threads() > 1;
        let mut total = SweepStats::EMPTY;
        let ls = self.linked_start;
        let adjacency = self.jacobi_adjacency.as_ref().unwrap_or(adjacency);
        match self.ordering {
            Ordering::GaussSeidel => {
                serial_range(
                    energy,
                    &self.elements[..ls],
                    &mut self.lambda[..ls],
                    &mut self.x_pred,
                    w,
                    rule,
                    psi_threshold,
                    &mut total,
                );
            }
            Ordering::Coloured => {
                for (colour, &(a, b)) in self.ranges.iter().enumerate() {
                    let els = &self.elements[a..b];
                    let lam = &mut self.lambda[a..b];
                    if parallel {
                        self.chunk_stats.clear();
                        self.chunk_stats
                            .resize(els.len().div_ceil(ELEMENT_CHUNK), SweepStats::EMPTY);
                        fill_corrections(&mut self.corrections, els.len());
                        let x: &[Vec2] = &self.x_pred;
                        self.corrections[..els.len()]
                            .par_chunks_mut(ELEMENT_CHUNK)
                            .zip(lam.par_chunks_mut(ELEMENT_CHUNK))
                            .zip(els.par_chunks(ELEMENT_CHUNK))
                            .zip(self.chunk_stats.par_iter_mut())
                            .for_each(|(((out, lam), els), st)| {
                                for ((o, l), el) in out.iter_mut().zip(lam).zip(els) {
                                    *o = project_one(energy, el, x, w, rule, psi_threshold, 1.0, l);
                                    st.add(o);
                                }
                            });
                        self.colour_scatter.apply(
                            colour,
                            &self.corrections[..els.len()],
                            &mut self.x_pred,
                        );
                        for st in &self.chunk_stats {
                            total.merge(st);
                        }
                    } else {
                        serial_range(
                            energy,
                            els,
                            lam,
                            &mut self.x_pred,
                            w,
                            rule,
                            psi_threshold,
                            &mut total,
                        );
                    }
                }
            }
            Ordering::Jacobi => {
                let els = &self.elements[..ls];
                let nc = els.len().div_ceil(ELEMENT_CHUNK);
                self.chunk_stats.clear();
                self.chunk_stats.resize(nc, SweepStats::EMPTY);
                fill_corrections(&mut self.corrections, els.len());
                let x: &[Vec2] = &self.x_pred;
                let scales = &self.jacobi_scale;
                let body =
                    |c: usize,
                     ((out, lam), els): ((&mut [Projection], &mut [Real]), &[PackedElement]),
                     st: &mut SweepStats| {
                        let scales = &scales[c * ELEMENT_CHUNK..];
                        for (((o, l), el), &sc) in out.iter_mut().zip(lam).zip(els).zip(scales) {
                            *o = project_one(energy, el, x, w, rule, psi_threshold, sc, l);
                            st.add(o);
                        }
                    };
                let corr = &mut self.corrections[..els.len()];
                if parallel {
                    corr.par_chunks_mut(ELEMENT_CHUNK)
                        .zip(self.lambda[..ls].par_chunks_mut(ELEMENT_CHUNK))
                        .zip(els.par_chunks(ELEMENT_CHUNK))
                        .zip(self.chunk_stats.par_iter_mut())
                        .enumerate()
                        .for_each(|(c, (a, st))| body(c, a, st));
                } else {
                    corr.chunks_mut(ELEMENT_CHUNK)
                        .zip(self.lambda[..ls].chunks_mut(ELEMENT_CHUNK))
                        .zip(els.chunks(ELEMENT_CHUNK))
                        .zip(self.chunk_stats.iter_mut())
                        .enumerate()
                        .for_each(|(c, (a, st))| body(c, a, st));
                }
                for st in &self.chunk_stats {
                    total.merge(st);
                }
                // Gather per vertex in element order (adjacency is sorted by element).
                let corr = &self.corrections[..];
                let gather = |c: usize, xs: &mut [Vec2]| {
                    for (k, xv) in xs.iter_mut().enumerate() {
                        let v = c * VERTEX_CHUNK + k;
                        let mut s = Vec2::zeros();
                        for &(e, corner) in adjacency.of(v) {
                            let p = &corr[e as usize];
                            if p.active {
                                s += p.dx[corner as usize];
                            }
                        }
                        *xv += s;
                    }
                };
                if parallel {
                    self.x_pred
                        .par_chunks_mut(VERTEX_CHUNK)
                        .enumerate()
                        .for_each(|(c, xs)| gather(c, xs));
                } else {
                    self.x_pred
                        .chunks_mut(VERTEX_CHUNK)
                        .enumerate()
                        .for_each(|(c, xs)| gather(c, xs));
                }
            }
        }
        // The elements touching free rigid bodies, serially in triangle order.
        for ((els, links), lam) in (self.elements[ls..].chunks(ELEMENT_CHUNK))
            .zip(self.links.chunks(ELEMENT_CHUNK))
            .zip(self.lambda[ls..].chunks_mut(ELEMENT_CHUNK))
        {
            let mut st = SweepStats::EMPTY;
            for ((el, link), l) in els.iter().zip(links).zip(lam) {
                let p = project_linked(
                    energy,
                    el,
                    link,
                    &mut self.x_pred,
                    w,
                    bodies,
                    &mut self.rigid_pred,
                    rule,
                    psi_threshold,
                    l,
                );
                st.add(&p);
            }
            total.merge(&st);
        }
        total
    }

    /// The rigid regions' free bodies take the vertices' inertial prediction (gravity, and
    /// the external forces on their vertices as a wrench), and their vertices are placed on
    /// the predicted poses.
    fn predict_rigid<E: Energy>(&mut self, model: &Model<E>, state: &State, h: Real) {
        let bodies = model.rigid_bodies();
        self.rigid_pred.clone_from(&state.rigid);
        if !bodies.iter().any(|b| b.is_free()) {
            return;
        }
        let g = model.gravity();
        for (body, b) in bodies.iter().zip(self.rigid_pred.iter_mut()) {
            if body.is_free() {
                b.velocity += g * h;
            }
        }
        for &(v, fe) in model.external_forces() {
            if let Some(k) = model.rigid_body_of(v as usize)
                && bodies[k].is_free()
            {
                let (im, ii) = bodies[k].inverse_mass();
                let arm = state.x[v as usize] - state.rigid[k].position;
                let b = &mut self.rigid_pred[k];
                b.velocity += fe * (im * h);
                b.angular_velocity += cross(arm, fe) * (ii * h);
            }
        }
        for (body, b) in bodies.iter().zip(self.rigid_pred.iter_mut()) {
            if body.is_free() {
                b.position += b.velocity * h;
                b.angle += b.angular_velocity * h;
                body.place_positions(b, &mut self.x_pred);
            }
        }
    }
}

fn fill_corrections(buf: &mut Vec<Projection>, n: usize) {
    if buf.len() < n {
        buf.resize_with(n, || Projection {
            dx: [Vec2::zeros(); 3],
            active: false,
            det: 0.0,
            residual2: 0.0,
        });
    }
}

/// In-place Gauss-Seidel over `els` (with multipliers `lam`), statistics accumulated per chunk
/// of [`ELEMENT_CHUNK`] elements exactly as the parallel coloured path does.
#[allow(clippy::too_many_arguments)]
fn serial_range<E: Energy>(
    energy: &ElementEnergies<E>,
    els: &[PackedElement],
    lam: &mut [Real],
    x: &mut [Vec2],
    w: &[Real],
    rule: Rule,
    psi_threshold: Real,
    total: &mut SweepStats,
) {
    for (els, lam) in els.chunks(ELEMENT_CHUNK).zip(lam.chunks_mut(ELEMENT_CHUNK)) {
        let mut st = SweepStats::EMPTY;
        for (el, l) in els.iter().zip(lam) {
            let p = project_one(energy, el, x, w, rule, psi_threshold, 1.0, l);
            st.add(&p);
            apply(x, el, &p);
        }
        total.merge(&st);
    }
}

macro_rules! position_based_stepper {
    ($name:ident, $params:ty, $doc:literal) => {
        #[doc = $doc]
        #[derive(Clone, Debug)]
        pub struct $name {
            params: $params,
            engine: Engine,
        }

        impl $name {
            /// The parameters.
            pub fn params(&self) -> &$params {
                &self.params
            }

            /// Number of colour classes of the coloured ordering (1 for the others).
            pub fn n_colours(&self) -> usize {
                self.engine.n_colours
            }
        }

        impl Stepper for $name {
            fn dt(&self) -> Real {
                self.params.dt
            }

            fn step<E: Energy>(
                &mut self,
                model: &Model<E>,
                state: &mut State,
            ) -> Result<StepReport, SolverError> {
                self.engine.step(model, state)
            }

            /// The projection contacts of the last substep: every pair a sweep corrected, with
            /// its multipliers summed over the sweeps as a force (see
            /// [`crate::contact::penalty`]).
            fn contacts(&self) -> &[Contact] {
                &self.engine.contact.records
            }
        }
    };
}

position_based_stepper!(
    PbdStepper,
    PbdParams,
    "Energy-based PBD (Bender et al. 2014), one `C = a psi` constraint per triangle."
);
position_based_stepper!(
    XpbdStepper,
    XpbdParams,
    "Energy-based XPBD (paper Algorithm II), consistent `C = sqrt(2 a psi)` by default."
);

impl PbdStepper {
    /// Validate the parameters and prepare the sweep order (colouring) for `model`.
    pub fn new<E: Energy>(model: &Model<E>, params: PbdParams) -> Result<Self, SolverError> {
        params.validate()?;
        Ok(PbdStepper {
            engine: Engine::new(
                model,
                params.dt,
                params.substeps,
                params.iterations,
                params.damping,
                params.rest_threshold,
                params.ordering,
                params.relaxation,
                Rule::Pbd {
                    stiffness: params.stiffness,
                },
            ),
            params,
        })
    }
}

impl XpbdStepper {
    /// Validate the parameters and prepare the sweep order (colouring) for `model`.
    pub fn new<E: Energy>(model: &Model<E>, params: XpbdParams) -> Result<Self, SolverError> {
        params.validate()?;
        let rule = match params.form {
            XpbdForm::Consistent => Rule::Consistent {
                alpha_tilde: params.compliance,
            },
            XpbdForm::Literal => Rule::Literal {
                alpha_tilde: params.compliance,
            },
        };
        let (substeps, iterations) = match params.schedule {
            XpbdSchedule::Iterations => (params.substeps, params.iterations),
            XpbdSchedule::SmallSteps => (params.substeps * params.iterations, 1),
        };
        let mut engine = Engine::new(
            model,
            params.dt,
            substeps,
            iterations,
            params.damping,
            params.rest_threshold,
            params.ordering,
            params.relaxation,
            rule,
        );
        engine.reset_lambda_each_sweep = params.lambda_reset == LambdaReset::Iteration;
        engine.tolerance = params.tolerance;
        Ok(XpbdStepper { engine, params })
    }
}

/// What the position-based frameworks share in the capability table.
const POSITION_BASED: Capabilities = Capabilities {
    title: "",
    summary: "",
    paper: true,
    contact: true,
    rigid_regions: true,
    averaged_pressure: false,
    implicit: false,
    iterations: true,
    substeps: true,
    factorisation: false,
    deterministic_across_threads: true,
    clock: Clock::Time,
    converges_to: "",
};

impl Solver for PbdStepper {
    type Params = PbdParams;
    const NAME: &'static str = "pbd";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "PBD",
        summary: "energy-based PBD (Bender et al. 2014; paper Eqs. 4-6): one C = a psi constraint per triangle, Gauss-Seidel projection",
        converges_to: "no material limit: stiffness depends on dt and iterations",
        ..POSITION_BASED
    };

    fn validate_params(p: &PbdParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &PbdParams) -> Result<Self, SolverError> {
        PbdStepper::new(model, *p)
    }

    fn dt_mut(p: &mut PbdParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }
}

impl Solver for XpbdStepper {
    type Params = XpbdParams;
    const NAME: &'static str = "xpbd";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "XPBD",
        summary: "energy-based XPBD (paper Algorithm II, Eq. 7): compliant C = sqrt(2 a psi) per triangle (the printed C = a psi selectable)",
        converges_to: "a fixed point of the sweeps, not implicit Euler: it drops the primal residual and depends on the ordering (0.2-1.5 % off implicit Euler on case A at dt = 10 ms)",
        ..POSITION_BASED
    };

    fn validate_params(p: &XpbdParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &XpbdParams) -> Result<Self, SolverError> {
        XpbdStepper::new(model, *p)
    }

    fn dt_mut(p: &mut XpbdParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }
}

/// Project the grab's springs (each `k/2 |x - goal|^2`) as compliant vector constraints
/// `C = x - goal` with compliance `1 / k` (XPBD's update with the multiplier `lambda` kept over
/// the substep's iterations), for PBD and XPBD alike: a spring has a stiffness of its own, so
/// PBD's material stiffness does not apply to it.
fn project_springs(springs: &[Spring], w: &[Real], h: Real, x: &mut [Vec2], lambda: &mut [Vec2]) {
    for (s, l) in springs.iter().zip(lambda) {
        let v = s.vertex as usize;
        if w[v] == 0.0 {
            continue;
        }
        let alpha_tilde = 1.0 / (s.stiffness * h * h);
        let dl = (-(x[v] - s.goal) - *l * alpha_tilde) / (w[v] + alpha_tilde);
        x[v] += dl * w[v];
        *l += dl;
    }
}
