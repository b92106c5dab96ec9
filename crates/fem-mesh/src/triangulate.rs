//! Constrained Delaunay triangulation of polygons with holes, refined for quality with spade's
//! Ruppert/Chew refinement (`ConstrainedDelaunayTriangulation::refine`, spade >= 2.15.1).
//!
//! Holes are recognised by spade's parity rule (`exclude_outer_faces`): crossing a constraint edge
//! toggles inside/outside. The refinement may split boundary edges (so the mesh is conforming),
//! never moves them, and stops after [`TriangulateParams::max_steiner_points`] insertions: it
//! cannot hang. The report says whether the requested quality was met; small angles *between
//! input edges* cannot be improved by any refinement and are reported separately.

use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation,
};

use crate::error::{MeshError, Result};
use crate::quality::triangle_angles_deg;
use crate::types::{Mesh2, PolygonWithHoles};

/// Parameters of [`triangulate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangulateParams {
    /// Largest allowed triangle area (model units squared). `None` (default): no area bound.
    pub max_area: Option<f64>,
    /// Smallest requested interior angle (degrees, 0 disables). Default 25. Above ~30 degrees
    /// refinement may not terminate and is stopped by the vertex cap.
    pub min_angle_deg: f64,
    /// Most Steiner points refinement may insert before giving up. Default 50 000.
    pub max_steiner_points: usize,
}

impl Default for TriangulateParams {
    fn default() -> Self {
        Self {
            max_area: None,
            min_angle_deg: 25.0,
            max_steiner_points: 50_000,
        }
    }
}

/// What [`triangulate`] achieved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangulateReport {
    /// Steiner points added by refinement.
    pub steiner_points: usize,
    /// False when refinement stopped at the vertex cap.
    pub refinement_complete: bool,
    /// Smallest interior angle of the mesh (degrees).
    pub min_angle_deg: f64,
    /// Largest triangle area of the mesh (model units squared).
    pub max_area: f64,
    /// Smallest angle between two consecutive input boundary edges (degrees); refinement cannot
    /// raise mesh angles above this at that corner.
    pub smallest_input_angle_deg: f64,
    /// Whether every mesh angle is at least the requested minimum angle.
    pub min_angle_met: bool,
    /// Whether every triangle is within the requested maximum area (true without a bound).
    pub max_area_met: bool,
}

impl TriangulateReport {
    /// Whether the requested quality was met in full.
    pub fn quality_met(&self) -> bool {
        self.refinement_complete && self.min_angle_met && self.max_area_met
    }
}

/// Relative slack on the angle and area checks of the report (floating-point round-off of the
/// quality measures, not of the mesh).
const CHECK_SLACK: f64 = 1e-9;

/// Most Steiner points a refinement may be allowed (`--max-steiner`, `mesh.max_steiner`): ten
/// million points is a mesh of about 20 million triangles.
pub const MAX_STEINER_POINTS: usize = 10_000_000;

/// Relative area below which a triangle is degenerate: fem-core's default
/// `ElementTolerance::relative_area`, so every mesh written here is one the solvers accept.
const DEGENERATE: f64 = 1e-10;

/// Smallest polygon area, relative to the square of its extent, that is meshed: a 1 m outline
/// 10 nm thick is below it. Real outlines are far above (the built-in body: 0.17).
const THIN: f64 = 1e-8;

/// Triangulates the polygons (outer rings counter-clockwise, holes clockwise, all valid and
/// mutually disjoint) into one mesh, refined per `params`.
pub fn triangulate(
    polygons: &[PolygonWithHoles],
    params: &TriangulateParams,
) -> Result<(Mesh2, TriangulateReport)> {
    if let Some(a) = params.max_area
        && !(a.is_finite() && a > 0.0)
    {
        return Err(MeshError::invalid(
            "triangulate",
            format!("max area must be positive and finite, got {a}"),
        ));
    }
    if params.max_steiner_points > MAX_STEINER_POINTS {
        return Err(MeshError::invalid(
            "triangulate",
            format!(
                "max Steiner points {} is above the limit {MAX_STEINER_POINTS}",
                params.max_steiner_points
            ),
        ));
    }
    if !(params.min_angle_deg.is_finite() && (0.0..60.0).contains(&params.min_angle_deg)) {
        return Err(MeshError::invalid(
            "triangulate",
            format!(
                "min angle must be in [0, 60) degrees, got {}",
                params.min_angle_deg
            ),
        ));
    }
    let mut vertices: Vec<Point2<f64>> = Vec::new();
    let mut edges: Vec<[usize; 2]> = Vec::new();
    let mut smallest_input_angle_deg = 180.0f64;
    for polygon in polygons {
        for ring in polygon.rings() {
            if ring.len() < 3 {
                return Err(MeshError::invalid(
                    "triangulate",
                    format!("ring with {} vertices", ring.len()),
                ));
            }
            let base = vertices.len();
            let n = ring.len();
            for (i, p) in ring.iter().enumerate() {
                if !(p[0].is_finite() && p[1].is_finite()) {
                    return Err(MeshError::invalid(
                        "triangulate",
                        format!("ring vertex {i} is not finite: {p:?}"),
                    ));
                }
                vertices.push(Point2::new(p[0], p[1]));
                edges.push([base + i, base + (i + 1) % n]);
                let [a, b, c] = [ring[(i + n - 1) % n], *p, ring[(i + 1) % n]];
                smallest_input_angle_deg = smallest_input_angle_deg.min(corner_angle_deg(a, b, c));
            }
        }
    }
    if vertices.is_empty() {
        return Err(MeshError::invalid(
            "triangulate",
            "no polygon to triangulate",
        ));
    }
    // A (nearly) collinear outline: nothing but slivers can mesh it, however long the
    // refinement runs. Refused per polygon, by its area against the square of its extent
    // (after the crossing-edges check: a bow tie's area is zero too).
    let mut thin = None;
    for (k, polygon) in polygons.iter().enumerate() {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &polygon.outer {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        let extent2 = (hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2);
        let area = polygon.area();
        if thin.is_none()
            && area.partial_cmp(&(THIN * extent2)) != Some(std::cmp::Ordering::Greater)
        {
            thin = Some(MeshError::invalid(
                "triangulate",
                format!(
                    "polygon {k} is (nearly) collinear: area {area:.3e} over an extent of {:.3e} (ratio {:.1e}, at least {THIN:.0e} needed); check the model and the view",
                    extent2.sqrt(),
                    area / extent2
                ),
            ));
        }
    }
    crate::guard::guarded("triangulate", || {
        mesh_rings(vertices, edges, smallest_input_angle_deg, params, thin)
    })?
}

/// The triangulation and refinement proper (spade), run under [`crate::guard::guarded`].
fn mesh_rings(
    vertices: Vec<Point2<f64>>,
    edges: Vec<[usize; 2]>,
    smallest_input_angle_deg: f64,
    params: &TriangulateParams,
    thin: Option<MeshError>,
) -> Result<(Mesh2, TriangulateReport)> {
    let mut conflicts = 0usize;
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<f64>> =
        ConstrainedDelaunayTriangulation::try_bulk_load_cdt(vertices, edges, |_| conflicts += 1)
            .map_err(|e| MeshError::invalid("triangulate", format!("constrained Delaunay: {e}")))?;
    if conflicts > 0 {
        return Err(MeshError::invalid(
            "triangulate",
            format!("{conflicts} boundary edges intersect (the polygon is not simple)"),
        ));
    }
    if let Some(e) = thin {
        return Err(e);
    }
    let initial = cdt.num_vertices();
    let mut refinement = RefinementParameters::<f64>::new()
        .exclude_outer_faces(true)
        .with_angle_limit(AngleLimit::from_deg(params.min_angle_deg))
        .with_max_additional_vertices(params.max_steiner_points);
    if let Some(a) = params.max_area {
        refinement = refinement.with_max_allowed_area(a);
    }
    let result = cdt.refine(refinement);
    let mut excluded = vec![false; cdt.num_all_faces()];
    for f in &result.excluded_faces {
        excluded[f.index()] = true;
    }
    let mut index = vec![usize::MAX; cdt.num_vertices()];
    let mut mesh = Mesh2::default();
    for face in cdt.inner_faces() {
        if excluded[face.fix().index()] {
            continue;
        }
        let tri = face.vertices().map(|v| {
            let i = v.fix().index();
            if index[i] == usize::MAX {
                index[i] = mesh.vertices.len();
                let p = v.position();
                mesh.vertices.push([p.x, p.y]);
            }
            index[i]
        });
        mesh.triangles.push(tri);
    }
    if mesh.triangles.is_empty() {
        return Err(MeshError::invalid(
            "triangulate",
            "the polygon encloses no triangle",
        ));
    }
    // The mesher never writes a triangle below the degeneracy threshold of the FEM element
    // (fem-core's `ElementTolerance`: |area| <= 1e-10 x longest edge^2): such input is (nearly)
    // collinear, and no refinement can mesh it.
    for t in 0..mesh.triangles.len() {
        let c = mesh.corners(t);
        let longest = (0..3)
            .map(|k| {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                (b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)
            })
            .fold(0.0f64, f64::max);
        let area = mesh.signed_area(t);
        if area <= DEGENERATE * longest {
            return Err(MeshError::invalid(
                "triangulate",
                format!(
                    "triangle {t} would be degenerate (area {area:.3e}, longest edge {:.3e}): the outline is (nearly) collinear or too thin to mesh; check the model and the view",
                    longest.sqrt()
                ),
            ));
        }
    }
    let mut min_angle = 180.0f64;
    let mut max_area = 0.0f64;
    for t in 0..mesh.triangles.len() {
        let angles = triangle_angles_deg(mesh.corners(t));
        min_angle = min_angle.min(angles[0].min(angles[1]).min(angles[2]));
        max_area = max_area.max(mesh.signed_area(t));
    }
    let report = TriangulateReport {
        steiner_points: cdt.num_vertices() - initial,
        refinement_complete: result.refinement_complete,
        min_angle_deg: min_angle,
        max_area,
        smallest_input_angle_deg,
        min_angle_met: min_angle >= params.min_angle_deg * (1.0 - CHECK_SLACK),
        max_area_met: params
            .max_area
            .is_none_or(|a| max_area <= a * (1.0 + CHECK_SLACK)),
    };
    Ok((mesh, report))
}

/// Angle of the meshed region at ring corner `b` of the ring `a -> b -> c` (degrees, in
/// (0, 360)). The region is on the left of the ring (outer rings counter-clockwise, holes
/// clockwise).
fn corner_angle_deg(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let u = [a[0] - b[0], a[1] - b[1]];
    let v = [c[0] - b[0], c[1] - b[1]];
    let cross = u[0] * v[1] - u[1] * v[0];
    let dot = u[0] * v[0] + u[1] * v[1];
    let angle = libm::atan2(cross.abs(), dot).to_degrees();
    if cross <= 0.0 { angle } else { 360.0 - angle }
}
