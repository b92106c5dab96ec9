//! Projective Dynamics' global matrix in either dimension, shared by the Projective Dynamics
//! solver ([`super::NdPd`]) and the quasi-Newton solver ([`super::NdQuasiNewton`]), which uses
//! it as its initial Hessian: the 2D `PdSystem` on a simplex mesh with fixed degrees of
//! freedom.
//!
//! `A = M / h^2 + L`, `L_ab = sum_e w_e g_a . g_b`, with `g` the shape-function gradients and
//! `w_e = 2 V_e mu + D V_e lambda` the weight of the co-rotational energy written as two
//! projective terms (see [`super::projective`]; `2 a (mu + lambda)` in 2D). The coordinates
//! decouple: coordinate `i`'s block is `A` over the vertices whose component `i` is free, and
//! the couplings to the fixed components move to the right-hand side. Coordinates with the same
//! free vertices (every coordinate, when whole vertices are pinned) share one factorisation and
//! are solved as one multi-column right-hand side, as the 2D solver's two columns; a
//! coordinate with other fixed components (a plane-strain side face) gets its own. `mu` and
//! `lambda` are read from the energy's tangent at rest (`dP/dF` at `F = I` is linear
//! elasticity's for every energy of `fem-core`), so the same matrix serves every energy.
//!
//! **Packed vectors** (the global step's right-hand sides, the quasi-Newton solver's
//! gradients and directions) hold the free degrees of freedom coordinate-major: component 0
//! of the free vertices in increasing order, then component 1, ... (the 2D solvers' `[x of
//! each, then y of each]`).
//!
//! `A` does not change during a run: it is assembled and factorised (faer's sparse Cholesky,
//! sequential, so bit-identical for any thread count) once, when the solver is built.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::Real;
use fem_core::par::prelude::*;
use fem_core::simplex::SimplexMesh;
use fem_core::simplex::assembly::ForceReport;

use crate::error::SolverError;

/// The Lamé parameters `(mu, lambda)` of `energy`'s tangent at rest: `dP/dF` at `F = I` is
/// `2 mu sym(dF) + lambda tr(dF) I` for every isotropic energy, so entry `(vec(0,0), vec(1,1))`
/// is `lambda` and `(vec(0,0), vec(0,0))` is `2 mu + lambda`.
pub(crate) fn rest_lame<D: Dim, E: Hyperelastic<D>>(energy: &E) -> (Real, Real) {
    let t = Hyperelastic::<D>::piola_tangent(energy, &D::identity());
    let dd = D::D * D::D;
    // Entry (r, c) of the column-major D^2 x D^2 tangent; vec(1, 1) = 1 + D.
    let lambda = t.at(dd * (1 + D::D));
    let mu = 0.5 * (t.at(0) - lambda);
    (mu, lambda)
}

/// Per cell, the weights `(w1, w2) = (2 V mu, D V lambda)` of the co-rotational energy's two
/// projective terms for the Lamé parameters `(mu, lambda)` (see [`super::projective`]).
pub(crate) fn projective_weights<D: Dim>(
    mesh: &SimplexMesh<D>,
    (mu, lambda): (Real, Real),
) -> (Vec<Real>, Vec<Real>) {
    let d = D::D as Real;
    let w1 = mesh
        .elements()
        .iter()
        .map(|e| 2.0 * e.measure * mu)
        .collect();
    let w2 = mesh
        .elements()
        .iter()
        .map(|e| d * e.measure * lambda)
        .collect();
    (w1, w2)
}

/// The smallest `det F` over the cells at `x` and the number with `det F <= 0` (or not a
/// number); min and count are exact, so the result is the same for any split.
pub(crate) fn inversion<D: Dim>(mesh: &SimplexMesh<D>, x: &[D::Vector]) -> ForceReport {
    mesh.elements()
        .par_iter()
        .enumerate()
        .map(|(c, _)| {
            let mut corners = [D::Vector::zeros(); 4];
            for (k, &i) in mesh.cells()[c].as_ref().iter().enumerate() {
                corners[k] = x[i as usize];
            }
            let det = D::det(&mesh.elements()[c].deformation_gradient(&corners[..D::NODES]));
            ForceReport {
                min_det_f: det,
                inverted: usize::from(det <= 0.0 || det.is_nan()),
            }
        })
        .reduce(
            || ForceReport {
                min_det_f: Real::INFINITY,
                inverted: 0,
            },
            |a, b| ForceReport {
                min_det_f: a.min_det_f.min(b.min_det_f),
                inverted: a.inverted + b.inverted,
            },
        )
}

/// One coordinate block's factorisation.
struct Factor {
    n: usize,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<Real>,
}

/// `A = M / h^2 + L` per coordinate over its free vertices, factorised; see the module docs.
pub(crate) struct NdPdSystem<D: Dim> {
    /// Packed index -> `(vertex, component)`, coordinate-major.
    dofs: Vec<(u32, u8)>,
    /// Degree of freedom (`D v + i`) -> packed index, or `usize::MAX` when fixed.
    packed: Vec<usize>,
    /// Coordinate `i`'s block of a packed vector: `start[i]..start[i + 1]`.
    start: Vec<usize>,
    /// Coordinate `i`'s factorisation (an index into `factors`), `None` with no free component.
    factor_of: Vec<Option<usize>>,
    factors: Vec<Factor>,
    /// Per packed row (compressed): the fixed vertices of the same component it couples to and
    /// `L_ab`.
    kin_offsets: Vec<usize>,
    kin_entries: Vec<(u32, Real)>,
    mem: MemBuffer,
    _dim: std::marker::PhantomData<D>,
}

impl<D: Dim> std::fmt::Debug for NdPdSystem<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NdPdSystem")
            .field("free", &self.dofs.len())
            .field("factorisations", &self.factors.len())
            .finish_non_exhaustive()
    }
}

impl<D: Dim> NdPdSystem<D> {
    /// Assemble and factorise `A` for `mesh` with cell weights `weights`, lumped `masses`,
    /// inertia weight `w = 1 / h^2` and the degrees of freedom `fixed` held. Errors name
    /// `prefix`.
    pub(crate) fn new(
        mesh: &SimplexMesh<D>,
        masses: &[Real],
        weights: &[Real],
        w: Real,
        fixed: &[bool],
        prefix: &str,
    ) -> Result<Self, SolverError> {
        let n = mesh.n_vertices();
        let failed =
            |what: String| SolverError::invalid(format!("{prefix}.factorisation"), what, "failed");
        let mut dofs: Vec<(u32, u8)> = Vec::new();
        let mut packed = vec![usize::MAX; D::D * n];
        let mut start = vec![0usize];
        let mut free_sets: Vec<Vec<u32>> = Vec::new();
        let mut factor_of: Vec<Option<usize>> = Vec::new();
        let mut factors: Vec<Factor> = Vec::new();
        let mut kin_rows: Vec<Vec<(u32, Real)>> = Vec::new();
        let mut scratch_req: Vec<StackReq> = Vec::new();
        for i in 0..D::D {
            let free: Vec<u32> = (0..n as u32)
                .filter(|&v| !fixed[D::D * v as usize + i])
                .collect();
            for &v in &free {
                packed[D::D * v as usize + i] = dofs.len();
                dofs.push((v, i as u8));
            }
            start.push(dofs.len());
            let mut local = vec![u32::MAX; n];
            for (k, &v) in free.iter().enumerate() {
                local[v as usize] = k as u32;
            }
            let (factor, kin) = assemble(mesh, masses, weights, w, &local, free.len());
            kin_rows.extend(kin);
            if free.is_empty() {
                factor_of.push(None);
                free_sets.push(free);
                continue;
            }
            // The same free vertices as an earlier coordinate: the same matrix.
            if let Some(k) = free_sets.iter().position(|s| *s == free) {
                factor_of.push(factor_of[k]);
                free_sets.push(free);
                continue;
            }
            let (col_ptr, row_idx, values) = factor;
            let m = free.len();
            let pattern = SymbolicSparseColMatRef::new_checked(m, m, &col_ptr, None, &row_idx);
            let symbolic = factorize_symbolic_cholesky(
                pattern,
                Side::Lower,
                SymmetricOrdering::Amd,
                CholeskySymbolicParams::default(),
            )
            .map_err(|e| failed(format!("symbolic analysis: {e:?}")))?;
            scratch_req
                .push(symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()));
            scratch_req.push(symbolic.solve_in_place_scratch::<Real>(D::D, Par::Seq));
            let mut mem = MemBuffer::try_new(StackReq::any_of(&scratch_req))
                .map_err(|_| failed("out of memory for the workspace".into()))?;
            let mut l_values = vec![0.0; symbolic.len_val()];
            let a = SparseColMatRef::new(pattern, &values);
            symbolic
                .factorize_numeric_llt::<Real>(
                    &mut l_values,
                    a,
                    Side::Lower,
                    LltRegularization {
                        dynamic_regularization_delta: 0.0,
                        dynamic_regularization_epsilon: 0.0,
                    },
                    Par::Seq,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .map_err(|_| {
                    SolverError::invalid(
                        format!("{prefix}.matrix"),
                        "M / h^2 + L",
                        "is not positive definite (a zero mass or weight?)",
                    )
                })?;
            factor_of.push(Some(factors.len()));
            factors.push(Factor {
                n: m,
                symbolic,
                l_values,
            });
            free_sets.push(free);
        }
        if dofs.is_empty() {
            return Err(SolverError::invalid(
                format!("{prefix}.unknowns"),
                0,
                "every degree of freedom is fixed: nothing to solve",
            ));
        }
        let mem = MemBuffer::try_new(StackReq::any_of(&scratch_req))
            .map_err(|_| failed("out of memory for the workspace".into()))?;
        let mut kin_offsets = Vec::with_capacity(dofs.len() + 1);
        let mut kin_entries = Vec::new();
        kin_offsets.push(0);
        for row in kin_rows {
            kin_entries.extend(row);
            kin_offsets.push(kin_entries.len());
        }
        Ok(NdPdSystem {
            dofs,
            packed,
            start,
            factor_of,
            factors,
            kin_offsets,
            kin_entries,
            mem,
            _dim: std::marker::PhantomData,
        })
    }

    /// Free degrees of freedom: the length of a packed vector.
    pub(crate) fn len(&self) -> usize {
        self.dofs.len()
    }

    /// The free degrees of freedom in packed order: `(vertex, component)`.
    pub(crate) fn dofs(&self) -> &[(u32, u8)] {
        &self.dofs
    }

    /// Degree of freedom `D v + i` -> its packed index, `usize::MAX` when fixed.
    pub(crate) fn packed(&self) -> &[usize] {
        &self.packed
    }

    /// Numeric factorisations done (one per distinct set of free vertices over the
    /// coordinates: one when whole vertices are pinned).
    pub(crate) fn factorisations(&self) -> usize {
        self.factors.len()
    }

    /// Subtract the couplings to the fixed components at `x` from the right-hand sides `rhs`
    /// (packed), so that solving gives the free components.
    pub(crate) fn move_fixed_to_rhs(&self, x: &[D::Vector], rhs: &mut [Real]) {
        for (k, r) in rhs.iter_mut().enumerate() {
            let i = self.dofs[k].1 as usize;
            for &(b, l) in &self.kin_entries[self.kin_offsets[k]..self.kin_offsets[k + 1]] {
                *r -= l * x[b as usize].at(i);
            }
        }
    }

    /// Solve `A X = rhs` in place (packed): each run of consecutive coordinates that share a
    /// factorisation as one multi-column right-hand side.
    pub(crate) fn solve(&mut self, rhs: &mut [Real]) {
        let mut i = 0;
        while i < D::D {
            let Some(f) = self.factor_of[i] else {
                i += 1;
                continue;
            };
            let mut j = i + 1;
            while j < D::D && self.factor_of[j] == Some(f) {
                j += 1;
            }
            let factor = &self.factors[f];
            let llt = LltRef::<'_, usize, Real>::new(&factor.symbolic, &factor.l_values);
            let block = &mut rhs[self.start[i]..self.start[j]];
            let m = MatMut::from_column_major_slice_mut(block, factor.n, j - i);
            llt.solve_in_place_with_conj(Conj::No, m, Par::Seq, MemStack::new(&mut self.mem));
            i = j;
        }
    }
}

/// A compressed lower triangle `(col_ptr, row_idx, values)` and, per free row, its couplings
/// to fixed vertices.
type Assembled = ((Vec<usize>, Vec<usize>, Vec<Real>), Vec<Vec<(u32, Real)>>);

/// One coordinate's `A` over the vertices with a local index in `local` (`u32::MAX`: fixed),
/// as the 2D `PdSystem` assembles it.
fn assemble<D: Dim>(
    mesh: &SimplexMesh<D>,
    masses: &[Real],
    weights: &[Real],
    w: Real,
    local: &[u32],
    n_free: usize,
) -> Assembled {
    // Triplets (column, row, value) of the lower triangle, and the fixed couplings.
    let mut lower: Vec<(u32, u32, Real)> = Vec::new();
    let mut kin: Vec<(u32, u32, Real)> = Vec::new();
    for (v, &m) in masses.iter().enumerate() {
        if local[v] != u32::MAX {
            lower.push((local[v], local[v], m * w));
        }
    }
    for ((cell, el), &we) in mesh.cells().iter().zip(mesh.elements()).zip(weights) {
        let cell = cell.as_ref();
        for a in 0..D::NODES {
            for b in 0..D::NODES {
                let (va, vb) = (cell[a] as usize, cell[b] as usize);
                let value = we * el.gradient(a).inner(&el.gradient(b));
                let (fa, fb) = (local[va], local[vb]);
                if fa == u32::MAX {
                    continue;
                }
                if fb == u32::MAX {
                    kin.push((fa, vb as u32, value));
                } else if fa >= fb {
                    lower.push((fb, fa, value));
                }
            }
        }
    }
    lower.sort_by_key(|&(c, r, _)| (c, r));
    let mut col_ptr = vec![0usize; n_free + 1];
    let mut row_idx: Vec<usize> = Vec::with_capacity(lower.len());
    let mut values: Vec<Real> = Vec::with_capacity(lower.len());
    let mut last = (u32::MAX, u32::MAX);
    for &(c, r, value) in &lower {
        if (c, r) == last {
            *values.last_mut().expect("an entry exists") += value;
        } else {
            row_idx.push(r as usize);
            values.push(value);
            col_ptr[c as usize + 1] = row_idx.len();
            last = (c, r);
        }
    }
    for c in 0..n_free {
        col_ptr[c + 1] = col_ptr[c + 1].max(col_ptr[c]);
    }
    kin.sort_by_key(|&(a, b, _)| (a, b));
    let mut rows: Vec<Vec<(u32, Real)>> = vec![Vec::new(); n_free];
    let mut last = (u32::MAX, u32::MAX);
    for &(a, b, value) in &kin {
        let row = &mut rows[a as usize];
        if (a, b) == last {
            row.last_mut().expect("an entry exists").1 += value;
        } else {
            row.push((b, value));
            last = (a, b);
        }
    }
    ((col_ptr, row_idx, values), rows)
}
