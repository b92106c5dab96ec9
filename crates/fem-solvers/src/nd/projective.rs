//! Projective Dynamics in either dimension: the 2D [`crate::projective`] solver (Bouaziz et
//! al. 2014, with Wang's Chebyshev acceleration) on a simplex mesh, for the co-rotational
//! energy.
//!
//! **The energy as projective terms, in `D` dimensions.** The co-rotational energy
//! `psi = mu |F - R|^2 + lambda/2 (tr S - D)^2`, `S = R^T F`, `R` the polar rotation
//! ([`Dim::polar_rotation`]; [`fem_core::energy::Corotational`]), is exactly
//! `mu |F - p1|^2 + (D lambda / 2) |F - p2|^2`:
//! - `p1 = R`, the projection onto the rotations (ARAP; at `lambda = 0` the whole energy);
//! - **the volume term.** Its zero set is the matrices whose stretch has trace `D`. Shifting
//!   the stretch uniformly, `p2 = R (S + c I) = F + c R` with `c = (D - tr S) / D`, gives
//!   `tr(S + c I) = tr S + D c = D`: `p2` is in the set, and it is the nearest point of the
//!   set while `S + c I` stays positive (the set is the sphere `tr S = D` of the nuclear
//!   norm, whose normal at `p2` is its polar rotation, `R`, and `F - p2 = -c R` is along it).
//!   Then `|F - p2|^2 = c^2 |R|^2 = D c^2 = (tr S - D)^2 / D`, so
//!   `lambda/2 (tr S - D)^2 = (D lambda / 2) |F - p2|^2`. Its gradient
//!   `D lambda (F - p2) = lambda (tr S - D) R` is the term's `P`, so nothing is approximated:
//!   the fixed point of the iterations is implicit Euler's step of the co-rotational energy.
//!   In 2D, `c = (2 - tr S) / 2` and the weight is `lambda`: the 2D solver's terms.
//!
//! So a cell of measure `V` has the weights `w1 = 2 V mu` and `w2 = D V lambda` (its energy is
//! `w1/2 |F - p1|^2 + w2/2 |F - p2|^2`; `2 V lambda` in 2D); `tests/suite/nd_projective.rs`
//! checks the identity and the gradient against the co-rotational energy's [`Hyperelastic`]
//! in 2D and 3D ([`corotational_projections`]).
//!
//! Each step of length `h` minimises implicit Euler's incremental potential
//! `sum m/(2 h^2) |x - x_hat|^2 - f . x + sum_e V_e psi(F_e)`, `x_hat = x + h v`, by
//! local-global iterations from `x_hat + h^2 f / m`: the **local step** computes `p1, p2` per
//! cell (in parallel into a buffer); the **global step** solves
//! `(M / h^2 + L) x = M / h^2 x_hat + f + sum_e G_e^T (w1 p1 + w2 p2)`,
//! `L = sum_e (w1 + w2) G_e^T G_e` ([`super::pd_system`]), one matrix per coordinate block for
//! the whole run, factorised once when the solver is built. Each vertex sums its cells'
//! contributions in the mesh's adjacency order, so the result is the same for any number of
//! threads. Fixed degrees of freedom keep their position (their couplings are on the
//! right-hand side) and zero velocity; `v' = (x' - x) / h exp(-c h)`.
//!
//! The parameters are the 2D solver's ([`PdParams`]) with the same meanings: `iterations`,
//! `chebyshev_rho` (0 = off; extrapolates the free degrees of freedom after each iteration),
//! `tolerance` (`residual_tolerance`; 0 = off: with a positive tolerance the step stops once
//! the gradient of its potential over the free degrees of freedom,
//! `m / h^2 (x - x_hat) - f + sum_e V_e P_e g_e`, is at most `tolerance` times Newton's force
//! scale, evaluated at the start and after each iteration from the next local step's
//! projections). The report's residual is the largest vertex displacement of the last
//! iteration, m (with a positive tolerance: that gradient's norm, N).
//!
//! Other energies are refused in one line naming them (`<prefix>.energy = neo-hookean: ...`),
//! as in 2D; the quasi-Newton solver ([`super::NdQuasiNewton`]) runs them with this matrix as its
//! initial Hessian. Backward Euler only: BDF2 (`integrator = "bdf2"`) is refused in one line.

use std::any::Any;

use fem_core::dim::{Dense, Dim};
use fem_core::energy::{
    AnyEnergy, Corotational, Energy, Hyperelastic, Linear, NeoHookean, StableNeoHookean, Stvk,
};
use fem_core::math::{Real, exp};
use fem_core::par::prelude::*;

use super::pd_system::{NdPdSystem, inversion, projective_weights, rest_lame};
use super::{NdModel, NdState, NdStepper, check_finite, step_number};
use crate::error::SolverError;
use crate::steppers::integrator::Integrator;
use crate::steppers::projective::PdParams;
use crate::steppers::report::StepReport;

/// The name of a built-in energy (`fem-core`'s, or any of them in an [`AnyEnergy`]); `None`
/// for another type.
pub(crate) fn energy_name<E: 'static>(energy: &E) -> Option<&'static str> {
    let any = energy as &dyn Any;
    if let Some(e) = any.downcast_ref::<AnyEnergy>() {
        return Some(e.name());
    }
    macro_rules! named {
        ($($ty:ty),*) => {$(
            if let Some(e) = any.downcast_ref::<$ty>() {
                return Some(e.name());
            }
        )*};
    }
    named!(Corotational, NeoHookean, StableNeoHookean, Stvk, Linear);
    None
}

/// Refuse BDF2 in one line naming `<prefix>.integrator` (the nd solvers are backward Euler).
pub(crate) fn backward_euler_only<D: Dim>(
    integrator: Integrator,
    prefix: &str,
) -> Result<(), SolverError> {
    if integrator != Integrator::BackwardEuler {
        return Err(SolverError::invalid(
            format!("{prefix}.integrator"),
            "bdf2",
            format!("is not available in {} yet (use backward-euler)", D::NAME),
        ));
    }
    Ok(())
}

/// Chebyshev's extrapolation of the free degrees of freedom (the 2D solvers' `Chebyshev`).
#[derive(Debug)]
struct Chebyshev<D: Dim> {
    prev: Vec<D::Vector>,
    last: Vec<D::Vector>,
    /// Iterations in the current sequence.
    k: usize,
    omega: Real,
}

impl<D: Dim> Chebyshev<D> {
    fn new(n: usize) -> Self {
        Chebyshev {
            prev: vec![D::Vector::zeros(); n],
            last: vec![D::Vector::zeros(); n],
            k: 0,
            omega: 1.0,
        }
    }

    /// Start a sequence at `x`.
    fn start(&mut self, x: &[D::Vector]) {
        self.last.copy_from_slice(x);
        self.k = 0;
        self.omega = 1.0;
    }

    /// Extrapolate the free degrees of freedom of `x`, just iterated.
    fn apply(&mut self, rho: Real, x: &mut [D::Vector], fixed: &[bool]) {
        self.k += 1;
        self.omega = match self.k {
            1 => 1.0,
            2 => 2.0 / (2.0 - rho * rho),
            _ => 4.0 / (4.0 - rho * rho * self.omega),
        };
        if self.k > 1 {
            for (v, p) in x.iter_mut().enumerate() {
                let q = self.prev[v];
                for i in 0..D::D {
                    if !fixed[D::D * v + i] {
                        p.set_at(i, (p.at(i) - q.at(i)) * self.omega + q.at(i));
                    }
                }
            }
        }
        // x_{k-2} <- x_{k-1}; x_{k-1} <- x_k.
        std::mem::swap(&mut self.prev, &mut self.last);
        self.last.copy_from_slice(x);
    }
}

/// The co-rotational energy's two projections of `F` (see the module docs): `p1 = R`, the
/// polar rotation, and `p2 = F + R (D - tr(R^T F)) / D`, whose stretch has trace `D`. With the
/// weights `w1 = 2 V mu` and `w2 = D V lambda` of a cell of measure `V`,
/// `V psi(F) = w1/2 |F - p1|^2 + w2/2 |F - p2|^2` and `V P(F) = w1 (F - p1) + w2 (F - p2)`.
pub fn corotational_projections<D: Dim>(f: &D::Matrix) -> (D::Matrix, D::Matrix) {
    let d = D::D as Real;
    let r = D::polar_rotation(f);
    let trace = D::trace(&(D::transpose(&r) * *f));
    (r, *f + r * ((d - trace) / d))
}

/// A matrix of not-a-numbers (the projections of a cell whose `F` overflows).
fn nan_matrix<D: Dim>() -> D::Matrix {
    let mut m = D::Matrix::zeros();
    (0..<D::Matrix as Dense>::LEN).for_each(|k| m.set_at(k, Real::NAN));
    m
}

/// Projective Dynamics on a [`NdModel`] of the co-rotational energy; see the module docs.
pub struct NdPd<D: Dim> {
    params: PdParams,
    decay: Real,
    /// `M / h^2 + L`, factorised.
    system: NdPdSystem<D>,
    /// Per cell: `2 V mu` and `D V lambda`.
    w_mu: Vec<Real>,
    w_lambda: Vec<Real>,
    /// Per cell: `w1 p1 + w2 p2` of the last local step.
    projections: Vec<D::Matrix>,
    target: Vec<D::Vector>,
    load: Vec<D::Vector>,
    x: Vec<D::Vector>,
    v_new: Vec<D::Vector>,
    /// Per vertex: the global step's right-hand side.
    rhs_v: Vec<D::Vector>,
    /// The right-hand sides over the free degrees of freedom, packed.
    rhs: Vec<Real>,
    chebyshev: Chebyshev<D>,
    /// The residual test's buffers (sized only when the tolerance is positive): per cell
    /// `V P = (w1 + w2) F - (w1 p1 + w2 p2)`, per vertex `sum_e V_e P_e g`.
    stress: Vec<D::Matrix>,
    elastic: Vec<D::Vector>,
    /// The force scale of the last step's residual test, N (0 when the tolerance is 0).
    force_scale: Real,
}

impl<D: Dim> NdPd<D> {
    /// For `model`: validates the parameters (errors name `<prefix>.<field>`), refuses
    /// energies other than the co-rotational one and BDF2, and assembles and factorises the
    /// global matrix.
    pub fn new<E: Hyperelastic<D> + 'static>(
        model: &NdModel<D, E>,
        params: PdParams,
        prefix: &str,
    ) -> Result<Self, SolverError> {
        params.validate_as(prefix)?;
        backward_euler_only::<D>(params.integrator, prefix)?;
        let name = energy_name(model.energy());
        if name != Some("corotational") {
            return Err(SolverError::invalid(
                format!("{prefix}.energy"),
                name.unwrap_or(std::any::type_name::<E>()),
                "Projective Dynamics runs the corotational energy only (the sum of two projective terms); use quasi-newton for the others",
            ));
        }
        let mesh = model.mesh();
        let n = mesh.n_vertices();
        let (w_mu, w_lambda) = projective_weights(mesh, rest_lame::<D, E>(model.energy()));
        let weights: Vec<Real> = w_mu.iter().zip(&w_lambda).map(|(a, b)| a + b).collect();
        let h = params.dt;
        let system = NdPdSystem::new(
            mesh,
            model.masses(),
            &weights,
            1.0 / (h * h),
            model.fixed(),
            prefix,
        )?;
        let with_test = params.tolerance > 0.0;
        Ok(NdPd {
            decay: exp(-params.damping * h),
            params,
            rhs: vec![0.0; system.len()],
            system,
            w_mu,
            w_lambda,
            projections: vec![D::Matrix::zeros(); mesh.n_cells()],
            target: vec![D::Vector::zeros(); n],
            load: vec![D::Vector::zeros(); n],
            x: vec![D::Vector::zeros(); n],
            v_new: vec![D::Vector::zeros(); n],
            rhs_v: vec![D::Vector::zeros(); n],
            chebyshev: Chebyshev::new(if params.chebyshev_rho > 0.0 { n } else { 0 }),
            stress: if with_test {
                vec![D::Matrix::zeros(); mesh.n_cells()]
            } else {
                Vec::new()
            },
            elastic: if with_test {
                vec![D::Vector::zeros(); n]
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

    /// Numeric factorisations of the global matrix since the solver was built: one per
    /// distinct set of free vertices over the coordinates (one when whole vertices are
    /// pinned), whatever the number of steps.
    pub fn factorisations(&self) -> usize {
        self.system.factorisations()
    }

    /// The force scale of the last step's residual test, N (0 when the tolerance is 0).
    pub fn force_scale(&self) -> Real {
        self.force_scale
    }

    /// The local step at `self.x` (the projections) and the global step's right-hand sides.
    fn local_step<E: Hyperelastic<D>>(&mut self, model: &NdModel<D, E>, w: Real) {
        let mesh = model.mesh();
        let x = &self.x;
        let (w_mu, w_lambda) = (&self.w_mu, &self.w_lambda);
        self.projections
            .par_iter_mut()
            .enumerate()
            .for_each(|(c, p)| {
                let mut corners = [D::Vector::zeros(); 4];
                for (k, &i) in mesh.cells()[c].as_ref().iter().enumerate() {
                    corners[k] = x[i as usize];
                }
                let f = mesh.elements()[c].deformation_gradient(&corners[..D::NODES]);
                // A deformation beyond double precision has no polar decomposition (the SVD's
                // `F^T F` would overflow): not-a-numbers, which the step reports.
                if !f.norm2().is_finite() {
                    *p = nan_matrix::<D>();
                    return;
                }
                let (p1, p2) = corotational_projections::<D>(&f);
                *p = p1 * w_mu[c] + p2 * w_lambda[c];
            });
        let (masses, target, load, projections) =
            (model.masses(), &self.target, &self.load, &self.projections);
        self.rhs_v.par_iter_mut().enumerate().for_each(|(v, r)| {
            let mut s = target[v] * (masses[v] * w) + load[v];
            for &(c, corner) in mesh.cells_of(v) {
                s +=
                    projections[c as usize] * mesh.elements()[c as usize].gradient(corner as usize);
            }
            *r = s;
        });
        for (k, &(v, i)) in self.system.dofs().iter().enumerate() {
            self.rhs[k] = self.rhs_v[v as usize].at(i as usize);
        }
        self.system.move_fixed_to_rhs(&self.x, &mut self.rhs);
    }

    /// The global step from the right-hand sides of [`NdPd::local_step`]: the new free
    /// components into `self.x`; returns the largest vertex displacement, m.
    fn global_step(&mut self) -> Real {
        self.system.solve(&mut self.rhs);
        let packed = self.system.packed();
        let mut change: Real = 0.0;
        for (v, p) in self.x.iter_mut().enumerate() {
            let old = *p;
            for i in 0..D::D {
                let k = packed[D::D * v + i];
                if k != usize::MAX {
                    p.set_at(i, self.rhs[k]);
                }
            }
            let d = (*p - old).norm2().sqrt();
            change = if d.is_nan() || change.is_nan() {
                Real::NAN
            } else {
                change.max(d)
            };
        }
        change
    }

    /// The residual test at `self.x`, after [`NdPd::local_step`] there: the norm of the
    /// gradient of the step's potential over the free degrees of freedom, N, with each cell's
    /// `V P = (w1 + w2) F - (w1 p1 + w2 p2)` from the local step's projections; with
    /// `elastic`, also the norm of the elastic forces on the free degrees of freedom, else 0.
    /// Parallel into buffers, summed serially in vertex order.
    fn gradient_norm<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        w: Real,
        elastic: bool,
    ) -> (Real, Real) {
        let mesh = model.mesh();
        let x = &self.x;
        let (w_mu, w_lambda, projections) = (&self.w_mu, &self.w_lambda, &self.projections);
        self.stress.par_iter_mut().enumerate().for_each(|(c, q)| {
            let mut corners = [D::Vector::zeros(); 4];
            for (k, &i) in mesh.cells()[c].as_ref().iter().enumerate() {
                corners[k] = x[i as usize];
            }
            let f = mesh.elements()[c].deformation_gradient(&corners[..D::NODES]);
            *q = f * (w_mu[c] + w_lambda[c]) - projections[c];
        });
        let stress = &self.stress;
        self.elastic.par_iter_mut().enumerate().for_each(|(v, e)| {
            let mut s = D::Vector::zeros();
            for &(c, corner) in mesh.cells_of(v) {
                s += stress[c as usize] * mesh.elements()[c as usize].gradient(corner as usize);
            }
            *e = s;
        });
        let (masses, fixed) = (model.masses(), model.fixed());
        let (mut sq, mut elastic_sq) = (0.0, 0.0);
        for v in 0..x.len() {
            let e = self.elastic[v];
            let g = (x[v] - self.target[v]) * (masses[v] * w) - self.load[v] + e;
            for i in 0..D::D {
                if !fixed[D::D * v + i] {
                    sq += g.at(i) * g.at(i);
                    if elastic {
                        elastic_sq += e.at(i) * e.at(i);
                    }
                }
            }
        }
        (sq.sqrt(), elastic_sq.sqrt())
    }
}

impl<D: Dim, E: Hyperelastic<D>> NdStepper<D, E> for NdPd<D> {
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
        let rho = self.params.chebyshev_rho;
        if rho > 0.0 {
            self.chebyshev.start(&self.x);
        }
        let mut residual = 0.0;
        let mut iterations = 0;
        let tolerance = self.params.tolerance;
        if tolerance == 0.0 {
            for _ in 0..self.params.iterations {
                self.local_step(model, w);
                residual = self.global_step();
                if rho > 0.0 {
                    self.chebyshev.apply(rho, &mut self.x, fixed);
                }
            }
            iterations = self.params.iterations;
        } else {
            // The test reads the local step of the iteration that follows it; the last one, at
            // the final positions, has no global step after it.
            let mut goal = 0.0;
            loop {
                self.local_step(model, w);
                let (g, elastic) = self.gradient_norm(model, w, iterations == 0);
                if iterations == 0 {
                    let load = self.load.iter().map(|f| f.norm2()).sum::<Real>().sqrt();
                    self.force_scale = g.max(load).max(elastic).max(1e-12);
                    goal = tolerance * self.force_scale;
                }
                residual = g;
                if g <= goal || iterations == self.params.iterations {
                    break;
                }
                self.global_step();
                iterations += 1;
                if rho > 0.0 {
                    self.chebyshev.apply(rho, &mut self.x, fixed);
                }
            }
        }
        for v in 0..state.x.len() {
            self.v_new[v] = (self.x[v] - state.x[v]) / h * self.decay;
        }
        let inv = inversion(model.mesh(), &self.x);
        let report = StepReport {
            min_det_f: inv.min_det_f,
            inverted: inv.inverted,
            iterations,
            residual,
            contacts: 0,
        };
        check_finite::<D>(
            &self.x,
            &self.v_new,
            step_number(state.t, h),
            state.t,
            &report,
        )?;
        std::mem::swap(&mut state.x, &mut self.x);
        std::mem::swap(&mut state.v, &mut self.v_new);
        state.t += h;
        Ok(report)
    }
}
