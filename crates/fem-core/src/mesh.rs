//! A validated triangle mesh in its rest configuration, with per-element rest data, the
//! vertex-to-triangle adjacency used by the deterministic parallel gather, and lumped masses.
//!
//! Vertices are `[x, y]` in metres; triangles are 0-based, counter-clockwise vertex indices (the
//! mesh JSON contract). Validation rejects, naming the offending index: an empty mesh,
//! non-finite coordinates, out-of-range or repeated indices, degenerate or clockwise rest
//! triangles, and vertices no triangle uses (they would have zero mass).

use crate::element::{ElementError, ElementTolerance, Tri3};
use crate::math::{Real, Vec2};
use crate::overlap::Problem;
use crate::partition::ScatterPlan;

/// Why a mesh is rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// No vertices or no triangles.
    #[error("mesh has no {0}")]
    Empty(&'static str),
    /// More vertices than 32-bit indices can address.
    #[error("mesh has {0} vertices; at most 4294967295 are supported")]
    TooManyVertices(usize),
    /// A coordinate is NaN or infinite.
    #[error("vertices[{vertex}] = [{x}, {y}]: coordinates must be finite")]
    NonFiniteVertex {
        /// Vertex index.
        vertex: usize,
        /// x coordinate.
        x: Real,
        /// y coordinate.
        y: Real,
    },
    /// A triangle names a vertex that does not exist.
    #[error(
        "triangles[{triangle}] = {indices:?}: index {index} is out of range (mesh has {n_vertices} vertices)"
    )]
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// Its vertex indices.
        indices: [u32; 3],
        /// The bad index.
        index: u32,
        /// Number of vertices.
        n_vertices: usize,
    },
    /// A triangle uses one vertex twice.
    #[error("triangles[{triangle}] = {indices:?}: repeated vertex index")]
    RepeatedIndex {
        /// Triangle index.
        triangle: usize,
        /// Its vertex indices.
        indices: [u32; 3],
    },
    /// The rest triangle is degenerate or clockwise.
    #[error("triangles[{triangle}] = {indices:?}: {source}")]
    Element {
        /// Triangle index.
        triangle: usize,
        /// Its vertex indices.
        indices: [u32; 3],
        /// What is wrong with it.
        source: ElementError,
    },
    /// Two triangles have the same three vertices.
    #[error(
        "triangles[{second}] = {indices:?} repeats triangles[{first}] (the same vertices): it would count that area twice"
    )]
    RepeatedTriangle {
        /// The earlier triangle.
        first: usize,
        /// The repeat.
        second: usize,
        /// The repeat's vertex indices.
        indices: [u32; 3],
    },
    /// An edge borders more than two triangles.
    #[error(
        "the edge between vertices {} and {} borders triangles[{}], triangles[{}] and triangles[{}]: an edge may border at most two",
        edge[0], edge[1], triangles[0], triangles[1], triangles[2]
    )]
    EdgeOfThree {
        /// The edge's vertices.
        edge: [u32; 2],
        /// Three of the triangles on it.
        triangles: [usize; 3],
    },
    /// The interiors of two triangles intersect.
    #[error(
        "triangles[{second}] = {second_indices:?} overlaps triangles[{first}] = {first_indices:?}: triangles may touch only along shared edges and at vertices"
    )]
    Overlap {
        /// The earlier triangle.
        first: usize,
        /// Its vertex indices.
        first_indices: [u32; 3],
        /// The later triangle.
        second: usize,
        /// Its vertex indices.
        second_indices: [u32; 3],
    },
    /// A vertex belongs to no triangle.
    #[error("vertices[{0}] is used by no triangle (it would have zero mass)")]
    UnreferencedVertex(usize),
    /// A structured rectangle's parameters are unusable
    /// ([`structured::rectangle`](crate::structured::rectangle)).
    #[error("rectangle: {0}")]
    Rectangle(String),
    /// A lumped-mass input is not a finite positive number.
    #[error("{field} = {value}: must be a finite number > 0")]
    BadMassInput {
        /// Field name (`density` or `total_mass`).
        field: &'static str,
        /// The rejected value.
        value: Real,
    },
    /// Region tags that do not fit the mesh.
    #[error("regions: {0}")]
    Regions(String),
}

/// For each vertex, the `(triangle, corner)` pairs that touch it, sorted by triangle index.
/// Compressed-row layout: the entries of vertex `v` are `entries[offsets[v]..offsets[v + 1]]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexAdjacency {
    offsets: Vec<u32>,
    entries: Vec<(u32, u8)>,
}

impl VertexAdjacency {
    fn build(n_vertices: usize, triangles: &[[u32; 3]]) -> Self {
        let mut counts = vec![0u32; n_vertices + 1];
        for t in triangles {
            for &v in t {
                counts[v as usize + 1] += 1;
            }
        }
        for i in 0..n_vertices {
            counts[i + 1] += counts[i];
        }
        let offsets = counts.clone();
        let mut next = counts;
        let mut entries = vec![(0u32, 0u8); 3 * triangles.len()];
        // Filling in triangle order keeps each vertex's list sorted by triangle index.
        for (e, t) in triangles.iter().enumerate() {
            for (corner, &v) in t.iter().enumerate() {
                let slot = &mut next[v as usize];
                entries[*slot as usize] = (e as u32, corner as u8);
                *slot += 1;
            }
        }
        VertexAdjacency { offsets, entries }
    }

    /// The `(triangle, corner)` pairs of vertex `v`, in increasing triangle order.
    #[inline]
    pub fn of(&self, v: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

/// A validated triangle mesh with rest-state element data.
#[derive(Clone, Debug)]
pub struct Mesh {
    vertices: Vec<Vec2>,
    triangles: Vec<[u32; 3]>,
    elements: Vec<Tri3>,
    adjacency: VertexAdjacency,
    plan: ScatterPlan,
    /// One region tag per triangle, or empty (see [`Mesh::set_regions`]).
    regions: Vec<u32>,
    /// The name of each region tag.
    region_names: Vec<String>,
}

impl Mesh {
    /// Validate with the default [`ElementTolerance`].
    pub fn new(vertices: Vec<Vec2>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        Self::with_tolerance(vertices, triangles, ElementTolerance::default())
    }

    /// Build from `[x, y]` pairs and `usize` indices (the shape of mesh JSON).
    pub fn from_arrays(
        vertices: &[[Real; 2]],
        triangles: &[[usize; 3]],
    ) -> Result<Self, MeshError> {
        if vertices.len() > u32::MAX as usize {
            return Err(MeshError::TooManyVertices(vertices.len()));
        }
        let n = vertices.len();
        let mut tris = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let mut out = [0u32; 3];
            for (k, &i) in tri.iter().enumerate() {
                if i >= n {
                    return Err(MeshError::IndexOutOfRange {
                        triangle: t,
                        indices: tri.map(|i| i.min(u32::MAX as usize) as u32),
                        index: i.min(u32::MAX as usize) as u32,
                        n_vertices: n,
                    });
                }
                out[k] = i as u32;
            }
            tris.push(out);
        }
        Self::new(
            vertices.iter().map(|p| Vec2::new(p[0], p[1])).collect(),
            tris,
        )
    }

    /// Validate with an explicit tolerance for degenerate triangles.
    pub fn with_tolerance(
        vertices: Vec<Vec2>,
        triangles: Vec<[u32; 3]>,
        tol: ElementTolerance,
    ) -> Result<Self, MeshError> {
        if vertices.is_empty() {
            return Err(MeshError::Empty("vertices"));
        }
        if triangles.is_empty() {
            return Err(MeshError::Empty("triangles"));
        }
        if vertices.len() > u32::MAX as usize {
            return Err(MeshError::TooManyVertices(vertices.len()));
        }
        if let Some((vertex, p)) = vertices
            .iter()
            .enumerate()
            .find(|(_, p)| !p.x.is_finite() || !p.y.is_finite())
        {
            return Err(MeshError::NonFiniteVertex {
                vertex,
                x: p.x,
                y: p.y,
            });
        }
        let n = vertices.len();
        let mut used = vec![false; n];
        let mut elements = Vec::with_capacity(triangles.len());
        for (t, &tri) in triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    triangle: t,
                    indices: tri,
                    index,
                    n_vertices: n,
                });
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(MeshError::RepeatedIndex {
                    triangle: t,
                    indices: tri,
                });
            }
            let rest = tri.map(|i| vertices[i as usize]);
            let element = Tri3::new(rest, tol).map_err(|source| MeshError::Element {
                triangle: t,
                indices: tri,
                source,
            })?;
            elements.push(element);
            tri.iter().for_each(|&i| used[i as usize] = true);
        }
        if let Some(v) = used.iter().position(|&u| !u) {
            return Err(MeshError::UnreferencedVertex(v));
        }
        match crate::overlap::check(&vertices, &triangles) {
            None => {}
            Some(Problem::Repeated { first, second }) => {
                return Err(MeshError::RepeatedTriangle {
                    first,
                    second,
                    indices: triangles[second],
                });
            }
            Some(Problem::EdgeOfThree { edge, triangles }) => {
                return Err(MeshError::EdgeOfThree { edge, triangles });
            }
            Some(Problem::Overlap { first, second }) => {
                return Err(MeshError::Overlap {
                    first,
                    first_indices: triangles[first],
                    second,
                    second_indices: triangles[second],
                });
            }
        }
        let adjacency = VertexAdjacency::build(n, &triangles);
        let plan = ScatterPlan::new(n, &triangles, &adjacency);
        Ok(Mesh {
            vertices,
            triangles,
            elements,
            adjacency,
            plan,
            regions: Vec::new(),
            region_names: Vec::new(),
        })
    }

    /// The same vertices with only the triangles `keep` selects (`keep[t]` for triangle `t`,
    /// in order), regions kept. Vertices that no kept triangle uses stay in place, unreferenced:
    /// the elastic part of a body whose other triangles are rigid, still indexed like the whole
    /// body. Unlike [`Mesh::new`] this checks nothing (the triangles come from a valid mesh).
    /// Panics when `keep` does not hold one flag per triangle.
    pub fn restricted(&self, keep: &[bool]) -> Mesh {
        assert_eq!(keep.len(), self.triangles.len(), "one flag per triangle");
        let pick = |t: usize| keep[t];
        let triangles: Vec<[u32; 3]> = (0..self.triangles.len())
            .filter(|&t| pick(t))
            .map(|t| self.triangles[t])
            .collect();
        let elements = (0..self.triangles.len())
            .filter(|&t| pick(t))
            .map(|t| self.elements[t])
            .collect();
        let regions = if self.regions.is_empty() {
            Vec::new()
        } else {
            (0..self.triangles.len())
                .filter(|&t| pick(t))
                .map(|t| self.regions[t])
                .collect()
        };
        let n = self.vertices.len();
        let adjacency = VertexAdjacency::build(n, &triangles);
        let plan = ScatterPlan::new(n, &triangles, &adjacency);
        Mesh {
            vertices: self.vertices.clone(),
            triangles,
            elements,
            adjacency,
            plan,
            regions,
            region_names: self.region_names.clone(),
        }
    }

    /// Tag the triangles with named regions (tissues: a bone inside soft tissue), as a mesh
    /// file or the mesh pipeline carries them: `tags[t]` is the region of triangle `t`, an
    /// index into `names`. Errors (naming the first bad entry) unless there is one tag per
    /// triangle and every tag has a name. The tags are data for the caller (a scene gives
    /// each region its material); the mesh itself does not use them.
    pub fn set_regions(&mut self, tags: Vec<u32>, names: Vec<String>) -> Result<(), MeshError> {
        if tags.len() != self.triangles.len() {
            return Err(MeshError::Regions(format!(
                "{} tags for {} triangles",
                tags.len(),
                self.triangles.len()
            )));
        }
        if let Some((t, tag)) = tags
            .iter()
            .enumerate()
            .find(|(_, t)| **t as usize >= names.len())
        {
            return Err(MeshError::Regions(format!(
                "triangle {t} has tag {tag}, but only {} region names are given",
                names.len()
            )));
        }
        self.regions = tags;
        self.region_names = names;
        Ok(())
    }

    /// The region tag of each triangle (empty when the mesh carries no regions).
    pub fn region_tags(&self) -> &[u32] {
        &self.regions
    }

    /// The name of each region tag (empty when the mesh carries no regions).
    pub fn region_names(&self) -> &[String] {
        &self.region_names
    }

    /// Rest positions.
    pub fn vertices(&self) -> &[Vec2] {
        &self.vertices
    }

    /// Triangles (counter-clockwise vertex indices).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Rest-state data, one per triangle.
    pub fn elements(&self) -> &[Tri3] {
        &self.elements
    }

    /// Vertex-to-triangle adjacency.
    pub fn adjacency(&self) -> &VertexAdjacency {
        &self.adjacency
    }

    /// The deterministic parallel scatter plan (see [`crate::partition`]).
    pub fn scatter_plan(&self) -> &ScatterPlan {
        &self.plan
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Total rest area, m^2 (summed in element order).
    pub fn area(&self) -> Real {
        self.elements.iter().map(|e| e.area).sum()
    }

    /// The current positions of one triangle's vertices.
    #[inline]
    pub fn gather(&self, triangle: usize, x: &[Vec2]) -> [Vec2; 3] {
        self.triangles[triangle].map(|i| x[i as usize])
    }

    /// Lumped (diagonal) masses, kg: each triangle gives a third of `density * area` to each
    /// of its vertices. `density` in kg/m^3 with unit thickness.
    pub fn lumped_masses_from_density(&self, density: Real) -> Result<Vec<Real>, MeshError> {
        if !density.is_finite() || density <= 0.0 {
            return Err(MeshError::BadMassInput {
                field: "density",
                value: density,
            });
        }
        let mut m = vec![0.0; self.n_vertices()];
        for (tri, el) in self.triangles.iter().zip(&self.elements) {
            let third = density * el.area / 3.0;
            tri.iter().for_each(|&i| m[i as usize] += third);
        }
        Ok(m)
    }

    /// Lumped masses from one density per triangle (kg/m^3 with unit thickness; a body of
    /// several materials): each triangle gives a third of its mass to each corner. Errors name
    /// the first density that is not finite and > 0, or a length that is not one per triangle.
    pub fn lumped_masses_from_densities(&self, densities: &[Real]) -> Result<Vec<Real>, MeshError> {
        if densities.len() != self.n_triangles() {
            return Err(MeshError::BadMassInput {
                field: "densities.len()",
                value: densities.len() as Real,
            });
        }
        if let Some(&d) = densities.iter().find(|d| !(d.is_finite() && **d > 0.0)) {
            return Err(MeshError::BadMassInput {
                field: "density",
                value: d,
            });
        }
        let mut m = vec![0.0; self.n_vertices()];
        for ((tri, el), &density) in self.triangles.iter().zip(&self.elements).zip(densities) {
            let third = density * el.area / 3.0;
            tri.iter().for_each(|&i| m[i as usize] += third);
        }
        Ok(m)
    }

    /// Lumped masses for a given total mass (kg), spread with uniform density.
    pub fn lumped_masses_from_total_mass(&self, total_mass: Real) -> Result<Vec<Real>, MeshError> {
        if !total_mass.is_finite() || total_mass <= 0.0 {
            return Err(MeshError::BadMassInput {
                field: "total_mass",
                value: total_mass,
            });
        }
        self.lumped_masses_from_density(total_mass / self.area())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        Mesh::from_arrays(
            &[[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]],
            &[[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn adjacency_lists_are_sorted_by_triangle() {
        let m = square();
        assert_eq!(m.adjacency().of(0), &[(0, 0), (1, 0)]);
        assert_eq!(m.adjacency().of(2), &[(0, 2), (1, 1)]);
        assert_eq!(m.adjacency().of(3), &[(1, 2)]);
    }

    #[test]
    fn lumped_masses_sum_to_total_mass() {
        let m = square();
        let masses = m.lumped_masses_from_total_mass(3.0).unwrap();
        assert!((masses.iter().sum::<Real>() - 3.0).abs() < 1e-15);
        assert!((masses[0] - 1.0).abs() < 1e-15); // two triangles of mass 1.5, a third each
        assert!(m.lumped_masses_from_density(0.0).is_err());
        assert!(m.lumped_masses_from_total_mass(Real::NAN).is_err());
        // Per-triangle densities: the second triangle three times as dense.
        let masses = m.lumped_masses_from_densities(&[1.0, 3.0]).unwrap();
        assert_eq!(masses, vec![4.0 / 3.0, 1.0 / 3.0, 4.0 / 3.0, 1.0]);
        assert!(m.lumped_masses_from_densities(&[1.0]).is_err());
        assert!(m.lumped_masses_from_densities(&[1.0, -1.0]).is_err());
    }

    #[test]
    fn region_tags_need_one_per_triangle_and_a_name_each() {
        let mut m = square();
        assert!(m.region_tags().is_empty());
        let e = m.set_regions(vec![0], vec!["a".into()]).unwrap_err();
        assert_eq!(e.to_string(), "regions: 1 tags for 2 triangles");
        let e = m
            .set_regions(vec![0, 2], vec!["a".into(), "b".into()])
            .unwrap_err();
        assert!(e.to_string().contains("triangle 1 has tag 2"), "{e}");
        m.set_regions(vec![0, 1], vec!["soft".into(), "bone".into()])
            .unwrap();
        assert_eq!(
            (m.region_tags(), &m.region_names()[1][..]),
            (&[0, 1][..], "bone")
        );
    }

    #[test]
    fn errors_name_the_offending_index() {
        let v = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let e = Mesh::from_arrays(&v, &[[0, 1, 2], [1, 3, 2], [0, 2, 1]]).unwrap_err();
        assert_eq!(
            e.to_string().split(':').next().unwrap(),
            "triangles[2] = [0, 2, 1]"
        );
        assert!(e.to_string().contains("inverted rest triangle"));
        let e = Mesh::from_arrays(&v, &[[0, 1, 7]]).unwrap_err();
        assert!(e.to_string().contains("index 7 is out of range"));
        let e = Mesh::from_arrays(&v, &[[0, 1, 2]]).unwrap_err();
        assert_eq!(e, MeshError::UnreferencedVertex(3));
        let e = Mesh::from_arrays(&[[0.0, Real::NAN]], &[[0, 0, 0]]).unwrap_err();
        assert!(matches!(e, MeshError::NonFiniteVertex { vertex: 0, .. }));
        assert_eq!(
            Mesh::new(vec![], vec![]).unwrap_err(),
            MeshError::Empty("vertices")
        );
        let e = Mesh::from_arrays(&v, &[[0, 1, 1]]).unwrap_err();
        assert!(matches!(e, MeshError::RepeatedIndex { triangle: 0, .. }));
    }
}
