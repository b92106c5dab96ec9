//! Newton's method on the potential of a [`NdModel`]'s body, for implicit Euler and statics in
//! either dimension.
//!
//! `Phi(x) = w/2 |x - x_hat|_M^2 + Psi(x) - s f_ext . x` over the free degrees of freedom,
//! with `w = 1/h^2` for implicit Euler and `w = 0` (and the load factor `s`) for statics, as in
//! the 2D Newton solver ([`crate::newton`]). Each iteration assembles the gradient and `w M + K`
//! with per-element **PSD-projected** tangents, factorises it with faer's sparse Cholesky (the
//! symbolic analysis with its AMD ordering done once) and takes a backtracking (Armijo) line
//! search step that rejects trial states of infinite or larger potential.
//!
//! **Stopping test.** The residual `|grad Phi|` over the free degrees of freedom falls below
//! `tolerance` times the force scale (the largest of the first residual, the external load's
//! norm, the free elastic forces' norm at the start, and `1e-12` N); or, with
//! `step_tolerance > 0`, a full Newton step moved no degree of freedom by more than it (the
//! implicit solver's `velocity_tolerance * dt`); or the residual's part above the 2D solver's
//! per-unknown round-off floors, `100 eps X sum_k |H_jk|` (`X` the largest coordinate, `H` the
//! assembled matrix), meets the same tolerance. The line search accepts a step that changes
//! `Phi` by less than its round-off (`1e-13 |Phi|`), which near the minimum is all a
//! decrease can show. Otherwise `max_iterations` ends the solve with
//! [`SolverError::NotConverged`], as does a line search that finds no acceptable step in
//! `max_halvings` halvings.
//!
//! The factorisation runs sequentially and assembly is deterministic (fem-core), so results are
//! bit-identical for any number of rayon threads. A solve allocates nothing after the first.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use fem_core::assembly::Tangent;
use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::Real;
use fem_core::simplex::assembly::{
    ForceReport, Scratch, SimplexStiffness, elastic_energy, populate_forces,
};

use super::model::NdModel;
use crate::error::SolverError;
use crate::optim::newton::{FLOOR_ULPS, NewtonParams};

/// The inertial part of the potential: weight `w` and target `x_hat` (statics: `w = 0`).
pub(crate) struct Inertia<'a, D: Dim> {
    pub w: Real,
    pub x_hat: &'a [D::Vector],
}

/// What one solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct NdNewtonReport {
    pub iterations: usize,
    pub residual: Real,
    pub forces: Option<ForceReport>,
}

/// The Newton solver of one model: pattern, factorisation and buffers.
pub(crate) struct NdNewton<D: Dim> {
    stiffness: SimplexStiffness<D>,
    scratch: Scratch<D>,
    /// Degree of freedom -> free index, or `usize::MAX` when fixed.
    free: Vec<usize>,
    n_free: usize,
    /// The free part of the matrix, upper triangle, compressed columns.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<Real>,
    /// CSR entry -> slot in `values` (or `u32::MAX` when outside the free upper triangle).
    map: Vec<u32>,
    /// Slot of each free diagonal entry.
    diag: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<Real>,
    mem: MemBuffer,
    forces: Vec<D::Vector>,
    gradient: Vec<Real>,
    direction: Vec<Real>,
    /// `w m` per degree of freedom, of the last assembly.
    inertia: Vec<Real>,
    packed: Vec<Real>,
    trial: Vec<D::Vector>,
    prefix: &'static str,
}

impl<D: Dim> NdNewton<D> {
    /// The pattern and the symbolic analysis for `model`.
    pub fn new<E: Hyperelastic<D>>(
        model: &NdModel<D, E>,
        prefix: &'static str,
    ) -> Result<Self, SolverError> {
        let mesh = model.mesh();
        let stiffness = SimplexStiffness::new(mesh);
        let m = &stiffness.matrix;
        let mut free = vec![usize::MAX; m.n];
        let mut n_free = 0;
        for (dof, &fixed) in model.fixed().iter().enumerate() {
            if !fixed {
                free[dof] = n_free;
                n_free += 1;
            }
        }
        if n_free == 0 {
            return Err(SolverError::invalid(
                format!("{prefix}.unknowns"),
                0,
                "every degree of freedom is fixed: nothing to solve",
            ));
        }
        // Column j of the upper triangle holds rows i <= j: by symmetry, row j's entries with
        // column <= j, in increasing order.
        let mut col_ptr = Vec::with_capacity(n_free + 1);
        let mut row_idx = Vec::new();
        let mut map = vec![u32::MAX; m.col_indices.len()];
        let mut diag = Vec::with_capacity(n_free);
        col_ptr.push(0);
        for r in 0..m.n {
            let fr = free[r];
            if fr == usize::MAX {
                continue;
            }
            let range = m.row_offsets[r]..m.row_offsets[r + 1];
            for (slot, &c) in map[range.clone()].iter_mut().zip(&m.col_indices[range]) {
                let fc = free[c];
                if c > r || fc == usize::MAX {
                    continue;
                }
                if c == r {
                    diag.push(row_idx.len());
                }
                *slot = row_idx.len() as u32;
                row_idx.push(fc);
            }
            col_ptr.push(row_idx.len());
        }
        let pattern =
            SymbolicSparseColMatRef::new_checked(n_free, n_free, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Upper,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| {
            SolverError::invalid(
                format!("{prefix}.factorisation"),
                format!("{e:?}"),
                "symbolic analysis failed",
            )
        })?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<Real>(1, Par::Seq),
        ]);
        let mem = MemBuffer::try_new(req).map_err(|_| {
            SolverError::invalid(
                format!("{prefix}.factorisation"),
                n_free,
                "out of memory for the workspace",
            )
        })?;
        let n = mesh.n_vertices();
        Ok(NdNewton {
            l_values: vec![0.0; symbolic.len_val()],
            values: vec![0.0; row_idx.len()],
            stiffness,
            scratch: Scratch::new(),
            free,
            n_free,
            col_ptr,
            row_idx,
            map,
            diag,
            symbolic,
            mem,
            forces: vec![D::Vector::zeros(); n],
            gradient: vec![0.0; D::D * n],
            direction: vec![0.0; D::D * n],
            packed: vec![0.0; n_free],
            inertia: vec![0.0; D::D * n],
            trial: vec![D::Vector::zeros(); n],
            prefix,
        })
    }

    /// `Phi(x)`, `+inf` where the energy is undefined.
    fn potential<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        inertia: &Inertia<'_, D>,
        load: Real,
        x: &[D::Vector],
    ) -> Real {
        let elastic = elastic_energy(model.mesh(), model.energy(), x, &mut self.scratch);
        let mut kinetic = 0.0;
        let mut work = 0.0;
        for (v, p) in x.iter().enumerate() {
            if inertia.w > 0.0 {
                kinetic += model.masses()[v] * (*p - inertia.x_hat[v]).norm2();
            }
            work += model.external_force(v).inner(p);
        }
        let phi = 0.5 * inertia.w * kinetic + elastic - load * work;
        if phi.is_nan() { Real::INFINITY } else { phi }
    }

    /// The gradient into `self.gradient` (fixed entries zero); returns its norm, the load's
    /// norm and the elastic forces' norm over the free entries, and the force pass's report.
    fn gradient<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        inertia: &Inertia<'_, D>,
        load: Real,
        x: &[D::Vector],
    ) -> (Real, Real, Real, ForceReport) {
        let report = populate_forces(
            model.mesh(),
            model.energy(),
            x,
            &mut self.scratch,
            &mut self.forces,
        );
        let (mut g2, mut l2, mut e2) = (0.0, 0.0, 0.0);
        for (v, p) in x.iter().enumerate() {
            let ext = model.external_force(v) * load;
            let mut g = -self.forces[v] - ext;
            if inertia.w > 0.0 {
                g += (*p - inertia.x_hat[v]) * (inertia.w * model.masses()[v]);
            }
            for i in 0..D::D {
                let dof = D::D * v + i;
                if self.free[dof] == usize::MAX {
                    self.gradient[dof] = 0.0;
                } else {
                    self.gradient[dof] = g.at(i);
                    g2 += g.at(i) * g.at(i);
                    l2 += ext.at(i) * ext.at(i);
                    e2 += self.forces[v].at(i) * self.forces[v].at(i);
                }
            }
        }
        (g2.sqrt(), l2.sqrt(), e2.sqrt(), report)
    }

    /// The 2-norm over the free entries of `max(|g_j| - floor sum_k |H_jk|, 0)`, with the
    /// matrix just assembled (`w M` on the diagonal: `self.inertia`).
    fn above_floors(&self, floor: Real) -> Real {
        let m = &self.stiffness.matrix;
        let mut sum = 0.0;
        for (dof, &f) in self.free.iter().enumerate() {
            if f == usize::MAX {
                continue;
            }
            let row: Real = (m.row_offsets[dof]..m.row_offsets[dof + 1])
                .map(|k| m.values[k].abs())
                .sum::<Real>()
                + self.inertia[dof];
            let excess = (self.gradient[dof].abs() - floor * row).max(0.0);
            sum += excess * excess;
        }
        sum.sqrt()
    }

    /// Assemble `w M + K` (projected) at `x` into the free upper triangle.
    fn assemble<E: Hyperelastic<D>>(&mut self, model: &NdModel<D, E>, w: Real, x: &[D::Vector]) {
        self.stiffness.populate(
            model.mesh(),
            model.energy(),
            x,
            Tangent::Projected,
            &mut self.scratch,
        );
        self.values.iter_mut().for_each(|v| *v = 0.0);
        for (k, &slot) in self.map.iter().enumerate() {
            if slot != u32::MAX {
                self.values[slot as usize] += self.stiffness.matrix.values[k];
            }
        }
        let mut d = 0;
        for dof in 0..self.free.len() {
            self.inertia[dof] = w * model.masses()[dof / D::D];
            if self.free[dof] != usize::MAX {
                if w > 0.0 {
                    self.values[self.diag[d]] += self.inertia[dof];
                }
                d += 1;
            }
        }
    }

    /// Factorise the assembled matrix, shifting the diagonal when it is not numerically
    /// positive definite.
    fn factorise(&mut self) -> Result<(), SolverError> {
        let scale = self
            .diag
            .iter()
            .map(|&s| self.values[s].abs())
            .fold(0.0, Real::max)
            .max(Real::MIN_POSITIVE);
        let mut shift = 0.0;
        for attempt in 0..8 {
            if attempt > 0 {
                let add = if shift == 0.0 {
                    1e-10 * scale
                } else {
                    9.0 * shift
                };
                for &s in &self.diag {
                    self.values[s] += add;
                }
                shift += add;
            }
            let pattern = SymbolicSparseColMatRef::new_checked(
                self.n_free,
                self.n_free,
                &self.col_ptr,
                None,
                &self.row_idx,
            );
            let a = SparseColMatRef::new(pattern, &self.values);
            let ok = self
                .symbolic
                .factorize_numeric_llt::<Real>(
                    &mut self.l_values,
                    a,
                    Side::Upper,
                    LltRegularization {
                        dynamic_regularization_delta: 0.0,
                        dynamic_regularization_epsilon: 0.0,
                    },
                    Par::Seq,
                    MemStack::new(&mut self.mem),
                    Default::default(),
                )
                .is_ok();
            if ok {
                return Ok(());
            }
        }
        Err(SolverError::invalid(
            format!("{}.hessian", self.prefix),
            format!("shift {shift:e}"),
            "is not positive definite even with a diagonal shift (is the body anchored?)",
        ))
    }

    /// `direction = -H^-1 gradient` over the free entries (fixed entries zero).
    fn solve(&mut self) {
        for (dof, &f) in self.free.iter().enumerate() {
            if f != usize::MAX {
                self.packed[f] = -self.gradient[dof];
            }
        }
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        let m = MatMut::from_column_major_slice_mut(&mut self.packed, self.n_free, 1);
        llt.solve_in_place_with_conj(Conj::No, m, Par::Seq, MemStack::new(&mut self.mem));
        for (dof, &f) in self.free.iter().enumerate() {
            self.direction[dof] = if f == usize::MAX { 0.0 } else { self.packed[f] };
        }
    }

    /// Minimise `Phi` from `x` (fixed entries already in place), in place.
    #[allow(clippy::too_many_arguments)]
    pub fn minimise<E: Hyperelastic<D>>(
        &mut self,
        model: &NdModel<D, E>,
        inertia: &Inertia<'_, D>,
        load: Real,
        x: &mut [D::Vector],
        params: &NewtonParams,
        step_tolerance: Real,
        step: u64,
    ) -> Result<NdNewtonReport, SolverError> {
        let mut phi = self.potential(model, inertia, load, x);
        if !phi.is_finite() {
            return Err(SolverError::invalid(
                format!("{}.start", self.prefix),
                phi,
                "the potential is not finite at the starting positions (an inverted element?)",
            ));
        }
        let mut scale = 0.0;
        let mut report = NdNewtonReport::default();
        for it in 0..=params.max_iterations {
            let (res, load_norm, elastic, forces) = self.gradient(model, inertia, load, x);
            report.residual = res;
            report.forces = Some(forces);
            if !res.is_finite() {
                return Err(SolverError::invalid(
                    format!("{}.forces", self.prefix),
                    res,
                    "the gradient is not finite (a force beyond double precision, or an inverted element)",
                ));
            }
            if it == 0 {
                scale = res.max(load_norm).max(elastic).max(1e-12);
            }
            if res <= params.tolerance * scale {
                return Ok(report);
            }
            if it == params.max_iterations {
                break;
            }
            self.assemble(model, inertia.w, x);
            // The residual's part above the per-unknown round-off floors (the 2D solver's
            // `100 eps X sum_k |H_jk|`): below the tolerance, the solve is as converged as
            // double precision allows.
            let reach = x.iter().fold(0.0, |m: Real, p| {
                (0..D::D).fold(m, |m, i| m.max(p.at(i).abs()))
            });
            let above = self.above_floors(FLOOR_ULPS * Real::EPSILON * reach);
            if above <= params.tolerance * scale {
                return Ok(report);
            }
            self.factorise()?;
            self.solve();
            report.iterations += 1;
            let slope: Real = self
                .gradient
                .iter()
                .zip(&self.direction)
                .map(|(g, d)| g * d)
                .sum();
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..=params.max_halvings {
                for (v, t) in self.trial.iter_mut().enumerate() {
                    *t = x[v];
                    for i in 0..D::D {
                        let dof = D::D * v + i;
                        t.set_at(i, x[v].at(i) + alpha * self.direction[dof]);
                    }
                }
                let trial = std::mem::take(&mut self.trial);
                let phi_t = self.potential(model, inertia, load, &trial);
                self.trial = trial;
                // Armijo, or a change within the potential's round-off (near the minimum the
                // decrease is below what Phi's sum can resolve).
                let round_off = 1e-13 * phi.abs().max(1e-300);
                if phi_t.is_finite()
                    && (phi_t <= phi + 1e-4 * alpha * slope || (phi_t - phi).abs() <= round_off)
                {
                    accepted = true;
                    phi = phi_t;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                return Err(SolverError::NotConverged {
                    step,
                    iterations: report.iterations,
                    residual: res,
                });
            }
            x.copy_from_slice(&self.trial);
            if step_tolerance > 0.0 && alpha == 1.0 {
                let moved = self.direction.iter().fold(0.0, |m: Real, d| m.max(d.abs()));
                if moved <= step_tolerance {
                    let (res, _, _, forces) = self.gradient(model, inertia, load, x);
                    report.residual = res;
                    report.forces = Some(forces);
                    return Ok(report);
                }
            }
        }
        Err(SolverError::NotConverged {
            step,
            iterations: report.iterations,
            residual: report.residual,
        })
    }
}
