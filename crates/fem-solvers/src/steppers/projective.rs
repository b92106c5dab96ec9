//! Projective Dynamics (Bouaziz, Martin, Liu, Kavan & Pauly, "Projective Dynamics: Fusing
//! Constraint Projections for Fast Simulation", ACM TOG 33(4), 2014) for the co-rotational
//! energy, with optional Chebyshev acceleration (Wang, "A Chebyshev Semi-Iterative Approach for
//! Accelerating Projective and Position-based Dynamics", ACM TOG 34(6), 2015).
//!
//! **The energy as projective terms.** The co-rotational energy
//! `psi = mu |F - R|^2 + lambda/2 (tr(R^T F) - 2)^2` ([`fem_core::energy::Corotational`]) is
//! exactly a sum of two squared distances to constraint sets:
//! - `mu |F - R|^2`: the distance to the rotations, projection `p1 = R` (the polar rotation).
//!   At `nu = 0` (`lambda = 0`) this is the whole energy: ARAP.
//! - **the area term**, `lambda/2 (tr S - 2)^2` with `S = R^T F`, equals `lambda |F - p2|^2` with
//!   `p2 = F + R (2 - tr S) / 2`, the nearest matrix whose stretch has trace 2 (the term's zero
//!   set): `|F - p2|^2 = 2 ((2 - tr S) / 2)^2`. Its gradient `2 lambda (F - p2) =
//!   lambda (tr S - 2) R` is the term's `P`, so for `nu > 0` nothing is approximated: the
//!   fixed point of the iterations is the implicit Euler step of the co-rotational energy.
//!
//! Each step of length `h` minimises implicit Euler's incremental potential
//! `sum m/(2 h^2) |x - x_hat|^2 - f . x + sum_e a_e psi(F_e)` by local-global iterations from
//! `x_hat + h^2 f / m`: the **local step** computes `p1, p2` per triangle (in parallel); the
//! **global step** solves `(M / h^2 + L) x = M / h^2 x_hat + f + sum_e G_e^T (w1 p1 + w2 p2)`
//! with `w1 = 2 a mu`, `w2 = 2 a lambda`, `L = sum_e (w1 + w2) G_e^T G_e` (`PdSystem`, in
//! `pd_system.rs`): one matrix for the whole run, factorised once when the stepper is built.
//! Each iteration lowers the potential; it converges linearly to the implicit Euler step
//! (`tests/suite/projective.rs` measures the gap against Newton's step).
//!
//! Chebyshev (`chebyshev_rho`, 0 = off) extrapolates the free positions after each iteration
//! as in [`crate::vbd`]; it does not change the fixed point, and a `rho` above the iterations'
//! spectral radius makes them diverge.
//!
//! **Residual tolerance** (`tolerance`, scene key `residual_tolerance`; 0 = off, the
//! default). With a positive tolerance the step evaluates, at its initial guess and after each
//! iteration, the norm of the incremental potential's gradient over the free vertices (N),
//! `g = m / h^2 (x - x_hat) - f + sum_e a_e P_e g_e + k (x - goal)`, and stops once it is at
//! most `tolerance` times Newton's force scale ([`crate::newton::NewtonParams::tolerance`]: the
//! largest of the first residual, the external load, the elastic forces on the free vertices
//! at the initial guess, and 1e-12 N); `iterations` is then the most iterations, and the report
//! gives the iterations done (global solves) and that norm. The test reads the next
//! iteration's local step: each triangle's `a P = (w1 + w2) F - (w1 p1 + w2 p2)` comes from its
//! projections, so a test costs a pass over the triangles and one over the vertices and no
//! polar decomposition, except the last (at the final positions), whose local step has no
//! global step after it. With tolerance 0 nothing of this runs: the iterations, the bits and
//! the report are those of a fixed count.
//!
//! Other energies are not sums of projective terms and are refused at construction (the
//! quasi-Newton solver runs them with this matrix as its initial Hessian). Contact is not
//! handled (refused, naming the steppers that handle it, quasi-Newton among them, with this
//! matrix in its initial Hessian). The step's residual is the largest position
//! change of its last iteration, m (with a positive tolerance: the gradient norm above, N).
//!
//! **BDF2** (`integrator = "bdf2"`, [`crate::integrator`]): the iterations minimise BDF2's
//! potential (inertia weight `9 / (4 h^2)`, BDF2's target and velocity) with a second global
//! matrix `9 M / (4 h^2) + L`, factorised with the first when the stepper is built; the first
//! step, and any step from a state the stepper did not commit, is backward Euler with the
//! first matrix.
//!
//! Registered as `pd` ([`Solver`]); scene keys `dt`, `iterations`, `damping`,
//! `chebyshev_rho`, `residual_tolerance`, `integrator`.

use fem_core::energy::Energy;
use fem_core::math::{Mat2, Real, Vec2, exp};
use fem_core::par::prelude::*;
use fem_core::polar::Polar2;

use super::{Stepper, check_step_inputs};
use crate::error::{
    SolverError, check_count, check_non_negative, check_positive, check_residual_tolerance,
    check_rho,
};
use crate::kernel::{
    ELEMENT_CHUNK, PackedElement, VERTEX_CHUNK, corner_gradient, deformation_gradient, pack,
};
use crate::model::Model;
use crate::model::grab::spring_of;
use crate::model::limits;
use crate::model::state::State;
use crate::optim::newton::force_scale;
use crate::optim::pd_system::{PdSystem, element_lame};
use crate::steppers::implicit::external_load;
use crate::steppers::integrator::{History, Integrator, pd_systems};
use crate::steppers::registry::{Capabilities, Clock, Solver};
use crate::steppers::report::StepReport;
use crate::steppers::vbd::{Chebyshev, commit_positions};

/// Parameters of [`PdStepper`] (scene keys: the field names).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct PdParams {
    /// Time step, s (finite, > 0). Default `1e-3`.
    pub dt: Real,
    /// Local-global iterations per step (>= 1). Default 10.
    pub iterations: usize,
    /// Velocity damping rate `c`, 1/s (`v <- v exp(-c dt)` each step). Default 0.
    pub damping: Real,
    /// Chebyshev's spectral radius estimate `rho`, in `[0, 1)`; 0 turns the acceleration off.
    /// Default 0.
    pub chebyshev_rho: Real,
    /// Relative residual tolerance in `[0, 1)`, dimensionless (scene key
    /// `residual_tolerance`): when positive, the step stops iterating once the gradient of its
    /// incremental potential over the free vertices (N) is at most `tolerance` times the force
    /// scale (Newton's: the largest of the first residual, the external load, the elastic
    /// forces at the start, 1e-12 N); `iterations` is then the most iterations. 0 runs exactly
    /// `iterations` iterations and evaluates no gradient. Default 0.
    #[cfg_attr(feature = "serde", serde(rename = "residual_tolerance"))]
    pub tolerance: Real,
    /// The time integrator: backward Euler (default) or BDF2 (second order; see
    /// [`crate::integrator`]). BDF2's inertia weight differs from backward Euler's, so a BDF2
    /// stepper factorises two matrices (its first step, and any step that falls back, is
    /// backward Euler).
    pub integrator: Integrator,
}

impl Default for PdParams {
    fn default() -> Self {
        PdParams {
            dt: 1e-3,
            iterations: 10,
            damping: 0.0,
            chebyshev_rho: 0.0,
            tolerance: 0.0,
            integrator: Integrator::BackwardEuler,
        }
    }
}

impl PdParams {
    /// Check every field; errors name `pd.<field>`.
    pub fn validate(&self) -> Result<(), SolverError> {
        self.validate_as(PdStepper::NAME)
    }

    /// Check every field; errors name `<prefix>.<field>`.
    pub fn validate_as(&self, prefix: &str) -> Result<(), SolverError> {
        let field = |name: &str| format!("{prefix}.{name}");
        check_positive(&field("dt"), self.dt)?;
        check_count(
            &field("iterations"),
            self.iterations,
            limits::MAX_ITERATIONS,
        )?;
        check_non_negative(&field("damping"), self.damping)?;
        check_rho(&field("chebyshev_rho"), self.chebyshev_rho)?;
        check_residual_tolerance(&field("residual_tolerance"), self.tolerance)
    }
}

/// Projective Dynamics for the co-rotational energy; see the module docs.
#[derive(Debug)]
pub struct PdStepper {
    params: PdParams,
    decay: Real,
    n_triangles: usize,
    els: Vec<PackedElement>,
    /// `M / h^2 + L`, factorised.
    system: PdSystem,
    /// Under BDF2, `9 M / (4 h^2) + L`, factorised.
    bdf2_system: Option<PdSystem>,
    /// The previous step's state (BDF2).
    history: History,
    /// Whether the current (or last) step is a BDF2 step: which matrix the global step solves
    /// with.
    bdf2: bool,
    /// Per triangle: `2 a mu` and `2 a lambda`.
    w_mu: Vec<Real>,
    w_lambda: Vec<Real>,
    /// Per triangle: `w1 p1 + w2 p2` of the last local step.
    projections: Vec<Mat2>,
    /// The free vertices, increasing.
    free: Vec<u32>,
    target: Vec<Vec2>,
    load: Vec<Vec2>,
    x: Vec<Vec2>,
    v_new: Vec<Vec2>,
    /// Per vertex: the global step's right-hand side.
    rhs_v: Vec<Vec2>,
    /// The right-hand sides over the free vertices, column-major (x, then y).
    rhs: Vec<Real>,
    chebyshev: Chebyshev,
    /// The model layout the matrix was factorised for.
    layout: u64,
    /// The residual test's buffers (sized only when the tolerance is positive): per triangle
    /// `a P = (w1 + w2) F - (w1 p1 + w2 p2)`, and per vertex the elastic gradient
    /// `sum_e a_e P_e g`.
    stress: Vec<Mat2>,
    elastic: Vec<Vec2>,
    /// The force scale of the last step's residual test, N (0 when the tolerance is 0).
    force_scale: Real,
}

impl PdStepper {
    /// A stepper for `model`: validates the parameters, refuses energies other than the
    /// co-rotational one and contact geometry, and assembles and factorises the global matrix.
    pub fn new<E: Energy>(model: &Model<E>, params: PdParams) -> Result<Self, SolverError> {
        params.validate()?;
        let name = model.energy().name();
        if name != "corotational" {
            return Err(SolverError::invalid(
                "pd.energy",
                name,
                "Projective Dynamics runs the corotational energy only (the sum of two projective terms); use quasi-newton for the others",
            ));
        }
        if model.has_contact() {
            return Err(SolverError::invalid(
                "pd.contact",
                "ground or obstacles",
                "contact is handled by the explicit, pbd, xpbd, implicit, static, vbd, quasi-newton and linear-implicit steppers",
            ));
        }
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        // Each element's weights from its region's Lamé parameters.
        let lame = element_lame(model.energies(), mesh.n_triangles());
        let w_mu: Vec<Real> = (mesh.elements().iter().zip(&lame))
            .map(|(e, &(mu, _))| 2.0 * e.area * mu)
            .collect();
        let w_lambda: Vec<Real> = (mesh.elements().iter().zip(&lame))
            .map(|(e, &(_, lambda))| 2.0 * e.area * lambda)
            .collect();
        let weights: Vec<Real> = w_mu.iter().zip(&w_lambda).map(|(a, b)| a + b).collect();
        let mut kinematic = vec![false; n];
        for v in model.kinematics().vertices() {
            kinematic[v] = true;
        }
        let h = params.dt;
        let (system, bdf2_system) = pd_systems(
            mesh,
            model.masses(),
            &weights,
            h,
            params.integrator,
            model.springs(),
            &kinematic,
            "pd",
        )?;
        let free: Vec<u32> = (0..n as u32).filter(|&v| !kinematic[v as usize]).collect();
        Ok(PdStepper {
            layout: model.layout(),
            decay: exp(-params.damping * h),
            params,
            n_triangles: mesh.n_triangles(),
            els: pack(mesh, model.energies().tags()),
            rhs: vec![0.0; 2 * system.n_free()],
            system,
            bdf2_system,
            history: History::new(params.integrator),
            bdf2: false,
            w_mu,
            w_lambda,
            projections: vec![Mat2::zeros(); mesh.n_triangles()],
            free,
            target: vec![Vec2::zeros(); n],
            load: vec![Vec2::zeros(); n],
            x: vec![Vec2::zeros(); n],
            v_new: vec![Vec2::zeros(); n],
            rhs_v: vec![Vec2::zeros(); n],
            chebyshev: Chebyshev::default(),
            stress: if params.tolerance > 0.0 {
                vec![Mat2::zeros(); mesh.n_triangles()]
            } else {
                Vec::new()
            },
            elastic: if params.tolerance > 0.0 {
                vec![Vec2::zeros(); n]
            } else {
                Vec::new()
            },
            force_scale: 0.0,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &PdParams {
        &self.params
    }

    /// Numeric factorisations of the global matrix since the stepper was built: one, whatever
    /// the number of steps, plus one for each change of the model's layout (a grab started or
    /// ended); twice that under BDF2 (backward Euler's matrix and BDF2's).
    pub fn factorisations(&self) -> usize {
        self.system.factorisations() + self.bdf2_system.as_ref().map_or(0, |s| s.factorisations())
    }

    /// Whether the last step was a BDF2 step (see [`crate::integrator`]).
    pub fn last_step_bdf2(&self) -> bool {
        self.bdf2
    }

    /// The force scale of the last step's residual test, N: with a positive tolerance the
    /// step's residual is at most `tolerance` times it when the iterations stopped early. 0
    /// when the tolerance is 0.
    pub fn force_scale(&self) -> Real {
        self.force_scale
    }

    /// One local-global iteration from `self.x`; returns the largest position change, m.
    fn iterate<E: Energy>(&mut self, model: &Model<E>, w: Real) -> Real {
        self.local_step(model, w);
        self.global_step()
    }

    /// The local step at `self.x` (the projections) and the global step's right-hand sides.
    fn local_step<E: Energy>(&mut self, model: &Model<E>, w: Real) {
        // Local: the projections, in parallel over fixed chunks (independent per triangle).
        let x = &self.x;
        self.projections
            .par_chunks_mut(ELEMENT_CHUNK)
            .zip(self.els.par_chunks(ELEMENT_CHUNK))
            .zip(self.w_mu.par_chunks(ELEMENT_CHUNK))
            .zip(self.w_lambda.par_chunks(ELEMENT_CHUNK))
            .for_each(|(((out, els), w1), w2)| {
                for (((p, el), w1), w2) in out.iter_mut().zip(els).zip(w1).zip(w2) {
                    let f = deformation_gradient(el, x);
                    let r = Polar2::new(&f).rotation();
                    let trace =
                        r[(0, 0)] * (f[(0, 0)] + f[(1, 1)]) + r[(1, 0)] * (f[(1, 0)] - f[(0, 1)]);
                    let p2 = f + r * (0.5 * (2.0 - trace));
                    *p = r * *w1 + p2 * *w2;
                }
            });
        // Global right-hand side per vertex, summed in adjacency (triangle) order.
        let adj = model.mesh().adjacency();
        let (masses, target, load, projections, els) = (
            model.masses(),
            &self.target,
            &self.load,
            &self.projections,
            &self.els,
        );
        self.rhs_v
            .par_chunks_mut(VERTEX_CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                for (k, r) in out.iter_mut().enumerate() {
                    let v = c * VERTEX_CHUNK + k;
                    let mut s = target[v] * (masses[v] * w) + load[v];
                    for &(t, corner) in adj.of(v) {
                        s += projections[t as usize] * corner_gradient(&els[t as usize], corner);
                    }
                    *r = s;
                }
            });
        for s in model.springs() {
            self.rhs_v[s.vertex as usize] += s.goal * s.stiffness;
        }
        let n = self.system.n_free();
        for (k, &v) in self.free.iter().enumerate() {
            let r = self.rhs_v[v as usize];
            self.rhs[k] = r.x;
            self.rhs[n + k] = r.y;
        }
        self.system.move_kinematic_to_rhs(&self.x, &mut self.rhs);
    }

    /// The global step from the right-hand sides of [`PdStepper::local_step`]: the new free
    /// positions into `self.x`; returns the largest position change, m.
    fn global_step(&mut self) -> Real {
        let n = self.system.n_free();
        match (&mut self.bdf2_system, self.bdf2) {
            (Some(system), true) => system.solve(&mut self.rhs),
            _ => self.system.solve(&mut self.rhs),
        }
        let mut change: Real = 0.0;
        for (k, &v) in self.free.iter().enumerate() {
            let p = Vec2::new(self.rhs[k], self.rhs[n + k]);
            let d = (p - self.x[v as usize]).norm();
            change = if d.is_nan() || change.is_nan() {
                Real::NAN
            } else {
                change.max(d)
            };
            self.x[v as usize] = p;
        }
        change
    }

    /// The residual test at `self.x`, after [`PdStepper::local_step`] there: the norm of the
    /// gradient of the step's incremental potential over the free vertices, N,
    /// `g = m w (x - x_hat) - f + sum_e a_e P_e g_e + k (x - goal)`, with each triangle's
    /// `a P = (w1 + w2) F - (w1 p1 + w2 p2)` from the local step's projections (the
    /// co-rotational energy's exact `P`: no further polar decomposition); with `elastic`, also
    /// the norm of the elastic forces on the free vertices (the force scale's third term), else
    /// 0. Parallel over fixed chunks, summed serially in vertex order.
    fn gradient_norm<E: Energy>(
        &mut self,
        model: &Model<E>,
        w: Real,
        elastic: bool,
    ) -> (Real, Real) {
        let x = &self.x;
        self.stress
            .par_chunks_mut(ELEMENT_CHUNK)
            .zip(self.projections.par_chunks(ELEMENT_CHUNK))
            .zip(self.els.par_chunks(ELEMENT_CHUNK))
            .zip(self.w_mu.par_chunks(ELEMENT_CHUNK))
            .zip(self.w_lambda.par_chunks(ELEMENT_CHUNK))
            .for_each(|((((out, proj), els), w1), w2)| {
                for ((((q, p), el), w1), w2) in out.iter_mut().zip(proj).zip(els).zip(w1).zip(w2) {
                    *q = deformation_gradient(el, x) * (w1 + w2) - p;
                }
            });
        let adj = model.mesh().adjacency();
        let (stress, els) = (&self.stress, &self.els);
        self.elastic
            .par_chunks_mut(VERTEX_CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                for (k, e) in out.iter_mut().enumerate() {
                    let mut s = Vec2::zeros();
                    for &(t, corner) in adj.of(c * VERTEX_CHUNK + k) {
                        s += stress[t as usize] * corner_gradient(&els[t as usize], corner);
                    }
                    *e = s;
                }
            });
        let (masses, springs) = (model.masses(), model.springs());
        let (mut sq, mut elastic_sq) = (0.0, 0.0);
        for &v in &self.free {
            let v = v as usize;
            let e = self.elastic[v];
            let mut g = (x[v] - self.target[v]) * (masses[v] * w) - self.load[v] + e;
            if let Some(s) = spring_of(springs, v) {
                g += (x[v] - s.goal) * s.stiffness;
            }
            sq += g.norm_squared();
            if elastic {
                elastic_sq += e.norm_squared();
            }
        }
        (sq.sqrt(), elastic_sq.sqrt())
    }
}

impl Stepper for PdStepper {
    fn dt(&self) -> Real {
        self.params.dt
    }

    fn step<E: Energy>(
        &mut self,
        model: &Model<E>,
        state: &mut State,
    ) -> Result<StepReport, SolverError> {
        check_step_inputs(model, self.n_triangles, state)?;
        if model.layout() != self.layout {
            let earlier = self.factorisations();
            *self = PdStepper::new(model, self.params)?;
            self.system.add_earlier(earlier);
        }
        let (h, t) = (self.params.dt, state.t);
        let bdf2 = self.history.begin(state, h, model.layout());
        self.bdf2 = bdf2;
        let (w, hh) = self.history.targets(bdf2, state, h, &mut self.target);
        external_load(model, &mut self.load);
        let masses = model.masses();
        // The start: the inertial target plus the external load's acceleration over the step.
        for (i, xh) in self.target.iter().enumerate() {
            self.x[i] = *xh + self.load[i] * (hh / masses[i]);
        }
        model
            .kinematics()
            .apply(t, h, t + h, &state.x, &mut self.x, &mut self.v_new);
        let rho = self.params.chebyshev_rho;
        if rho > 0.0 {
            self.chebyshev.start(&self.x);
        }
        let mut residual = 0.0;
        let mut iterations = 0;
        let tolerance = self.params.tolerance;
        if tolerance == 0.0 {
            for _ in 0..self.params.iterations {
                residual = self.iterate(model, w);
                if rho > 0.0 {
                    // The co-rotational energy is finite under inversion: no restart needed.
                    self.chebyshev
                        .apply(rho, &mut self.x, &self.free, &self.els, false);
                }
            }
            iterations = self.params.iterations;
        } else {
            // The residual test reads the local step of the iteration that follows it (its
            // projections give each triangle's P), so it costs no polar decomposition of its
            // own; the last one, at the final positions, has no global step after it.
            let mut goal = 0.0;
            loop {
                self.local_step(model, w);
                let (g, elastic) = self.gradient_norm(model, w, iterations == 0);
                if iterations == 0 {
                    self.force_scale = force_scale(g, &self.load, elastic);
                    goal = tolerance * self.force_scale;
                }
                residual = g;
                if g <= goal || iterations == self.params.iterations {
                    break;
                }
                self.global_step();
                iterations += 1;
                if rho > 0.0 {
                    self.chebyshev
                        .apply(rho, &mut self.x, &self.free, &self.els, false);
                }
            }
        }
        let inv = commit_positions(
            model,
            state,
            &self.els,
            &mut self.x,
            &mut self.v_new,
            None,
            None,
            h,
            t + h,
            self.decay,
            true,
            bdf2.then_some(&self.history.prev.x[..]),
        )?;
        self.history.commit(state);
        Ok(StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations,
            residual,
            contacts: 0,
        })
    }
}

impl Solver for PdStepper {
    type Params = PdParams;
    const NAME: &'static str = "pd";
    const CAPABILITIES: Capabilities = Capabilities {
        title: "Projective Dynamics",
        summary: "Projective Dynamics (Bouaziz et al. 2014), co-rotational energy only: local projections per element, one global matrix factorised once",
        paper: false,
        contact: false,
        rigid_regions: false,
        averaged_pressure: false,
        dims: 3,
        implicit: true,
        iterations: true,
        substeps: false,
        factorisation: true,
        deterministic_across_threads: true,
        clock: Clock::Time,
        converges_to: "each step to implicit Euler's (BDF2's with integrator = bdf2) as iterations grow (the co-rotational energy is exactly two projective terms, area term included)",
    };

    fn validate_params(p: &PdParams, prefix: &str) -> Result<(), SolverError> {
        p.validate_as(prefix)
    }

    fn build<E: Energy>(model: &Model<E>, p: &PdParams) -> Result<Self, SolverError> {
        PdStepper::new(model, *p)
    }

    fn dt_mut(p: &mut PdParams) -> Option<&mut Real> {
        Some(&mut p.dt)
    }

    fn integrator_mut(p: &mut PdParams) -> Option<&mut Integrator> {
        Some(&mut p.integrator)
    }
}
