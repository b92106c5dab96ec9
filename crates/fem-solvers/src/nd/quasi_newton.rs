//! Quasi-Newton implicit Euler in either dimension: the 2D [`crate::quasi_newton`] solver
//! (L-BFGS with Projective Dynamics' matrix as the initial Hessian; Liu, Bouaziz & Kavan 2017)
//! on a simplex mesh, for every energy (without the 2D solver's contact and rigid bodies).
//!
//! Each step of length `h` minimises implicit Euler's incremental potential
//! `G(x) = sum m/(2 h^2) |x - x_hat|^2 - f . (x - X) + sum_e V_e psi(F_e)` (the load's work
//! measured from the rest positions `X`) over the free degrees of freedom, from
//! `x_hat + h^2 f / m`, or, when the potential is not finite there or a cell is inverted under
//! an energy that forbids inversion, from the current positions. Each iteration:
//! - the direction `d = -H g` by L-BFGS's two-loop recursion over the last `history` pairs
//!   `(s, y)` of position and gradient changes, with the initial inverse Hessian `A^-1`,
//!   `A = M / h^2 + L` the Projective Dynamics matrix of the energy's Lamé parameters at rest
//!   ([`super::pd_system`]; for the co-rotational energy the exact PD matrix), factorised once
//!   when the solver is built; a direction that is not a descent direction restarts from
//!   `A^-1` alone;
//! - a backtracking (Armijo) line search of at most `max_halvings` halvings: a trial of
//!   infinite potential (an inverted Neo-Hookean cell) is never accepted; within the
//!   potential's round-off (`1e-12` times its terms' magnitudes plus the modulus times the
//!   volume) a trial that lowers the gradient is taken;
//! - a pair is kept only when `s . y > 0` (curvature), so `H` stays positive definite.
//!
//! It stops after `iterations` iterations, or earlier when the gradient's norm over the free
//! degrees of freedom falls below `tolerance` times the force scale (the largest of the first
//! gradient, the external load, the elastic forces on the free degrees of freedom at the start
//! and 1e-12 N). Not reaching the tolerance is not an error (a real-time step has a fixed
//! budget): the report gives the iterations taken (a line search that finds no acceptable step
//! counts and ends the step) and the gradient's norm at the positions the step ends at, N. A
//! step that took no trial from the current positions, or whose every trial was infinite, is an
//! error, unless its smallest trial inverts a cell of an energy that forbids it (a stall of the
//! fixed budget). With enough iterations the step is implicit Euler's for every energy
//! (`tests/suite/nd_quasi_newton.rs`).
//!
//! Fixed degrees of freedom keep their position and zero velocity;
//! `v' = (x' - x) / h exp(-c h)`. Per-cell work runs in parallel into buffers and every sum is
//! in a fixed order, so the result is the same for any number of threads; a step allocates
//! nothing. Backward Euler only: BDF2 (`integrator = "bdf2"`) is refused in one line.

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::{Real, exp};
use fem_core::simplex::assembly::{Scratch, elastic_energy, populate_forces};

use super::pd_system::{NdPdSystem, inversion, projective_weights, rest_lame};
use super::projective::backward_euler_only;
use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::steppers::quasi_newton::{
    Lbfgs, QuasiNewtonParams, QuasiNewtonReport, dot, overflowing_start,
};
use crate::steppers::report::StepReport;

/// Quasi-Newton implicit Euler on a [`NdModel`]; see the module docs.
pub struct NdQuasiNewton<D: Dim> {
    params: QuasiNewtonParams,
    decay: Real,
    /// `M / h^2 + L`, factorised.
    system: NdPdSystem<D>,
    forbids_inversion: bool,
    /// The P-wave modulus times the body's measure: the scale of the elastic energy's
    /// round-off.
    psi_scale: Real,
    target: Vec<D::Vector>,
    load: Vec<D::Vector>,
    x: Vec<D::Vector>,
    trial: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
    forces: Vec<D::Vector>,
    scratch: Scratch<D>,
    /// Packed over the free degrees of freedom: the gradient at `x`, at the trial, the
    /// direction and the position change.
    g: Vec<Real>,
    g_new: Vec<Real>,
    d: Vec<Real>,
    s: Vec<Real>,
    lbfgs: Lbfgs,
    last: QuasiNewtonReport,
}

/// Which position buffer an evaluation reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Which {
    X,
    Trial,
}

/// Whether `energy` forbids inversion: `psi` is infinite at `F = diag(1, .., 1, -1)`.
fn forbids_inversion<D: Dim, E: Hyperelastic<D>>(energy: &E) -> bool {
    let mut f = D::identity();
    f.set_at(D::D * D::D - 1, -1.0);
    !Hyperelastic::<D>::density(energy, &f).is_finite()
}

impl<D: Dim> NdQuasiNewton<D> {
    /// For `model`: validates the parameters (errors name `<prefix>.<field>`), refuses BDF2,
    /// and assembles and factorises the Projective Dynamics matrix.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        params: QuasiNewtonParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        params.validate_as(prefix)?;
        backward_euler_only::<D>(params.integrator, prefix)?;
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        let (mu, lambda) = rest_lame::<D, E>(model.energy());
        let (w_mu, w_lambda) = projective_weights(mesh, (mu, lambda));
        let weights: Vec<Real> = w_mu.iter().zip(&w_lambda).map(|(a, b)| a + b).collect();
        let psi_scale = (2.0 * mu + lambda).abs() * mesh.measure();
        let h = params.dt;
        let system = NdPdSystem::new(
            mesh,
            model.masses(),
            &weights,
            1.0 / (h * h),
            model.fixed(),
            prefix,
        )?;
        let m = system.len();
        Ok(NdQuasiNewton {
            decay: exp(-params.damping * h),
            system,
            forbids_inversion: forbids_inversion::<D, E>(model.energy()),
            psi_scale,
            target: vec![D::Vector::zeros(); n],
            load: vec![D::Vector::zeros(); n],
            x: vec![D::Vector::zeros(); n],
            trial: vec![D::Vector::zeros(); n],
            v_new: vec![D::Vector::zeros(); n],
            forces: vec![D::Vector::zeros(); n],
            scratch: Scratch::new(),
            g: vec![0.0; m],
            g_new: vec![0.0; m],
            d: vec![0.0; m],
            s: vec![0.0; m],
            lbfgs: Lbfgs::new(params.history, m),
            last: QuasiNewtonReport::default(),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &QuasiNewtonParams {
        &self.params
    }

    /// What the last step did.
    pub fn last_report(&self) -> &QuasiNewtonReport {
        &self.last
    }

    /// Numeric factorisations of the initial Hessian since the solver was built (one per
    /// distinct set of free vertices over the coordinates), whatever the number of steps.
    pub fn factorisations(&self) -> usize {
        self.system.factorisations()
    }

    /// The potential at `which` and the sum of its terms' magnitudes (the scale of its
    /// round-off); when `gradient` is given and the potential is finite, also its gradient
    /// over the free degrees of freedom, packed, into `g` (`Which::X`) or `g_new`.
    fn evaluate<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        w: Real,
        which: Which,
        gradient: Option<Which>,
    ) -> (Real, Real) {
        let x = match which {
            Which::X => &self.x,
            Which::Trial => &self.trial,
        };
        let mesh = model.mesh();
        let elastic = elastic_energy(mesh, model.energy(), x, &mut self.scratch);
        let (mut rest, mut magnitude) = (0.0, elastic.abs());
        // The load's work is measured from the rest positions: the same minimiser, without a
        // large constant that would swamp the line search's comparisons in round-off.
        for ((v, p), x0) in x.iter().enumerate().zip(mesh.vertices()) {
            let inertia = 0.5 * w * model.masses()[v] * (*p - self.target[v]).norm2();
            rest += inertia;
            magnitude += inertia;
            let work = self.load[v].inner(&(*p - *x0));
            rest -= work;
            magnitude += work.abs();
        }
        let e = elastic + rest;
        if gradient.is_some() && e.is_finite() {
            populate_forces(mesh, model.energy(), x, &mut self.scratch, &mut self.forces);
            let out = match gradient {
                Some(Which::X) => &mut self.g,
                _ => &mut self.g_new,
            };
            for (k, &(v, i)) in self.system.dofs().iter().enumerate() {
                let v = v as usize;
                let gv = (x[v] - self.target[v]) * (w * model.masses()[v])
                    - self.load[v]
                    - self.forces[v];
                out[k] = gv.at(i as usize);
            }
        }
        (e, magnitude)
    }

    /// `d = -H g` by the two-loop recursion with `H0 = A^-1`.
    fn direction(&mut self) {
        let system = &mut self.system;
        self.lbfgs
            .direction(&self.g, &mut self.d, |d| system.solve(d));
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdQuasiNewton<D> {
    fn step(
        &mut self,
        model: &NdModel<D, E>,
        state: &mut NdState<D>,
    ) -> Result<StepReport, SolverError> {
        let h = self.params.dt;
        let (w, hh) = (1.0 / (h * h), h * h);
        let fixed = model.fixed();
        let masses = model.masses();
        // The inertial target, and the start: the target plus the external load's acceleration
        // over the step; fixed components where they are.
        for v in 0..state.x.len() {
            let (x0, v0) = (state.x[v], state.v[v]);
            let load = model.external_force(v);
            let mut t = x0 + v0 * h;
            let mut p = t + load * (hh / masses[v]);
            for i in 0..D::D {
                if fixed[D::D * v + i] {
                    t.set_at(i, x0.at(i));
                    p.set_at(i, x0.at(i));
                }
            }
            self.load[v] = load;
            self.target[v] = t;
            self.x[v] = p;
        }
        // The last report's buffer of residuals, reused.
        let mut residuals = std::mem::take(&mut self.last.residuals);
        residuals.clear();
        let mut report = QuasiNewtonReport {
            residuals,
            ..QuasiNewtonReport::default()
        };
        let (mut energy, mut magnitude) = self.evaluate(model, w, Which::X, Some(Which::X));
        if !energy.is_finite()
            || (self.forbids_inversion && inversion(model.mesh(), &self.x).inverted > 0)
        {
            self.x.copy_from_slice(&state.x);
            (energy, magnitude) = self.evaluate(model, w, Which::X, Some(Which::X));
            report.fallback_guess = true;
        }
        self.lbfgs.clear();
        // Newton's force scale: the first gradient, the load, and the elastic forces on the
        // free degrees of freedom at the start (`self.forces`, from the evaluation above).
        let elastic = (self.system.dofs().iter())
            .map(|&(v, i)| {
                let f = self.forces[v as usize].at(i as usize);
                f * f
            })
            .sum::<Real>()
            .sqrt();
        let mut gnorm = dot(&self.g, &self.g).sqrt();
        let load = self.load.iter().map(|f| f.norm2()).sum::<Real>().sqrt();
        let scale = gnorm.max(load).max(elastic).max(1e-12);
        overflowing_start(gnorm, scale)?;
        // Whether any trial of the step had a finite potential, and whether any was taken.
        let (mut finite_trial, mut moved) = (false, false);
        report.force_scale = scale;
        report.residuals.push(gnorm);
        while report.iterations < self.params.iterations && energy.is_finite() {
            if gnorm <= self.params.tolerance * scale {
                report.converged = true;
                break;
            }
            self.direction();
            let mut slope = dot(&self.g, &self.d);
            if slope >= 0.0 || !slope.is_finite() {
                // Not a descent direction (round-off in the history): restart from A^-1.
                self.lbfgs.clear();
                self.direction();
                slope = dot(&self.g, &self.d);
            }
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..=self.params.max_halvings {
                self.trial.copy_from_slice(&self.x);
                for (k, &(v, i)) in self.system.dofs().iter().enumerate() {
                    let (v, i) = (v as usize, i as usize);
                    self.trial[v].set_at(i, self.x[v].at(i) + self.d[k] * alpha);
                }
                let (e, m) = self.evaluate(model, w, Which::Trial, None);
                report.evaluations += 1;
                if !e.is_finite() {
                    alpha *= 0.5;
                    continue;
                }
                finite_trial = true;
                // Near the minimum the change of the potential falls below its round-off:
                // there the trial is accepted if it lowers the gradient instead.
                let armijo = e <= energy + 1e-4 * alpha * slope;
                let in_round_off = (e - energy).abs() <= 1e-12 * (magnitude + m + self.psi_scale);
                let lowers_gradient = !armijo && in_round_off && {
                    self.evaluate(model, w, Which::Trial, Some(Which::Trial));
                    dot(&self.g_new, &self.g_new).sqrt() < gnorm
                };
                if armijo || lowers_gradient {
                    (energy, magnitude) = (e, m);
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            report.iterations += 1;
            moved |= accepted;
            if !accepted {
                break;
            }
            self.evaluate(model, w, Which::Trial, Some(Which::Trial));
            for (k, &(v, i)) in self.system.dofs().iter().enumerate() {
                let (v, i) = (v as usize, i as usize);
                self.s[k] = self.trial[v].at(i) - self.x[v].at(i);
            }
            self.lbfgs.remember(&self.s, &self.g_new, &self.g);
            std::mem::swap(&mut self.x, &mut self.trial);
            std::mem::swap(&mut self.g, &mut self.g_new);
            gnorm = dot(&self.g, &self.g).sqrt();
            report.residuals.push(gnorm);
        }
        if gnorm <= self.params.tolerance * scale {
            report.converged = true;
        }
        if !moved && (report.fallback_guess || !finite_trial) && !report.converged {
            stalled::<D>(
                model.mesh(),
                &self.x,
                &self.trial,
                self.forbids_inversion,
                self.params.max_halvings,
                gnorm,
            )?;
        }
        for v in 0..state.x.len() {
            self.v_new[v] = (self.x[v] - state.x[v]) / h * self.decay;
        }
        let inv = inversion(model.mesh(), &self.x);
        let out = StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations: report.iterations,
            residual: gnorm,
            contacts: 0,
        };
        check_finite::<D>(&self.x, &self.v_new, step_number(state.t, h), state.t, &out)?;
        std::mem::swap(&mut state.x, &mut self.x);
        std::mem::swap(&mut state.v, &mut self.v_new);
        state.t += h;
        self.last = report;
        Ok(out)
    }
}

/// A step that took no trial, from a start that is the current state (the prediction was not
/// finite) or with every trial's potential infinite, leaves the body at `x` under a load it
/// did not resist: no step of the problem posed, so an error, unless the smallest trial
/// (`trial`) inverts a cell under an energy that forbids it within the body's size of the
/// start (a stall of the fixed budget, reported by its residual). The 2D solver's rule.
fn stalled<D: Dim>(
    mesh: &fem_core::simplex::SimplexMesh<D>,
    x: &[D::Vector],
    trial: &[D::Vector],
    forbids_inversion: bool,
    max_halvings: usize,
    gnorm: Real,
) -> Result<(), SolverError> {
    let reach = (x.iter().zip(trial))
        .map(|(a, b)| (*a - *b).norm2().sqrt())
        .fold(0.0, Real::max);
    // The diagonal of the bounding box of `x`.
    let size = (0..D::D)
        .map(|i| {
            let (lo, hi) = x
                .iter()
                .fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p.at(i)), hi.max(p.at(i)))
                });
            (hi - lo) * (hi - lo)
        })
        .sum::<Real>()
        .sqrt();
    if forbids_inversion && reach <= size && inversion(mesh, trial).inverted > 0 {
        return Ok(());
    }
    Err(SolverError::BeyondPrecision {
        prefix: "quasi-newton",
        detail: format!(
            "the step did not move the body: no trial along the search direction has a \
             finite, lower potential (halved {max_halvings} times; residual {gnorm:.3e} N)"
        ),
    })
}
