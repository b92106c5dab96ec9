//! The drag attachment: a hand (a pointer, a haptic device) holding the body at a point and
//! pulling it toward a target, honoured by every stepper.
//!
//! A [`Grab`] names an **anchor**: one vertex with weight 1, or the vertices of the triangle
//! under the pointer weighted by the hit point's barycentric coordinates (any set of vertices
//! with non-negative weights; they are normalised to sum to 1). When the grab starts
//! ([`Model::grab`](crate::Model::grab)) the anchor point is `p0 = sum w_i x_i` at the current
//! positions, and each anchor vertex keeps its offset `o_i = x_i - p0`; its **goal** is then
//! `target + o_i`, so the patch is carried rigidly and a target left at `p0` pulls nothing.
//! Vertices that are already kinematic (pinned or moved on a schedule) leave the anchor.
//!
//! Two models:
//! - [`GrabModel::Pin`]: the anchor vertices become kinematic; over each step they move along a
//!   straight line at constant speed and land on their goals at the step's end. The force the
//!   hand exerts ([`Model::grab_force`](crate::Model::grab_force)) is the quasi-static reaction:
//!   the elastic forces on the held vertices minus their weight and nodal loads (their inertia
//!   is left out).
//! - [`GrabModel::Spring`] with stiffness `k` (N/m per unit thickness): a zero-length spring
//!   from each anchor vertex to its goal, of stiffness `w_i k`, the energy
//!   `sum_i w_i k / 2 |x_i - target - o_i|^2`. The springs' total force on the body is exactly
//!   `k (target - sum w_i x_i)` (the offsets sum to zero with the weights), the force a haptic
//!   device would render; it is what [`Model::grab_force`](crate::Model::grab_force) returns.
//!   Each spring is a term of every stepper's equations: a nodal force in explicit FEM, a term
//!   of the incremental potential (value, gradient, Hessian) in implicit Euler, the static
//!   solver and quasi-Newton, of each vertex's local potential in Vertex Block Descent, a
//!   quadratic term of the global matrix in Projective Dynamics, and a compliant constraint
//!   (compliance `1 / (w_i k)`, with its own multiplier) in PBD and XPBD.
//!
//! Moving the target ([`Model::move_grab`](crate::Model::move_grab)) changes goals only;
//! starting or ending a grab changes the model's [layout](crate::Model::layout), and steppers
//! that precompute from it (a factorisation, a colouring, the free degrees of freedom) redo
//! that work at their next step.

use fem_core::math::{Real, Vec2};

use crate::error::{SolverError, check_finite_vec};

/// How a grab holds the body.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum GrabModel {
    /// The anchor vertices are kinematic and follow the target rigidly.
    Pin,
    /// Zero-length springs pull the anchor vertices toward the target.
    Spring {
        /// Total stiffness, N/m per unit thickness (finite, > 0), shared by the anchor
        /// vertices in proportion to their weights.
        stiffness: Real,
    },
}

/// A hand holding the body: which point, where it pulls, how (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Grab {
    /// Anchor vertices and their weights (finite, >= 0, not all zero; normalised to sum 1).
    pub anchor: Vec<(usize, Real)>,
    /// Where the hand holds the anchor point, m.
    pub target: Vec2,
    /// Pin or spring.
    pub model: GrabModel,
}

impl Grab {
    /// A grab of the single vertex `vertex`, with the target at `target`.
    pub fn vertex(vertex: usize, target: Vec2, model: GrabModel) -> Self {
        Grab {
            anchor: vec![(vertex, 1.0)],
            target,
            model,
        }
    }
}

/// One anchor vertex of an active grab.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Anchor {
    pub vertex: u32,
    /// Normalised weight.
    pub weight: Real,
    /// Offset from the anchor point when the grab started, m.
    pub offset: Vec2,
}

/// A zero-length spring of a spring grab: `stiffness / 2 |x_vertex - goal|^2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Spring {
    pub vertex: u32,
    pub stiffness: Real,
    pub goal: Vec2,
}

/// An active grab, resolved against the mesh.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ActiveGrab {
    /// Sorted by vertex.
    pub anchors: Vec<Anchor>,
    pub target: Vec2,
    pub model: GrabModel,
    /// The springs of a spring grab (sorted by vertex; empty for a pin).
    pub springs: Vec<Spring>,
}

impl ActiveGrab {
    /// Validate `grab` against a mesh of `n` vertices with the kinematic flags `kinematic`
    /// and resolve it at positions `x`.
    pub(crate) fn new(grab: &Grab, x: &[Vec2], kinematic: &[bool]) -> Result<Self, SolverError> {
        check_finite_vec("grab.target", grab.target)?;
        if let GrabModel::Spring { stiffness } = grab.model
            && !(stiffness.is_finite() && stiffness > 0.0)
        {
            return Err(SolverError::invalid(
                "grab.stiffness",
                stiffness,
                "must be a finite number > 0 (N/m)",
            ));
        }
        if grab.anchor.is_empty() {
            return Err(SolverError::invalid(
                "grab.anchor",
                "[]",
                "must name at least one vertex",
            ));
        }
        let mut anchors: Vec<Anchor> = Vec::with_capacity(grab.anchor.len());
        for (i, &(v, w)) in grab.anchor.iter().enumerate() {
            if v >= x.len() {
                return Err(SolverError::VertexOutOfRange {
                    field: format!("grab.anchor[{i}]"),
                    index: v,
                    n_vertices: x.len(),
                });
            }
            if !(w.is_finite() && w >= 0.0) {
                return Err(SolverError::invalid(
                    format!("grab.anchor[{i}].weight"),
                    w,
                    "must be a finite number >= 0",
                ));
            }
            if kinematic[v] || w == 0.0 {
                continue;
            }
            match anchors.iter_mut().find(|a| a.vertex as usize == v) {
                Some(a) => a.weight += w,
                None => anchors.push(Anchor {
                    vertex: v as u32,
                    weight: w,
                    offset: Vec2::zeros(),
                }),
            }
        }
        let total: Real = anchors.iter().map(|a| a.weight).sum();
        // Weights are finite and >= 0, so the total is too.
        if anchors.is_empty() || total <= 0.0 {
            return Err(SolverError::invalid(
                "grab.anchor",
                format!("{} vertices", grab.anchor.len()),
                "holds no free vertex with a weight > 0 (pinned and moved vertices cannot be grabbed)",
            ));
        }
        anchors.sort_by_key(|a| a.vertex);
        let mut p0 = Vec2::zeros();
        for a in &mut anchors {
            a.weight /= total;
            p0 += x[a.vertex as usize] * a.weight;
        }
        for a in &mut anchors {
            a.offset = x[a.vertex as usize] - p0;
        }
        let mut active = ActiveGrab {
            anchors,
            target: grab.target,
            model: grab.model,
            springs: Vec::new(),
        };
        active.refresh_springs();
        Ok(active)
    }

    /// The goal of anchor `a`, m.
    pub(crate) fn goal(&self, a: &Anchor) -> Vec2 {
        self.target + a.offset
    }

    /// Move the target (goals follow).
    pub(crate) fn move_to(&mut self, target: Vec2) {
        self.target = target;
        self.refresh_springs();
    }

    fn refresh_springs(&mut self) {
        self.springs.clear();
        if let GrabModel::Spring { stiffness } = self.model {
            for a in &self.anchors {
                self.springs.push(Spring {
                    vertex: a.vertex,
                    stiffness: stiffness * a.weight,
                    goal: self.goal(a),
                });
            }
        }
    }

    /// The anchor point `sum w_i x_i` at positions `x`, m.
    pub(crate) fn point(&self, x: &[Vec2]) -> Vec2 {
        self.anchors
            .iter()
            .fold(Vec2::zeros(), |p, a| p + x[a.vertex as usize] * a.weight)
    }
}

/// The springs' energy `sum k/2 |x - goal|^2` at `x`, J per unit thickness.
pub(crate) fn spring_energy(springs: &[Spring], x: &[Vec2]) -> Real {
    springs
        .iter()
        .map(|s| 0.5 * s.stiffness * (x[s.vertex as usize] - s.goal).norm_squared())
        .sum()
}

/// The spring on vertex `v`, if any (`springs` sorted by vertex, a handful long).
#[inline]
pub(crate) fn spring_of(springs: &[Spring], v: usize) -> Option<&Spring> {
    if springs.is_empty() {
        return None;
    }
    springs
        .binary_search_by_key(&(v as u32), |s| s.vertex)
        .ok()
        .map(|k| &springs[k])
}
