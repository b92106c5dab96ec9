//! Energy diagnostics on demand: kinetic, elastic and gravitational energy of a state.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};

use crate::kernel;
use crate::model::Model;
use crate::model::state::State;
use crate::rigid::ObstacleMotion;

/// Energies of a state, J per unit thickness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energies {
    /// `1/2 sum m |v|^2` over vertices plus the kinetic energy of dynamic rigid bodies; a
    /// free rigid region's vertices count by their body's `M |v|^2 / 2 + I omega^2 / 2`.
    pub kinetic: Real,
    /// `sum_e a_e psi(F_e)`.
    pub elastic: Real,
    /// `-sum m g . (x - X)` over vertices (zero in the rest configuration) plus the same for
    /// dynamic rigid bodies' centroids (zero at their initial pose).
    pub gravitational: Real,
}

impl Energies {
    /// Kinetic + elastic + gravitational.
    pub fn total(&self) -> Real {
        self.kinetic + self.elastic + self.gravitational
    }
}

/// Reusable buffer for [`energies`] (one per-element energy array).
#[derive(Clone, Debug, Default)]
pub struct EnergyScratch {
    element: Vec<Real>,
    /// The averaged nodal pressure triangle's buffers.
    core: fem_core::assembly::Scratch,
}

/// The energies of `state`. Element energies are evaluated on the current rayon pool and
/// summed in element order, so the result does not depend on the thread count.
pub fn energies<E: Energy>(
    model: &Model<E>,
    state: &State,
    scratch: &mut EnergyScratch,
) -> Energies {
    let g = model.gravity();
    let mut kinetic = 0.0;
    let mut gravitational = 0.0;
    for (i, ((m, v), (x, x0))) in model
        .masses()
        .iter()
        .zip(&state.v)
        .zip(state.x.iter().zip(model.mesh().vertices()))
        .enumerate()
    {
        if model
            .rigid_body_of(i)
            .is_none_or(|b| !model.rigid_bodies()[b].is_free())
        {
            kinetic += 0.5 * m * v.norm_squared();
        }
        gravitational -= m * g.dot(&(x - x0));
    }
    for (body, b) in model.rigid_bodies().iter().zip(&state.rigid) {
        if body.is_free() {
            kinetic += 0.5 * body.mass * b.velocity.norm_squared()
                + 0.5 * body.inertia * b.angular_velocity * b.angular_velocity;
        }
    }
    for (obs, body) in model.obstacles().iter().zip(&state.bodies) {
        if let ObstacleMotion::Dynamic { mass, .. } = obs.motion() {
            kinetic += 0.5 * mass * body.velocity.norm_squared()
                + 0.5 * obs.inertia() * body.angular_velocity * body.angular_velocity;
            let d: Vec2 = body.position - obs.initial_centroid();
            gravitational -= mass * g.dot(&d);
        }
    }
    let elastic = if model.uses_averaged_pressure() {
        fem_core::assembly::elastic_energy(
            model.elastic_mesh(),
            model.elastic_energies(),
            &state.x,
            &mut scratch.core,
        )
    } else {
        kernel::elastic_energy(
            model.energies(),
            &model.elements,
            &state.x,
            &mut scratch.element,
        )
    };
    Energies {
        kinetic,
        elastic,
        gravitational,
    }
}

/// The load the soft tissue puts on each rigid body of the rigid regions at `state`: the
/// elastic forces of the deformable triangles on the body's vertices, summed (N per unit
/// thickness), and their torque about the body's centroid (N m per unit thickness). This is
/// the load a fracture assessment of the bone starts from. `forces` is a buffer (one force per
/// vertex, resized here).
pub fn rigid_loads<E: Energy>(
    model: &Model<E>,
    state: &State,
    forces: &mut Vec<Vec2>,
    scratch: &mut fem_core::assembly::Scratch,
) -> Vec<(Vec2, Real)> {
    if model.rigid_bodies().is_empty() {
        return Vec::new();
    }
    forces.resize(state.x.len(), Vec2::zeros());
    fem_core::assembly::populate_forces(
        model.elastic_mesh(),
        model.elastic_energies(),
        &state.x,
        forces,
        scratch,
    );
    (model.rigid_bodies().iter().zip(&state.rigid))
        .map(|(body, b)| body.wrench(b, &state.x, forces))
        .collect()
}
