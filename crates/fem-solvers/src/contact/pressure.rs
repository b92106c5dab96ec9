//! The normal contact traction (pressure) on the soft body's boundary, from the contact
//! records of a step ([`crate::Stepper::contacts`]).
//!
//! **Definition.** Every contact gives its normal force `F` (N per metre of thickness) to
//! boundary vertices as consistent nodal forces: a vertex contact (ground or obstacle edge) all
//! of it to its vertex; a corner-on-edge contact at the edge point `p = (1 - t) x_a + t x_b`
//! (`t` from the record's point, clamped to `[0, 1]`) `(1 - t) F` to `a` and `t F` to `b`. A
//! vertex's nodal force `F_v` is the sum of what it receives. Its tributary length `l_v` is
//! half the length of each boundary edge it belongs to, in the current configuration, and its
//! pressure is `p_v = F_v / l_v` (Pa). Along each boundary edge the pressure is linear between
//! the values at its two ends, so the boundary carries a piecewise-linear pressure, 0 off
//! contact.
//!
//! **Exact integral.** The trapezoidal integral of that pressure along the boundary,
//! `sum over edges |e| (p_a + p_b) / 2`, is `sum over vertices p_v l_v = sum F_v`: it equals the
//! total normal contact force exactly (to round-off), whatever the mesh and the contacts.
//! [`ContactPressure::integral`] evaluates it edge by edge.
//!
//! The summary numbers: the peak vertex pressure and its vertex's position, the contact length
//! (the sum of the tributary lengths of the loaded vertices, those with `F_v > 0`) and the mean
//! pressure (total force over contact length).
//!
//! The pressure is a boundary measure of the contact forces the solver computed: a solver's
//! contact forces (penalty, projection, barrier; see the [`crate::contact`] module) determine
//! it. Under penalty contact a vertex in contact carries the force of its penetration, so the
//! pressure is exact in the integral and the nodal sense, not pointwise.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use super::{Contact, ContactKind};
use crate::model::Model;

/// The largest vertex pressure of a [`ContactPressure`] and where it acts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeakPressure {
    /// The boundary vertex.
    pub vertex: u32,
    /// Its pressure, Pa.
    pub pressure: Real,
    /// Its position (current configuration), m.
    pub position: Vec2,
}

/// The contact pressure on the body's boundary, recomputed by [`ContactPressure::update`] from
/// a step's contacts. Buffers are sized on the first call for a model and reused: later calls
/// do not allocate. See the module documentation for the definition.
#[derive(Clone, Debug, Default)]
pub struct ContactPressure {
    /// Nodal normal force per mesh vertex, N/m.
    force: Vec<Real>,
    /// Tributary boundary length per mesh vertex, m (0 off the boundary).
    length: Vec<Real>,
    /// Pressure per mesh vertex, Pa (0 off contact).
    pressure: Vec<Real>,
    /// Length of each boundary edge, m.
    edge_length: Vec<Real>,
    /// Pressure at the two ends of each boundary edge, Pa.
    edge_pressure: Vec<[Real; 2]>,
    /// The loaded vertices (`F_v > 0`), ascending.
    loaded: Vec<u32>,
    total: Real,
    contact_length: Real,
    peak: Option<PeakPressure>,
}

impl ContactPressure {
    /// An empty pressure (no contact); buffers come with the first [`ContactPressure::update`].
    pub fn new() -> Self {
        Self::default()
    }

    /// Recompute from the `contacts` of a step of `model` at positions `x` (the state after
    /// the step). Does not allocate once the buffers have the model's sizes.
    pub fn update<E: Energy>(&mut self, model: &Model<E>, x: &[Vec2], contacts: &[Contact]) {
        self.update_parts(model.boundary_edges(), x, contacts);
    }

    /// [`ContactPressure::update`] from the parts it reads: the boundary edges (counter-clockwise,
    /// as [`Model::boundary_edges`]) and the positions.
    pub fn update_parts(&mut self, edges: &[[u32; 2]], x: &[Vec2], contacts: &[Contact]) {
        let n = x.len();
        for buf in [&mut self.force, &mut self.length, &mut self.pressure] {
            buf.clear();
            buf.resize(n, 0.0);
        }
        self.edge_length.clear();
        for &[a, b] in edges {
            let l = (x[b as usize] - x[a as usize]).norm();
            self.edge_length.push(l);
            self.length[a as usize] += 0.5 * l;
            self.length[b as usize] += 0.5 * l;
        }
        self.total = 0.0;
        for c in contacts {
            self.total += c.force;
            match c.kind {
                ContactKind::VertexGround { vertex }
                | ContactKind::VertexObstacle { vertex, .. } => {
                    self.force[vertex as usize] += c.force;
                }
                ContactKind::CornerEdge { edge: [a, b], .. } => {
                    let (xa, xb) = (x[a as usize], x[b as usize]);
                    let e = xb - xa;
                    let ee = e.norm_squared();
                    let t = if ee > 0.0 {
                        ((c.point - xa).dot(&e) / ee).clamp(0.0, 1.0)
                    } else {
                        0.5
                    };
                    self.force[a as usize] += (1.0 - t) * c.force;
                    self.force[b as usize] += t * c.force;
                }
            }
        }
        self.loaded.clear();
        self.contact_length = 0.0;
        self.peak = None;
        for (v, (&xv, (&f, &l))) in x
            .iter()
            .zip(self.force.iter().zip(&self.length))
            .enumerate()
        {
            if f > 0.0 && l > 0.0 {
                let p = f / l;
                self.pressure[v] = p;
                self.loaded.push(v as u32);
                self.contact_length += l;
                if self.peak.is_none_or(|pk| p > pk.pressure) {
                    self.peak = Some(PeakPressure {
                        vertex: v as u32,
                        pressure: p,
                        position: xv,
                    });
                }
            }
        }
        self.edge_pressure.clear();
        self.edge_pressure.extend(
            edges
                .iter()
                .map(|&[a, b]| [self.pressure[a as usize], self.pressure[b as usize]]),
        );
    }

    /// Pressure per mesh vertex, Pa (0 off contact and off the boundary).
    pub fn vertex_pressure(&self) -> &[Real] {
        &self.pressure
    }

    /// Nodal normal contact force per mesh vertex, N per metre of thickness.
    pub fn nodal_force(&self) -> &[Real] {
        &self.force
    }

    /// Tributary boundary length per mesh vertex, m (0 off the boundary).
    pub fn tributary_length(&self) -> &[Real] {
        &self.length
    }

    /// Pressure at the two ends of each boundary edge, Pa, in the order of the boundary edges
    /// given to the last update (linear in between).
    pub fn edge_pressure(&self) -> &[[Real; 2]] {
        &self.edge_pressure
    }

    /// The loaded boundary vertices (nodal force > 0), ascending.
    pub fn loaded_vertices(&self) -> &[u32] {
        &self.loaded
    }

    /// The total normal contact force, N per metre of thickness: the sum of the contacts'
    /// forces.
    pub fn total_force(&self) -> Real {
        self.total
    }

    /// The contact length, m: the sum of the loaded vertices' tributary lengths.
    pub fn contact_length(&self) -> Real {
        self.contact_length
    }

    /// The mean pressure, Pa: total force over contact length (0 without contact).
    pub fn mean_pressure(&self) -> Real {
        if self.contact_length > 0.0 {
            self.total / self.contact_length
        } else {
            0.0
        }
    }

    /// The largest vertex pressure and where it acts; `None` without contact. On a tie, the
    /// lowest vertex index.
    pub fn peak(&self) -> Option<PeakPressure> {
        self.peak
    }

    /// The trapezoidal integral of the piecewise-linear pressure along the boundary,
    /// `sum over edges |e| (p_a + p_b) / 2`, N per metre of thickness: the total normal contact
    /// force (see the module documentation).
    pub fn integral(&self) -> Real {
        self.edge_length
            .iter()
            .zip(&self.edge_pressure)
            .map(|(l, [pa, pb])| l * 0.5 * (pa + pb))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(kind: ContactKind, point: Vec2, force: Real) -> Contact {
        Contact {
            kind,
            point,
            normal: Vec2::new(0.0, 1.0),
            gap: 1e-4,
            force,
        }
    }

    /// A unit square (0,0)-(1,0)-(1,1)-(0,1) with a mid-bottom vertex 4 at (0.4, 0): boundary
    /// 0-4-1-2-3 counter-clockwise.
    fn square() -> (Vec<[u32; 2]>, Vec<Vec2>) {
        let x = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(0.4, 0.0),
            Vec2::new(0.5, 0.5),
        ];
        (vec![[0, 4], [4, 1], [1, 2], [2, 3], [3, 0]], x)
    }

    #[test]
    fn vertex_and_corner_edge_forces_integrate_to_their_sum() {
        let (edges, x) = square();
        let contacts = [
            contact(ContactKind::VertexGround { vertex: 0 }, x[0], 3.0),
            contact(
                ContactKind::VertexObstacle {
                    vertex: 4,
                    obstacle: 0,
                    edge: 1,
                },
                x[4],
                5.0,
            ),
            // A corner on edge 1-2 at t = 0.25, and one on 4-1 at t = 0.5.
            contact(
                ContactKind::CornerEdge {
                    obstacle: 1,
                    corner: 2,
                    edge: [1, 2],
                },
                Vec2::new(1.0, 0.25),
                7.0,
            ),
            contact(
                ContactKind::CornerEdge {
                    obstacle: 1,
                    corner: 0,
                    edge: [4, 1],
                },
                Vec2::new(0.7, 0.0),
                2.0,
            ),
        ];
        let mut p = ContactPressure::new();
        p.update_parts(&edges, &x, &contacts);
        // Nodal forces: 0 gets 3, 4 gets 5 + 0.5 * 2, 1 gets 0.75 * 7 + 0.5 * 2, 2 gets 0.25 * 7.
        let f = p.nodal_force();
        assert_eq!(f[0], 3.0);
        assert_eq!(f[4], 6.0);
        assert!((f[1] - 6.25).abs() < 1e-15 && (f[2] - 1.75).abs() < 1e-15);
        assert_eq!(f[3] + f[5], 0.0);
        // Tributary lengths: 0: (0.4 + 1) / 2, 4: (0.4 + 0.6) / 2, 1: (0.6 + 1) / 2, 2: 1.
        let l = p.tributary_length();
        assert!((l[0] - 0.7).abs() < 1e-15 && (l[4] - 0.5).abs() < 1e-15);
        assert!((l[1] - 0.8).abs() < 1e-15 && (l[2] - 1.0).abs() < 1e-15);
        assert_eq!(l[5], 0.0);
        assert_eq!(p.loaded_vertices(), &[0, 1, 2, 4]);
        assert_eq!(p.total_force(), 17.0);
        // The exact-integral property, to round-off.
        assert!(
            (p.integral() - 17.0).abs() < 1e-13,
            "integral {} N/m, forces 17 N/m",
            p.integral()
        );
        assert!((p.contact_length() - 3.0).abs() < 1e-15);
        assert!((p.mean_pressure() - 17.0 / 3.0).abs() < 1e-14);
        let peak = p.peak().unwrap();
        assert_eq!((peak.vertex, peak.position), (4, x[4]));
        assert!((peak.pressure - 12.0).abs() < 1e-14);
        assert_eq!(p.edge_pressure()[2], [6.25 / 0.8, 1.75]);
        // Without contact: all zero, no peak.
        p.update_parts(&edges, &x, &[]);
        assert!(p.vertex_pressure().iter().all(|&v| v == 0.0));
        assert!(p.peak().is_none() && p.integral() == 0.0 && p.mean_pressure() == 0.0);
    }

    #[test]
    fn a_deformed_boundary_keeps_the_exact_integral() {
        // Irregular positions (current configuration) and many corner contacts along the
        // boundary: the integral still equals the sum, to round-off.
        let (edges, mut x) = square();
        x[2] = Vec2::new(1.3, 0.9);
        x[4] = Vec2::new(0.35, -0.05);
        let mut contacts = Vec::new();
        for (k, &[a, b]) in edges.iter().enumerate() {
            let t = (k as Real + 0.5) / 7.0;
            let point = x[a as usize] * (1.0 - t) + x[b as usize] * t;
            let kind = ContactKind::CornerEdge {
                obstacle: 0,
                corner: k as u32,
                edge: [a, b],
            };
            contacts.push(contact(kind, point, 1.0 + k as Real));
        }
        let mut p = ContactPressure::new();
        p.update_parts(&edges, &x, &contacts);
        let sum: Real = contacts.iter().map(|c| c.force).sum();
        assert!((p.integral() - sum).abs() < 1e-13 * sum, "{}", p.integral());
        // A moved corner splits differently, but the integral does not change.
        assert_eq!(p.total_force(), sum);
    }
}
