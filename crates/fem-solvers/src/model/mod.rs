//! The model: everything about a simulation that does not change while it runs (mesh, energy,
//! lumped masses, boundary conditions, loads, obstacles), plus the stability guard.
//!
//! A model is built once and then passed by shared reference to a stepper's `step`, together
//! with a mutable [`State`](crate::State). Every setter takes `&mut self` and returns
//! `&mut Self`, so calls chain (`model.set_standard_gravity().pin(&left)?.pin(&right)?`);
//! one that validates its input returns it in a `Result` whose error is a one-line
//! [`SolverError`] naming the field and the value. [`Model::add_obstacle`] alone returns the
//! new obstacle's index, by which the state refers to it. Between steps a model may change:
//! a drag attachment ([`Model::grab`], [`Model::move_grab`], [`Model::release`]) or a new
//! boundary condition or obstacle. Each structural change gives the model a new
//! [`Model::layout`]; a stepper that precomputed something from the old one (a factorisation,
//! a colouring, the free degrees of freedom) redoes it at its next step.
//!
//! Beside the model, this folder holds what it is made of and what every solver reads with it:
//! the [`state`], boundary conditions ([`bc`]), the drag attachment ([`grab`]), the contact
//! parameters ([`contact_params`]), the bounds on every count a solver takes ([`limits`]) and
//! energy [`diagnostics`]. It knows no contact algorithm and no stepper.

use std::sync::atomic::{AtomicU64, Ordering};

use fem_core::energy::{ElementEnergies, Energy, EnergyOf};
use fem_core::math::{Mat2, Mat6, Real, Vec2, exp, ln_1p};
use fem_core::mesh::Mesh;
use fem_core::simd::Isa;
use nalgebra::SymmetricEigen;

pub mod bc;
pub mod contact_params;
pub mod diagnostics;
pub mod grab;
pub mod limits;
pub mod state;

use self::bc::{Kinematics, Motion, PrescribedMotion, Region};
use self::contact_params::ContactParams;
use self::grab::{ActiveGrab, Grab, GrabModel, Spring};
use crate::error::{SolverError, check_finite_vec, check_positive};
use crate::kernel::{
    ElementBlock, PackedElement, corner_gradient, deformation_gradient, pack, pack_blocks,
};
use crate::rigid::body::build_bodies;
use crate::rigid::{BodyMotion, Ground, Obstacle, ObstacleMotion, RigidBody};

/// A new layout identifier, unique in the process.
fn fresh_layout() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// Standard gravity used by [`Model::set_standard_gravity`], m/s^2 (the paper's cases use 9.8).
pub const STANDARD_GRAVITY: Real = 9.8;

/// Mesh, energy, masses, boundary conditions, loads and obstacles of one simulation.
///
/// Generic over the energy: steppers monomorphise their kernels for `E`; the model never
/// names a concrete energy.
#[derive(Clone, Debug)]
pub struct Model<E: Energy> {
    mesh: Mesh,
    /// The energy of each element (one per region; a homogeneous body has one).
    energies: ElementEnergies<E>,
    masses: Vec<Real>,
    inv_masses: Vec<Real>,
    /// Pinned and scheduled vertices (the boundary conditions).
    base: Kinematics,
    /// `base` plus the vertices a pinning grab holds.
    kinematics: Kinematics,
    grab: Option<ActiveGrab>,
    layout: u64,
    gravity: Vec2,
    external_forces: Vec<(u32, Vec2)>,
    tractions: usize,
    ground: Option<Ground>,
    obstacles: Vec<Obstacle>,
    contact: ContactParams,
    pub(crate) elements: Vec<PackedElement>,
    /// The same elements in blocks for the batched force kernel (triangle order).
    pub(crate) blocks: Vec<ElementBlock>,
    /// The instruction set the batched force kernel runs under.
    isa: Isa,
    modulus: Real,
    /// The mesh's boundary edges (counter-clockwise: the body lies to the left of `a -> b`).
    boundary: Vec<[u32; 2]>,
    /// The vertices of the boundary edges, sorted.
    boundary_vertices: Vec<u32>,
    /// The rigid regions: `(region tag, density kg/m^3)`, in the order they were declared.
    rigid_regions: Vec<(u32, Real)>,
    /// The rigid bodies of the rigid regions (see [`crate::rigid::body`]).
    bodies: Vec<RigidBody>,
    /// The body each vertex is slaved to (`u32::MAX`: none).
    slave: Vec<u32>,
    /// With rigid regions: the mesh of the deformable triangles only (every vertex kept) and
    /// their energies; `None` when every triangle is deformable.
    elastic: Option<(Mesh, ElementEnergies<E>)>,
}

impl<E: Energy> Model<E> {
    /// A model with the given lumped vertex masses (kg per unit thickness, one per vertex,
    /// finite and > 0), no gravity, no boundary conditions and no obstacles.
    pub fn new(mesh: Mesh, energy: E, masses: Vec<Real>) -> Result<Self, SolverError> {
        Self::with_regions(mesh, ElementEnergies::uniform(energy), masses)
    }

    /// A model whose elements have their own energies (one per region, see
    /// [`ElementEnergies`]: a bone inside soft tissue), with the given lumped vertex masses
    /// ([`Mesh::lumped_masses_from_densities`] spreads per-element densities).
    pub fn with_regions(
        mesh: Mesh,
        energies: ElementEnergies<E>,
        masses: Vec<Real>,
    ) -> Result<Self, SolverError> {
        if let Err(message) = energies.check_len(mesh.n_triangles()) {
            return Err(SolverError::invalid(
                "regions",
                message,
                "need one tag per triangle",
            ));
        }
        if masses.len() != mesh.n_vertices() {
            return Err(SolverError::invalid(
                "masses.len()",
                masses.len(),
                "must equal the number of mesh vertices",
            ));
        }
        if let Some(i) = masses.iter().position(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(SolverError::invalid(
                format!("masses[{i}]"),
                masses[i],
                "must be a finite number > 0 (kg)",
            ));
        }
        let inv_masses = masses.iter().map(|m| 1.0 / m).collect();
        // P-wave modulus of the linearised energy: d^2 psi / d F00^2 at F = I (lambda + 2 mu
        // for every isotropic energy that linearises to linear elasticity), of every region.
        for (k, energy) in energies.energies().iter().enumerate() {
            let m = energy.dpk1(&Mat2::identity())[(0, 0)];
            if !(m.is_finite() && m > 0.0) {
                let field = if k == 0 {
                    "energy".to_string()
                } else {
                    format!("regions[{k}]")
                };
                return Err(SolverError::invalid(
                    field,
                    format!("{} (stiffness at rest {m:e} Pa)", energy.name()),
                    "must have a finite stiffness > 0 at rest: check youngs_modulus and poisson_ratio",
                ));
            }
        }
        let modulus = energies.base().dpk1(&Mat2::identity())[(0, 0)];
        let elements = pack(&mesh, energies.tags());
        let boundary = boundary_edges(mesh.triangles());
        let mut boundary_vertices: Vec<u32> = boundary.iter().flatten().copied().collect();
        boundary_vertices.sort_unstable();
        boundary_vertices.dedup();
        Ok(Model {
            boundary,
            boundary_vertices,
            blocks: pack_blocks(&elements),
            isa: Isa::detected(),
            elements,
            mesh,
            energies,
            masses,
            inv_masses,
            base: Kinematics::default(),
            kinematics: Kinematics::default(),
            grab: None,
            layout: fresh_layout(),
            gravity: Vec2::zeros(),
            external_forces: Vec::new(),
            tractions: 0,
            ground: None,
            obstacles: Vec::new(),
            contact: ContactParams::default(),
            modulus,
            rigid_regions: Vec::new(),
            bodies: Vec::new(),
            slave: Vec::new(),
            elastic: None,
        })
    }

    /// Masses from a total mass (kg per unit thickness) spread with uniform density.
    pub fn with_total_mass(mesh: Mesh, energy: E, total_mass: Real) -> Result<Self, SolverError> {
        check_positive("total_mass", total_mass)?;
        let m = mesh
            .lumped_masses_from_total_mass(total_mass)
            .map_err(|_| {
                SolverError::invalid("total_mass", total_mass, "must be a finite number > 0 (kg)")
            })?;
        Self::new(mesh, energy, m)
    }

    /// Masses from a density (kg/m^3 with unit thickness).
    pub fn with_density(mesh: Mesh, energy: E, density: Real) -> Result<Self, SolverError> {
        check_positive("density", density)?;
        let m = mesh.lumped_masses_from_density(density).map_err(|_| {
            SolverError::invalid("density", density, "must be a finite number > 0 (kg/m^3)")
        })?;
        Self::new(mesh, energy, m)
    }

    /// Set the gravitational acceleration (m/s^2, a vector; `[0, -9.8]` points down).
    pub fn set_gravity(&mut self, g: Vec2) -> Result<&mut Self, SolverError> {
        check_finite_vec("gravity", g)?;
        self.gravity = g;
        Ok(self)
    }

    /// Gravity `[0, -9.8]` m/s^2.
    pub fn set_standard_gravity(&mut self) -> &mut Self {
        self.gravity = Vec2::new(0.0, -STANDARD_GRAVITY);
        self
    }

    /// Make the triangles of region `region` (a tag of [`Model::energies`]) rigid, with density
    /// `density` (kg/m^3): each connected component of the rigid triangles becomes one rigid
    /// body that carries the vertices of its triangles (see [`crate::rigid::body`]). Its
    /// triangles leave the elastic mesh ([`Model::elastic_mesh`]): they carry no energy and no
    /// stress. Components of different rigid regions that share a vertex are one body. Fails
    /// when the region does not exist, the density is not a finite number > 0, or no
    /// deformable triangle would be left. Changes the layout.
    pub fn make_rigid(&mut self, region: usize, density: Real) -> Result<&mut Self, SolverError> {
        let field = format!("regions[{region}].rigid");
        if region >= self.energies.n_regions() {
            return Err(SolverError::invalid(
                field,
                region,
                format!(
                    "no such region (the model has {})",
                    self.energies.n_regions()
                ),
            ));
        }
        check_positive(&format!("regions[{region}].density"), density)?;
        let tag = region as u32;
        match self.rigid_regions.iter_mut().find(|(t, _)| *t == tag) {
            Some(r) => r.1 = density,
            None => self.rigid_regions.push((tag, density)),
        }
        let n = self.mesh.n_triangles();
        let tags: Vec<u32> = (0..n).map(|t| self.energies.tag(t)).collect();
        let density_of = |t: usize| {
            (self.rigid_regions.iter())
                .find(|(r, _)| *r == tags[t])
                .map_or(0.0, |r| r.1)
        };
        let rigid: Vec<bool> = (0..n).map(|t| density_of(t) > 0.0).collect();
        if rigid.iter().all(|&r| r) {
            self.rigid_regions.retain(|(t, _)| *t != tag);
            return Err(SolverError::invalid(
                field,
                true,
                "would make every triangle rigid: a body needs deformable triangles",
            ));
        }
        let (bodies, slave) = build_bodies(&self.mesh, &rigid, density_of, &tags, &self.masses);
        let keep: Vec<bool> = rigid.iter().map(|r| !r).collect();
        let elastic_mesh = self.mesh.restricted(&keep);
        let elastic_tags: Vec<u32> = (0..n).filter(|&t| keep[t]).map(|t| tags[t]).collect();
        let mut energies = ElementEnergies::new(self.energies.energies().to_vec(), elastic_tags)
            .map_err(|e| SolverError::invalid(field.clone(), true, e.to_string()))?;
        if self.uses_averaged_pressure() {
            energies = energies
                .with_nodal_pressure(&elastic_mesh)
                .map_err(|e| SolverError::invalid(field.clone(), true, e.to_string()))?;
        }
        self.elements = pack(&elastic_mesh, energies.tags());
        self.blocks = pack_blocks(&self.elements);
        self.elastic = Some((elastic_mesh, energies));
        self.bodies = bodies;
        self.slave = slave;
        self.refresh_kinematics();
        Ok(self)
    }

    /// Use the averaged nodal pressure triangle (`on`), a locking-free formulation of the
    /// linear triangle for nearly incompressible bodies ([`fem_core::nodal_pressure`]), or plain
    /// linear triangles. The nodes are those of the elastic mesh (rigid regions' triangles are
    /// not in it). Solvers that do not support it refuse the model when they are built (the
    /// capability table's `averaged pressure` column). Changes the layout.
    pub fn set_averaged_pressure(&mut self, on: bool) -> Result<&mut Self, SolverError> {
        let apply = |e: ElementEnergies<E>, mesh: &Mesh| {
            if on {
                e.with_nodal_pressure(mesh).map_err(|e| {
                    SolverError::invalid("formulation", "averaged-pressure", e.to_string())
                })
            } else {
                Ok(e.without_nodal_pressure())
            }
        };
        self.energies = apply(self.energies.clone(), &self.mesh)?;
        if let Some((mesh, energies)) = self.elastic.take() {
            let energies = apply(energies, &mesh)?;
            self.elastic = Some((mesh, energies));
        }
        self.layout = fresh_layout();
        Ok(self)
    }

    /// Whether the elements are averaged nodal pressure triangles
    /// ([`Model::set_averaged_pressure`]).
    pub fn uses_averaged_pressure(&self) -> bool {
        self.energies.nodal_pressure().is_some()
    }

    /// Pin the vertices of `region` (zero velocity for the whole run).
    pub fn pin(&mut self, region: &Region) -> Result<&mut Self, SolverError> {
        let list = region.select(self.mesh.vertices(), "pinned")?;
        self.base.assign(&list, Motion::Pinned);
        self.refresh_kinematics();
        Ok(self)
    }

    /// Move the vertices of `motion.region` on a schedule (see [`PrescribedMotion`]).
    pub fn add_prescribed_motion(
        &mut self,
        motion: PrescribedMotion,
    ) -> Result<&mut Self, SolverError> {
        let field = format!("prescribed_motion[{}]", self.base.motions.len());
        motion.validate(&field)?;
        let list = motion.region.select(self.mesh.vertices(), &field)?;
        let id = self.base.motions.len() as u32;
        self.base.motions.push(motion);
        self.base.assign(&list, Motion::Scheduled(id));
        self.refresh_kinematics();
        Ok(self)
    }

    /// Add a constant external nodal force (N per unit thickness) on `vertex`.
    pub fn add_external_force(
        &mut self,
        vertex: usize,
        force: Vec2,
    ) -> Result<&mut Self, SolverError> {
        let field = format!("external_forces[{}]", self.external_forces.len());
        if vertex >= self.mesh.n_vertices() {
            return Err(SolverError::VertexOutOfRange {
                field,
                index: vertex,
                n_vertices: self.mesh.n_vertices(),
            });
        }
        check_finite_vec(&field, force)?;
        self.external_forces.push((vertex as u32, force));
        Ok(self)
    }

    /// Add a uniform traction `traction` (force per unit boundary length per unit thickness,
    /// N/m^2 = Pa) on every boundary edge whose two end vertices lie in `region`, distributed
    /// consistently: an edge of length `L` gives `traction L / 2` to each end (exact for linear
    /// elements under a uniform traction). The nodal forces join the external forces. Fails
    /// when the region holds no boundary edge.
    pub fn add_traction(
        &mut self,
        region: &Region,
        traction: Vec2,
    ) -> Result<&mut Self, SolverError> {
        let field = format!("tractions[{}]", self.tractions);
        check_finite_vec(&field, traction)?;
        let inside = region.select(self.mesh.vertices(), &field)?;
        let mut member = vec![false; self.mesh.n_vertices()];
        for &v in &inside {
            member[v] = true;
        }
        let mut nodal = vec![Vec2::zeros(); self.mesh.n_vertices()];
        let x = self.mesh.vertices();
        let mut edges = 0;
        for [a, b] in boundary_edges(self.mesh.triangles()) {
            let (a, b) = (a as usize, b as usize);
            if member[a] && member[b] {
                let half = 0.5 * (x[b] - x[a]).norm() * traction;
                nodal[a] += half;
                nodal[b] += half;
                edges += 1;
            }
        }
        if edges == 0 {
            return Err(SolverError::invalid(
                field,
                format!("{} vertices", inside.len()),
                "the region contains no boundary edge (both end vertices inside)",
            ));
        }
        for (v, f) in nodal.iter().enumerate() {
            if *f != Vec2::zeros() {
                self.external_forces.push((v as u32, *f));
            }
        }
        self.tractions += 1;
        Ok(self)
    }

    /// Set (or, with `None`, remove) the ground half-space.
    ///
    /// Fails when a rest vertex lies below the ground (by more than `1e-9` times the mesh's
    /// size): the penalty would fling it out at the first step.
    pub fn set_ground(&mut self, ground: Option<Ground>) -> Result<&mut Self, SolverError> {
        let ground = ground.map(Ground::validated).transpose()?;
        if let Some(g) = &ground {
            let tol = 1e-9 * self.extent();
            let below = self
                .mesh
                .vertices()
                .iter()
                .enumerate()
                .map(|(v, p)| (v, (p - g.point).dot(&g.normal)))
                .filter(|&(_, d)| d < -tol)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((v, d)) = below {
                let p = self.mesh.vertices()[v];
                return Err(SolverError::Ground(format!(
                    "vertex {v} at [{}, {}] is {:.3e} m below the ground at t = 0 (the body must start on or above it)",
                    p.x, p.y, -d
                )));
            }
        }
        self.ground = ground;
        self.layout = fresh_layout();
        Ok(self)
    }

    /// The largest coordinate extent of the rest mesh, m (at least 1e-300).
    fn extent(&self) -> Real {
        let v = self.mesh.vertices();
        let (mut lo, mut hi) = (v[0], v[0]);
        for p in v {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (hi - lo).max().max(1e-300)
    }

    /// Add a rigid polygonal obstacle (counter-clockwise world polygon at `t = 0`); returns its
    /// index, which is also its index in [`State::bodies`](crate::State::bodies).
    pub fn add_obstacle(
        &mut self,
        polygon: &[Vec2],
        motion: ObstacleMotion,
    ) -> Result<usize, SolverError> {
        let index = self.obstacles.len();
        let obstacle = Obstacle::new(index, polygon, motion)?;
        // Overlap with the body at t = 0: a vertex inside the obstacle, or an obstacle corner
        // inside a triangle. Touching (within 1e-9 of the mesh size) is fine.
        let margin = 1e-9 * self.extent();
        let vertices = self.mesh.vertices();
        let overlap = |reason: String| SolverError::Obstacle { index, reason };
        if let Some(v) = vertices
            .iter()
            .position(|&p| crate::rigid::obstacle::strictly_inside(polygon, p, margin))
        {
            return Err(overlap(format!(
                "overlaps the body at t = 0: vertex {v} at [{}, {}] lies inside it; start it apart from the body",
                vertices[v].x, vertices[v].y
            )));
        }
        for (k, &c) in polygon.iter().enumerate() {
            if let Some(t) = self.mesh.triangles().iter().position(|tri| {
                crate::rigid::obstacle::strictly_inside(
                    &tri.map(|i| vertices[i as usize]),
                    c,
                    margin,
                )
            }) {
                return Err(overlap(format!(
                    "overlaps the body at t = 0: its corner {k} at [{}, {}] lies inside triangle {t}; start it apart from the body",
                    c.x, c.y
                )));
            }
        }
        self.obstacles.push(obstacle);
        self.layout = fresh_layout();
        Ok(index)
    }

    /// Set the penalty contact parameters.
    pub fn set_contact_params(&mut self, params: ContactParams) -> Result<&mut Self, SolverError> {
        params.validate()?;
        self.contact = params;
        self.layout = fresh_layout();
        Ok(self)
    }

    /// Start a drag attachment (replacing any active one), resolved at positions `x` (the
    /// state's): see [`crate::grab`]. Vertices that are pinned or moved on a schedule leave
    /// the anchor; an anchor with no free vertex left is an error. Changes the layout.
    pub fn grab(&mut self, grab: &Grab, x: &[Vec2]) -> Result<&mut Self, SolverError> {
        if x.len() != self.mesh.n_vertices() {
            return Err(SolverError::invalid(
                "grab.positions",
                format!("{} positions", x.len()),
                format!(
                    "must hold one position per mesh vertex ({})",
                    self.mesh.n_vertices()
                ),
            ));
        }
        let mut kinematic = vec![false; x.len()];
        for v in self.base.vertices() {
            kinematic[v] = true;
        }
        for (k, &b) in self.slave.iter().enumerate() {
            kinematic[k] |= b != u32::MAX;
        }
        self.grab = Some(ActiveGrab::new(grab, x, &kinematic)?);
        self.refresh_kinematics();
        Ok(self)
    }

    /// Move the active grab's target (m); the layout does not change. Fails when no grab
    /// is active or the target is not finite.
    pub fn move_grab(&mut self, target: Vec2) -> Result<&mut Self, SolverError> {
        check_finite_vec("grab.target", target)?;
        let Some(grab) = self.grab.as_mut() else {
            return Err(SolverError::invalid(
                "grab",
                "none",
                "no grab is active (start one with Model::grab)",
            ));
        };
        grab.move_to(target);
        if grab.model == GrabModel::Pin {
            for a in &grab.anchors {
                if let Ok(k) = self.kinematics.vertices.binary_search(&a.vertex) {
                    self.kinematics.motion[k] = Motion::Held(grab.goal(a));
                }
            }
        }
        Ok(self)
    }

    /// End the active grab, if any (the held vertices are free again). Changes the layout
    /// when a grab was active.
    pub fn release(&mut self) -> &mut Self {
        if self.grab.take().is_some() {
            self.refresh_kinematics();
        }
        self
    }

    /// The active grab: its anchor (vertices and normalised weights), target and model.
    pub fn active_grab(&self) -> Option<Grab> {
        self.grab.as_ref().map(|g| Grab {
            anchor: g
                .anchors
                .iter()
                .map(|a| (a.vertex as usize, a.weight))
                .collect(),
            target: g.target,
            model: g.model,
        })
    }

    /// Whether a grab is active.
    pub fn is_grabbed(&self) -> bool {
        self.grab.is_some()
    }

    /// The active grab's anchor point `sum w_i x_i` at positions `x`, m.
    pub fn grab_point(&self, x: &[Vec2]) -> Option<Vec2> {
        self.grab.as_ref().map(|g| g.point(x))
    }

    /// The force the hand exerts on the body at positions `x` (N per unit thickness): for a
    /// spring, `k (target - sum w_i x_i)`; for a pin, the quasi-static reaction, minus the sum
    /// of the elastic forces, weights and nodal loads on the held vertices (their inertia left
    /// out). `None` without a grab.
    pub fn grab_force(&self, x: &[Vec2]) -> Option<Vec2> {
        let grab = self.grab.as_ref()?;
        Some(match grab.model {
            GrabModel::Spring { .. } => grab.springs.iter().fold(Vec2::zeros(), |f, s| {
                f + (s.goal - x[s.vertex as usize]) * s.stiffness
            }),
            GrabModel::Pin => {
                let adj = self.elastic_mesh().adjacency();
                let mut f = Vec2::zeros();
                for a in &grab.anchors {
                    let v = a.vertex as usize;
                    for &(t, corner) in adj.of(v) {
                        let el = &self.elements[t as usize];
                        let p = self
                            .elastic_energies()
                            .energy_of(t as usize)
                            .pk1(&deformation_gradient(el, x));
                        f += (p * corner_gradient(el, corner)) * el.area;
                    }
                    f -= self.gravity * self.masses[v];
                }
                for &(v, load) in &self.external_forces {
                    if grab.anchors.iter().any(|a| a.vertex == v) {
                        f -= load;
                    }
                }
                f
            }
        })
    }

    /// The springs of an active spring grab (sorted by vertex; empty otherwise).
    pub(crate) fn springs(&self) -> &[Spring] {
        self.grab.as_ref().map_or(&[], |g| &g.springs)
    }

    /// An identifier of the model's structure (kinematic vertices, grab, contact geometry),
    /// unique in the process: it changes whenever [`Model::pin`],
    /// [`Model::add_prescribed_motion`], [`Model::set_ground`], [`Model::add_obstacle`],
    /// [`Model::set_contact_params`], [`Model::grab`] or [`Model::release`] is called (a clone
    /// shares it). Steppers compare it with the one they were built for and rebuild what
    /// depends on it.
    pub fn layout(&self) -> u64 {
        self.layout
    }

    /// Effective kinematics from the boundary conditions and the grab; new layout.
    fn refresh_kinematics(&mut self) {
        self.kinematics = self.base.clone();
        // A rigid body follows its kinematic vertices: pinned when one is pinned, else moved
        // by the prescribed motion of the first scheduled one; all its vertices then move so.
        for (b, body) in self.bodies.iter_mut().enumerate() {
            let mut motion = BodyMotion::Free;
            for &v in &body.vertices {
                if let Ok(k) = self.base.vertices.binary_search(&v) {
                    match self.base.motion[k] {
                        Motion::Pinned => {
                            motion = BodyMotion::Pinned;
                            break;
                        }
                        Motion::Scheduled(m) if motion == BodyMotion::Free => {
                            motion = BodyMotion::Scheduled(m);
                        }
                        _ => {}
                    }
                }
            }
            body.motion = motion;
            let list: Vec<usize> = body.vertices.iter().map(|&v| v as usize).collect();
            let m = match motion {
                BodyMotion::Free => Motion::Rigid(b as u32),
                BodyMotion::Pinned => Motion::Pinned,
                BodyMotion::Scheduled(m) => Motion::Scheduled(m),
            };
            self.kinematics.assign(&list, m);
        }
        if let Some(g) = &self.grab
            && g.model == GrabModel::Pin
        {
            for a in &g.anchors {
                self.kinematics
                    .assign(&[a.vertex as usize], Motion::Held(g.goal(a)));
            }
        }
        self.refresh_inverse_masses();
        self.layout = fresh_layout();
    }

    fn refresh_inverse_masses(&mut self) {
        for (w, m) in self.inv_masses.iter_mut().zip(&self.masses) {
            *w = 1.0 / m;
        }
        for v in self.kinematics.vertices() {
            self.inv_masses[v] = 0.0;
        }
    }

    /// The instruction set the explicit force kernel runs under: [`Isa::detected`] unless
    /// set with [`Model::set_isa`].
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Run the explicit force kernel under `isa` (or the widest supported set below it). The
    /// results are the same bits under every set (see [`fem_core::simd`]); only the speed
    /// changes.
    pub fn set_isa(&mut self, isa: Isa) -> &mut Self {
        self.isa = isa;
        self
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The body's energy: that of region 0, the whole body's when it is homogeneous (see
    /// [`Model::energies`] for a body of several materials).
    pub fn energy(&self) -> &E {
        self.energies.base()
    }

    /// The energy of every element ([`EnergyOf::energy_of`]), one per region.
    pub fn energies(&self) -> &ElementEnergies<E> {
        &self.energies
    }

    /// Lumped vertex masses, kg.
    pub fn masses(&self) -> &[Real] {
        &self.masses
    }

    /// The rigid bodies of the rigid regions ([`Model::make_rigid`]), in order of their first
    /// triangle; their poses are [`State::rigid`](crate::State::rigid).
    pub fn rigid_bodies(&self) -> &[RigidBody] {
        &self.bodies
    }

    /// The rigid body vertex `v` is slaved to, if any.
    #[inline]
    pub fn rigid_body_of(&self, v: usize) -> Option<usize> {
        match self.slave.get(v) {
            Some(&b) if b != u32::MAX => Some(b as usize),
            _ => None,
        }
    }

    /// The rigid regions: `(region tag, density)` in the order they were declared.
    pub fn rigid_regions(&self) -> &[(u32, Real)] {
        &self.rigid_regions
    }

    /// Whether triangle `t` of [`Model::mesh`] belongs to a rigid region.
    pub fn is_rigid_triangle(&self, t: usize) -> bool {
        let tag = self.energies.tag(t);
        self.rigid_regions.iter().any(|(r, _)| *r == tag)
    }

    /// The mesh of the deformable triangles, with every vertex of [`Model::mesh`] (those of
    /// rigid regions alone stay unreferenced): the mesh every elastic term is assembled on. It
    /// is the whole mesh when no region is rigid.
    pub fn elastic_mesh(&self) -> &Mesh {
        self.elastic.as_ref().map_or(&self.mesh, |e| &e.0)
    }

    /// The energies of [`Model::elastic_mesh`]'s triangles (one per region, as
    /// [`Model::energies`], tagged per deformable triangle).
    pub fn elastic_energies(&self) -> &ElementEnergies<E> {
        self.elastic.as_ref().map_or(&self.energies, |e| &e.1)
    }

    /// Inverse masses, 1/kg; zero for kinematic (pinned or prescribed) vertices.
    pub fn inverse_masses(&self) -> &[Real] {
        &self.inv_masses
    }

    /// Pinned and prescribed vertices.
    pub fn kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// Gravitational acceleration, m/s^2.
    pub fn gravity(&self) -> Vec2 {
        self.gravity
    }

    /// External nodal forces `(vertex, force)`, in the order they were added.
    pub fn external_forces(&self) -> &[(u32, Vec2)] {
        &self.external_forces
    }

    /// The mesh's boundary edges, `[a, b]` in counter-clockwise order (the body lies to the
    /// left of `a -> b`), sorted: the soft side of edge contact.
    pub fn boundary_edges(&self) -> &[[u32; 2]] {
        &self.boundary
    }

    /// The vertices on the mesh's boundary, sorted: the soft side of vertex contact.
    pub fn boundary_vertices(&self) -> &[u32] {
        &self.boundary_vertices
    }

    /// The ground, if any.
    pub fn ground(&self) -> Option<&Ground> {
        self.ground.as_ref()
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Give kinematic obstacle `index` further moves after its first window (see
    /// [`Obstacle::set_moves`]: in time order, e.g. lowered onto the body, held, lifted off).
    pub fn set_obstacle_moves(
        &mut self,
        index: usize,
        moves: &[crate::rigid::ObstacleMove],
    ) -> Result<(), SolverError> {
        let count = self.obstacles.len();
        let obstacle = self.obstacles.get_mut(index).ok_or_else(|| {
            SolverError::invalid(
                "obstacles",
                index,
                format!("no such obstacle (the model has {count})"),
            )
        })?;
        obstacle.set_moves(index, moves)
    }

    /// Penalty contact parameters.
    pub fn contact_params(&self) -> &ContactParams {
        &self.contact
    }

    /// Whether any contact geometry exists.
    pub fn has_contact(&self) -> bool {
        self.ground.is_some() || !self.obstacles.is_empty()
    }

    /// The P-wave modulus of the linearised energy at rest, Pa (`lambda + 2 mu`), of the base
    /// material (region 0: the body's own, the soft tissue of a body with bones). Contact
    /// stiffness defaults scale with it.
    pub fn p_wave_modulus(&self) -> Real {
        self.modulus
    }

    /// An upper bound on the highest angular frequency of the elastic body at rest, rad/s:
    /// `omega_max^2 = lambda_max(M^-1 K)` with `K` the stiffness at rest (`dP/dF` at `F = I`) and
    /// `M` the lumped masses.
    ///
    /// The bound is the element eigenvalue inequality (Irons; Fried 1972). Split the lumped
    /// masses into non-negative diagonal element parts, `M = sum_e M_e`, each vertex's mass
    /// going to its triangles in proportion to their areas (`m_{i,e} = m_i a_e / sum_{e' at i}
    /// a_e'`; for masses from a uniform density this is exactly `rho a_e / 3`). With
    /// `K = sum_e K_e`, every Rayleigh quotient obeys
    /// `u^T K u / u^T M u = sum_e u_e^T K_e u_e / sum_e u_e^T M_e u_e <= max_e lambda_max(M_e^-1 K_e)`,
    /// so `lambda_max(M^-1 K) <= max_e lambda_max(M_e^-1 K_e)`. Each element's 6x6 generalised
    /// eigenproblem is solved as the symmetric `M_e^-1/2 K_e M_e^-1/2`. Pinned and prescribed
    /// vertices remove degrees of freedom, which can only lower `lambda_max` (Cauchy
    /// interlacing), so the bound holds for the constrained body too.
    pub fn rest_frequency_bound(&self) -> Real {
        let nv = self.mesh.n_vertices();
        let mut area_around = vec![0.0; nv];
        for el in &self.elements {
            for &i in &el.idx {
                area_around[i as usize] += el.area;
            }
        }
        // One rest tangent per region: the bound is the stiffest element's, so a stiff bone
        // region sets the step of the whole body.
        let dpdf: Vec<_> = (self.energies.energies().iter())
            .map(|e| e.dpk1(&Mat2::identity()))
            .collect();
        let mut lambda_max: Real = 0.0;
        for (tri, el) in self.elastic_mesh().elements().iter().zip(&self.elements) {
            let k = tri.stiffness(&dpdf[el.region as usize]);
            let mut scale = [0.0; 6];
            for (a, &i) in el.idx.iter().enumerate() {
                let i = i as usize;
                let m = self.masses[i] * el.area / area_around[i];
                scale[2 * a] = 1.0 / m.sqrt();
                scale[2 * a + 1] = scale[2 * a];
            }
            let s = Mat6::from_fn(|r, c| scale[r] * k[(r, c)] * scale[c]);
            let top = SymmetricEigen::new(s).eigenvalues.max();
            lambda_max = lambda_max.max(top);
        }
        if let Some(np) = self.elastic_energies().nodal_pressure() {
            return self.averaged_pressure_frequency_bound(np, &area_around);
        }
        lambda_max.sqrt()
    }

    /// [`Model::rest_frequency_bound`] of the averaged nodal pressure triangle: its rest
    /// stiffness is the elements' deviatoric part `K_d` (the tangent less `U''(1) t t^T`) plus
    /// each node's rank-one `U''(1) / V_n h_n h_n^T`, both positive semi-definite, so
    /// `lambda_max(M^-1 K) <= lambda_max(M^-1 K_d) + lambda_max(M^-1 K_p)`. The first is bounded
    /// element by element as above; the second node by node with each vertex's mass split
    /// equally among the node patches it lies in: `max_n U''(1) / V_n sum_i |h_n,i|^2 / m_i,n`.
    fn averaged_pressure_frequency_bound(
        &self,
        np: &fem_core::nodal_pressure::NodalPressure,
        area_around: &[Real],
    ) -> Real {
        let mesh = self.elastic_mesh();
        let energies = self.elastic_energies();
        let dev: Vec<_> = (energies.energies().iter())
            .map(|e| {
                let vol = e.volumetric();
                let t = fem_core::math::vec(&vol.dtheta(&Mat2::identity()));
                e.dpk1(&Mat2::identity()) - t * t.transpose() * vol.d2u(1.0)
            })
            .collect();
        let mut deviatoric: Real = 0.0;
        for (tri, el) in mesh.elements().iter().zip(&self.elements) {
            let k = tri.stiffness(&dev[el.region as usize]);
            let mut scale = [0.0; 6];
            for (a, &i) in el.idx.iter().enumerate() {
                let i = i as usize;
                let m = self.masses[i] * el.area / area_around[i];
                scale[2 * a] = 1.0 / m.sqrt();
                scale[2 * a + 1] = scale[2 * a];
            }
            let s = Mat6::from_fn(|r, c| scale[r] * k[(r, c)] * scale[c]);
            deviatoric = deviatoric.max(SymmetricEigen::new(s).eigenvalues.max());
        }
        // How many node patches each vertex lies in.
        let mut patches = vec![0u32; mesh.n_vertices()];
        let mut patch = Vec::new();
        for n in 0..np.n_nodes() {
            np.patch(mesh, n, &mut patch);
            for &v in &patch {
                patches[v as usize] += 1;
            }
        }
        let mut nodal: Real = 0.0;
        for n in 0..np.n_nodes() {
            np.patch(mesh, n, &mut patch);
            let mut h = vec![Vec2::zeros(); patch.len()];
            for &(t, _) in np.entries(n) {
                let el = &mesh.elements()[t as usize];
                let g = el.gradients();
                for (corner, &v) in mesh.triangles()[t as usize].iter().enumerate() {
                    let slot = patch.binary_search(&v).expect("patch holds the vertex");
                    h[slot] += g[corner] * (el.area / 3.0);
                }
            }
            let law = energies.energy_of(np.entries(n)[0].0 as usize).volumetric();
            let q: Real = (patch.iter().zip(&h))
                .map(|(&v, hv)| {
                    let m = self.masses[v as usize] / Real::from(patches[v as usize]);
                    hv.norm_squared() / m
                })
                .sum();
            nodal = nodal.max(law.d2u(1.0) / np.volume(n) * q);
        }
        (deviatoric + nodal).sqrt()
    }

    /// The explicit critical time step of the elastic body, s: `2 / omega`, with `omega` the
    /// bound on the highest rest-state frequency of [`Model::rest_frequency_bound`]. It is
    /// provably conservative for the stiffness at rest (no safety factor is applied, none is
    /// needed: the true rest-state limit `2 / omega_max` is never smaller), and within a factor
    /// of about 2 of it on structured meshes. Large deformations change the stiffness (StVK
    /// under compression softens, other energies stiffen) and can still need a smaller step.
    pub fn elastic_critical_time_step(&self) -> Real {
        2.0 / self.rest_frequency_bound()
    }

    /// Compare `dt` with the explicit stability limits: the elastic one and, when the model
    /// has contact geometry, the penalty spring's ([`ContactParams::critical_time_step`]).
    pub fn check_time_step(&self, dt: Real) -> TimeStepCheck {
        let elastic = self.elastic_critical_time_step();
        let contact = self
            .has_contact()
            .then(|| self.contact.critical_time_step());
        TimeStepCheck {
            dt,
            elastic,
            contact,
        }
    }
}

/// The explicit stability estimate for a time step (see [`Model::check_time_step`]).
///
/// The elastic limit is provably conservative for the stiffness at rest, with safety factor 1
/// ([`Model::elastic_critical_time_step`]); large deformations can still need a smaller step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeStepCheck {
    /// The time step checked, s.
    pub dt: Real,
    /// Elastic critical time step `2 / omega`, s, with `omega` the bound on the highest
    /// rest-state frequency ([`Model::rest_frequency_bound`]).
    pub elastic: Real,
    /// Penalty-contact critical time step, s (when the model has contact geometry).
    pub contact: Option<Real>,
}

impl TimeStepCheck {
    /// The binding limit, s.
    pub fn critical(&self) -> Real {
        self.contact.map_or(self.elastic, |c| c.min(self.elastic))
    }

    /// `dt / critical`: above 1 the symplectic explicit stepper is expected to blow up.
    pub fn ratio(&self) -> Real {
        self.dt / self.critical()
    }

    /// The bound on the highest elastic angular frequency at rest, rad/s (`2 / elastic`).
    pub fn omega(&self) -> Real {
        2.0 / self.elastic
    }

    /// A one-line warning when `dt` exceeds the limit, else `None`.
    pub fn warning(&self) -> Option<String> {
        (self.ratio() > 1.0).then(|| {
            let which = match self.contact {
                Some(c) if c < self.elastic => "penalty contact",
                _ => "elastic",
            };
            format!(
                "dt = {:e} s exceeds the explicit critical time step {:e} s ({which} limit at rest-state stiffness, provably conservative, ratio {:.2}): expect the run to blow up",
                self.dt,
                self.critical(),
                self.ratio()
            )
        })
    }

    /// Forward Euler's amplification of the highest elastic mode per step, with velocity
    /// damping `damping` = `c` (1/s, applied as `v <- v exp(-c dt)`).
    ///
    /// For a mode of angular frequency `omega`, the update `x' = x + dt v`,
    /// `v' = (v - dt omega^2 x) d` with `d = exp(-c dt)` has the matrix
    /// `[[1, dt], [-omega^2 dt d, d]]`: trace `1 + d`, determinant `d (1 + (omega dt)^2)`. The
    /// result is its spectral radius; when it exceeds 1 the eigenvalues are a complex pair and it
    /// equals `sqrt(1 + (omega dt)^2) exp(-c dt / 2)` (the damping acts on the velocity only, so
    /// the amplitude sees half its rate), which grows with `omega`: evaluated at the bound
    /// [`TimeStepCheck::omega`] it bounds every mode's growth. It exceeds 1 exactly when
    /// `c < ln(1 + (omega dt)^2) / dt` ([`TimeStepCheck::forward_euler_damping`]).
    pub fn forward_euler_growth(&self, damping: Real) -> Real {
        let w = self.omega() * self.dt;
        let d = exp(-damping * self.dt);
        let (trace, det) = (1.0 + d, d * (1.0 + w * w));
        let disc = trace * trace - 4.0 * det;
        if disc < 0.0 {
            det.sqrt()
        } else {
            0.5 * (trace + disc.sqrt())
        }
    }

    /// The damping rate (1/s) forward Euler needs for its highest mode not to grow:
    /// `ln(1 + (omega dt)^2) / dt`.
    pub fn forward_euler_damping(&self) -> Real {
        let w = self.omega() * self.dt;
        ln_1p(w * w) / self.dt
    }

    /// A one-line warning when forward Euler with damping `damping` (1/s) amplifies the highest
    /// elastic mode ([`TimeStepCheck::forward_euler_growth`] above 1), else `None`.
    pub fn forward_euler_warning(&self, damping: Real) -> Option<String> {
        let growth = self.forward_euler_growth(damping);
        (growth > 1.0).then(|| {
            format!(
                "forward Euler (x uses the old velocity) amplifies the highest mode (omega <= {:.4e} rad/s) by up to {growth:.4} per step at dt = {:e} s, damping c = {:e} 1/s (growth sqrt(1 + (omega dt)^2) exp(-c dt / 2)); it is unstable unless c >= ln(1 + (omega dt)^2) / dt = {:.4e} 1/s: use the symplectic scheme",
                self.omega(),
                self.dt,
                damping,
                self.forward_euler_damping()
            )
        })
    }
}

/// The edges that belong to exactly one triangle, as `[a, b]` in the triangle's
/// counter-clockwise order, sorted.
pub fn boundary_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut all: Vec<([u32; 2], [u32; 2])> = triangles
        .iter()
        .flat_map(|t| {
            [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])].map(|(a, b)| ([a.min(b), a.max(b)], [a, b]))
        })
        .collect();
    all.sort_unstable();
    let mut out = Vec::new();
    let mut i = 0;
    while i < all.len() {
        let mut j = i + 1;
        while j < all.len() && all[j].0 == all[i].0 {
            j += 1;
        }
        if j - i == 1 {
            out.push(all[i].1);
        }
        i = j;
    }
    out
}
