//! What the dimension-generic solvers read ([`NdModel`]) and what they change ([`NdState`]).

use fem_core::dim::{Dense, Dim};
use fem_core::energy::Hyperelastic;
use fem_core::math::Real;
use fem_core::simplex::SimplexMesh;

use crate::error::SolverError;

/// A set of vertices chosen by their rest positions: those in an axis-aligned box (with a
/// margin of `1e-9` m, as the 2D [`crate::Region::in_box`]).
#[derive(Clone, Debug, PartialEq)]
pub struct NdRegion<D: Dim> {
    /// The box's corner with the smallest coordinates.
    pub min: D::Vector,
    /// The box's corner with the largest coordinates.
    pub max: D::Vector,
}

impl<D: Dim> NdRegion<D> {
    /// The box `[min, max]`.
    pub fn in_box(min: D::Vector, max: D::Vector) -> Self {
        NdRegion { min, max }
    }

    fn contains(&self, p: &D::Vector) -> bool {
        (0..D::D).all(|i| p.at(i) >= self.min.at(i) - 1e-9 && p.at(i) <= self.max.at(i) + 1e-9)
    }

    /// The vertices of `rest` in the region, in increasing index order; an empty selection is
    /// an error naming `field`.
    pub fn select(&self, rest: &[D::Vector], field: &str) -> Result<Vec<usize>, SolverError> {
        if !(self.min.all_finite() && self.max.all_finite()) {
            return Err(SolverError::invalid(
                field,
                format!("{:?} .. {:?}", self.min, self.max),
                "box corners must be finite",
            ));
        }
        let out: Vec<usize> = (0..rest.len())
            .filter(|&v| self.contains(&rest[v]))
            .collect();
        if out.is_empty() {
            return Err(SolverError::invalid(
                field,
                format!("{:?} .. {:?}", self.min, self.max),
                "selects no vertex of the mesh",
            ));
        }
        Ok(out)
    }
}

/// A soft body of linear simplices in `D` dimensions: mesh, energy, lumped masses, fixed
/// degrees of freedom, gravity and nodal loads. The dimension-generic solvers
/// ([`super::NdStepper`]) read it; it does not change during a run.
#[derive(Clone, Debug)]
pub struct NdModel<D: Dim, E> {
    mesh: SimplexMesh<D>,
    energy: E,
    masses: Vec<Real>,
    /// One flag per degree of freedom (`D v + i`): held at its rest value.
    fixed: Vec<bool>,
    gravity: D::Vector,
    /// Nodal loads (tractions included), N.
    loads: Vec<D::Vector>,
}

impl<D: Dim, E: Hyperelastic<D>> NdModel<D, E> {
    /// A body of uniform density (kg/m^D), no boundary condition, no gravity.
    pub fn with_density(
        mesh: SimplexMesh<D>,
        energy: E,
        density: Real,
    ) -> Result<Self, SolverError> {
        let masses = mesh
            .lumped_masses(density)
            .map_err(|e| SolverError::invalid("density", density, e.to_string()))?;
        Ok(Self::from_masses(mesh, energy, masses))
    }

    /// A body of the given total mass, spread by volume.
    pub fn with_total_mass(
        mesh: SimplexMesh<D>,
        energy: E,
        total_mass: Real,
    ) -> Result<Self, SolverError> {
        if !(total_mass.is_finite() && total_mass > 0.0) {
            return Err(SolverError::invalid(
                "total_mass",
                total_mass,
                "must be a finite number > 0",
            ));
        }
        let density = total_mass / mesh.measure();
        Self::with_density(mesh, energy, density)
    }

    fn from_masses(mesh: SimplexMesh<D>, energy: E, masses: Vec<Real>) -> Self {
        let n = mesh.n_vertices();
        NdModel {
            mesh,
            energy,
            masses,
            fixed: vec![false; D::D * n],
            gravity: D::Vector::zeros(),
            loads: vec![D::Vector::zeros(); n],
        }
    }

    /// Hold every component of the region's vertices at rest. Returns how many vertices.
    pub fn pin(&mut self, region: &NdRegion<D>) -> Result<usize, SolverError> {
        self.fix(region, &[true; 3][..D::D], "pinned")
    }

    /// Hold the chosen components (`components[i]` for axis `i`) of the region's vertices at
    /// their rest values: `[false, false, true]` keeps `u_z = 0` (a plane-strain side face).
    pub fn fix(
        &mut self,
        region: &NdRegion<D>,
        components: &[bool],
        field: &str,
    ) -> Result<usize, SolverError> {
        if components.len() != D::D {
            return Err(SolverError::invalid(
                field,
                format!("{components:?}"),
                format!("needs one flag per axis ({})", D::D),
            ));
        }
        let vs = region.select(self.mesh.vertices(), field)?;
        for &v in &vs {
            for (i, &c) in components.iter().enumerate() {
                self.fixed[D::D * v + i] |= c;
            }
        }
        Ok(vs.len())
    }

    /// Gravity, m/s^2.
    pub fn set_gravity(&mut self, g: D::Vector) -> Result<(), SolverError> {
        if !g.all_finite() {
            return Err(SolverError::invalid(
                "gravity",
                format!("{g:?}"),
                "must be finite",
            ));
        }
        self.gravity = g;
        Ok(())
    }

    /// A uniform traction `t` (Pa) on the boundary facets whose vertices all lie in the region,
    /// lumped to their vertices (each gets `|facet| t / D`). Returns the loaded area (length in
    /// 2D).
    pub fn add_traction(
        &mut self,
        region: &NdRegion<D>,
        t: D::Vector,
    ) -> Result<Real, SolverError> {
        if !t.all_finite() {
            return Err(SolverError::invalid(
                "traction",
                format!("{t:?}"),
                "must be finite",
            ));
        }
        let inside = region.select(self.mesh.vertices(), "traction")?;
        let mut is_in = vec![false; self.mesh.n_vertices()];
        inside.iter().for_each(|&v| is_in[v] = true);
        let mut total = 0.0;
        for facet in self.mesh.boundary_facets() {
            if !facet.iter().all(|&v| is_in[v as usize]) {
                continue;
            }
            let p: Vec<D::Vector> = facet
                .iter()
                .map(|&v| self.mesh.vertices()[v as usize])
                .collect();
            let size = facet_measure::<D>(&p);
            total += size;
            for &v in &facet {
                self.loads[v as usize] += t * (size / D::D as Real);
            }
        }
        if total == 0.0 {
            return Err(SolverError::invalid(
                "traction",
                format!("{:?} .. {:?}", region.min, region.max),
                "contains no boundary facet",
            ));
        }
        Ok(total)
    }

    /// The mesh.
    pub fn mesh(&self) -> &SimplexMesh<D> {
        &self.mesh
    }
    /// The energy.
    pub fn energy(&self) -> &E {
        &self.energy
    }
    /// Lumped masses, kg.
    pub fn masses(&self) -> &[Real] {
        &self.masses
    }
    /// One flag per degree of freedom: held at rest.
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }
    /// Gravity.
    pub fn gravity(&self) -> D::Vector {
        self.gravity
    }
    /// Nodal loads, N.
    pub fn loads(&self) -> &[D::Vector] {
        &self.loads
    }
    /// The external force on vertex `v`: `m_v g + load_v`, N.
    #[inline]
    pub fn external_force(&self, v: usize) -> D::Vector {
        self.gravity * self.masses[v] + self.loads[v]
    }
    /// The body's size: the largest extent of its rest vertices along an axis, m.
    pub fn size(&self) -> Real {
        (0..D::D)
            .map(|i| {
                let (lo, hi) = self
                    .mesh
                    .vertices()
                    .iter()
                    .fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.at(i)), hi.max(p.at(i)))
                    });
                hi - lo
            })
            .fold(0.0, Real::max)
    }
}

/// The measure of a facet of `D` vertices: an edge's length, a triangle's area.
fn facet_measure<D: Dim>(p: &[D::Vector]) -> Real {
    if D::D == 2 {
        (p[1] - p[0]).norm2().sqrt()
    } else {
        let (a, b) = (p[1] - p[0], p[2] - p[0]);
        // |a x b| / 2 from the Gram determinant, without naming the 3D cross product.
        let (aa, bb, ab) = (a.norm2(), b.norm2(), a.inner(&b));
        0.5 * (aa * bb - ab * ab).max(0.0).sqrt()
    }
}

/// Positions, velocities and the clock of a [`NdModel`]'s body.
#[derive(Clone, Debug, PartialEq)]
pub struct NdState<D: Dim> {
    /// Positions, m.
    pub x: Vec<D::Vector>,
    /// Velocities, m/s.
    pub v: Vec<D::Vector>,
    /// Simulated time, s (the load factor for the static solver).
    pub t: Real,
}

impl<D: Dim> NdState<D> {
    /// At rest: rest positions, zero velocity, `t = 0`.
    pub fn at_rest<E: Hyperelastic<D>>(model: &NdModel<D, E>) -> Self {
        NdState {
            x: model.mesh().vertices().to_vec(),
            v: vec![D::Vector::zeros(); model.mesh().n_vertices()],
            t: 0.0,
        }
    }

    /// The displacement of vertex `v` from rest.
    pub fn displacement<E: Hyperelastic<D>>(&self, model: &NdModel<D, E>, v: usize) -> D::Vector {
        self.x[v] - model.mesh().vertices()[v]
    }
}
