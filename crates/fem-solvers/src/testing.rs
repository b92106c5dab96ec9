//! The case A beam and models built on it, and a brute-force contact oracle, for tests,
//! benches and examples.
//!
//! The meshes come from the framework's one rectangle generator,
//! [`fem_core::structured::rectangle`] (re-exported here): node `(i, j)` sits at
//! `origin + (width i / nx, height j / ny)` with index `j (nx + 1) + i` ([`node_index`]), and
//! with the default [`Diagonal::Right`] each cell is split along its `(i, j)-(i + 1, j + 1)`
//! diagonal into the counter-clockwise triangles `(a, b, c)` and `(a, c, d)`, with
//! `a = (i, j)`, `b = (i + 1, j)`, `c = (i + 1, j + 1)`, `d = (i, j + 1)`. Triangles are
//! numbered cell by cell, row by row.

use fem_core::energy::Energy;
use fem_core::math::{Real, Vec2};
use fem_core::mesh::{Mesh, MeshError};
pub use fem_core::structured::{Diagonal, NodeOrder, RectangleParams, rectangle};

use crate::error::SolverError;
use crate::model::Model;
use crate::model::bc::Region;
use crate::model::state::State;

/// Length of the case A beam, m.
pub const BEAM_LENGTH: Real = 5.0;
/// Height of the case A beam, m.
pub const BEAM_HEIGHT: Real = 1.0;

/// The case A beam (5 m x 1 m, lower-left corner at the origin) with `nx` x `ny` cells.
pub fn beam_mesh(nx: usize, ny: usize) -> Result<Mesh, MeshError> {
    rectangle(&RectangleParams::new(BEAM_LENGTH, BEAM_HEIGHT, nx, ny))
}

/// The index of grid node `(i, j)` in a rectangle mesh with `nx` columns of cells:
/// `j (nx + 1) + i` (as [`RectangleParams::node`]).
pub fn node_index(i: usize, j: usize, nx: usize) -> usize {
    j * (nx + 1) + i
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
    let mut model = Model::with_total_mass(mesh, energy, 1.0)?;
    model.set_standard_gravity();
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

/// Whether `p` lies strictly inside the closed polygon (even-odd rule).
fn inside(polygon: &[Vec2], p: Vec2) -> bool {
    let n = polygon.len();
    let mut c = false;
    for k in 0..n {
        let (a, b) = (polygon[k], polygon[(k + 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x) {
            c = !c;
        }
    }
    c
}

/// A contact oracle independent of any solver's candidate pairs: panics when a vertex lies on
/// or below the ground or inside an obstacle, or an obstacle corner inside a triangle of the
/// body. Returns the smallest height of a vertex above the ground (infinite without one).
/// Brute force over every vertex, triangle and corner: for tests.
pub fn assert_apart<E: Energy>(model: &Model<E>, state: &State) -> Real {
    let mut lowest = Real::INFINITY;
    if let Some(g) = model.ground() {
        for (v, p) in state.x.iter().enumerate() {
            let h = (p - g.point).dot(&g.normal);
            assert!(
                h > 0.0,
                "t = {}: vertex {v} at {p:?} on or below the ground",
                state.t
            );
            lowest = lowest.min(h);
        }
    }
    for (o, (obs, body)) in model.obstacles().iter().zip(&state.bodies).enumerate() {
        let poly = obs.world_polygon(body);
        for (v, p) in state.x.iter().enumerate() {
            assert!(
                !inside(&poly, *p),
                "t = {}: vertex {v} inside obstacle {o}",
                state.t
            );
        }
        for (k, c) in poly.iter().enumerate() {
            for (t, tri) in model.mesh().triangles().iter().enumerate() {
                let tri = tri.map(|i| state.x[i as usize]);
                assert!(
                    !inside(&tri, *c),
                    "t = {}: corner {k} of obstacle {o} inside triangle {t}",
                    state.t
                );
            }
        }
    }
    lowest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beam_layout_is_the_documented_one() {
        let m = beam_mesh(20, 4).unwrap();
        assert_eq!(m.n_vertices(), 21 * 5);
        assert_eq!(m.n_triangles(), 160);
        assert_eq!(m.vertices()[node_index(20, 0, 20)], Vec2::new(5.0, 0.0));
        assert_eq!(m.vertices()[node_index(3, 4, 20)], Vec2::new(0.75, 1.0));
        assert_eq!(m.triangles()[0], [0, 1, 22]);
        assert_eq!(m.triangles()[1], [0, 22, 21]);
        assert!((m.area() - 5.0).abs() < 1e-12);
        assert_eq!(beam_cells_for(64_000), (400, 80));
    }
}
