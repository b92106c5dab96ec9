//! Projective Dynamics' global matrix, shared by the Projective Dynamics stepper
//! ([`crate::projective`]) and the quasi-Newton stepper ([`crate::quasi_newton`]), which uses it
//! as its initial Hessian (Liu, Bouaziz & Kavan 2017).
//!
//! `A = M / h^2 + L`, `L_ab = sum_e w_e g_a . g_b`, over the free vertices, with `g` the
//! shape-function gradients and `w_e = 2 a_e (mu + lambda)` the weight of the co-rotational
//! energy written as two projective terms (see [`crate::projective`]). The x and y coordinates
//! decouple, so `A` is `n_free x n_free` and every solve takes both coordinates as two
//! right-hand sides. `mu` and `lambda` are read from the energy's tangent at rest
//! (`dP/dF` at `F = I` is linear elasticity's for every energy of `fem-core`), so the same
//! matrix serves every energy.
//!
//! The springs of a spring grab (`k/2 |x - goal|^2`, see [`crate::grab`]) are quadratic too:
//! each adds `k` to its vertex's diagonal.
//!
//! `A` does not change during a run: it is assembled and factorised (faer's sparse Cholesky,
//! sequential, so bit-identical for any thread count) once, when the stepper is built, and
//! again only when the model's layout changes (a grab starts or ends); the count of
//! factorisations is kept so tests can check it.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use fem_core::energy::{ElementEnergies, Energy};
use fem_core::math::{Mat2, Real, Vec2, vec_index};
use fem_core::mesh::Mesh;

use crate::error::SolverError;
use crate::model::grab::Spring;

/// The Lamé parameters `(mu, lambda)` of `energy`'s tangent at rest.
pub(crate) fn rest_lame<E: Energy>(energy: &E) -> (Real, Real) {
    let d = energy.dpk1(&Mat2::identity());
    let lambda = d[(vec_index(0, 0), vec_index(1, 1))];
    let mu = 0.5 * (d[(vec_index(0, 0), vec_index(0, 0))] - lambda);
    (mu, lambda)
}

/// `(mu, lambda)` of every element's region ([`rest_lame`] of its energy), in triangle order.
pub(crate) fn element_lame<E: Energy>(
    energies: &ElementEnergies<E>,
    n_triangles: usize,
) -> Vec<(Real, Real)> {
    let per_region: Vec<(Real, Real)> = energies.energies().iter().map(rest_lame).collect();
    (0..n_triangles)
        .map(|t| per_region[energies.tag(t) as usize])
        .collect()
}

/// `A = M / h^2 + L` over the free vertices, factorised; see the module docs.
pub(crate) struct PdSystem {
    n_free: usize,
    /// Per free vertex (compressed rows): the kinematic vertices it couples to and `L_ab`.
    kin_offsets: Vec<usize>,
    kin_entries: Vec<(u32, Real)>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<Real>,
    mem: MemBuffer,
    factorisations: usize,
}

impl std::fmt::Debug for PdSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PdSystem")
            .field("free", &self.n_free)
            .field("factor_entries", &self.l_values.len())
            .field("factorisations", &self.factorisations)
            .finish_non_exhaustive()
    }
}

impl PdSystem {
    /// Assemble and factorise `A` for `mesh` with element weights `weights`, lumped `masses`,
    /// inertia weight `w = 1 / h^2`, the grab's `springs` and the vertices `kinematic` held.
    /// Errors name `prefix`.
    pub(crate) fn new(
        mesh: &Mesh,
        masses: &[Real],
        weights: &[Real],
        w: Real,
        springs: &[Spring],
        kinematic: &[bool],
        prefix: &str,
    ) -> Result<Self, SolverError> {
        let n = mesh.n_vertices();
        let mut free = vec![u32::MAX; n];
        let mut n_free = 0usize;
        for v in 0..n {
            if !kinematic[v] {
                free[v] = n_free as u32;
                n_free += 1;
            }
        }
        if n_free == 0 {
            return Err(SolverError::invalid(
                format!("{prefix}.model"),
                "every vertex kinematic",
                "needs at least one free vertex",
            ));
        }
        // Triplets (column, row, value) of the lower triangle, and the kinematic couplings.
        let mut lower: Vec<(u32, u32, Real)> = Vec::with_capacity(6 * mesh.n_triangles() + n);
        let mut kin: Vec<(u32, u32, Real)> = Vec::new();
        for (v, &m) in masses.iter().enumerate() {
            if free[v] != u32::MAX {
                lower.push((free[v], free[v], m * w));
            }
        }
        for s in springs {
            let f = free[s.vertex as usize];
            if f != u32::MAX {
                lower.push((f, f, s.stiffness));
            }
        }
        for ((tri, el), &we) in mesh.triangles().iter().zip(mesh.elements()).zip(weights) {
            let g = el.gradients();
            for a in 0..3 {
                for b in 0..3 {
                    let (va, vb) = (tri[a] as usize, tri[b] as usize);
                    let value = we * g[a].dot(&g[b]);
                    let (fa, fb) = (free[va], free[vb]);
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
        let mut kin_offsets = vec![0usize; n_free + 1];
        let mut kin_entries: Vec<(u32, Real)> = Vec::new();
        let mut last = (u32::MAX, u32::MAX);
        for &(a, b, value) in &kin {
            if (a, b) == last {
                kin_entries.last_mut().expect("an entry exists").1 += value;
            } else {
                kin_entries.push((b, value));
                kin_offsets[a as usize + 1] = kin_entries.len();
                last = (a, b);
            }
        }
        for a in 0..n_free {
            kin_offsets[a + 1] = kin_offsets[a + 1].max(kin_offsets[a]);
        }
        let failed =
            |what: String| SolverError::invalid(format!("{prefix}.factorisation"), what, "failed");
        let pattern =
            SymbolicSparseColMatRef::new_checked(n_free, n_free, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| failed(format!("symbolic analysis: {e:?}")))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<Real>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<Real>(2, Par::Seq),
        ]);
        let mut mem = MemBuffer::try_new(req)
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
        Ok(PdSystem {
            n_free,
            kin_offsets,
            kin_entries,
            symbolic,
            l_values,
            mem,
            factorisations: 1,
        })
    }

    /// Free degrees of freedom per coordinate.
    pub(crate) fn n_free(&self) -> usize {
        self.n_free
    }

    /// Numeric factorisations done since construction (one).
    pub(crate) fn factorisations(&self) -> usize {
        self.factorisations
    }

    /// Count `earlier` factorisations of the systems this one replaces.
    pub(crate) fn add_earlier(&mut self, earlier: usize) {
        self.factorisations += earlier;
    }

    /// Subtract the couplings to the kinematic vertices at `x` from the right-hand sides
    /// `rhs` (column-major, x then y), so that solving gives the free positions.
    pub(crate) fn move_kinematic_to_rhs(&self, x: &[Vec2], rhs: &mut [Real]) {
        let n = self.n_free;
        for a in 0..n {
            for &(b, l) in &self.kin_entries[self.kin_offsets[a]..self.kin_offsets[a + 1]] {
                let p = x[b as usize];
                rhs[a] -= l * p.x;
                rhs[n + a] -= l * p.y;
            }
        }
    }

    /// Solve `A X = rhs` in place for the two columns of `rhs` (column-major, `2 n_free`).
    pub(crate) fn solve(&mut self, rhs: &mut [Real]) {
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        let m = MatMut::from_column_major_slice_mut(rhs, self.n_free, 2);
        llt.solve_in_place_with_conj(Conj::No, m, Par::Seq, MemStack::new(&mut self.mem));
    }
}
