//! Energy, forces and the sparse stiffness of a [`SimplexMesh<D>`] under a
//! [`Hyperelastic<D>`] energy.
//!
//! Degrees of freedom are `[x0, y0, (z0,) x1, ...]`: component `i` of vertex `v` is `D v + i`.
//!
//! **Determinism.** Every result is the same for any number of threads: per-cell quantities
//! (`P`, `dP/dF`, energy) are computed in parallel into a buffer indexed by cell, and each
//! vertex then sums its cells' contributions in increasing cell order (forces), or the blocks
//! are added into the matrix in cell order (stiffness), or the energies are summed in cell order.
//! After the first call with a given mesh the buffers are reused: no allocation per call.

use crate::assembly::{CsrMatrix, Tangent};
use crate::dim::{Dense, Dim};
use crate::energy::Hyperelastic;
use crate::math::Real;
use crate::par::prelude::*;

use super::SimplexMesh;

/// Reusable per-cell buffers of the assembly functions.
#[derive(Clone, Debug, Default)]
pub struct Scratch<D: Dim> {
    stress: Vec<D::Matrix>,
    tangent: Vec<D::Tangent>,
    energy: Vec<Real>,
    det: Vec<Real>,
}

impl<D: Dim> Scratch<D> {
    /// Empty buffers (sized on first use).
    pub fn new() -> Self {
        Scratch {
            stress: Vec::new(),
            tangent: Vec::new(),
            energy: Vec::new(),
            det: Vec::new(),
        }
    }
}

fn gather<D: Dim>(mesh: &SimplexMesh<D>, cell: usize, x: &[D::Vector], out: &mut [D::Vector]) {
    for (k, &i) in mesh.cells()[cell].as_ref().iter().enumerate() {
        out[k] = x[i as usize];
    }
}

/// The elastic energy `sum_e V_e psi(F_e)`, summed in cell order.
pub fn elastic_energy<D: Dim, E: Hyperelastic<D>>(
    mesh: &SimplexMesh<D>,
    energy: &E,
    x: &[D::Vector],
    scratch: &mut Scratch<D>,
) -> Real {
    assert_eq!(x.len(), mesh.n_vertices(), "positions: one per mesh vertex");
    scratch.energy.resize(mesh.n_cells(), 0.0);
    scratch
        .energy
        .par_iter_mut()
        .enumerate()
        .for_each(|(c, out)| {
            let mut corners = [D::Vector::zeros(); 4];
            gather(mesh, c, x, &mut corners);
            let el = &mesh.elements()[c];
            *out = el.measure * energy.density(&el.deformation_gradient(&corners[..D::NODES]));
        });
    scratch.energy.iter().fold(0.0, |acc, &e| acc + e)
}

/// What a force pass saw: the smallest `det F` and the number of cells with `det F <= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceReport {
    /// The smallest `det F` over the cells.
    pub min_det_f: Real,
    /// Cells with `det F <= 0`.
    pub inverted: usize,
}

/// Elastic nodal forces `f = -dE/dx` into `out` (overwritten).
pub fn populate_forces<D: Dim, E: Hyperelastic<D>>(
    mesh: &SimplexMesh<D>,
    energy: &E,
    x: &[D::Vector],
    scratch: &mut Scratch<D>,
    out: &mut [D::Vector],
) -> ForceReport {
    assert_eq!(x.len(), mesh.n_vertices(), "positions: one per mesh vertex");
    assert_eq!(out.len(), mesh.n_vertices(), "forces: one per mesh vertex");
    let n = mesh.n_cells();
    scratch.stress.resize(n, D::Matrix::zeros());
    scratch.det.resize(n, 0.0);
    scratch
        .stress
        .par_iter_mut()
        .zip(scratch.det.par_iter_mut())
        .enumerate()
        .for_each(|(c, (p, det))| {
            let mut corners = [D::Vector::zeros(); 4];
            gather(mesh, c, x, &mut corners);
            let f = mesh.elements()[c].deformation_gradient(&corners[..D::NODES]);
            *det = D::det(&f);
            // P scaled by -V, so the force on corner a is (-V P) g_a.
            *p = energy.piola(&f) * (-mesh.elements()[c].measure);
        });
    let stress = &scratch.stress;
    out.par_iter_mut().enumerate().for_each(|(v, f)| {
        let mut sum = D::Vector::zeros();
        for &(c, corner) in mesh.cells_of(v) {
            sum += stress[c as usize] * mesh.elements()[c as usize].gradient(corner as usize);
        }
        *f = sum;
    });
    ForceReport {
        min_det_f: scratch.det.iter().copied().fold(Real::INFINITY, Real::min),
        inverted: scratch
            .det
            .iter()
            .filter(|&&d| d <= 0.0 || d.is_nan())
            .count(),
    }
}

/// The stiffness matrix `K = d^2 E / dx^2` of a mesh with its pattern built once (every
/// vertex pair that shares a cell), so repeated assembly only rewrites values.
#[derive(Clone, Debug)]
pub struct SimplexStiffness<D: Dim> {
    /// The matrix.
    pub matrix: CsrMatrix,
    /// For each cell and corner pair `(a, b)` (index `(D + 1) a + b`), the offset of the
    /// `D x D` block's first column within row `D v_a` (the block's rows share one pattern).
    offsets: Vec<u32>,
    _dim: std::marker::PhantomData<D>,
}

impl<D: Dim> SimplexStiffness<D> {
    /// The pattern with zero values.
    pub fn new(mesh: &SimplexMesh<D>) -> Self {
        let (nv, d) = (mesh.n_vertices(), D::D);
        let mut neighbours: Vec<Vec<u32>> = Vec::with_capacity(nv);
        for v in 0..nv {
            let mut list: Vec<u32> = mesh
                .cells_of(v)
                .iter()
                .flat_map(|&(c, _)| mesh.cells()[c as usize].as_ref().to_vec())
                .collect();
            list.sort_unstable();
            list.dedup();
            neighbours.push(list);
        }
        let mut row_offsets = Vec::with_capacity(d * nv + 1);
        let mut col_indices = Vec::new();
        row_offsets.push(0);
        for list in &neighbours {
            for _ in 0..d {
                for &w in list {
                    for k in 0..d {
                        col_indices.push(d * w as usize + k);
                    }
                }
                row_offsets.push(col_indices.len());
            }
        }
        let nodes = D::NODES;
        let mut offsets = Vec::with_capacity(mesh.n_cells() * nodes * nodes);
        for cell in mesh.cells() {
            let idx = cell.as_ref();
            for &va in idx {
                for &vb in idx {
                    let k = neighbours[va as usize]
                        .binary_search(&vb)
                        .expect("in pattern");
                    offsets.push((d * k) as u32);
                }
            }
        }
        let values = vec![0.0; col_indices.len()];
        SimplexStiffness {
            matrix: CsrMatrix {
                n: d * nv,
                row_offsets,
                col_indices,
                values,
            },
            offsets,
            _dim: std::marker::PhantomData,
        }
    }

    /// Assemble `K` at positions `x` with the exact or the per-cell projected tangent (values
    /// overwritten; the tangents are computed in parallel, the blocks added in cell order).
    pub fn populate<E: Hyperelastic<D>>(
        &mut self,
        mesh: &SimplexMesh<D>,
        energy: &E,
        x: &[D::Vector],
        tangent: Tangent,
        scratch: &mut Scratch<D>,
    ) {
        assert_eq!(x.len(), mesh.n_vertices(), "positions: one per mesh vertex");
        scratch.tangent.resize(mesh.n_cells(), D::Tangent::zeros());
        scratch
            .tangent
            .par_iter_mut()
            .enumerate()
            .for_each(|(c, t)| {
                let mut corners = [D::Vector::zeros(); 4];
                gather(mesh, c, x, &mut corners);
                let f = mesh.elements()[c].deformation_gradient(&corners[..D::NODES]);
                *t = match tangent {
                    Tangent::Exact => energy.piola_tangent(&f),
                    Tangent::Projected => energy.piola_tangent_projected(&f),
                };
            });
        let (d, nodes) = (D::D, D::NODES);
        let m = &mut self.matrix;
        m.values.iter_mut().for_each(|v| *v = 0.0);
        for (c, cell) in mesh.cells().iter().enumerate() {
            let idx = cell.as_ref();
            let el = &mesh.elements()[c];
            for (a, &va) in idx.iter().enumerate() {
                let row0 = d * va as usize;
                for b in 0..nodes {
                    let block = el.stiffness_block(&scratch.tangent[c], a, b);
                    let off = self.offsets[c * nodes * nodes + a * nodes + b] as usize;
                    for i in 0..d {
                        let start = m.row_offsets[row0 + i] + off;
                        for k in 0..d {
                            m.values[start + k] += block.at(i + d * k);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Material;
    use crate::dim::{D2, D3, Vec3};
    use crate::energy::NeoHookean;
    use crate::fd::{FdOptions, check_gradient, check_jacobian};
    use crate::material::PlaneModel;
    use crate::structured::{BoxParams, box_mesh};

    fn energy() -> NeoHookean {
        NeoHookean::new(
            Material::new(1000.0, 0.3, 1.0)
                .unwrap()
                .lame(PlaneModel::PlaneStrain),
        )
        .unwrap()
    }

    fn deformed(mesh: &SimplexMesh<D3>) -> Vec<Vec3> {
        mesh.vertices()
            .iter()
            .map(|p| {
                Vec3::new(
                    1.05 * p.x + 0.03 * (2.0 * p.y).sin(),
                    0.97 * p.y + 0.04 * p.z * p.x,
                    p.z + 0.02 * (3.0 * p.x).cos(),
                )
            })
            .collect()
    }

    fn flat(x: &[Vec3]) -> Vec<Real> {
        x.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
    }

    fn unflat(v: &[Real]) -> Vec<Vec3> {
        v.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
    }

    /// Forces are minus the gradient of the energy, and the stiffness is minus the Jacobian of
    /// the forces (central differences, `1e-7` relative: the FD oracle's error is about 1e-10
    /// here).
    #[test]
    fn forces_and_stiffness_are_derivatives_of_the_energy() {
        let mesh = box_mesh(&BoxParams::new(1.0, 0.5, 0.4, 2, 1, 1)).unwrap();
        let e = energy();
        let x = deformed(&mesh);
        let mut scratch = Scratch::new();
        let mut f = vec![Vec3::zeros(); mesh.n_vertices()];
        populate_forces(&mesh, &e, &x, &mut scratch, &mut f);
        let minus_f: Vec<Real> = flat(&f).iter().map(|v| -v).collect();
        let r = check_gradient(
            |v| elastic_energy(&mesh, &e, &unflat(v), &mut Scratch::new()),
            &flat(&x),
            &minus_f,
            &FdOptions::default(),
        );
        assert!(r.relative_error < 1e-7, "{r:?}");
        let mut k = SimplexStiffness::new(&mesh);
        k.populate(&mesh, &e, &x, Tangent::Exact, &mut scratch);
        let n = k.matrix.n;
        let mut dense = vec![0.0; n * n];
        for (r, c, v) in k.matrix.triplets() {
            dense[r * n + c] = v;
        }
        let r = check_jacobian(
            |v| {
                let mut f = vec![Vec3::zeros(); mesh.n_vertices()];
                populate_forces(&mesh, &e, &unflat(v), &mut Scratch::new(), &mut f);
                flat(&f).iter().map(|x| -x).collect()
            },
            &flat(&x),
            &dense,
            &FdOptions::default(),
        );
        assert!(r.relative_error < 1e-7, "{r:?}");
    }

    /// The patch test: an affine deformation gives the same `F` in every cell, so the interior
    /// vertices feel no net force; the energy is the volume times `psi(F)`.
    #[test]
    fn affine_deformation_leaves_interior_vertices_in_equilibrium() {
        let p = BoxParams::new(2.0, 1.0, 1.0, 4, 2, 2);
        let mesh = box_mesh(&p).unwrap();
        let e = energy();
        let a = crate::dim::Mat3::new(1.1, 0.05, 0.0, -0.02, 0.95, 0.03, 0.01, 0.0, 1.02);
        let x: Vec<Vec3> = mesh.vertices().iter().map(|q| a * q).collect();
        let mut f = vec![Vec3::zeros(); mesh.n_vertices()];
        populate_forces(&mesh, &e, &x, &mut Scratch::new(), &mut f);
        let scale = f.iter().map(|v| v.norm()).fold(0.0, Real::max);
        let interior = p.node(2, 1, 1);
        assert!(f[interior].norm() < 1e-12 * scale, "{:?}", f[interior]);
        let psi = Hyperelastic::<D3>::density(&e, &a);
        let total = elastic_energy(&mesh, &e, &x, &mut Scratch::new());
        assert!((total - psi * 2.0).abs() < 1e-12 * total.abs());
    }

    /// Determinism: one thread and two give the same bits.
    #[test]
    fn one_and_two_threads_give_the_same_bits() {
        let mesh = box_mesh(&BoxParams::new(1.0, 0.5, 0.4, 4, 2, 2)).unwrap();
        let e = energy();
        let x = deformed(&mesh);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut s = Scratch::new();
                let mut f = vec![Vec3::zeros(); mesh.n_vertices()];
                populate_forces(&mesh, &e, &x, &mut s, &mut f);
                let mut k = SimplexStiffness::new(&mesh);
                k.populate(&mesh, &e, &x, Tangent::Projected, &mut s);
                (f, k.matrix.values, elastic_energy(&mesh, &e, &x, &mut s))
            })
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.0, b.0);
        assert_eq!(a.1, b.1);
        assert_eq!(a.2.to_bits(), b.2.to_bits());
    }

    /// In 2D the generic assembly gives the triangle mesh's forces.
    #[test]
    fn the_2d_assembly_matches_the_triangle_assembly() {
        use crate::math::Vec2;
        use crate::structured::{RectangleParams, rectangle};
        let tri = rectangle(&RectangleParams::new(2.0, 1.0, 4, 2)).unwrap();
        let mesh =
            SimplexMesh::<D2>::new(tri.vertices().to_vec(), tri.triangles().to_vec()).unwrap();
        let e = energy();
        let x: Vec<Vec2> = tri
            .vertices()
            .iter()
            .map(|p| Vec2::new(1.1 * p.x + 0.1 * p.y * p.y, 0.9 * p.y))
            .collect();
        let mut want = vec![Vec2::zeros(); x.len()];
        crate::assembly::populate_forces_serial(&tri, &e, &x, &mut want);
        let mut got = vec![Vec2::zeros(); x.len()];
        populate_forces(&mesh, &e, &x, &mut Scratch::new(), &mut got);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).norm() < 1e-12 * 1000.0, "{g} vs {w}");
        }
    }
}
