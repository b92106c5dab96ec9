//! Explicit FEM (paper Algorithm I): elastic forces from the energy (Eq. 3), then a
//! first-order explicit update with exponential velocity damping.
//!
//! With `a = M^-1 (f + f_ext) + g` and `decay = exp(-c dt)` ([`ExplicitParams::damping`] = `c`,
//! 1/s), per free vertex:
//! - **symplectic Euler** (default): `v' = (v + dt a) decay`, `x' = x + dt v'` (the position
//!   uses the new, damped velocity);
//! - **forward Euler** (Algorithm I as printed, line 9): `x' = x + dt v`, `v' = (v + dt a) decay`.
//!
//! Kinematic vertices follow their schedule; dynamic rigid bodies are advanced by the same
//! scheme under gravity and the penalty reactions ([`crate::contact::penalty`]: vertices in
//! obstacles and obstacle corners in soft boundary edges, recorded in [`Stepper::contacts`]).
//!
//! Rigid regions ([`crate::rigid::body`]): the elastic forces come from the deformable
//! triangles only; the forces on a free body's vertices (elastic, external, grab, contact)
//! sum to its force and torque about its centroid, and the body takes the same step as the
//! vertices (its velocities damped alike), [`BodyState::advance`](crate::rigid::BodyState::advance);
//! the step's end places its vertices on it. Linear and angular momentum are conserved to
//! round-off: the forces of each element sum to zero, and so do their torques. The stability
//! guard ([`Model::check_time_step`]) bounds the deformable elements' frequencies, a slaved
//! vertex counted with its lumped mass in its elements.
//!
//! Blow-up detection: the new positions and velocities are written into the stepper's own
//! buffers and only swapped into the state when every value is finite; otherwise the step
//! returns [`SolverError::NonFinite`] naming the step and the first bad vertex, and the state is
//! left at the last good step.
//!
//! Registered as `explicit` ([`Solver`]); scene keys `dt`, `damping`, `scheme`
//! (`"symplectic"` | `"forward-euler"`).

use fem_core::energy::Energy;
use fem_core::energy::EnergyOf as _;
use fem_core::math::{Real, Vec2, exp};
use fem_core::par::prelude::*;
use fem_core::simd::Isa;

use super::{Stepper, check_step_inputs};
use crate::contact::Contact;
use crate::contact::penalty::{ContactWorkspace, accumulate_penalty_forces};
use crate::error::{SolverError, check_non_negative, check_positive};
use crate::kernel::{self, VERTEX_CHUNK};
use crate::model::state::State;
use crate::model::{Model, TimeStepCheck};
use crate::rigid::{ObstacleMotion, Wrench};
use crate::steppers::commit::{Kinematic, StepEnd};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;

/// Which explicit update. Serde names: `symplectic`, `forward-euler`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum ExplicitScheme {
    /// `x' = x + dt v'` (uses the new velocity). Default.
    #[default]
    #[cfg_attr(feature = "serde", serde(rename = "symplectic"))]
    SymplecticEuler,
    /// `x' = x + dt v` (uses the old velocity): Algorithm I line 9 as printed.
    #[cfg_attr(feature = "serde", serde(rename = "forward-euler"))]
    ForwardEuler,
}

/// Parameters of [`ExplicitStepper`] (scene keys `dt`, `damping`, `scheme`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct ExplicitParams {
    /// Time step, s (finite, > 0). Default `1e-3` (case A).
    pub dt: Real,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c dt)` each step; finite, >= 0). Default 0.
    pub damping: Real,
    /// Update scheme. Default symplectic Euler.
    pub scheme: ExplicitScheme,
}

impl Default for ExplicitParams {
    fn default() -> Self {
        ExplicitParams {
            dt: 1e-3,
            damping: 0.0,
            scheme: ExplicitScheme::SymplecticEuler,
        }
    }
}

impl ExplicitParams {
    /// Check every field; errors name `explicit.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(ExplicitStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        check_positive(&format!("{prefix}.dt"), self.dt)?;
        check_non_negative(&format!("{prefix}.damping"), self.damping)
    }
}

/// The explicit stepper; owns its workspace (no allocation after the first step).
#[derive(Clone, Debug)]
pub struct ExplicitStepper {
    params: ExplicitParams,
    decay: Real,
    n_triangles: usize,
    check: TimeStepCheck,
    f: Vec<Vec2>,
    slots: Vec<Vec2>,
    /// The averaged nodal pressure triangle's fields.
    pressure: fem_core::nodal_pressure::PressureFields,
    x_new: Vec<Vec2>,
    v_new: Vec<Vec2>,
    wrenches: Vec<Wrench>,
    bodies_new: Vec<crate::rigid::BodyState>,
    rigid_new: Vec<crate::rigid::BodyState>,
    contact: ContactWorkspace,
}

impl ExplicitStepper {
    /// Validate the parameters and estimate the stability limit for `model` (see
    /// [`ExplicitStepper::time_step_check`]).
    pub fn new<E: Energy>(model: &Model<E>, params: ExplicitParams) -> Result<Self, SolverError> {
        params.validate()?;
        let n = model.mesh().n_vertices();
        Ok(ExplicitStepper {
            params,
            decay: exp(-params.damping * params.dt),
            n_triangles: model.mesh().n_triangles(),
            check: model.check_time_step(params.dt),
            f: vec![Vec2::zeros(); n],
            slots: Vec::new(),
            pressure: fem_core::nodal_pressure::PressureFields::new(),
            x_new: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            wrenches: vec![Wrench::default(); model.obstacles().len()],
            bodies_new: Vec::new(),
            rigid_new: Vec::new(),
            contact: ContactWorkspace::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &ExplicitParams {
        &self.params
    }

    /// The stability estimate made at construction; [`TimeStepCheck::warning`] is `Some` when
    /// `dt` exceeds the critical time step. The stepper's warning
    /// ([`Solver::time_step_warning`]) adds, for forward Euler,
    /// [`TimeStepCheck::forward_euler_warning`]: that scheme amplifies the highest mode at any
    /// `dt` unless damped enough.
    pub fn time_step_check(&self) -> &TimeStepCheck {
        &self.check
    }

    /// The elastic plus external plus contact forces of the last step (N), for inspection.
    pub fn forces(&self) -> &[Vec2] {
        &self.f
    }
}

impl Stepper for ExplicitStepper {
    fn dt(&self) -> Real {
        self.params.dt
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        let n = state.x.len();
        self.f.resize(n, Vec2::zeros());
        self.x_new.resize(n, Vec2::zeros());
        self.v_new.resize(n, Vec2::zeros());
        self.wrenches
            .resize(model.obstacles().len(), Wrench::default());
        let (dt, t) = (self.params.dt, state.t);

        // The averaged nodal pressure triangle: its nodal pressures first, then each element's
        // correction joins its stress in the batched kernel.
        let energies = model.elastic_energies();
        let corr = match energies.nodal_pressure() {
            Some(np) => {
                self.pressure
                    .update_mean_pressures(np, model.elastic_mesh(), energies, &state.x);
                Some(self.pressure.correction())
            }
            None => None,
        };
        let inv = kernel::forces(
            energies,
            &model.blocks,
            model.elastic_mesh(),
            &state.x,
            &mut self.f,
            &mut self.slots,
            model.isa(),
            corr,
        );
        for &(v, fe) in model.external_forces() {
            self.f[v as usize] += fe;
        }
        for s in model.springs() {
            let v = s.vertex as usize;
            self.f[v] += (s.goal - state.x[v]) * s.stiffness;
        }
        let contacts = if model.has_contact() {
            accumulate_penalty_forces(
                model.ground(),
                model.obstacles(),
                model.contact_params(),
                model.masses(),
                model.boundary_edges(),
                &state.x,
                &state.v,
                &state.bodies,
                &mut self.f,
                &mut self.wrenches,
                &mut self.contact,
            )
        } else {
            self.contact.records.clear();
            0
        };

        let known_finite = integrate(
            model.isa(),
            self.params.scheme,
            dt,
            self.decay,
            model.gravity(),
            &state.x,
            &state.v,
            &self.f,
            model.inverse_masses(),
            &mut self.x_new,
            &mut self.v_new,
        );
        let symplectic = self.params.scheme == ExplicitScheme::SymplecticEuler;
        self.bodies_new.clone_from(&state.bodies);
        for (o, (obs, body)) in model
            .obstacles()
            .iter()
            .zip(self.bodies_new.iter_mut())
            .enumerate()
        {
            match obs.motion() {
                ObstacleMotion::Static => {}
                ObstacleMotion::Kinematic { .. } => obs.advance_kinematic(body, t, dt),
                ObstacleMotion::Dynamic { .. } => {
                    let w = self.wrenches[o];
                    body.advance(
                        obs.inverse_mass(),
                        w.force,
                        w.torque,
                        model.gravity(),
                        dt,
                        1.0,
                        symplectic,
                    );
                }
            }
        }
        // Rigid regions: the nodal forces on a body's vertices (elastic, external, grab and
        // contact; gravity acts on its mass) give its wrench, and the body takes the same
        // step as the vertices, damping included.
        self.rigid_new.clone_from(&state.rigid);
        for (body, b) in model.rigid_bodies().iter().zip(self.rigid_new.iter_mut()) {
            if body.is_free() {
                let (force, torque) = body.wrench(b, &state.x, &self.f);
                b.advance(
                    body.inverse_mass(),
                    force,
                    torque,
                    model.gravity(),
                    dt,
                    self.decay,
                    symplectic,
                );
            }
        }
        StepEnd {
            kinematics: Kinematic::Schedule {
                t,
                dt,
                until: t + dt,
            },
            x: &mut self.x_new,
            v: &mut self.v_new,
            bodies: Some(&mut self.bodies_new),
            rigid: Some(&mut self.rigid_new),
            known_finite,
            inverted: inv.inverted,
            min_det_f: inv.min_det_f,
            t_end: t + dt,
            count_step: true,
        }
        .commit(model, state, || Ok(()))?;
        Ok(StepReport::explicit(inv.min_det_f, inv.inverted, contacts))
    }

    /// The penalty contacts of the last step, evaluated at its start (where the forces are).
    fn contacts(&self) -> &[Contact] {
        &self.contact.records
    }
}

impl Solver for ExplicitStepper {
    type Params = ExplicitParams;
    const NAME: &'static str = "explicit";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Explicit FEM",
        summary: "explicit FEM (paper Algorithm I): symplectic Euler (or the printed forward Euler) on the elastic forces",
        paper: true,
        contact: true,
        rigid_regions: true,
        averaged_pressure: true,
        dims: 3,
        implicit: false,
        iterations: false,
        substeps: false,
        factorisation: false,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "the exact solution as dt -> 0 (first order), below the stability limit",
    };

    fn validate_params(p: &ExplicitParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &ExplicitParams) -> Result<Self, SolverError> {
        ExplicitStepper::new(model, *p)
    }

    fn dt_mut(p: &mut ExplicitParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }

    fn time_step_warning(&self) -> Option<String> {
        let limit = self.check.warning();
        match self.params.scheme {
            ExplicitScheme::SymplecticEuler => limit,
            ExplicitScheme::ForwardEuler => {
                match (limit, self.check.forward_euler_warning(self.params.damping)) {
                    (Some(a), Some(b)) => Some(format!("{a}; {b}")),
                    (a, b) => a.or(b),
                }
            }
        }
    }
}

/// The per-vertex update into `x_new`, `v_new` (every vertex treated as free; the caller then
/// overwrites kinematic ones). Returns whether every written value is finite. Parallel in
/// fixed chunks; the arithmetic per vertex does not depend on the thread count.
#[allow(clippy::too_many_arguments)]
fn integrate(
    isa: Isa,
    scheme: ExplicitScheme,
    dt: Real,
    decay: Real,
    g: Vec2,
    x: &[Vec2],
    v: &[Vec2],
    f: &[Vec2],
    w: &[Real],
    x_new: &mut [Vec2],
    v_new: &mut [Vec2],
) -> bool {
    match scheme {
        ExplicitScheme::SymplecticEuler => {
            integrate_with::<true>(isa, dt, decay, g, x, v, f, w, x_new, v_new)
        }
        ExplicitScheme::ForwardEuler => {
            integrate_with::<false>(isa, dt, decay, g, x, v, f, w, x_new, v_new)
        }
    }
}

/// [`integrate`] for one scheme (`SYMPLECTIC`: position from the new velocity), so the loop
/// body has no branch; zipped iterators, so it has no bounds checks either.
#[allow(clippy::too_many_arguments)]
fn integrate_with<const SYMPLECTIC: bool>(
    isa: Isa,
    dt: Real,
    decay: Real,
    g: Vec2,
    x: &[Vec2],
    v: &[Vec2],
    f: &[Vec2],
    w: &[Real],
    x_new: &mut [Vec2],
    v_new: &mut [Vec2],
) -> bool {
    #[inline(always)]
    fn update<const SYMPLECTIC: bool>(
        (dt, decay, g): (Real, Real, Vec2),
        xn: &mut [Vec2],
        vn: &mut [Vec2],
        x: &[Vec2],
        v: &[Vec2],
        f: &[Vec2],
        w: &[Real],
    ) -> bool {
        // One running flag: the sum of a vertex's four values is finite when they all are
        // (a finite sum that overflows only raises a false alarm, which the caller's
        // per-vertex scan then clears).
        let mut ok = true;
        for (((((xn, vn), &xi), &vi), &fi), &wi) in
            xn.iter_mut().zip(vn).zip(x).zip(v).zip(f).zip(w)
        {
            let v1 = (vi + (fi * wi + g) * dt) * decay;
            let x1 = if SYMPLECTIC {
                xi + v1 * dt
            } else {
                xi + vi * dt
            };
            ok &= (x1.x + x1.y + v1.x + v1.y).is_finite();
            *xn = x1;
            *vn = v1;
        }
        ok
    }
    // Compiled for the kernels' instruction set; element-wise IEEE arithmetic, so the same
    // bits under every set.
    let chunk =
        |xn: &mut [Vec2], vn: &mut [Vec2], x: &[Vec2], v: &[Vec2], f: &[Vec2], w: &[Real]| {
            isa.run(
                #[inline(always)]
                || update::<SYMPLECTIC>((dt, decay, g), xn, vn, x, v, f, w),
            )
        };
    if fem_core::par::current_num_threads() == 1 {
        return chunk(x_new, v_new, x, v, f, w);
    }
    x_new
        .par_chunks_mut(VERTEX_CHUNK)
        .zip(v_new.par_chunks_mut(VERTEX_CHUNK))
        .zip(x.par_chunks(VERTEX_CHUNK))
        .zip(v.par_chunks(VERTEX_CHUNK))
        .zip(f.par_chunks(VERTEX_CHUNK))
        .zip(w.par_chunks(VERTEX_CHUNK))
        .map(|(((((xn, vn), x), v), f), w)| chunk(xn, vn, x, v, f, w))
        .reduce(|| true, |a, b| a && b)
}
