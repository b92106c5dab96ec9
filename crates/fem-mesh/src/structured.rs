//! Structured triangle meshes of an axis-aligned rectangle (cases A-C: the cantilever and the
//! bar), with a selectable diagonal pattern.

use crate::error::{MeshError, Result};
use crate::types::Mesh2;

/// How each grid cell is split into triangles. Named `right`, `left`, `alternating` and
/// `crossed` in files (serde).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Diagonal {
    /// Every cell split along the diagonal from its lower-left to its upper-right corner (`/`).
    /// Default.
    #[default]
    Right,
    /// Every cell split along the diagonal from its lower-right to its upper-left corner (`\`).
    Left,
    /// Alternating `/` and `\` in a checkerboard (a symmetric "union jack" pattern over 2x2 cells).
    Alternating,
    /// Four triangles per cell around an extra vertex at the cell centre (isotropic, twice the
    /// triangles).
    Crossed,
}

impl Diagonal {
    /// Every pattern.
    pub const ALL: [Diagonal; 4] = [
        Diagonal::Right,
        Diagonal::Left,
        Diagonal::Alternating,
        Diagonal::Crossed,
    ];

    /// The name in files (`right`, `left`, `alternating`, `crossed`).
    pub fn name(self) -> &'static str {
        match self {
            Diagonal::Right => "right",
            Diagonal::Left => "left",
            Diagonal::Alternating => "alternating",
            Diagonal::Crossed => "crossed",
        }
    }
}

/// Parameters of [`rectangle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectangleParams {
    /// Lower-left corner (metres). Default (0, 0).
    pub origin: [f64; 2],
    /// Width along x (metres, > 0).
    pub width: f64,
    /// Height along y (metres, > 0).
    pub height: f64,
    /// Cells along x (>= 1).
    pub nx: usize,
    /// Cells along y (>= 1).
    pub ny: usize,
    /// Diagonal pattern. Default [`Diagonal::Right`].
    pub diagonal: Diagonal,
}

impl RectangleParams {
    /// A `width` x `height` rectangle at the origin with `nx` x `ny` cells and `/` diagonals.
    pub fn new(width: f64, height: f64, nx: usize, ny: usize) -> Self {
        Self {
            origin: [0.0, 0.0],
            width,
            height,
            nx,
            ny,
            diagonal: Diagonal::Right,
        }
    }
}

/// Most cells accepted by [`rectangle`] (guards against accidental huge allocations).
const MAX_CELLS: usize = 50_000_000;

/// Builds the structured mesh. Grid vertex `(i, j)` (column `i`, row `j`) has index
/// `j * (nx + 1) + i`; [`Diagonal::Crossed`] appends the cell centres after the grid vertices.
/// Triangles are counter-clockwise.
pub fn rectangle(params: &RectangleParams) -> Result<Mesh2> {
    let RectangleParams {
        origin,
        width,
        height,
        nx,
        ny,
        diagonal,
    } = *params;
    if !(width.is_finite() && width > 0.0 && height.is_finite() && height > 0.0) {
        return Err(MeshError::invalid(
            "rectangle",
            format!("width and height must be positive, got {width} x {height}"),
        ));
    }
    if !(origin[0].is_finite() && origin[1].is_finite()) {
        return Err(MeshError::invalid(
            "rectangle",
            format!("origin {origin:?} is not finite"),
        ));
    }
    if nx == 0 || ny == 0 || nx.saturating_mul(ny) > MAX_CELLS {
        return Err(MeshError::invalid(
            "rectangle",
            format!("cell counts must be in 1..={MAX_CELLS} in total, got {nx} x {ny}"),
        ));
    }
    let mut mesh = Mesh2::default();
    for j in 0..=ny {
        for i in 0..=nx {
            mesh.vertices.push([
                origin[0] + width * i as f64 / nx as f64,
                origin[1] + height * j as f64 / ny as f64,
            ]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            let right = match diagonal {
                Diagonal::Right => true,
                Diagonal::Left => false,
                Diagonal::Alternating => (i + j) % 2 == 0,
                Diagonal::Crossed => {
                    let m = mesh.vertices.len();
                    let [pa, pc] = [mesh.vertices[a], mesh.vertices[c]];
                    mesh.vertices
                        .push([0.5 * (pa[0] + pc[0]), 0.5 * (pa[1] + pc[1])]);
                    mesh.triangles
                        .extend([[a, b, m], [b, c, m], [c, d, m], [d, a, m]]);
                    continue;
                }
            };
            if right {
                mesh.triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                mesh.triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    Ok(mesh)
}
