//! Shared set-up for the integration tests: the case A material and beam models, and beams
//! with every diagonal pattern.
#![allow(dead_code)]

use fem_core::PlaneModel;
use fem_core::energy::Energy;
use fem_core::material::{Lame, Material};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_solvers::Model;
use fem_solvers::testing::{BEAM_HEIGHT, BEAM_LENGTH, beam_mesh, node_index};

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
#[derive(Clone, Copy, Debug)]
pub enum Pattern {
    /// `/` in every cell.
    Right,
    /// `\` in every cell.
    Left,
    /// `/` and `\` in a checkerboard.
    Alternating,
    /// Four triangles around the cell centre.
    Crossed,
}

pub const PATTERNS: [Pattern; 4] = [
    Pattern::Right,
    Pattern::Left,
    Pattern::Alternating,
    Pattern::Crossed,
];

/// The case A beam with `nx` x `ny` cells split by `pattern`; grid vertex `(i, j)` has the
/// index of [`node_index`], cell centres (crossed) follow the grid.
pub fn beam(nx: usize, ny: usize, pattern: Pattern) -> Mesh {
    let (hx, hy) = (BEAM_LENGTH / nx as Real, BEAM_HEIGHT / ny as Real);
    let mut vertices = Vec::new();
    for i in 0..=nx {
        for j in 0..=ny {
            vertices.push(Vec2::new(i as Real * hx, j as Real * hy));
        }
    }
    let mut triangles = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            let n = |i, j| node_index(i, j, ny) as u32;
            let (a, b, c, d) = (n(i, j), n(i + 1, j), n(i + 1, j + 1), n(i, j + 1));
            let right = match pattern {
                Pattern::Right => true,
                Pattern::Left => false,
                Pattern::Alternating => (i + j) % 2 == 0,
                Pattern::Crossed => {
                    let m = vertices.len() as u32;
                    vertices.push(Vec2::new((i as Real + 0.5) * hx, (j as Real + 0.5) * hy));
                    triangles.extend([[a, b, m], [b, c, m], [c, d, m], [d, a, m]]);
                    continue;
                }
            };
            if right {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    Mesh::new(vertices, triangles).unwrap()
}
