//! Structured rectangle meshes for tests, benches and examples (the case A beam and friends).
//!
//! The layout is the one the cross-framework benchmarks of the explicit kernel use (so their
//! timings compare the same mesh): node `(i, j)` sits at
//! `origin + (i * width / nx, j * height / ny)` with index `i * (ny + 1) + j`, and each cell is
//! split along its `(i, j)-(i + 1, j + 1)` diagonal into the counter-clockwise triangles
//! `(a, b, c)` and `(a, c, d)`, with `a = (i, j)`, `b = (i + 1, j)`, `c = (i + 1, j + 1)`,
//! `d = (i, j + 1)`. Triangles are numbered cell by cell, `i` slowest.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};
use fem_core::mesh::{Mesh, MeshError};

use crate::{Model, Region, SolverError, State};

/// Length of the case A beam, m.
pub const BEAM_LENGTH: Real = 5.0;
/// Height of the case A beam, m.
pub const BEAM_HEIGHT: Real = 1.0;

/// A `width` x `height` rectangle with its lower-left corner at `origin`, split into
/// `nx` x `ny` cells of two triangles each (`2 nx ny` triangles).
pub fn rectangle_mesh(
    origin: Vec2,
    width: Real,
    height: Real,
    nx: usize,
    ny: usize,
) -> Result<Mesh, MeshError> {
    let node = |i: usize, j: usize| (i * (ny + 1) + j) as u32;
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1));
    for i in 0..=nx {
        for j in 0..=ny {
            vertices.push(
                origin
                    + Vec2::new(
                        i as Real * (width / nx as Real),
                        j as Real * (height / ny as Real),
                    ),
            );
        }
    }
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for i in 0..nx {
        for j in 0..ny {
            let (a, b, c, d) = (
                node(i, j),
                node(i + 1, j),
                node(i + 1, j + 1),
                node(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh::new(vertices, triangles)
}

/// The case A beam (5 m x 1 m, lower-left corner at the origin) with `nx` x `ny` cells.
pub fn beam_mesh(nx: usize, ny: usize) -> Result<Mesh, MeshError> {
    rectangle_mesh(Vec2::zeros(), BEAM_LENGTH, BEAM_HEIGHT, nx, ny)
}

/// The index of node `(i, j)` in a mesh from [`rectangle_mesh`] with `ny` rows of cells.
pub fn node_index(i: usize, j: usize, ny: usize) -> usize {
    i * (ny + 1) + j
}

/// Cells `(nx, ny)` of a beam mesh with about `triangles` triangles and the 5:1 aspect of the
/// beam (square cells): `nx = 5 ny`, `2 nx ny ~ triangles`.
pub fn beam_cells_for(triangles: usize) -> (usize, usize) {
    let ny = ((triangles as Real / 10.0).sqrt().round() as usize).max(1);
    (5 * ny, ny)
}

/// The case A cantilever on a beam mesh (from [`beam_mesh`]): total mass 1 kg, standard
/// gravity, left edge (`x = 0`) pinned.
pub fn cantilever<E: Energy>(mesh: Mesh, energy: E) -> Result<Model<E>, SolverError> {
    let mut model = Model::with_total_mass(mesh, energy, 1.0)?.with_standard_gravity();
    model.pin(&Region::in_box(
        Vec2::new(0.0, 0.0),
        Vec2::new(0.0, BEAM_HEIGHT),
    ))?;
    Ok(model)
}

/// The model's rest shape stretched by `factor` along x, at rest: every element is strained,
/// so no position-based constraint is skipped as being at rest.
pub fn stretched<E: Energy>(model: &Model<E>, factor: Real) -> Result<State, SolverError> {
    let x = model
        .mesh()
        .vertices()
        .iter()
        .map(|p| Vec2::new(factor * p.x, p.y))
        .collect();
    State::new(model, x, vec![Vec2::zeros(); model.mesh().n_vertices()])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beam_layout_is_the_documented_one() {
        let m = beam_mesh(20, 4).unwrap();
        assert_eq!(m.n_vertices(), 21 * 5);
        assert_eq!(m.n_triangles(), 160);
        assert_eq!(m.vertices()[node_index(20, 0, 4)], Vec2::new(5.0, 0.0));
        assert_eq!(m.triangles()[0], [0, 5, 6]);
        assert_eq!(m.triangles()[1], [0, 6, 1]);
        assert!((m.area() - 5.0).abs() < 1e-12);
        assert_eq!(beam_cells_for(64_000), (400, 80));
    }
}
