//! The structured triangle mesh of an axis-aligned rectangle (cases A-C: the cantilever and the
//! bar), with a selectable diagonal pattern: the framework's one rectangle generator (scenes,
//! tests, benchmarks and `fem_solvers::testing` all use it). Its default numbering,
//! [`NodeOrder::XFastest`], is the one they share; [`NodeOrder::YFastest`] is there for the
//! cross-framework benchmark, whose peer scripts number the beam that way.
//!
//! ```
//! use fem_core::structured::{Diagonal, RectangleParams, rectangle};
//! let params = RectangleParams { diagonal: Diagonal::Alternating, ..RectangleParams::new(5.0, 1.0, 10, 2) };
//! let mesh = rectangle(&params).unwrap();
//! assert_eq!(mesh.n_triangles(), 40);
//! // Node (i, j) = (10, 2) is the upper-right corner.
//! assert_eq!(mesh.vertices()[params.node(10, 2)], nalgebra::Vector2::new(5.0, 1.0));
//! ```

use crate::math::{Real, Vec2};
use crate::mesh::{Mesh, MeshError};

/// How each grid cell is split into triangles. Named `right`, `left`, `alternating` and
/// `crossed` in files (with the `serde` feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
#[non_exhaustive]
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

/// The order of the grid nodes, and of the cells, in a [`rectangle`] mesh.
///
/// The numbering decides which vertices sit close in memory, and so the speed of the loops
/// over a long mesh (not their results, beyond the order of floating-point sums and of
/// Gauss-Seidel sweeps): numbering across the short side first keeps each triangle's vertices
/// near each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum NodeOrder {
    /// Rows from the bottom, x fastest: node `(i, j)` is `j (nx + 1) + i`; cells row by row.
    /// Default (the scenes' rectangles).
    #[default]
    XFastest,
    /// Columns from the left, y fastest: node `(i, j)` is `i (ny + 1) + j`; cells column by
    /// column (the layout of the cross-framework benchmark scripts; the better one for a mesh
    /// much longer than high).
    YFastest,
}

/// Parameters of [`rectangle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectangleParams {
    /// Lower-left corner (metres). Default (0, 0).
    pub origin: [Real; 2],
    /// Width along x (metres, > 0).
    pub width: Real,
    /// Height along y (metres, > 0).
    pub height: Real,
    /// Cells along x (>= 1).
    pub nx: usize,
    /// Cells along y (>= 1).
    pub ny: usize,
    /// Diagonal pattern. Default [`Diagonal::Right`].
    pub diagonal: Diagonal,
    /// Node numbering. Default [`NodeOrder::XFastest`].
    pub order: NodeOrder,
}

impl RectangleParams {
    /// A `width` x `height` rectangle at the origin with `nx` x `ny` cells and `/` diagonals.
    pub fn new(width: Real, height: Real, nx: usize, ny: usize) -> Self {
        Self {
            origin: [0.0, 0.0],
            width,
            height,
            nx,
            ny,
            diagonal: Diagonal::Right,
            order: NodeOrder::XFastest,
        }
    }

    /// The index of grid node `(i, j)` (column `i` in `0..=nx`, row `j` in `0..=ny`):
    /// `j (nx + 1) + i` with [`NodeOrder::XFastest`], `i (ny + 1) + j` with
    /// [`NodeOrder::YFastest`].
    pub fn node(&self, i: usize, j: usize) -> usize {
        match self.order {
            NodeOrder::XFastest => j * (self.nx + 1) + i,
            NodeOrder::YFastest => i * (self.ny + 1) + j,
        }
    }
}

/// Most cells accepted by [`rectangle`] (guards against accidental huge allocations).
const MAX_CELLS: usize = 50_000_000;

/// Builds the structured mesh. Grid vertex `(i, j)` (column `i`, row `j`) has index
/// [`RectangleParams::node`] (`j (nx + 1) + i` by default); [`Diagonal::Crossed`] appends the
/// cell centres after the grid vertices. Triangles are counter-clockwise, numbered cell by
/// cell in the same order as the nodes (by default row by row from the bottom). Fails (naming the value) on a non-positive or non-finite size,
/// a non-finite origin, or a cell count outside `1..=50_000_000` in total.
pub fn rectangle(params: &RectangleParams) -> Result<Mesh, MeshError> {
    let RectangleParams {
        origin,
        width,
        height,
        nx,
        ny,
        diagonal,
        order,
    } = *params;
    let invalid = |message: String| Err(MeshError::Rectangle(message));
    if !(width.is_finite() && width > 0.0 && height.is_finite() && height > 0.0) {
        return invalid(format!(
            "width and height must be finite and > 0, got {width} x {height}"
        ));
    }
    if !(origin[0].is_finite() && origin[1].is_finite()) {
        return invalid(format!("origin {origin:?} is not finite"));
    }
    if nx == 0 || ny == 0 || nx.saturating_mul(ny) > MAX_CELLS {
        return invalid(format!(
            "cell counts must be in 1..={MAX_CELLS} in total, got {nx} x {ny}"
        ));
    }
    let centres = if diagonal == Diagonal::Crossed {
        nx * ny
    } else {
        0
    };
    // Grid nodes and cells in the numbering's order: the first index of the pair that runs
    // fastest.
    let grid = move |n_i: usize, n_j: usize| {
        (0..n_i * n_j).map(move |k| match order {
            NodeOrder::YFastest => (k / n_j, k % n_j),
            NodeOrder::XFastest => (k % n_i, k / n_i),
        })
    };
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) + centres);
    for (i, j) in grid(nx + 1, ny + 1) {
        vertices.push(Vec2::new(
            origin[0] + width * i as Real / nx as Real,
            origin[1] + height * j as Real / ny as Real,
        ));
    }
    let per_cell = if diagonal == Diagonal::Crossed { 4 } else { 2 };
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(per_cell * nx * ny);
    let id = |i: usize, j: usize| params.node(i, j) as u32;
    for (i, j) in grid(nx, ny) {
        let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
        let right = match diagonal {
            Diagonal::Right => true,
            Diagonal::Left => false,
            Diagonal::Alternating => (i + j) % 2 == 0,
            Diagonal::Crossed => {
                let m = vertices.len() as u32;
                let (pa, pc) = (vertices[a as usize], vertices[c as usize]);
                vertices.push(Vec2::new(0.5 * (pa.x + pc.x), 0.5 * (pa.y + pc.y)));
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
    Mesh::new(vertices, triangles)
}

/// The parameters of [`box_mesh`]: an axis-aligned box `[x0, x0 + width] x [y0, y0 + height] x
/// [z0, z0 + depth]` of `nx x ny x nz` cubes (case A's beam extruded by `depth`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxParams {
    /// The corner with the smallest coordinates, m.
    pub origin: [Real; 3],
    /// Extent along x, m.
    pub width: Real,
    /// Extent along y, m.
    pub height: Real,
    /// Extent along z, m.
    pub depth: Real,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Cells along z.
    pub nz: usize,
}

impl BoxParams {
    /// A box at the origin.
    pub fn new(width: Real, height: Real, depth: Real, nx: usize, ny: usize, nz: usize) -> Self {
        BoxParams {
            origin: [0.0; 3],
            width,
            height,
            depth,
            nx,
            ny,
            nz,
        }
    }

    /// The index of grid node `(i, j, k)`: `k (nx + 1)(ny + 1) + j (nx + 1) + i` (x fastest,
    /// then y, then z, so the nodes of the plane `k = 0` are numbered as
    /// [`rectangle`]'s nodes).
    pub fn node(&self, i: usize, j: usize, k: usize) -> usize {
        (k * (self.ny + 1) + j) * (self.nx + 1) + i
    }
}

/// The structured tetrahedral mesh of a box: each cube split into six tetrahedra around its
/// main diagonal (from corner `(0, 0, 0)` to `(1, 1, 1)`; Kuhn's subdivision), one per order of
/// the three axes. Every cube is split the same way, so neighbouring cubes' faces are split
/// along the same diagonal and the mesh is conforming. All tetrahedra are positively oriented,
/// with volume `width height depth / (6 nx ny nz)`.
///
/// ```
/// use fem_core::structured::{BoxParams, box_mesh};
/// let params = BoxParams::new(5.0, 1.0, 0.5, 10, 2, 1);
/// let mesh = box_mesh(&params).unwrap();
/// assert_eq!(mesh.n_cells(), 6 * 20);
/// assert!((mesh.measure() - 2.5).abs() < 1e-12);
/// ```
pub fn box_mesh(
    params: &BoxParams,
) -> Result<crate::simplex::SimplexMesh<crate::dim::D3>, crate::simplex::SimplexMeshError> {
    use crate::dim::Vec3;
    let BoxParams {
        origin,
        width,
        height,
        depth,
        nx,
        ny,
        nz,
    } = *params;
    let invalid = |message: String| Err(crate::simplex::SimplexMeshError::Box(message));
    if ![width, height, depth]
        .iter()
        .all(|v| v.is_finite() && *v > 0.0)
    {
        return invalid(format!(
            "width, height and depth must be finite and > 0, got {width} x {height} x {depth}"
        ));
    }
    if !origin.iter().all(|v| v.is_finite()) {
        return invalid(format!("origin {origin:?} is not finite"));
    }
    if nx == 0 || ny == 0 || nz == 0 || nx.saturating_mul(ny).saturating_mul(nz) > MAX_CELLS {
        return invalid(format!(
            "cell counts must be in 1..={MAX_CELLS} in total, got {nx} x {ny} x {nz}"
        ));
    }
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                vertices.push(Vec3::new(
                    origin[0] + width * i as Real / nx as Real,
                    origin[1] + height * j as Real / ny as Real,
                    origin[2] + depth * k as Real / nz as Real,
                ));
            }
        }
    }
    // The six orders of the axes; the odd permutations give negatively oriented tetrahedra,
    // whose middle two vertices are swapped.
    const ORDERS: [([usize; 3], bool); 6] = [
        ([0, 1, 2], true),
        ([1, 2, 0], true),
        ([2, 0, 1], true),
        ([0, 2, 1], false),
        ([2, 1, 0], false),
        ([1, 0, 2], false),
    ];
    let mut cells = Vec::with_capacity(6 * nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for (order, even) in ORDERS {
                    let mut corner = [i, j, k];
                    let mut tet = [params.node(i, j, k) as u32, 0, 0, 0];
                    for (step, &axis) in order.iter().enumerate() {
                        corner[axis] += 1;
                        tet[step + 1] = params.node(corner[0], corner[1], corner[2]) as u32;
                    }
                    if !even {
                        tet.swap(1, 2);
                    }
                    cells.push(tet);
                }
            }
        }
    }
    crate::simplex::SimplexMesh::new(vertices, cells)
}
