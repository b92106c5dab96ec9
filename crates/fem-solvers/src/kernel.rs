//! The fused per-element kernels every stepper runs: gather the three vertex positions, form
//! `F = Ds Dm^-1`, evaluate the energy, and turn `P` into nodal forces (explicit) or constraint
//! gradients (PBD/XPBD).
//!
//! Element data are packed once per model into [`PackedElement`] (indices, `Dm^-1`, rest area:
//! 56 bytes, streamed in element order) so the hot loop touches one array plus the positions.
//!
//! Architecture invariant: **the parallel force assembly is bit-identical to the serial one for
//! any number of threads.** The serial path scatters element forces into the output in element
//! order. The parallel path writes each element's forces on its vertices 1 and 2 into a
//! per-element buffer (work split in fixed chunks of [`ELEMENT_CHUNK`] elements), then sums each
//! vertex's contributions over the vertex-to-element adjacency, which is sorted by element, so
//! every sum is formed in the same order from the same zero. The force on vertex 0,
//! `-(f1 + f2)`, is recomputed by the same expression in both paths.

use fem_core::energy::Energy;
use fem_core::math::{Mat2, Real, Vec2};
use fem_core::mesh::{Mesh, VertexAdjacency};
use rayon::prelude::*;

/// Elements per parallel task. Fixed, so the work split never depends on the thread count.
pub(crate) const ELEMENT_CHUNK: usize = 1024;
/// Vertices per parallel task.
pub(crate) const VERTEX_CHUNK: usize = 2048;

/// Rest data of one triangle, laid out for streaming.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PackedElement {
    /// `Dm^-1`.
    pub dm_inv: Mat2,
    /// Rest area, m^2.
    pub area: Real,
    /// Vertex indices (counter-clockwise).
    pub idx: [u32; 3],
}

/// Pack the mesh's elements in triangle order.
pub(crate) fn pack(mesh: &Mesh) -> Vec<PackedElement> {
    mesh.triangles()
        .iter()
        .zip(mesh.elements())
        .map(|(t, e)| PackedElement {
            dm_inv: e.dm_inv,
            area: e.area,
            idx: *t,
        })
        .collect()
}

/// Inversion statistics of one pass over the elements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Inversion {
    /// Smallest `det F`.
    pub min_det_f: Real,
    /// Elements with `det F <= 0`.
    pub inverted: usize,
}

impl Inversion {
    pub const EMPTY: Inversion = Inversion {
        min_det_f: Real::INFINITY,
        inverted: 0,
    };

    #[inline(always)]
    pub fn add(&mut self, j: Real) {
        self.min_det_f = self.min_det_f.min(j);
        self.inverted += usize::from(j <= 0.0);
    }

    pub fn merge(a: Self, b: Self) -> Self {
        Inversion {
            min_det_f: a.min_det_f.min(b.min_det_f),
            inverted: a.inverted + b.inverted,
        }
    }
}

/// The deformation gradient of `el` at positions `x`.
#[inline(always)]
pub(crate) fn deformation_gradient(el: &PackedElement, x: &[Vec2]) -> Mat2 {
    let [i0, i1, i2] = el.idx;
    let x0 = x[i0 as usize];
    let e1 = x[i1 as usize] - x0;
    let e2 = x[i2 as usize] - x0;
    let d = &el.dm_inv;
    // F = [e1 e2] Dm^-1, written out.
    Mat2::new(
        e1.x * d[(0, 0)] + e2.x * d[(1, 0)],
        e1.x * d[(0, 1)] + e2.x * d[(1, 1)],
        e1.y * d[(0, 0)] + e2.y * d[(1, 0)],
        e1.y * d[(0, 1)] + e2.y * d[(1, 1)],
    )
}

/// `a P g_1` and `a P g_2`: the gradients of the element energy `a psi` with respect to its
/// vertices 1 and 2 (the gradient for vertex 0 is minus their sum). Forces are the negatives.
#[inline(always)]
pub(crate) fn energy_gradients(el: &PackedElement, p: &Mat2) -> (Vec2, Vec2) {
    let d = &el.dm_inv;
    let a = el.area;
    // g_1 = row 0 of Dm^-1, g_2 = row 1.
    let g1 = Vec2::new(
        p[(0, 0)] * d[(0, 0)] + p[(0, 1)] * d[(0, 1)],
        p[(1, 0)] * d[(0, 0)] + p[(1, 1)] * d[(0, 1)],
    );
    let g2 = Vec2::new(
        p[(0, 0)] * d[(1, 0)] + p[(0, 1)] * d[(1, 1)],
        p[(1, 0)] * d[(1, 0)] + p[(1, 1)] * d[(1, 1)],
    );
    (g1 * a, g2 * a)
}

/// Forces on vertices 1 and 2 of one element and its `det F`.
#[inline(always)]
fn element_forces<E: Energy>(energy: &E, el: &PackedElement, x: &[Vec2]) -> ([Vec2; 2], Real) {
    let f = deformation_gradient(el, x);
    let p = energy.pk1(&f);
    let (g1, g2) = energy_gradients(el, &p);
    ([-g1, -g2], f.determinant())
}

/// Elements evaluated per block before their forces are scattered (serial path).
const BLOCK: usize = 32;

/// Elastic forces `f = -dE/dx` into `f` (overwritten), serial scatter in element order.
///
/// Elements are evaluated in blocks of [`BLOCK`] into a small buffer and then scattered: the
/// evaluation loop has no stores into `f`, so the out-of-order core overlaps the long-latency
/// parts of consecutive elements (`ln`, divisions); the sums are formed in element order as in
/// a plain scatter loop.
pub(crate) fn forces_serial<E: Energy>(
    energy: &E,
    elements: &[PackedElement],
    x: &[Vec2],
    f: &mut [Vec2],
) -> Inversion {
    f.fill(Vec2::zeros());
    let mut inv = Inversion::EMPTY;
    let mut buf = [[Vec2::zeros(); 2]; BLOCK];
    for block in elements.chunks(BLOCK) {
        for (b, el) in buf.iter_mut().zip(block) {
            let (fe, j) = element_forces(energy, el, x);
            inv.add(j);
            *b = fe;
        }
        for (&[f1, f2], el) in buf.iter().zip(block) {
            let [i0, i1, i2] = el.idx;
            f[i0 as usize] += -(f1 + f2);
            f[i1 as usize] += f1;
            f[i2 as usize] += f2;
        }
    }
    inv
}

/// Elastic forces on the current rayon pool, bit-identical to [`forces_serial`]; `buf` is the
/// per-element workspace (resized here). With one thread it runs [`forces_serial`].
pub(crate) fn forces<E: Energy>(
    energy: &E,
    elements: &[PackedElement],
    adjacency: &VertexAdjacency,
    x: &[Vec2],
    f: &mut [Vec2],
    buf: &mut Vec<[Vec2; 2]>,
) -> Inversion {
    if rayon::current_num_threads() == 1 {
        return forces_serial(energy, elements, x, f);
    }
    buf.resize(elements.len(), [Vec2::zeros(); 2]);
    let inv = buf
        .par_chunks_mut(ELEMENT_CHUNK)
        .zip(elements.par_chunks(ELEMENT_CHUNK))
        .map(|(out, els)| {
            let mut inv = Inversion::EMPTY;
            for (o, el) in out.iter_mut().zip(els) {
                let (fe, j) = element_forces(energy, el, x);
                inv.add(j);
                *o = fe;
            }
            inv
        })
        .reduce(|| Inversion::EMPTY, Inversion::merge);
    let buf = &buf[..];
    f.par_chunks_mut(VERTEX_CHUNK)
        .enumerate()
        .for_each(|(c, fs)| {
            for (k, fv) in fs.iter_mut().enumerate() {
                let mut s = Vec2::zeros();
                for &(e, corner) in adjacency.of(c * VERTEX_CHUNK + k) {
                    let [f1, f2] = buf[e as usize];
                    s += match corner {
                        0 => -(f1 + f2),
                        1 => f1,
                        _ => f2,
                    };
                }
                *fv = s;
            }
        });
    inv
}

/// Total elastic energy `sum_e a_e psi(F_e)`, summed in element order (parallel evaluation into
/// `buf`, serial sum: the same bits for any thread count).
pub(crate) fn elastic_energy<E: Energy>(
    energy: &E,
    elements: &[PackedElement],
    x: &[Vec2],
    buf: &mut Vec<Real>,
) -> Real {
    buf.resize(elements.len(), 0.0);
    buf.par_chunks_mut(ELEMENT_CHUNK)
        .zip(elements.par_chunks(ELEMENT_CHUNK))
        .for_each(|(out, els)| {
            for (o, el) in out.iter_mut().zip(els) {
                *o = el.area * energy.psi(&deformation_gradient(el, x));
            }
        });
    buf.iter().fold(0.0, |acc, &e| acc + e)
}
