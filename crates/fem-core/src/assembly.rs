//! Assembly of the elastic energy `E(x) = sum_e a_e psi(F_e)`, the nodal forces `f = -dE/dx`
//! and the stiffness matrix `K = d^2E/dx^2 = -df/dx` over a [`Mesh`].
//!
//! Every quantity has a plain serial reference path (`*_serial`: one loop over triangles in
//! index order, scattering into the output) and a parallel path on the current rayon pool.
//! Architecture invariant: **the parallel path is bit-identical to the serial one for any
//! number of threads**: every output entry sums the same terms in increasing triangle order
//! from the same zero. Forces use the mesh's [`ScatterPlan`](crate::partition::ScatterPlan)
//! (chunks scatter directly into the vertices they own, shared vertices go through slots);
//! energy and stiffness evaluate elements in parallel into per-element buffers and sum them in
//! triangle order. No atomics, no thread-dependent reduction tree.
//!
//! Hot paths do not allocate once their [`Scratch`] (and [`Stiffness`] pattern) has been sized
//! by the first call.

use crate::par::prelude::*;

use crate::element::Tri3;
use crate::energy::{Energy, EnergyOf};
use crate::math::{Mat2, Mat6, Real, Vec2};
use crate::mesh::Mesh;
use crate::nodal_pressure::{self, NodalPattern, PressureFields};
use crate::partition::{ELEMENT_CHUNK, Target, for_each_chunk};

/// What one assembly pass saw, for step reports and inversion checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AssemblyReport {
    /// The smallest `det F` over all elements.
    pub min_det_f: Real,
    /// How many elements have `det F <= 0`.
    pub inverted: usize,
}

impl AssemblyReport {
    pub(crate) const EMPTY: AssemblyReport = AssemblyReport {
        min_det_f: Real::INFINITY,
        inverted: 0,
    };

    #[inline]
    pub(crate) fn add(&mut self, j: Real) {
        self.min_det_f = self.min_det_f.min(j);
        self.inverted += usize::from(j <= 0.0);
    }

    pub(crate) fn merge(a: Self, b: Self) -> Self {
        AssemblyReport {
            min_det_f: a.min_det_f.min(b.min_det_f),
            inverted: a.inverted + b.inverted,
        }
    }
}

/// Per-element buffers reused by the parallel paths. Create one per thread of control and keep
/// it across steps; it grows to the mesh size on first use.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    slots: Vec<Vec2>,
    pub(crate) element_energies: Vec<Real>,
    pub(crate) element_stiffness: Vec<Mat6>,
    /// The averaged nodal pressure triangle's fields ([`crate::nodal_pressure`]).
    pub(crate) pressure: PressureFields,
}

impl Scratch {
    /// Empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// The averaged nodal pressure fields of the last pass that evaluated them (forces,
    /// energy or stiffness of an [`EnergyOf`] with [`EnergyOf::nodal_pressure`]).
    pub fn pressure(&self) -> &PressureFields {
        &self.pressure
    }
}

/// Which `dP/dF` the stiffness uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tangent {
    /// The exact `dP/dF`: `K` is the true Hessian, possibly indefinite.
    #[default]
    Exact,
    /// The per-element PSD projection: `K` is positive semi-definite.
    Projected,
}

#[inline(always)]
fn element_forces<E: Energy>(
    energy: &E,
    el: &Tri3,
    tri: &[u32; 3],
    x: &[Vec2],
) -> ([Vec2; 3], Real) {
    let f = el.deformation_gradient(tri.map(|i| x[i as usize]));
    let p: Mat2 = energy.pk1(&f);
    (el.forces(&p), f.determinant())
}

fn check_len(mesh: &Mesh, x: &[Vec2], what: &str, len: usize) {
    assert_eq!(
        x.len(),
        mesh.n_vertices(),
        "positions: expected one per mesh vertex"
    );
    assert_eq!(
        len,
        mesh.n_vertices(),
        "{what}: expected one per mesh vertex"
    );
}

/// Elastic nodal forces `f = -dE/dx` (N per unit thickness), serial reference path.
/// Overwrites `f`. Panics if `x` or `f` does not have one entry per vertex.
pub fn populate_forces_serial<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    f: &mut [Vec2],
) -> AssemblyReport {
    check_len(mesh, x, "forces", f.len());
    if let Some(np) = energy.nodal_pressure() {
        return nodal_pressure::populate_forces(np, mesh, energy, x, f, &mut Scratch::new());
    }
    f.fill(Vec2::zeros());
    let mut report = AssemblyReport::EMPTY;
    for (t, (tri, el)) in mesh.triangles().iter().zip(mesh.elements()).enumerate() {
        let (fe, j) = element_forces(energy.energy_of(t), el, tri, x);
        report.add(j);
        for (k, &v) in tri.iter().enumerate() {
            f[v as usize] += fe[k];
        }
    }
    report
}

/// Elastic nodal forces on the current rayon pool; bit-identical to [`populate_forces_serial`].
pub fn populate_forces<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    f: &mut [Vec2],
    scratch: &mut Scratch,
) -> AssemblyReport {
    if let Some(np) = energy.nodal_pressure() {
        check_len(mesh, x, "forces", f.len());
        return nodal_pressure::populate_forces(np, mesh, energy, x, f, scratch);
    }
    if crate::par::current_num_threads() == 1 {
        return populate_forces_serial(mesh, energy, x, f);
    }
    check_len(mesh, x, "forces", f.len());
    let plan = mesh.scatter_plan();
    scratch.slots.resize(plan.n_slots(), Vec2::zeros());
    let report = std::sync::Mutex::new(AssemblyReport::EMPTY);
    for_each_chunk(plan, f, &mut scratch.slots, &|k, owned, slots| {
        owned.fill(Vec2::zeros());
        let base = plan.slot_range(k).start;
        let range = k * ELEMENT_CHUNK..((k + 1) * ELEMENT_CHUNK).min(mesh.n_triangles());
        let mut r = AssemblyReport::EMPTY;
        for e in range {
            let (fe, j) = element_forces(
                energy.energy_of(e),
                &mesh.elements()[e],
                &mesh.triangles()[e],
                x,
            );
            r.add(j);
            for (c, target) in plan.targets(e).into_iter().enumerate() {
                match target {
                    Target::Owned(i) => owned[i] += fe[c],
                    Target::Shared(slot) => slots[slot - base] = fe[c],
                }
            }
        }
        // min and + on counts are exact, so merge order does not matter.
        let mut total = report.lock().unwrap_or_else(|p| p.into_inner());
        *total = AssemblyReport::merge(*total, r);
    });
    plan.sum_shared(f, &scratch.slots, Vec2::zeros());
    report.into_inner().unwrap_or_else(|p| p.into_inner())
}

/// Total elastic energy `sum_e a_e psi(F_e)` (J per unit thickness), summed in triangle order.
pub fn elastic_energy_serial<M: EnergyOf>(mesh: &Mesh, energy: &M, x: &[Vec2]) -> Real {
    check_len(mesh, x, "positions", x.len());
    if let Some(np) = energy.nodal_pressure() {
        return nodal_pressure::elastic_energy(np, mesh, energy, x, &mut Scratch::new());
    }
    let mut total = 0.0;
    for (t, el) in mesh.elements().iter().enumerate() {
        total += el.area
            * energy
                .energy_of(t)
                .psi(&el.deformation_gradient(mesh.gather(t, x)));
    }
    total
}

/// Total elastic energy on the current rayon pool; bit-identical to [`elastic_energy_serial`]
/// (element energies are computed in parallel and summed in triangle order).
pub fn elastic_energy<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    scratch: &mut Scratch,
) -> Real {
    check_len(mesh, x, "positions", x.len());
    if let Some(np) = energy.nodal_pressure() {
        return nodal_pressure::elastic_energy(np, mesh, energy, x, scratch);
    }
    let buf = &mut scratch.element_energies;
    buf.resize(mesh.n_triangles(), 0.0);
    buf.par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let t = c * ELEMENT_CHUNK + k;
                let el = &mesh.elements()[t];
                *o = el.area
                    * energy
                        .energy_of(t)
                        .psi(&el.deformation_gradient(mesh.gather(t, x)));
            }
        });
    buf.iter().fold(0.0, |acc, &e| acc + e)
}

/// A square sparse matrix in compressed sparse row form with sorted column indices.
///
/// The stiffness matrix is symmetric, so this is also its compressed-column form (the layout
/// sparse Cholesky factorisations take).
#[derive(Clone, Debug, PartialEq)]
pub struct CsrMatrix {
    /// Number of rows (= columns).
    pub n: usize,
    /// `row_offsets[r]..row_offsets[r + 1]` indexes row `r`'s entries.
    pub row_offsets: Vec<usize>,
    /// Column of each stored entry, increasing within a row.
    pub col_indices: Vec<usize>,
    /// Value of each stored entry.
    pub values: Vec<Real>,
}

impl CsrMatrix {
    /// The entries as `(row, col, value)` triplets, row by row.
    pub fn triplets(&self) -> impl Iterator<Item = (usize, usize, Real)> + '_ {
        (0..self.n).flat_map(move |r| {
            (self.row_offsets[r]..self.row_offsets[r + 1])
                .map(move |k| (r, self.col_indices[k], self.values[k]))
        })
    }

    /// The stored value at `(row, col)`, or zero when it is outside the pattern.
    pub fn get(&self, row: usize, col: usize) -> Real {
        let range = self.row_offsets[row]..self.row_offsets[row + 1];
        match self.col_indices[range.clone()].binary_search(&col) {
            Ok(k) => self.values[range.start + k],
            Err(_) => 0.0,
        }
    }

    /// `y = A x`.
    pub fn mul_vec(&self, x: &[Real], y: &mut [Real]) {
        for (r, yr) in y.iter_mut().enumerate().take(self.n) {
            let range = self.row_offsets[r]..self.row_offsets[r + 1];
            *yr = self.col_indices[range.clone()]
                .iter()
                .zip(&self.values[range])
                .map(|(&c, &v)| v * x[c])
                .sum();
        }
    }
}

/// The stiffness matrix of a mesh (degrees of freedom `[x0, y0, x1, y1, ...]`) with its
/// sparsity pattern built once, so repeated assembly only rewrites values and a factorisation
/// can reuse its symbolic analysis.
#[derive(Clone, Debug)]
pub struct Stiffness {
    /// The matrix.
    pub matrix: CsrMatrix,
    /// For each triangle and each of its 3x3 vertex pairs `(a, b)` (index `3a + b`), the offset
    /// of the 2x2 block's first column within rows `2 v_a` and `2 v_a + 1` (both rows share
    /// one column pattern).
    pub(crate) block_offsets: Vec<[u32; 9]>,
    /// The nodal terms' patches of the averaged nodal pressure triangle, when built for one.
    pub(crate) nodal: Option<NodalPattern>,
}

impl Stiffness {
    /// Build the pattern (every vertex pair that shares a triangle) with zero values.
    pub fn new(mesh: &Mesh) -> Self {
        let nv = mesh.n_vertices();
        let adj = mesh.adjacency();
        let mut neighbours: Vec<Vec<u32>> = Vec::with_capacity(nv);
        for v in 0..nv {
            let mut list: Vec<u32> = adj
                .of(v)
                .iter()
                .flat_map(|&(e, _)| mesh.triangles()[e as usize])
                .collect();
            list.sort_unstable();
            list.dedup();
            neighbours.push(list);
        }
        Self::from_neighbours(mesh, neighbours)
    }

    /// The pattern for the energy `energy` on `mesh`: [`Stiffness::new`], or
    /// [`Stiffness::with_nodal_pressure`] when the energy has the averaged nodal pressure
    /// triangle.
    pub fn for_energy<M: EnergyOf>(mesh: &Mesh, energy: &M) -> Self {
        match energy.nodal_pressure() {
            Some(np) => Self::with_nodal_pressure(mesh, np),
            None => Self::new(mesh),
        }
    }

    /// The wider pattern of the averaged nodal pressure triangle ([`crate::nodal_pressure`]):
    /// every vertex pair that shares a node's patch (the triangles around a vertex of one
    /// region), which includes every pair that shares a triangle.
    pub fn with_nodal_pressure(mesh: &Mesh, np: &nodal_pressure::NodalPressure) -> Self {
        let neighbours = np.stencil(mesh);
        let nodal = NodalPattern::new(np, mesh, &neighbours);
        let mut k = Self::from_neighbours(mesh, neighbours);
        k.nodal = Some(nodal);
        k
    }

    fn from_neighbours(mesh: &Mesh, neighbours: Vec<Vec<u32>>) -> Self {
        let n = 2 * mesh.n_vertices();
        let mut row_offsets = Vec::with_capacity(n + 1);
        row_offsets.push(0);
        let mut col_indices = Vec::new();
        for list in &neighbours {
            for _ in 0..2 {
                col_indices.extend(
                    list.iter()
                        .flat_map(|&w| [2 * w as usize, 2 * w as usize + 1]),
                );
                row_offsets.push(col_indices.len());
            }
        }
        let block_offsets = mesh
            .triangles()
            .iter()
            .map(|tri| {
                let mut offs = [0u32; 9];
                for a in 0..3 {
                    let list = &neighbours[tri[a] as usize];
                    for b in 0..3 {
                        let pos = list
                            .binary_search(&tri[b])
                            .expect("pattern holds every pair");
                        offs[3 * a + b] = 2 * pos as u32;
                    }
                }
                offs
            })
            .collect();
        let nnz = col_indices.len();
        Stiffness {
            matrix: CsrMatrix {
                n,
                row_offsets,
                col_indices,
                values: vec![0.0; nnz],
            },
            block_offsets,
            nodal: None,
        }
    }

    #[inline]
    pub(crate) fn add_block(&mut self, tri: &[u32; 3], offs: &[u32; 9], ke: &Mat6) {
        let m = &mut self.matrix;
        for a in 0..3 {
            for i in 0..2 {
                let row = 2 * tri[a] as usize + i;
                let start = m.row_offsets[row];
                for b in 0..3 {
                    let o = start + offs[3 * a + b] as usize;
                    m.values[o] += ke[(2 * a + i, 2 * b)];
                    m.values[o + 1] += ke[(2 * a + i, 2 * b + 1)];
                }
            }
        }
    }
}

#[inline]
fn element_stiffness<E: Energy>(
    energy: &E,
    el: &Tri3,
    xs: [Vec2; 3],
    tangent: Tangent,
) -> (Mat6, Real) {
    let f = el.deformation_gradient(xs);
    let dpdf = match tangent {
        Tangent::Exact => energy.dpk1(&f),
        Tangent::Projected => energy.dpk1_projected(&f),
    };
    (el.stiffness(&dpdf), f.determinant())
}

/// Stiffness `K = d^2E/dx^2` into `k` (which must have been built for `mesh`), serial path.
pub fn populate_stiffness_serial<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    tangent: Tangent,
    k: &mut Stiffness,
) -> AssemblyReport {
    check_len(mesh, x, "stiffness", k.matrix.n / 2);
    if let Some(np) = energy.nodal_pressure() {
        return nodal_pressure::populate_stiffness(
            np,
            mesh,
            energy,
            x,
            tangent,
            k,
            &mut Scratch::new(),
        );
    }
    k.matrix.values.fill(0.0);
    let mut report = AssemblyReport::EMPTY;
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let (ke, j) = element_stiffness(
            energy.energy_of(t),
            &mesh.elements()[t],
            mesh.gather(t, x),
            tangent,
        );
        report.add(j);
        let offs = k.block_offsets[t];
        k.add_block(tri, &offs, &ke);
    }
    report
}

/// Stiffness on the current rayon pool: element blocks in parallel, then added into the matrix
/// in triangle order, so the result is bit-identical to [`populate_stiffness_serial`].
pub fn populate_stiffness<M: EnergyOf>(
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    tangent: Tangent,
    k: &mut Stiffness,
    scratch: &mut Scratch,
) -> AssemblyReport {
    if let Some(np) = energy.nodal_pressure() {
        check_len(mesh, x, "stiffness", k.matrix.n / 2);
        return nodal_pressure::populate_stiffness(np, mesh, energy, x, tangent, k, scratch);
    }
    if crate::par::current_num_threads() == 1 {
        return populate_stiffness_serial(mesh, energy, x, tangent, k);
    }
    check_len(mesh, x, "stiffness", k.matrix.n / 2);
    let buf = &mut scratch.element_stiffness;
    buf.resize(mesh.n_triangles(), Mat6::zeros());
    let report = buf
        .par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .map(|(c, out)| {
            let mut r = AssemblyReport::EMPTY;
            for (i, o) in out.iter_mut().enumerate() {
                let t = c * ELEMENT_CHUNK + i;
                let (ke, j) = element_stiffness(
                    energy.energy_of(t),
                    &mesh.elements()[t],
                    mesh.gather(t, x),
                    tangent,
                );
                r.add(j);
                *o = ke;
            }
            r
        })
        .reduce(|| AssemblyReport::EMPTY, AssemblyReport::merge);
    k.matrix.values.fill(0.0);
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let offs = k.block_offsets[t];
        k.add_block(tri, &offs, &buf[t]);
    }
    report
}
