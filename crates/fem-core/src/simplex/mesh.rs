//! A validated mesh of linear simplices of either dimension, with rest data, the
//! vertex-to-cell adjacency of the deterministic gather, lumped masses and the boundary.

use crate::dim::{Dense, Dim};
use crate::element::{ElementError, ElementTolerance};
use crate::math::Real;

use super::Simplex;

/// Why a simplex mesh is rejected (each message names the offending index).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimplexMeshError {
    /// No vertices or no cells.
    #[error("mesh has no {0}")]
    Empty(&'static str),
    /// More vertices than 32-bit indices can address.
    #[error("mesh has {0} vertices; at most 4294967295 are supported")]
    TooManyVertices(usize),
    /// A coordinate is NaN or infinite.
    #[error("vertices[{0}]: coordinates must be finite")]
    NonFiniteVertex(usize),
    /// A cell names a vertex that does not exist.
    #[error(
        "cells[{cell}] = {indices:?}: index {index} is out of range (mesh has {n_vertices} vertices)"
    )]
    IndexOutOfRange {
        /// Cell index.
        cell: usize,
        /// Its vertex indices.
        indices: Vec<u32>,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        n_vertices: usize,
    },
    /// A cell uses one vertex twice.
    #[error("cells[{cell}] = {indices:?}: repeated vertex index")]
    RepeatedIndex {
        /// Cell index.
        cell: usize,
        /// Its vertex indices.
        indices: Vec<u32>,
    },
    /// The rest simplex is degenerate or negatively oriented.
    #[error("cells[{cell}] = {indices:?}: {message}")]
    Element {
        /// Cell index.
        cell: usize,
        /// Its vertex indices.
        indices: Vec<u32>,
        /// What is wrong with it.
        source: ElementError,
        /// The same, in words naming the simplex.
        message: String,
    },
    /// A facet (an edge in 2D, a triangle in 3D) is shared by more than two cells, or twice
    /// with the same orientation (two cells on the same side of it: they overlap).
    #[error(
        "the facet {facet:?} is shared by cells[{first}] and cells[{second}] on the same side, or by more than two cells: cells may meet only face to face"
    )]
    BadFacet {
        /// The facet's vertices (sorted).
        facet: Vec<u32>,
        /// One cell on it.
        first: usize,
        /// Another.
        second: usize,
    },
    /// A vertex belongs to no cell.
    #[error("vertices[{0}] is used by no cell (it would have zero mass)")]
    UnreferencedVertex(usize),
    /// A lumped-mass input is not a finite positive number.
    #[error("density = {0}: must be a finite number > 0")]
    BadDensity(Real),
    /// A structured box's parameters are unusable
    /// ([`structured::box_mesh`](crate::structured::box_mesh)).
    #[error("box: {0}")]
    Box(String),
}

/// A validated mesh of [`Simplex<D>`] cells.
#[derive(Clone, Debug)]
pub struct SimplexMesh<D: Dim> {
    vertices: Vec<D::Vector>,
    cells: Vec<D::Cell>,
    elements: Vec<Simplex<D>>,
    /// Compressed rows: the `(cell, corner)` pairs of vertex `v` are
    /// `adjacency[offsets[v]..offsets[v + 1]]`, in increasing cell order.
    offsets: Vec<u32>,
    adjacency: Vec<(u32, u8)>,
    /// The boundary facets as `(cell, opposite corner)`, in cell order.
    boundary: Vec<(u32, u8)>,
}

/// The corners of the facet opposite corner `a`, ordered so that its normal (the
/// counter-clockwise one in 3D, the right-hand one of the edge direction in 2D) points out of a
/// positively oriented cell.
pub(crate) fn facet_corners(d: usize, a: usize) -> &'static [usize] {
    const TRI: [[usize; 2]; 3] = [[1, 2], [2, 0], [0, 1]];
    const TET: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    if d == 2 { &TRI[a] } else { &TET[a] }
}

impl<D: Dim> SimplexMesh<D> {
    /// Validate with the default [`ElementTolerance`]: non-empty, finite coordinates, indices in
    /// range and distinct, every rest cell non-degenerate and positively oriented, every
    /// facet shared by at most two cells from opposite sides (so no cell repeats another and
    /// neighbours do not fold over each other), and every vertex used. Cells that overlap
    /// without sharing a facet are not detected (the 2D [`crate::mesh::Mesh`] checks that
    /// too).
    pub fn new(vertices: Vec<D::Vector>, cells: Vec<D::Cell>) -> Result<Self, SimplexMeshError> {
        let tol = ElementTolerance::default();
        if vertices.is_empty() {
            return Err(SimplexMeshError::Empty("vertices"));
        }
        if cells.is_empty() {
            return Err(SimplexMeshError::Empty("cells"));
        }
        if vertices.len() > u32::MAX as usize {
            return Err(SimplexMeshError::TooManyVertices(vertices.len()));
        }
        if let Some(v) = vertices.iter().position(|p| !p.all_finite()) {
            return Err(SimplexMeshError::NonFiniteVertex(v));
        }
        let n = vertices.len();
        let mut used = vec![false; n];
        let mut elements = Vec::with_capacity(cells.len());
        let mut rest = vec![D::Vector::zeros(); D::NODES];
        for (c, cell) in cells.iter().enumerate() {
            let idx = cell.as_ref();
            if let Some(&index) = idx.iter().find(|&&i| i as usize >= n) {
                return Err(SimplexMeshError::IndexOutOfRange {
                    cell: c,
                    indices: idx.to_vec(),
                    index,
                    n_vertices: n,
                });
            }
            for a in 0..idx.len() {
                if idx[a + 1..].contains(&idx[a]) {
                    return Err(SimplexMeshError::RepeatedIndex {
                        cell: c,
                        indices: idx.to_vec(),
                    });
                }
            }
            for (k, &i) in idx.iter().enumerate() {
                rest[k] = vertices[i as usize];
                used[i as usize] = true;
            }
            let element = Simplex::new(&rest, tol).map_err(|source| SimplexMeshError::Element {
                cell: c,
                indices: idx.to_vec(),
                source,
                message: describe::<D>(&source),
            })?;
            elements.push(element);
        }
        if let Some(v) = used.iter().position(|&u| !u) {
            return Err(SimplexMeshError::UnreferencedVertex(v));
        }
        let boundary = boundary_facets::<D>(&cells)?;
        let (offsets, adjacency) = vertex_adjacency::<D>(n, &cells);
        Ok(SimplexMesh {
            vertices,
            cells,
            elements,
            offsets,
            adjacency,
            boundary,
        })
    }

    /// The rest vertices.
    pub fn vertices(&self) -> &[D::Vector] {
        &self.vertices
    }

    /// The cells' vertex indices.
    pub fn cells(&self) -> &[D::Cell] {
        &self.cells
    }

    /// The cells' rest data.
    pub fn elements(&self) -> &[Simplex<D>] {
        &self.elements
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len()
    }

    /// The total rest measure (area or volume).
    pub fn measure(&self) -> Real {
        self.elements.iter().map(|e| e.measure).sum()
    }

    /// The `(cell, corner)` pairs of vertex `v`, in increasing cell order.
    #[inline]
    pub fn cells_of(&self, v: usize) -> &[(u32, u8)] {
        &self.adjacency[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Lumped masses: each cell gives `density V / (D + 1)` to each of its vertices.
    pub fn lumped_masses(&self, density: Real) -> Result<Vec<Real>, SimplexMeshError> {
        if !(density.is_finite() && density > 0.0) {
            return Err(SimplexMeshError::BadDensity(density));
        }
        let share = 1.0 / D::NODES as Real;
        Ok((0..self.n_vertices())
            .map(|v| {
                self.cells_of(v)
                    .iter()
                    .map(|&(c, _)| density * self.elements[c as usize].measure * share)
                    .sum()
            })
            .collect())
    }

    /// The boundary facets (edges in 2D, triangles in 3D), each as its vertex indices ordered
    /// so that the normal points out of the body (counter-clockwise seen from outside in 3D),
    /// in cell order.
    pub fn boundary_facets(&self) -> Vec<Vec<u32>> {
        self.boundary
            .iter()
            .map(|&(c, a)| {
                let cell = self.cells[c as usize].as_ref();
                facet_corners(D::D, a as usize)
                    .iter()
                    .map(|&k| cell[k])
                    .collect()
            })
            .collect()
    }

    /// The boundary facets as `(cell, opposite corner)` pairs.
    pub fn boundary_cells(&self) -> &[(u32, u8)] {
        &self.boundary
    }
}

/// An element error in the words of the dimension (area or volume, triangle or tetrahedron).
fn describe<D: Dim>(e: &ElementError) -> String {
    let (simplex, measure) = (D::SIMPLEX, if D::D == 2 { "area" } else { "volume" });
    match *e {
        ElementError::Degenerate { area, threshold } => {
            format!("degenerate rest {simplex} ({measure} {area:e}, below {threshold:e})")
        }
        ElementError::Inverted { area } => {
            format!("inverted rest {simplex} (negative orientation, signed {measure} {area:e})")
        }
        ElementError::NonFinite => format!("non-finite rest {simplex} vertex coordinate"),
    }
}

fn vertex_adjacency<D: Dim>(n: usize, cells: &[D::Cell]) -> (Vec<u32>, Vec<(u32, u8)>) {
    let mut offsets = vec![0u32; n + 1];
    for cell in cells {
        for &v in cell.as_ref() {
            offsets[v as usize + 1] += 1;
        }
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut next = offsets.clone();
    let mut entries = vec![(0u32, 0u8); D::NODES * cells.len()];
    for (c, cell) in cells.iter().enumerate() {
        for (corner, &v) in cell.as_ref().iter().enumerate() {
            let slot = &mut next[v as usize];
            entries[*slot as usize] = (c as u32, corner as u8);
            *slot += 1;
        }
    }
    (offsets, entries)
}

/// Pair every facet with the cells on it (a sort, no hashing: the same order on every run).
/// A facet met once is on the boundary; twice, it must be met from opposite sides (opposite
/// parity of its oriented vertex order); three times or more is refused.
fn boundary_facets<D: Dim>(cells: &[D::Cell]) -> Result<Vec<(u32, u8)>, SimplexMeshError> {
    // (sorted vertices, orientation parity, cell, opposite corner)
    let mut facets: Vec<([u32; 3], bool, u32, u8)> = Vec::with_capacity(D::NODES * cells.len());
    for (c, cell) in cells.iter().enumerate() {
        let idx = cell.as_ref();
        for a in 0..D::NODES {
            let corners = facet_corners(D::D, a);
            let mut key = [u32::MAX; 3];
            for (k, &corner) in corners.iter().enumerate() {
                key[k] = idx[corner];
            }
            let parity = sort_parity(&mut key[..corners.len()]);
            facets.push((key, parity, c as u32, a as u8));
        }
    }
    facets.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.2.cmp(&y.2)).then(x.3.cmp(&y.3)));
    let mut boundary = Vec::new();
    let mut i = 0;
    while i < facets.len() {
        let mut j = i + 1;
        while j < facets.len() && facets[j].0 == facets[i].0 {
            j += 1;
        }
        let facet = || {
            facets[i]
                .0
                .iter()
                .copied()
                .filter(|&v| v != u32::MAX)
                .collect()
        };
        match j - i {
            1 => boundary.push((facets[i].2, facets[i].3)),
            2 if facets[i].1 != facets[i + 1].1 => {}
            _ => {
                return Err(SimplexMeshError::BadFacet {
                    facet: facet(),
                    first: facets[i].2 as usize,
                    second: facets[i + 1].2 as usize,
                });
            }
        }
        i = j;
    }
    boundary.sort_unstable();
    Ok(boundary)
}

/// Sort `v` in place; `true` when the permutation that sorted it was odd.
fn sort_parity(v: &mut [u32]) -> bool {
    let mut odd = false;
    for i in 1..v.len() {
        let mut j = i;
        while j > 0 && v[j - 1] > v[j] {
            v.swap(j - 1, j);
            odd = !odd;
            j -= 1;
        }
    }
    odd
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dim::{D2, D3, Vec3};
    use crate::math::Vec2;

    fn two_tets() -> (Vec<Vec3>, Vec<[u32; 4]>) {
        let v = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        // Both positively oriented, sharing the face (1, 2, 3).
        (v, vec![[0, 1, 2, 3], [1, 4, 2, 3]])
    }

    #[test]
    fn two_tetrahedra_share_one_face_and_have_six_boundary_faces() {
        let (v, c) = two_tets();
        let mesh = SimplexMesh::<D3>::new(v, c).unwrap();
        let faces = mesh.boundary_facets();
        assert_eq!(faces.len(), 6);
        // Every boundary face's normal points away from the centroid of the body.
        let centroid: Vec3 = mesh.vertices().iter().sum::<Vec3>() / 5.0;
        for f in &faces {
            let p: Vec<Vec3> = f.iter().map(|&i| mesh.vertices()[i as usize]).collect();
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            let mid = (p[0] + p[1] + p[2]) / 3.0;
            assert!(n.dot(&(mid - centroid)) > 0.0, "{f:?}");
        }
        let m = mesh.lumped_masses(2.0).unwrap();
        assert!((m.iter().sum::<Real>() - 2.0 * mesh.measure()).abs() < 1e-15);
    }

    #[test]
    fn bad_meshes_are_refused_naming_the_cell() {
        let (v, mut c) = two_tets();
        c.push([0, 1, 2, 3]);
        let err = SimplexMesh::<D3>::new(v.clone(), c).unwrap_err();
        assert!(matches!(err, SimplexMeshError::BadFacet { .. }), "{err}");
        let err = SimplexMesh::<D3>::new(v.clone(), vec![[0, 2, 1, 3], [1, 4, 2, 3]]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "cells[0] = [0, 2, 1, 3]: inverted rest tetrahedron (negative orientation, signed volume -1.6666666666666666e-1)"
        );
        let err = SimplexMesh::<D3>::new(v.clone(), vec![[0, 1, 2, 9]]).unwrap_err();
        assert!(err.to_string().contains("index 9 is out of range"), "{err}");
        let err = SimplexMesh::<D3>::new(v, vec![[0, 1, 2, 3]]).unwrap_err();
        assert_eq!(err, SimplexMeshError::UnreferencedVertex(4));
    }

    #[test]
    fn a_square_of_two_triangles_has_four_boundary_edges() {
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        let mesh = SimplexMesh::<D2>::new(v, vec![[0, 1, 2], [0, 2, 3]]).unwrap();
        assert_eq!(mesh.boundary_facets().len(), 4);
        assert!((mesh.measure() - 1.0).abs() < 1e-15);
        // Overlapping from the same side of the shared edge is refused.
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.5, 0.2),
        ];
        let err = SimplexMesh::<D2>::new(v, vec![[0, 1, 2], [0, 3, 2]]);
        assert!(err.is_err());
    }
}
