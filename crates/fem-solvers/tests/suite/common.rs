//! Shared set-up for the integration tests: the case A material and beam models, and beams
//! with every diagonal pattern.
#![allow(dead_code)]

use fem_core::PlaneModel;
use fem_core::energy::Energy;
use fem_core::material::{Lame, Material};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_solvers::Model;
use fem_solvers::testing::{BEAM_HEIGHT, BEAM_LENGTH, RectangleParams, beam_mesh, rectangle};

/// Case A material: E = 1000 Pa, nu = 0.3, plane strain.
pub fn case_a_lame() -> Lame {
    Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

/// Lamé parameters for Young's modulus `e` (Pa), nu = 0.3, plane strain.
pub fn lame(e: Real) -> Lame {
    Material::new(e, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

/// The case A beam with `nx` x `ny` cells, total mass 1 kg, no gravity, nothing pinned.
pub fn free_beam<E: Energy>(energy: E, nx: usize, ny: usize) -> Model<E> {
    Model::with_total_mass(beam_mesh(nx, ny).unwrap(), energy, 1.0).unwrap()
}

/// The case A cantilever: left edge pinned, standard gravity.
pub fn cantilever<E: Energy>(energy: E, nx: usize, ny: usize) -> Model<E> {
    fem_solvers::testing::cantilever(beam_mesh(nx, ny).unwrap(), energy).unwrap()
}

/// Bit patterns of a vector of points, for exact comparisons (`-0.0 != 0.0`, NaN == NaN).
pub fn bits(x: &[Vec2]) -> Vec<[u64; 2]> {
    x.iter().map(|p| [p.x.to_bits(), p.y.to_bits()]).collect()
}

/// How each cell of a structured beam is split.
pub use fem_solvers::testing::Diagonal as Pattern;

pub const PATTERNS: [Pattern; 4] = Pattern::ALL;

/// The case A beam with `nx` x `ny` cells split by `pattern`; grid vertex `(i, j)` has the
/// index of [`node_index`](fem_solvers::testing::node_index), cell centres (crossed) follow
/// the grid.
pub fn beam(nx: usize, ny: usize, pattern: Pattern) -> Mesh {
    rectangle(&RectangleParams {
        diagonal: pattern,
        ..RectangleParams::new(BEAM_LENGTH, BEAM_HEIGHT, nx, ny)
    })
    .unwrap()
}
