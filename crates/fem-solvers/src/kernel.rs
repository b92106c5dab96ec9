//! The fused per-element kernels every stepper runs: gather the three vertex positions, form
//! `F = Ds Dm^-1`, evaluate the energy, and turn `P` into nodal forces (explicit) or constraint
//! gradients (PBD/XPBD).
//!
//! Element data are packed once per model into [`PackedElement`] (indices, `Dm^-1`, rest area:
//! 56 bytes, streamed in element order) so the hot loop touches one array plus the positions.
//! The explicit force kernel uses them regrouped into [`ElementBlock`]s of [`LANES`] triangles
//! in structure-of-arrays form and evaluates a block at a time with lane-wise arithmetic
//! ([`Energy::pk1_lanes`]), which the compiler vectorises.
//!
//! Architecture invariant: **the parallel force assembly is bit-identical to the serial one for
//! any number of threads.** The serial path scatters element forces into the output in element
//! order. The parallel path follows the mesh's
//! [`ScatterPlan`](fem_core::partition::ScatterPlan) (fixed chunks of triangles; each chunk adds
//! straight into the vertices only it touches and writes the rest into slots, summed per vertex
//! in triangle order afterwards), so every sum is formed in the same order from the same zero.
//! Lane `l` of a block performs exactly the scalar operations for its element, so the batching
//! does not depend on anything but the (fixed) triangle order either.

use std::sync::Mutex;

use fem_core::energy::{ElementEnergies, Energy, VolumeMeasure};
use fem_core::math::{LANES, Lanes, Mat2, Mat2Lanes, Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::par::prelude::*;
use fem_core::partition::{ELEMENT_CHUNK as PLAN_CHUNK, Target, for_each_chunk};
use fem_core::simd::Isa;

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
    /// The element's region: the index of its energy in [`ElementEnergies::energies`].
    pub region: u32,
}

impl PackedElement {
    /// The element's energy.
    #[inline(always)]
    pub fn energy<'a, E: Energy>(&self, energies: &'a ElementEnergies<E>) -> &'a E {
        &energies.energies()[self.region as usize]
    }
}

/// Pack the mesh's elements in triangle order; `tags` are the elements' regions (empty: all
/// in region 0).
pub(crate) fn pack(mesh: &Mesh, tags: &[u32]) -> Vec<PackedElement> {
    mesh.triangles()
        .iter()
        .zip(mesh.elements())
        .enumerate()
        .map(|(k, (t, e))| PackedElement {
            dm_inv: e.dm_inv,
            area: e.area,
            idx: *t,
            region: tags.get(k).copied().unwrap_or(0),
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
    /// Over every element of `mesh` at positions `x` (sequential: after a solve, not in one).
    pub fn of_mesh(mesh: &Mesh, x: &[Vec2]) -> Inversion {
        let mut inv = Inversion::EMPTY;
        for (t, el) in mesh.elements().iter().enumerate() {
            inv.add(el.deformation_gradient(mesh.gather(t, x)).determinant());
        }
        inv
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

/// The shape-function gradient of `corner` (see `fem_core::element::Tri3::gradients`).
#[inline(always)]
pub(crate) fn corner_gradient(el: &PackedElement, corner: u8) -> Vec2 {
    let d = &el.dm_inv;
    let g1 = Vec2::new(d[(0, 0)], d[(0, 1)]);
    let g2 = Vec2::new(d[(1, 0)], d[(1, 1)]);
    match corner {
        0 => -(g1 + g2),
        1 => g1,
        _ => g2,
    }
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

/// Rest data of [`LANES`] consecutive triangles in structure-of-arrays form, for the batched
/// force kernel. The last block of a mesh is padded with copies of its first triangle; padded
/// lanes are evaluated but never scattered nor counted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ElementBlock {
    /// `Dm^-1` of each lane.
    pub dm_inv: Mat2Lanes,
    /// Rest area of each lane, m^2.
    pub area: Lanes,
    /// `idx[corner][lane]`: vertex indices.
    pub idx: [[u32; LANES]; 3],
    /// The region of every lane, or [`MIXED`] when they differ (a block on a material
    /// interface evaluates lane by lane).
    pub region: u32,
    /// The region of each lane.
    pub regions: [u32; LANES],
}

/// [`ElementBlock::region`] of a block whose lanes lie in different regions.
pub(crate) const MIXED: u32 = u32::MAX;

// A scatter-plan chunk is a whole number of blocks.
const _: () = assert!(PLAN_CHUNK.is_multiple_of(LANES));

/// Pack elements (in triangle order) into blocks of [`LANES`].
pub(crate) fn pack_blocks(elements: &[PackedElement]) -> Vec<ElementBlock> {
    elements
        .chunks(LANES)
        .map(|c| {
            let el = |l: usize| c.get(l).unwrap_or(&c[0]);
            ElementBlock {
                dm_inv: Mat2Lanes::from_mats(&std::array::from_fn(|l| el(l).dm_inv)),
                area: Lanes(std::array::from_fn(|l| el(l).area)),
                idx: std::array::from_fn(|k| std::array::from_fn(|l| el(l).idx[k])),
                region: if c.iter().all(|e| e.region == c[0].region) {
                    c[0].region
                } else {
                    MIXED
                },
                regions: std::array::from_fn(|l| el(l).region),
            }
        })
        .collect()
}

/// Forces of one block: on vertices 0, 1 and 2 of every lane, and `det F` per lane.
struct BlockForces {
    f: [[Lanes; 2]; 3],
    det: Lanes,
}

/// The batched element kernel: gather, `F = Ds Dm^-1`, [`Energy::pk1_lanes`], and the nodal
/// forces `-a P g_j` (`g_1`, `g_2` the rows of `Dm^-1`, `g_0 = -(g_1 + g_2)`), all lane-wise.
/// Each lane performs exactly the operations of the scalar [`deformation_gradient`] and
/// [`energy_gradients`].
///
/// With `pressure` (the averaged nodal pressure triangle's mean nodal pressure `p_e` of each
/// lane, [`fem_core::nodal_pressure::PressureFields::update_mean_pressures`]) each lane's `P`
/// gains `(p_e - U'(theta_e)) dtheta/dF` (times `cof F`, or `I` for the trace measure), with
/// `U'(theta_e)` evaluated here, batched.
#[inline(always)]
fn block_forces<E: Energy>(
    energies: &ElementEnergies<E>,
    b: &ElementBlock,
    x: &[Vec2],
    pressure: Option<Lanes>,
) -> BlockForces {
    // Each vertex is read as one 16-byte pair, then the pairs are split into x and y lanes.
    let gather = |idx: &[u32; LANES]| {
        let mut px = [0.0; LANES];
        let mut py = [0.0; LANES];
        for l in 0..LANES {
            let p = x[idx[l] as usize];
            px[l] = p.x;
            py[l] = p.y;
        }
        (Lanes(px), Lanes(py))
    };
    let (x0, y0) = gather(&b.idx[0]);
    let (x1, y1) = gather(&b.idx[1]);
    let (x2, y2) = gather(&b.idx[2]);
    let (e1x, e1y) = (x1 - x0, y1 - y0);
    let (e2x, e2y) = (x2 - x0, y2 - y0);
    let d = &b.dm_inv;
    let (d00, d10, d01, d11) = (d.m00(), d.m10(), d.m01(), d.m11());
    let f = Mat2Lanes([
        e1x * d00 + e2x * d10,
        e1y * d00 + e2y * d10,
        e1x * d01 + e2x * d11,
        e1y * d01 + e2y * d11,
    ]);
    let p = if b.region != MIXED {
        energies.energies()[b.region as usize].pk1_lanes(&f)
    } else {
        // Lane `l` of `pk1_lanes` is bit-identical to `pk1` of that lane (the trait's
        // contract), so a mixed block gives the same bits as a uniform one would.
        let mut p = Mat2Lanes::default();
        for l in 0..LANES {
            let e = &energies.energies()[b.regions[l] as usize];
            p.set_lane(l, &e.pk1(&f.lane(l)));
        }
        p
    };
    let (mut p00, mut p10, mut p01, mut p11) = (p.m00(), p.m10(), p.m01(), p.m11());
    let corr = pressure.map(|pe| {
        let vol = energies.energies()[b.regions[0] as usize].volumetric();
        let du = if b.region != MIXED {
            let theta = match vol.measure() {
                VolumeMeasure::Determinant => f.determinant(),
                VolumeMeasure::Trace => f.m00() + f.m11() - 1.0,
            };
            vol.du_lanes(theta)
        } else {
            Lanes(std::array::from_fn(|l| {
                let v = energies.energies()[b.regions[l] as usize].volumetric();
                v.du(v.theta(&f.lane(l)))
            }))
        };
        (pe - du, vol.measure())
    });
    match corr {
        None => {}
        Some((c, VolumeMeasure::Determinant)) => {
            // cof(F) = [[F11, -F10], [-F01, F00]].
            p00 = p00 + c * f.m11();
            p10 = p10 - c * f.m01();
            p01 = p01 - c * f.m10();
            p11 = p11 + c * f.m00();
        }
        Some((c, VolumeMeasure::Trace)) => {
            p00 = p00 + c;
            p11 = p11 + c;
        }
    }
    let a = b.area;
    let f1 = [
        -((p00 * d00 + p01 * d01) * a),
        -((p10 * d00 + p11 * d01) * a),
    ];
    let f2 = [
        -((p00 * d10 + p01 * d11) * a),
        -((p10 * d10 + p11 * d11) * a),
    ];
    let f0 = [-(f1[0] + f2[0]), -(f1[1] + f2[1])];
    BlockForces {
        f: [f0, f1, f2],
        det: f.determinant(),
    }
}

impl BlockForces {
    /// The force on corner `c` of lane `l`.
    #[inline(always)]
    fn at(&self, c: usize, l: usize) -> Vec2 {
        Vec2::new(self.f[c][0].0[l], self.f[c][1].0[l])
    }
}

/// Inversion statistics kept per lane over full blocks (merged at the end; min and counts are
/// exact, so the merge order does not matter).
#[derive(Clone, Copy)]
struct LaneInversion {
    min: Lanes,
    inverted: Lanes,
}

impl LaneInversion {
    const EMPTY: LaneInversion = LaneInversion {
        min: Lanes([Real::INFINITY; LANES]),
        inverted: Lanes([0.0; LANES]),
    };

    #[inline(always)]
    fn add(&mut self, j: Lanes) {
        self.min = self.min.zip_with(j, Real::min);
        self.inverted = self
            .inverted
            .zip_with(j, |n, j| if j <= 0.0 { n + 1.0 } else { n });
    }

    fn finish(self, mut inv: Inversion) -> Inversion {
        for l in 0..LANES {
            inv.min_det_f = inv.min_det_f.min(self.min.0[l]);
            inv.inverted += self.inverted.0[l] as usize;
        }
        inv
    }
}

/// Evaluate `blocks` (the first of which holds element `first`, `n_elements` valid elements
/// in all) and hand every corner's force to `scatter(element, corner, vertex, force)` in
/// element order (`element` counted from the first block).
#[inline(always)]
fn blocks_forces<E: Energy>(
    energy: &ElementEnergies<E>,
    blocks: &[ElementBlock],
    n_elements: usize,
    x: &[Vec2],
    pressure: Option<&[Real]>,
    mut scatter: impl FnMut(usize, usize, u32, Vec2),
) -> Inversion {
    let mut lanes = LaneInversion::EMPTY;
    let mut tail = Inversion::EMPTY;
    for (k, b) in blocks.iter().enumerate() {
        let c = pressure.map(|c| {
            // A padded lane repeats the block's first element (see `pack_blocks`).
            let lane = |l: usize| c.get(k * LANES + l).copied().unwrap_or(c[k * LANES]);
            Lanes(std::array::from_fn(lane))
        });
        let bf = block_forces(energy, b, x, c);
        let valid = (n_elements - k * LANES).min(LANES);
        if valid == LANES {
            lanes.add(bf.det);
        } else {
            (0..valid).for_each(|l| tail.add(bf.det.0[l]));
        }
        for l in 0..valid {
            for c in 0..3 {
                scatter(k * LANES + l, c, b.idx[c][l], bf.at(c, l));
            }
        }
    }
    lanes.finish(tail)
}

/// Elastic forces `f = -dE/dx` into `f` (overwritten), serial scatter in element order.
/// `blocks` are the mesh's triangles in triangle order ([`pack_blocks`]).
pub(crate) fn forces_serial<E: Energy>(
    energy: &ElementEnergies<E>,
    blocks: &[ElementBlock],
    mesh: &Mesh,
    x: &[Vec2],
    f: &mut [Vec2],
    isa: Isa,
    pressure: Option<&[Real]>,
) -> Inversion {
    f.fill(Vec2::zeros());
    isa.run(
        #[inline(always)]
        || {
            blocks_forces(
                energy,
                blocks,
                mesh.n_triangles(),
                x,
                pressure,
                |_, _, v, fc| {
                    f[v as usize] += fc;
                },
            )
        },
    )
}

/// Elastic forces on the current rayon pool, bit-identical to [`forces_serial`] for any
/// number of threads. With one thread it runs [`forces_serial`]; otherwise it follows the
/// mesh's [`ScatterPlan`](fem_core::partition::ScatterPlan): each chunk of
/// [`PLAN_CHUNK`] triangles adds its forces straight into the vertices it owns and stores
/// the others in `slots` (resized here), which are then summed per shared vertex in triangle
/// order. Every vertex thus sums the same terms in the same order from the same zero as the
/// serial scatter.
#[allow(clippy::too_many_arguments)] // the kernel's inputs, each used once
pub(crate) fn forces<E: Energy>(
    energy: &ElementEnergies<E>,
    blocks: &[ElementBlock],
    mesh: &Mesh,
    x: &[Vec2],
    f: &mut [Vec2],
    slots: &mut Vec<Vec2>,
    isa: Isa,
    pressure: Option<&[Real]>,
) -> Inversion {
    if fem_core::par::current_num_threads() == 1 {
        return forces_serial(energy, blocks, mesh, x, f, isa, pressure);
    }
    let plan = mesh.scatter_plan();
    let n = mesh.n_triangles();
    slots.resize(plan.n_slots(), Vec2::zeros());
    let total = Mutex::new(Inversion::EMPTY);
    for_each_chunk(plan, f, slots, &|k, owned, slots| {
        owned.fill(Vec2::zeros());
        let first = k * PLAN_CHUNK;
        let base = plan.slot_range(k).start;
        let bs = &blocks[first / LANES..(first + PLAN_CHUNK).min(n).div_ceil(LANES)];
        let inv = isa.run(
            #[inline(always)]
            || {
                let pressure = pressure.map(|c| &c[first..]);
                blocks_forces(energy, bs, n - first, x, pressure, |e, c, _, fc| match plan
                    .targets(first + e)[c]
                {
                    Target::Owned(i) => owned[i] += fc,
                    Target::Shared(s) => slots[s - base] = fc,
                })
            },
        );
        let mut t = total.lock().unwrap_or_else(|p| p.into_inner());
        *t = Inversion::merge(*t, inv);
    });
    plan.sum_shared(f, slots, Vec2::zeros());
    total.into_inner().unwrap_or_else(|p| p.into_inner())
}

/// Total elastic energy `sum_e a_e psi(F_e)`, summed in element order (parallel evaluation into
/// `buf`, serial sum: the same bits for any thread count).
pub(crate) fn elastic_energy<E: Energy>(
    energy: &ElementEnergies<E>,
    elements: &[PackedElement],
    x: &[Vec2],
    buf: &mut Vec<Real>,
) -> Real {
    buf.resize(elements.len(), 0.0);
    buf.par_chunks_mut(ELEMENT_CHUNK)
        .zip(elements.par_chunks(ELEMENT_CHUNK))
        .for_each(|(out, els)| {
            for (o, el) in out.iter_mut().zip(els) {
                *o = el.area * el.energy(energy).psi(&deformation_gradient(el, x));
            }
        });
    buf.iter().fold(0.0, |acc, &e| acc + e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{RectangleParams, rectangle};
    use fem_core::PlaneModel;
    use fem_core::energy::EnergyKind;
    use fem_core::material::Material;

    /// The plain per-element loop the batched kernel must reproduce bit for bit.
    fn reference<E: Energy>(
        energies: &ElementEnergies<E>,
        elements: &[PackedElement],
        x: &[Vec2],
    ) -> Vec<Vec2> {
        let mut f = vec![Vec2::zeros(); x.len()];
        for el in elements {
            let p = el.energy(energies).pk1(&deformation_gradient(el, x));
            let (g1, g2) = energy_gradients(el, &p);
            let (f1, f2) = (-g1, -g2);
            let [i0, i1, i2] = el.idx.map(|i| i as usize);
            f[i0] += -(f1 + f2);
            f[i1] += f1;
            f[i2] += f2;
        }
        f
    }

    fn bits(f: &[Vec2]) -> Vec<[u64; 2]> {
        f.iter().map(|v| [v.x.to_bits(), v.y.to_bits()]).collect()
    }

    /// Every energy, every instruction set this machine has, 1, 2 and 3 threads, one material
    /// and two (blocks of one region and blocks across the interface): the same bits as the
    /// scalar per-element loop.
    #[test]
    fn batched_and_parallel_forces_equal_the_per_element_loop_bit_for_bit() {
        // 2 x 47 x 23 = 2162 triangles: two scatter-plan chunks and a partial last block.
        let mesh = rectangle(&RectangleParams::new(5.0, 1.0, 47, 23)).unwrap();
        assert_eq!(mesh.n_triangles() % LANES, 2);
        let lame = Material::new(1000.0, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        let stiff = Material::new(3.0e6, 0.2, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        // Region 1: triangles whose centroid lies in a disc, so some blocks straddle it.
        let tags: Vec<u32> = (0..mesh.n_triangles())
            .map(|t| {
                let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
                u32::from((c - Vec2::new(2.0, 0.5)).norm() < 0.4)
            })
            .collect();
        for tagged in [false, true] {
            let tags = if tagged { tags.clone() } else { Vec::new() };
            let elements = pack(&mesh, &tags);
            let blocks = pack_blocks(&elements);
            let mixed = blocks.iter().filter(|b| b.region == MIXED).count();
            let stiff_blocks = blocks.iter().filter(|b| b.region == 1).count();
            assert_eq!((mixed > 0, stiff_blocks > 0), (tagged, tagged));
            for kind in EnergyKind::ALL {
                let base = kind.build(lame).unwrap();
                let energies = if tagged {
                    ElementEnergies::new(
                        vec![base.clone(), base.with_lame(stiff).unwrap()],
                        tags.clone(),
                    )
                    .unwrap()
                } else {
                    ElementEnergies::uniform(base)
                };
                check_bits(&energies, &mesh, &elements, &blocks);
            }
        }
    }

    /// The batched kernel with the averaged nodal pressure triangle's corrections equals
    /// fem-core's assembly of the same energy (to round-off: the sums differ in order), for
    /// every energy on two materials, and the same bits for 1, 2 and 3 threads.
    #[test]
    fn batched_forces_with_averaged_pressure_equal_the_assembly() {
        let mesh = rectangle(&RectangleParams::new(5.0, 1.0, 47, 23)).unwrap();
        let soft = Material::new(1000.0, 0.49, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        let stiff = Material::new(3.0e4, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain);
        let tags: Vec<u32> = (0..mesh.n_triangles())
            .map(|t| {
                let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
                u32::from((c - Vec2::new(2.0, 0.5)).norm() < 0.4)
            })
            .collect();
        let elements = pack(&mesh, &tags);
        let blocks = pack_blocks(&elements);
        let x: Vec<Vec2> = (mesh.vertices().iter())
            .map(|p| Vec2::new(p.x * 1.02 + 0.03 * p.y * p.y, p.y * 0.97 + 0.01 * p.x))
            .collect();
        for kind in EnergyKind::ALL {
            let base = kind.build(soft).unwrap();
            let energies = ElementEnergies::new(
                vec![base.clone(), base.with_lame(stiff).unwrap()],
                tags.clone(),
            )
            .unwrap()
            .with_nodal_pressure(&mesh)
            .unwrap();
            let np = fem_core::energy::EnergyOf::nodal_pressure(&energies).unwrap();
            let mut fields = fem_core::nodal_pressure::PressureFields::new();
            fields.update_mean_pressures(np, &mesh, &energies, &x);
            let corr = Some(fields.correction());
            let mut batched = vec![Vec2::zeros(); x.len()];
            let isa = Isa::detected();
            forces_serial(&energies, &blocks, &mesh, &x, &mut batched, isa, corr);
            let mut assembled = vec![Vec2::zeros(); x.len()];
            fem_core::assembly::populate_forces_serial(&mesh, &energies, &x, &mut assembled);
            let scale = assembled.iter().map(|f| f.norm()).fold(0.0, Real::max);
            for (a, b) in batched.iter().zip(&assembled) {
                assert!((a - b).norm() <= 1e-10 * scale, "{kind:?}: {a:?} vs {b:?}");
            }
            for threads in [2, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut par = vec![Vec2::zeros(); x.len()];
                let mut slots = Vec::new();
                pool.install(|| {
                    forces(
                        &energies, &blocks, &mesh, &x, &mut par, &mut slots, isa, corr,
                    )
                });
                assert_eq!(bits(&par), bits(&batched), "{kind:?}, {threads} threads");
            }
        }
    }

    fn check_bits<E: Energy>(
        energies: &ElementEnergies<E>,
        mesh: &Mesh,
        elements: &[PackedElement],
        blocks: &[ElementBlock],
    ) {
        let x: Vec<Vec2> = mesh
            .vertices()
            .iter()
            .map(|p| Vec2::new(p.x * (1.0 + 0.03 * p.y), p.y + 0.05 * (0.7 * p.x).sin()))
            .collect();
        let min = elements
            .iter()
            .map(|el| deformation_gradient(el, &x).determinant())
            .fold(Real::INFINITY, Real::min);
        let pools: Vec<_> = [2, 3]
            .map(|n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
            })
            .into();
        let kind = energies.base().name();
        let want = bits(&reference(energies, elements, &x));
        for isa in Isa::supported() {
            let mut serial = vec![Vec2::zeros(); x.len()];
            let inv = forces_serial(energies, blocks, mesh, &x, &mut serial, isa, None);
            assert_eq!(bits(&serial), want, "{kind:?}, {isa}");
            assert_eq!(inv.inverted, 0);
            assert_eq!(inv.min_det_f, min);
            for pool in &pools {
                let mut par = vec![Vec2::zeros(); x.len()];
                let mut slots = Vec::new();
                let pinv = pool.install(|| {
                    forces(energies, blocks, mesh, &x, &mut par, &mut slots, isa, None)
                });
                let threads = pool.current_num_threads();
                assert_eq!(bits(&par), want, "{kind:?}, {isa}, {threads} threads");
                assert_eq!(pinv, inv);
            }
        }
    }
}
