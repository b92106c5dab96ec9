//! The **averaged nodal pressure** linear triangle: a locking-free formulation of the linear
//! triangle for nearly incompressible bodies (Bonet & Burton 1998, "A simple average nodal
//! pressure tetrahedral element for incompressible and nearly incompressible dynamic explicit
//! applications"; in its variational form, Bonet, Marriott & Hassan 2001).
//!
//! A plain linear triangle carries one volume constraint per element; a triangle mesh has about
//! twice as many elements as vertices, so as `nu -> 1/2` the constraints outnumber the free
//! degrees of freedom and the mesh **locks**: too stiff, its pressure a checkerboard. This
//! formulation keeps each element's deviatoric part and moves the volumetric part
//! [`Volumetric`] of every energy to the mesh's nodes, one constraint per node:
//!
//! ```text
//! E(x) = sum_e a_e [psi(F_e) - U(theta_e)]  +  sum_n V_n U(theta_n),
//! theta_n = sum_{e at n} (a_e / 3) theta_e / V_n,     V_n = sum_{e at n} a_e / 3,
//! ```
//!
//! with `theta = J` (or `1 + tr(eps)` for the small-strain energy): `V_n theta_n` is a third of
//! the current area of the triangles at node `n`. It is an energy, so every solver that
//! minimises or differentiates energies uses it unchanged:
//!
//! - **forces**: each element sees `P_e + (p_e - U'(theta_e)) dtheta/dF` with the nodal
//!   pressures `p_n = U'(theta_n)` averaged over its three nodes, `p_e = (p_0 + p_1 + p_2) / 3`
//!   (the averaged nodal pressure); the element's Cauchy stress is shifted by
//!   `(p_e - U'(theta_e)) I` in plane and out of plane, so its hydrostatic part is the smooth
//!   nodal one;
//! - **Hessian**: the element's `dP/dF - U''(theta_e) t t^T + (p_e - U'(theta_e)) d2theta`
//!   (`t = dtheta/dF`), plus at each node the rank-one `U''(theta_n) / V_n h_n h_n^T` with
//!   `h_n = V_n dtheta_n/dx`, which couples every vertex of the triangles at the node (a wider
//!   stencil: [`Stiffness::with_nodal_pressure`]). The projected Hessian projects the element
//!   part (isotropic: [`project_psd_isotropic`]) and clamps `U''(theta_n)` at zero.
//!
//! Under a uniform deformation every `theta_n` equals every `theta_e`, so the energy, the
//! forces and the stress equal the plain triangle's exactly: the patch test holds, the rest
//! state is stress-free, and nothing changes where nothing locks but the discretisation error.
//!
//! **Materials**: a node is a (vertex, region) pair, so volumes are averaged within one
//! material only (a vertex on a bone-tissue interface has one node per side), and a rigid
//! region's triangles are not in the elastic mesh at all.
//!
//! Every loop is deterministic: elements and nodes are evaluated into per-item buffers (in
//! parallel) and every sum is formed in a fixed order (nodes' triangles in increasing index,
//! vertices' triangles in increasing index), so the results are bit-identical for any number of
//! threads, with or without the `parallel` feature.

use crate::assembly::{AssemblyReport, Scratch, Stiffness, Tangent};
use crate::energy::{
    Energy, EnergyOf, VolumeMeasure, Volumetric, project_psd, project_psd_isotropic,
};
use crate::math::{Mat2, Mat4, Mat6, Real, Vec2, vec};
use crate::mesh::Mesh;
use crate::par::prelude::*;
use crate::partition::ELEMENT_CHUNK;

/// Nodes per parallel task.
const NODE_CHUNK: usize = 1024;

/// The nodes of a mesh for the averaged nodal pressure triangle: one per (vertex, region)
/// pair, with the triangles around it and its rest volume `V_n = sum a_e / 3`.
#[derive(Clone, Debug, PartialEq)]
pub struct NodalPressure {
    /// The node of each corner of each triangle.
    corner_node: Vec<[u32; 3]>,
    /// The vertex of each node.
    node_vertex: Vec<u32>,
    /// `offsets[n]..offsets[n + 1]` indexes node `n`'s `(triangle, corner)` entries.
    offsets: Vec<u32>,
    /// The triangles at each node with the node's corner, in increasing triangle order.
    entries: Vec<(u32, u8)>,
    /// `V_n`, m^2.
    volume: Vec<Real>,
    /// Each entry's weight `(a_e / 3) / V_n` in its node's average.
    weights: Vec<Real>,
}

impl NodalPressure {
    /// The nodes of `mesh` whose triangles carry the region `tags` (empty: one region). Panics
    /// when `tags` is neither empty nor one per triangle.
    pub fn new(mesh: &Mesh, tags: &[u32]) -> Self {
        assert!(
            tags.is_empty() || tags.len() == mesh.n_triangles(),
            "one region tag per triangle"
        );
        let tag = |t: u32| tags.get(t as usize).copied().unwrap_or(0);
        let adj = mesh.adjacency();
        let mut corner_node = vec![[u32::MAX; 3]; mesh.n_triangles()];
        let (mut node_vertex, mut offsets, mut entries, mut volume) =
            (Vec::new(), vec![0u32], Vec::new(), Vec::new());
        let mut regions: Vec<u32> = Vec::new();
        for v in 0..mesh.n_vertices() {
            regions.clear();
            regions.extend(adj.of(v).iter().map(|&(t, _)| tag(t)));
            regions.sort_unstable();
            regions.dedup();
            for &r in &regions {
                let n = node_vertex.len() as u32;
                let mut vol = 0.0;
                for &(t, c) in adj.of(v).iter().filter(|&&(t, _)| tag(t) == r) {
                    corner_node[t as usize][c as usize] = n;
                    entries.push((t, c));
                    vol += mesh.elements()[t as usize].area / 3.0;
                }
                node_vertex.push(v as u32);
                offsets.push(entries.len() as u32);
                volume.push(vol);
            }
        }
        let mut weights = Vec::with_capacity(entries.len());
        for n in 0..node_vertex.len() {
            for &(t, _) in &entries[offsets[n] as usize..offsets[n + 1] as usize] {
                weights.push(mesh.elements()[t as usize].area / 3.0 / volume[n]);
            }
        }
        NodalPressure {
            corner_node,
            node_vertex,
            offsets,
            entries,
            volume,
            weights,
        }
    }

    /// The number of nodes (at least the number of vertices that have a triangle).
    pub fn n_nodes(&self) -> usize {
        self.node_vertex.len()
    }

    /// The vertex of node `n`.
    pub fn vertex(&self, n: usize) -> usize {
        self.node_vertex[n] as usize
    }

    /// The nodes of triangle `t`'s corners.
    pub fn corner_nodes(&self, t: usize) -> [u32; 3] {
        self.corner_node[t]
    }

    /// The `(triangle, corner)` pairs at node `n`, in increasing triangle order.
    pub fn entries(&self, n: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[n] as usize..self.offsets[n + 1] as usize]
    }

    /// `V_n`, m^2.
    pub fn volume(&self, n: usize) -> Real {
        self.volume[n]
    }

    /// The vertices of the triangles at node `n` (its **patch**), sorted, into `out`.
    pub fn patch(&self, mesh: &Mesh, n: usize, out: &mut Vec<u32>) {
        out.clear();
        out.extend(
            self.entries(n)
                .iter()
                .flat_map(|&(t, _)| mesh.triangles()[t as usize]),
        );
        out.sort_unstable();
        out.dedup();
    }

    /// The stencil of the nodal terms: for every vertex, the sorted vertices it couples with
    /// (every vertex of every patch it lies in; a superset of the triangles' neighbours).
    pub fn stencil(&self, mesh: &Mesh) -> Vec<Vec<u32>> {
        let mut out: Vec<Vec<u32>> = vec![Vec::new(); mesh.n_vertices()];
        let mut patch = Vec::new();
        for n in 0..self.n_nodes() {
            self.patch(mesh, n, &mut patch);
            for &v in &patch {
                out[v as usize].extend_from_slice(&patch);
            }
        }
        for list in &mut out {
            list.sort_unstable();
            list.dedup();
        }
        out
    }
}

/// The per-state fields of the formulation at positions `x` ([`PressureFields::update`]):
/// element and nodal volume measures, nodal pressures and stiffnesses, and each element's
/// correction. Reused across steps (kept in a [`Scratch`]).
#[derive(Clone, Debug, Default)]
pub struct PressureFields {
    /// `theta_e`.
    theta: Vec<Real>,
    /// `dtheta/dF` of each element.
    dtheta: Vec<Mat2>,
    /// `theta_n`.
    node_theta: Vec<Real>,
    /// `p_n = U'(theta_n)`, Pa.
    node_p: Vec<Real>,
    /// `U''(theta_n)`, Pa.
    node_k: Vec<Real>,
    /// `p_e - U'(theta_e)`, Pa: the shift of the element's stress.
    corr: Vec<Real>,
    /// `U''(theta_e)`, Pa.
    d2u: Vec<Real>,
    /// Per-node and per-element buffers of the energy and force passes.
    node_energy: Vec<Real>,
    element_forces: Vec<[Vec2; 3]>,
}

impl PressureFields {
    /// Empty fields.
    pub fn new() -> Self {
        Self::default()
    }

    /// Evaluate the fields of `np` on `mesh` at positions `x`: everything the forces, the
    /// energy and the stiffness need.
    pub fn update<M: EnergyOf>(&mut self, np: &NodalPressure, mesh: &Mesh, energy: &M, x: &[Vec2]) {
        self.evaluate(np, mesh, energy, x, true);
    }

    /// [`PressureFields::update`] without what only the stiffness needs (`dtheta/dF`,
    /// `U''`): the corrections of an explicit force pass.
    pub fn update_corrections<M: EnergyOf>(
        &mut self,
        np: &NodalPressure,
        mesh: &Mesh,
        energy: &M,
        x: &[Vec2],
    ) {
        self.evaluate(np, mesh, energy, x, false);
    }

    /// The measures `theta_e`, the nodes' `theta_n` and pressures, and in place of the
    /// corrections each element's mean nodal pressure `p_e` ([`PressureFields::correction`]
    /// then holds `p_e`, not `p_e - U'(theta_e)`): for a kernel that evaluates `U'(theta_e)`
    /// itself, batched.
    pub fn update_mean_pressures<M: EnergyOf>(
        &mut self,
        np: &NodalPressure,
        mesh: &Mesh,
        energy: &M,
        x: &[Vec2],
    ) {
        let ne = mesh.n_triangles();
        self.theta.resize(ne, 0.0);
        self.corr.resize(ne, 0.0);
        self.theta
            .par_chunks_mut(ELEMENT_CHUNK)
            .enumerate()
            .for_each(|(c, theta)| {
                for (k, th) in theta.iter_mut().enumerate() {
                    let t = c * ELEMENT_CHUNK + k;
                    let f = mesh.elements()[t].deformation_gradient(mesh.gather(t, x));
                    *th = energy.energy_of(t).volumetric().theta(&f);
                }
            });
        self.nodes(np, energy);
        let node_p = &self.node_p;
        self.corr
            .par_chunks_mut(ELEMENT_CHUNK)
            .enumerate()
            .for_each(|(c, corr)| {
                for (k, co) in corr.iter_mut().enumerate() {
                    let [a, b, d] =
                        np.corner_node[c * ELEMENT_CHUNK + k].map(|n| node_p[n as usize]);
                    *co = (a + b + d) / 3.0;
                }
            });
    }

    /// `theta_n` and `p_n` from `theta_e`.
    fn nodes<M: EnergyOf>(&mut self, np: &NodalPressure, energy: &M) {
        let nn = np.n_nodes();
        self.node_theta.resize(nn, 0.0);
        self.node_p.resize(nn, 0.0);
        let theta = &self.theta;
        (self.node_theta.par_chunks_mut(NODE_CHUNK))
            .zip(self.node_p.par_chunks_mut(NODE_CHUNK))
            .enumerate()
            .for_each(|(c, (th, p))| {
                for i in 0..th.len() {
                    let n = c * NODE_CHUNK + i;
                    let range = np.offsets[n] as usize..np.offsets[n + 1] as usize;
                    let mut tn = 0.0;
                    for (&(t, _), w) in np.entries[range.clone()].iter().zip(&np.weights[range]) {
                        tn += w * theta[t as usize];
                    }
                    let vol = energy.energy_of(np.entries(n)[0].0 as usize).volumetric();
                    th[i] = tn;
                    p[i] = vol.du(tn);
                }
            });
    }

    fn evaluate<M: EnergyOf>(
        &mut self,
        np: &NodalPressure,
        mesh: &Mesh,
        energy: &M,
        x: &[Vec2],
        full: bool,
    ) {
        let (ne, nn) = (mesh.n_triangles(), np.n_nodes());
        self.theta.resize(ne, 0.0);
        // `corr` holds `U'(theta_e)` until the last pass turns it into the correction.
        self.corr.resize(ne, 0.0);
        self.node_theta.resize(nn, 0.0);
        self.node_p.resize(nn, 0.0);
        if full {
            self.dtheta.resize(ne, Mat2::zeros());
            self.d2u.resize(ne, 0.0);
            self.node_k.resize(nn, 0.0);
        }
        (self.theta.par_chunks_mut(ELEMENT_CHUNK))
            .zip(self.corr.par_chunks_mut(ELEMENT_CHUNK))
            .enumerate()
            .for_each(|(c, (theta, du))| {
                for (k, (th, du)) in theta.iter_mut().zip(du.iter_mut()).enumerate() {
                    let t = c * ELEMENT_CHUNK + k;
                    let f = mesh.elements()[t].deformation_gradient(mesh.gather(t, x));
                    let vol = energy.energy_of(t).volumetric();
                    *th = vol.theta(&f);
                    *du = vol.du(*th);
                }
            });
        if full {
            (self.dtheta.par_chunks_mut(ELEMENT_CHUNK))
                .zip(self.d2u.par_chunks_mut(ELEMENT_CHUNK))
                .zip(self.theta.par_chunks(ELEMENT_CHUNK))
                .enumerate()
                .for_each(|(c, ((dtheta, d2u), theta))| {
                    for (k, ((dt, dd), th)) in
                        dtheta.iter_mut().zip(d2u.iter_mut()).zip(theta).enumerate()
                    {
                        let t = c * ELEMENT_CHUNK + k;
                        let f = mesh.elements()[t].deformation_gradient(mesh.gather(t, x));
                        let vol = energy.energy_of(t).volumetric();
                        *dt = vol.dtheta(&f);
                        *dd = vol.d2u(*th);
                    }
                });
        }
        self.nodes(np, energy);
        let node_k = &mut self.node_k;
        if full {
            let node_theta = &self.node_theta;
            node_k
                .par_chunks_mut(NODE_CHUNK)
                .enumerate()
                .for_each(|(c, k)| {
                    for (i, k) in k.iter_mut().enumerate() {
                        let n = c * NODE_CHUNK + i;
                        let vol = energy.energy_of(np.entries(n)[0].0 as usize).volumetric();
                        *k = vol.d2u(node_theta[n]);
                    }
                });
        }
        let node_p = &self.node_p;
        self.corr
            .par_chunks_mut(ELEMENT_CHUNK)
            .enumerate()
            .for_each(|(c, corr)| {
                for (k, co) in corr.iter_mut().enumerate() {
                    let t = c * ELEMENT_CHUNK + k;
                    let [a, b, d] = np.corner_node[t].map(|n| node_p[n as usize]);
                    *co = (a + b + d) / 3.0 - *co;
                }
            });
    }

    /// `theta_e` of each element (after [`PressureFields::update`]).
    pub fn theta(&self) -> &[Real] {
        &self.theta
    }

    /// `theta_n` of each node.
    pub fn node_theta(&self) -> &[Real] {
        &self.node_theta
    }

    /// The nodal pressures `p_n = U'(theta_n)`, Pa (tension positive).
    pub fn node_pressure(&self) -> &[Real] {
        &self.node_p
    }

    /// `U''(theta_n)` of each node, Pa.
    pub fn node_stiffness(&self) -> &[Real] {
        &self.node_k
    }

    /// Each element's correction `p_e - U'(theta_e)`, Pa: what the formulation adds to the
    /// element's stress (times `dtheta/dF` in `P`, times `I` in the Cauchy stress).
    pub fn correction(&self) -> &[Real] {
        &self.corr
    }

    /// `U''(theta_e)` of each element, Pa.
    pub fn element_stiffness(&self) -> &[Real] {
        &self.d2u
    }

    /// `dtheta/dF` of each element (after [`PressureFields::update`]).
    pub fn dtheta(&self) -> &[Mat2] {
        &self.dtheta
    }

    /// Element `t`'s first Piola-Kirchhoff stress under the formulation:
    /// `P(F) + (p_e - U'(theta_e)) dtheta/dF`.
    #[inline]
    pub fn pk1<E: Energy>(&self, t: usize, energy: &E, f: &Mat2) -> Mat2 {
        energy.pk1(f) + energy.volumetric().dtheta(f) * self.corr[t]
    }

    /// Element `t`'s `dP/dF` under the formulation at fixed nodal pressures (the element part
    /// of the Hessian): `dP/dF - U''(theta_e) t t^T + (p_e - U'(theta_e)) d2theta`, exact or
    /// projected onto the positive semi-definite cone.
    pub fn dpk1<E: Energy>(&self, t: usize, energy: &E, f: &Mat2, tangent: Tangent) -> Mat4 {
        let vol = energy.volumetric();
        let tv = vec(&self.dtheta[t]);
        let d = energy.dpk1(f) - tv * tv.transpose() * self.d2u[t] + vol.d2theta() * self.corr[t];
        match (tangent, vol.measure()) {
            (Tangent::Exact, _) => d,
            (Tangent::Projected, VolumeMeasure::Determinant) => project_psd_isotropic(f, &d),
            (Tangent::Projected, VolumeMeasure::Trace) => project_psd(&d),
        }
    }
}

/// `psi - U(theta)` of one element: `+inf` stays `+inf` (an inverted Neo-Hookean element).
#[inline]
fn deviatoric_psi(psi: Real, vol: &Volumetric, theta: Real) -> Real {
    if psi == Real::INFINITY {
        psi
    } else {
        psi - vol.u(theta)
    }
}

/// The total elastic energy under the formulation, J per unit thickness: element terms summed
/// in triangle order, then node terms in node order.
pub fn elastic_energy<M: EnergyOf>(
    np: &NodalPressure,
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    scratch: &mut Scratch,
) -> Real {
    let fields = &mut scratch.pressure;
    fields.update_corrections(np, mesh, energy, x);
    let buf = &mut scratch.element_energies;
    buf.resize(mesh.n_triangles(), 0.0);
    let theta = &fields.theta;
    buf.par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let t = c * ELEMENT_CHUNK + k;
                let el = &mesh.elements()[t];
                let e = energy.energy_of(t);
                let psi = e.psi(&el.deformation_gradient(mesh.gather(t, x)));
                *o = el.area * deviatoric_psi(psi, &e.volumetric(), theta[t]);
            }
        });
    let nodes = &mut fields.node_energy;
    nodes.resize(np.n_nodes(), 0.0);
    let node_theta = &fields.node_theta;
    nodes
        .par_chunks_mut(NODE_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let n = c * NODE_CHUNK + k;
                let vol = energy.energy_of(np.entries(n)[0].0 as usize).volumetric();
                *o = np.volume(n) * vol.u(node_theta[n]);
            }
        });
    let elements = buf.iter().fold(0.0, |acc, &e| acc + e);
    nodes.iter().fold(elements, |acc, &e| acc + e)
}

/// Elastic nodal forces `f = -dE/dx` under the formulation (N per unit thickness) into `f`:
/// each element's three forces into a buffer, then each vertex sums its triangles' in
/// increasing triangle order.
pub fn populate_forces<M: EnergyOf>(
    np: &NodalPressure,
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    f: &mut [Vec2],
    scratch: &mut Scratch,
) -> AssemblyReport {
    let fields = &mut scratch.pressure;
    fields.update_corrections(np, mesh, energy, x);
    let mut forces = std::mem::take(&mut fields.element_forces);
    forces.resize(mesh.n_triangles(), [Vec2::zeros(); 3]);
    let fields_ref = &*fields;
    let report = forces
        .par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .map(|(c, out)| {
            let mut r = AssemblyReport::EMPTY;
            for (k, o) in out.iter_mut().enumerate() {
                let t = c * ELEMENT_CHUNK + k;
                let el = &mesh.elements()[t];
                let fg = el.deformation_gradient(mesh.gather(t, x));
                r.add(fg.determinant());
                *o = el.forces(&fields_ref.pk1(t, energy.energy_of(t), &fg));
            }
            r
        })
        .reduce(|| AssemblyReport::EMPTY, AssemblyReport::merge);
    let adj = mesh.adjacency();
    let forces_ref = &forces;
    f.par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let v = c * ELEMENT_CHUNK + k;
                let mut s = Vec2::zeros();
                for &(t, corner) in adj.of(v) {
                    s += forces_ref[t as usize][corner as usize];
                }
                *o = s;
            }
        });
    fields.element_forces = forces;
    report
}

/// The stiffness `K = d^2E/dx^2` under the formulation (exact or projected) into `k`, which
/// must have been built by [`Stiffness::with_nodal_pressure`] for `np`: element blocks in
/// parallel, added in triangle order, then the nodal rank-one terms in node order.
pub fn populate_stiffness<M: EnergyOf>(
    np: &NodalPressure,
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
    tangent: Tangent,
    k: &mut Stiffness,
    scratch: &mut Scratch,
) -> AssemblyReport {
    let fields = &mut scratch.pressure;
    fields.update(np, mesh, energy, x);
    let fields = &scratch.pressure;
    let buf = &mut scratch.element_stiffness;
    buf.resize(mesh.n_triangles(), Mat6::zeros());
    let report = buf
        .par_chunks_mut(ELEMENT_CHUNK)
        .enumerate()
        .map(|(c, out)| {
            let mut r = AssemblyReport::EMPTY;
            for (i, o) in out.iter_mut().enumerate() {
                let t = c * ELEMENT_CHUNK + i;
                let el = &mesh.elements()[t];
                let fg = el.deformation_gradient(mesh.gather(t, x));
                r.add(fg.determinant());
                *o = el.stiffness(&fields.dpk1(t, energy.energy_of(t), &fg, tangent));
            }
            r
        })
        .reduce(|| AssemblyReport::EMPTY, AssemblyReport::merge);
    k.matrix.values.fill(0.0);
    for (t, tri) in mesh.triangles().iter().enumerate() {
        let offs = k.block_offsets[t];
        k.add_block(tri, &offs, &buf[t]);
    }
    k.add_nodal(np, mesh, fields, tangent);
    report
}

impl Stiffness {
    /// Add the nodal terms `U''(theta_n) / V_n h_n h_n^T` (clamped at zero when projected).
    fn add_nodal(
        &mut self,
        np: &NodalPressure,
        mesh: &Mesh,
        fields: &PressureFields,
        tangent: Tangent,
    ) {
        let nodal = self
            .nodal
            .as_ref()
            .expect("a stiffness built by Stiffness::with_nodal_pressure");
        assert_eq!(
            nodal.patch_offsets.len(),
            np.n_nodes() + 1,
            "the stiffness was built for another mesh"
        );
        let mut h: Vec<Vec2> = Vec::new();
        for n in 0..np.n_nodes() {
            let mut kn = fields.node_k[n];
            if tangent == Tangent::Projected {
                kn = kn.max(0.0);
            }
            let range = nodal.patch_offsets[n] as usize..nodal.patch_offsets[n + 1] as usize;
            let patch = &nodal.patch_vertices[range.clone()];
            h.clear();
            h.resize(patch.len(), Vec2::zeros());
            for &(t, _) in np.entries(n) {
                let el = &mesh.elements()[t as usize];
                let g = el.gradients();
                let w = fields.dtheta[t as usize] * (el.area / 3.0);
                for (corner, &v) in mesh.triangles()[t as usize].iter().enumerate() {
                    let slot = patch.binary_search(&v).expect("patch holds the vertex");
                    h[slot] += w * g[corner];
                }
            }
            let scale = kn / np.volume(n);
            let pairs = &nodal.pair_offsets[nodal.pair_start[n] as usize..];
            let m = &mut self.matrix;
            let p = patch.len();
            for (a, &va) in patch.iter().enumerate() {
                for i in 0..2 {
                    let row = 2 * va as usize + i;
                    let start = m.row_offsets[row];
                    for (b, hb) in h.iter().enumerate() {
                        let o = start + pairs[a * p + b] as usize;
                        m.values[o] += scale * h[a][i] * hb.x;
                        m.values[o + 1] += scale * h[a][i] * hb.y;
                    }
                }
            }
        }
    }
}

/// The stiffness pattern's extra data for the nodal terms: each node's patch and, for each
/// ordered pair of its patch vertices, the column offset within the first's rows.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NodalPattern {
    pub patch_offsets: Vec<u32>,
    pub patch_vertices: Vec<u32>,
    pub pair_start: Vec<u32>,
    pub pair_offsets: Vec<u32>,
}

impl NodalPattern {
    /// For `np` on `mesh`, with `neighbours` the pattern's column vertices of each vertex.
    pub(crate) fn new(np: &NodalPressure, mesh: &Mesh, neighbours: &[Vec<u32>]) -> Self {
        let (mut patch_offsets, mut patch_vertices) = (vec![0u32], Vec::new());
        let (mut pair_start, mut pair_offsets) = (Vec::new(), Vec::new());
        let mut patch = Vec::new();
        for n in 0..np.n_nodes() {
            np.patch(mesh, n, &mut patch);
            pair_start.push(pair_offsets.len() as u32);
            for &a in &patch {
                let list = &neighbours[a as usize];
                for &b in &patch {
                    let pos = list.binary_search(&b).expect("the stencil holds the patch");
                    pair_offsets.push(2 * pos as u32);
                }
            }
            patch_vertices.extend_from_slice(&patch);
            patch_offsets.push(patch_vertices.len() as u32);
        }
        NodalPattern {
            patch_offsets,
            patch_vertices,
            pair_start,
            pair_offsets,
        }
    }
}

/// The stress shift of every element under the formulation, Pa (see
/// [`PressureFields::correction`]), at positions `x`; allocates (a per-frame output, not a
/// solver's inner loop).
pub fn stress_correction<M: EnergyOf>(
    np: &NodalPressure,
    mesh: &Mesh,
    energy: &M,
    x: &[Vec2],
) -> Vec<Real> {
    let mut fields = PressureFields::new();
    fields.update(np, mesh, energy, x);
    fields.corr
}
