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
use crate::types::{InnerRegion, Mesh2, PolygonWithHoles, orient};

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
    check_params(params)?;
    let mut rings = Rings::default();
    rings.push(polygons, "", false)?;
    let Rings {
        vertices,
        edges,
        smallest_input_angle_deg,
    } = rings;
    if vertices.is_empty() {
        return Err(MeshError::invalid(
            "triangulate",
            "no polygon to triangulate",
        ));
    }
    let thin = thin_polygon(polygons);
    crate::guard::guarded("triangulate", || {
        mesh_rings(
            vertices,
            edges,
            smallest_input_angle_deg,
            params,
            thin,
            None,
        )
    })?
}

/// Name of region 0, the outer domain around the inner regions, in meshes from
/// [`triangulate_regions`].
pub const OUTER_REGION_NAME: &str = "soft-tissue";

/// Triangulates the `outer` polygons with the `inner` regions' rings as constraint edges, so
/// every triangle lies in exactly one region, and tags the triangles: region 0 is the outer
/// domain outside every inner region (named [`OUTER_REGION_NAME`]), region `k + 1` is
/// `inner[k]` (named after it). Refinement splits the region boundaries where quality needs it
/// but never moves them, so each region's meshed area is its polygons' area up to round-off.
///
/// Inner polygons must lie strictly inside the outer domain (no vertex outside, no edge touching
/// or crossing an outer ring) and must not touch or overlap each other (one inside a hole of
/// another is fine); otherwise a one-line error names the region. With no inner region this is
/// [`triangulate`] with every triangle tagged 0.
///
/// The refinement runs over a rectangular frame around the input, a tenth of its extent away
/// (spade's inside/outside parity rule would count every inner region as a hole), and the
/// faces outside the outer domain are dropped afterwards; the report's Steiner count includes
/// the dropped ones.
pub fn triangulate_regions(
    outer: &[PolygonWithHoles],
    inner: &[InnerRegion],
    params: &TriangulateParams,
) -> Result<(Mesh2, TriangulateReport)> {
    if inner.is_empty() {
        let (mut mesh, report) = triangulate(outer, params)?;
        mesh.regions = vec![0; mesh.triangles.len()];
        mesh.region_names = vec![OUTER_REGION_NAME.to_owned()];
        return Ok((mesh, report));
    }
    check_params(params)?;
    let mut rings = Rings::default();
    rings.push(outer, "", false)?;
    let outer_vertices = rings.vertices.len();
    if rings.vertices.is_empty() {
        return Err(MeshError::invalid(
            "triangulate",
            "no polygon to triangulate",
        ));
    }
    for region in inner {
        if region.polygons.is_empty() {
            return Err(MeshError::invalid(
                "triangulate",
                format!("inner region {:?} has no polygon", region.name),
            ));
        }
        rings.push(
            &region.polygons,
            &format!("inner region {:?}: ", region.name),
            true,
        )?;
    }
    check_inner_regions(outer, inner)?;
    let Rings {
        mut vertices,
        mut edges,
        smallest_input_angle_deg,
    } = rings;
    // A frame around the domain, a tenth of its extent away, becomes the convex hull: the
    // outside that refinement sees is then an ordinary region, not slivers between the hull and
    // straight stretches of the outline (whose refinement would chop those into specks).
    let b = outer
        .iter()
        .map(|p| bbox(&p.outer))
        .fold(bbox(&[]), |a, b| {
            [
                a[0].min(b[0]),
                a[1].min(b[1]),
                a[2].max(b[2]),
                a[3].max(b[3]),
            ]
        });
    let margin = 0.1 * (b[2] - b[0]).max(b[3] - b[1]);
    let base = vertices.len();
    for [x, y] in [
        [b[0] - margin, b[1] - margin],
        [b[2] + margin, b[1] - margin],
        [b[2] + margin, b[3] + margin],
        [b[0] - margin, b[3] + margin],
    ] {
        vertices.push(Point2::new(x, y));
    }
    edges.extend((0..4).map(|i| [base + i, base + (i + 1) % 4]));
    let thin = thin_polygon(outer);
    let (mut mesh, report) = crate::guard::guarded("triangulate", || {
        mesh_rings(
            vertices,
            edges,
            smallest_input_angle_deg,
            params,
            thin,
            Some(outer_vertices),
        )
    })??;
    let inner_boxes: Vec<Vec<[f64; 4]>> = inner
        .iter()
        .map(|r| r.polygons.iter().map(|p| bbox(&p.outer)).collect())
        .collect();
    mesh.regions = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            let centroid = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0];
            inner
                .iter()
                .zip(&inner_boxes)
                .position(|(region, boxes)| {
                    region
                        .polygons
                        .iter()
                        .zip(boxes)
                        .any(|(q, b)| in_box(centroid, b) && q.contains(centroid))
                })
                .map_or(0, |k| k as u32 + 1)
        })
        .collect();
    mesh.region_names = std::iter::once(OUTER_REGION_NAME.to_owned())
        .chain(inner.iter().map(|r| r.name.clone()))
        .collect();
    Ok((mesh, report))
}

/// Checks that every inner polygon lies strictly inside the outer domain and that no two inner
/// polygons touch or overlap; the error names the region(s) and a place.
pub(crate) fn check_inner_regions(outer: &[PolygonWithHoles], inner: &[InnerRegion]) -> Result<()> {
    let outer_rings: Vec<(&Vec<[f64; 2]>, [f64; 4])> = outer
        .iter()
        .flat_map(PolygonWithHoles::rings)
        .map(|r| (r, bbox(r)))
        .collect();
    // Every inner polygon, with its region's name.
    let polygons: Vec<(&str, &PolygonWithHoles, [f64; 4])> = inner
        .iter()
        .flat_map(|r| {
            r.polygons
                .iter()
                .map(|p| (r.name.as_str(), p, bbox(&p.outer)))
        })
        .collect();
    for &(name, polygon, _) in &polygons {
        for ring in polygon.rings() {
            if let Some(v) = ring.iter().find(|&&v| !outer.iter().any(|q| q.contains(v))) {
                return Err(MeshError::invalid(
                    "triangulate",
                    format!(
                        "inner region {name:?} is not inside the outer domain: its vertex ({}, {}) lies outside",
                        v[0], v[1]
                    ),
                ));
            }
            let b = bbox(ring);
            for &(other, ob) in &outer_rings {
                if let Some(p) = rings_touch(ring, &b, other, &ob) {
                    return Err(MeshError::invalid(
                        "triangulate",
                        format!(
                            "inner region {name:?} touches or crosses the outer boundary near ({}, {})",
                            p[0], p[1]
                        ),
                    ));
                }
            }
        }
    }
    for (i, &(name_a, a, box_a)) in polygons.iter().enumerate() {
        for &(name_b, b, box_b) in &polygons[i + 1..] {
            if !boxes_overlap(&box_a, &box_b) {
                continue;
            }
            let overlap = |p: [f64; 2]| {
                MeshError::invalid(
                    "triangulate",
                    format!(
                        "inner regions {name_a:?} and {name_b:?} touch or overlap near ({}, {})",
                        p[0], p[1]
                    ),
                )
            };
            for ra in a.rings() {
                let ba = bbox(ra);
                for rb in b.rings() {
                    if let Some(p) = rings_touch(ra, &ba, rb, &bbox(rb)) {
                        return Err(overlap(p));
                    }
                }
            }
            // No boundary contact: overlapping means one lies inside the other.
            if b.contains(a.outer[0]) {
                return Err(overlap(a.outer[0]));
            }
            if a.contains(b.outer[0]) {
                return Err(overlap(b.outer[0]));
            }
        }
    }
    Ok(())
}

/// Bounding box `[xmin, ymin, xmax, ymax]` of a ring.
fn bbox(ring: &[[f64; 2]]) -> [f64; 4] {
    ring.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        },
    )
}

fn in_box(p: [f64; 2], b: &[f64; 4]) -> bool {
    p[0] >= b[0] && p[0] <= b[2] && p[1] >= b[1] && p[1] <= b[3]
}

fn boxes_overlap(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// A point where an edge of ring `a` touches or crosses an edge of ring `b` (boxes given).
fn rings_touch(
    a: &[[f64; 2]],
    box_a: &[f64; 4],
    b: &[[f64; 2]],
    box_b: &[f64; 4],
) -> Option<[f64; 2]> {
    if !boxes_overlap(box_a, box_b) {
        return None;
    }
    let (n, m) = (a.len(), b.len());
    for i in 0..n {
        let (p, q) = (a[i], a[(i + 1) % n]);
        let e = bbox(&[p, q]);
        if !boxes_overlap(&e, box_b) {
            continue;
        }
        for j in 0..m {
            let (r, s) = (b[j], b[(j + 1) % m]);
            if boxes_overlap(&e, &bbox(&[r, s])) && segments_touch(p, q, r, s) {
                return Some(p);
            }
        }
    }
    None
}

/// Whether the closed segments `pq` and `rs` share a point.
fn segments_touch(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> bool {
    let d1 = orient(r, s, p);
    let d2 = orient(r, s, q);
    let d3 = orient(p, q, r);
    let d4 = orient(p, q, s);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        c[0] >= a[0].min(b[0])
            && c[0] <= a[0].max(b[0])
            && c[1] >= a[1].min(b[1])
            && c[1] <= a[1].max(b[1])
    };
    (d1 == 0.0 && on(r, s, p))
        || (d2 == 0.0 && on(r, s, q))
        || (d3 == 0.0 && on(p, q, r))
        || (d4 == 0.0 && on(p, q, s))
}

/// Refuses unusable refinement parameters.
fn check_params(params: &TriangulateParams) -> Result<()> {
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
    Ok(())
}

/// The error for the first (nearly) collinear polygon, if any.
fn thin_polygon(polygons: &[PolygonWithHoles]) -> Option<MeshError> {
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
    thin
}

/// The constraint rings of a triangulation: vertices, closed ring edges and the smallest
/// angle between two consecutive edges.
struct Rings {
    vertices: Vec<Point2<f64>>,
    edges: Vec<[usize; 2]>,
    smallest_input_angle_deg: f64,
}

impl Default for Rings {
    fn default() -> Self {
        Self {
            vertices: Vec::new(),
            edges: Vec::new(),
            smallest_input_angle_deg: 180.0,
        }
    }
}

impl Rings {
    /// Appends every ring of `polygons`; `what` names them in errors (empty for the outer
    /// domain).
    /// `both_sides`: the rings separate two meshed regions (inner regions), so the angle on
    /// either side counts.
    fn push(&mut self, polygons: &[PolygonWithHoles], what: &str, both_sides: bool) -> Result<()> {
        for polygon in polygons {
            for ring in polygon.rings() {
                if ring.len() < 3 {
                    return Err(MeshError::invalid(
                        "triangulate",
                        format!("{what}ring with {} vertices", ring.len()),
                    ));
                }
                let base = self.vertices.len();
                let n = ring.len();
                for (i, p) in ring.iter().enumerate() {
                    if !(p[0].is_finite() && p[1].is_finite()) {
                        return Err(MeshError::invalid(
                            "triangulate",
                            format!("{what}ring vertex {i} is not finite: {p:?}"),
                        ));
                    }
                    self.vertices.push(Point2::new(p[0], p[1]));
                    self.edges.push([base + i, base + (i + 1) % n]);
                    let [a, b, c] = [ring[(i + n - 1) % n], *p, ring[(i + 1) % n]];
                    let mut angle = corner_angle_deg(a, b, c);
                    if both_sides {
                        angle = angle.min(360.0 - angle);
                    }
                    self.smallest_input_angle_deg = self.smallest_input_angle_deg.min(angle);
                }
            }
        }
        Ok(())
    }
}

/// The triangulation and refinement proper (spade), run under [`crate::guard::guarded`].
fn mesh_rings(
    vertices: Vec<Point2<f64>>,
    edges: Vec<[usize; 2]>,
    smallest_input_angle_deg: f64,
    params: &TriangulateParams,
    thin: Option<MeshError>,
    outer_vertices: Option<usize>,
) -> Result<(Mesh2, TriangulateReport)> {
    // The outer rings' input vertices (the first `outer_vertices` of the input), by position:
    // spade's bulk load does not keep vertex indices.
    let outer_positions: Option<std::collections::HashSet<[u64; 2]>> = outer_vertices.map(|n| {
        vertices[..n]
            .iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits()])
            .collect()
    });
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
    // Without inner regions, spade's parity rule tells inside from outside. Inner regions'
    // rings would flip that parity (every region would count as a hole), so then every face is
    // refined and the faces of the domain are picked afterwards by a parity of the outer rings
    // alone (`outer_domain_faces`).
    let mut refinement = RefinementParameters::<f64>::new()
        .exclude_outer_faces(outer_positions.is_none())
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
    if let Some(outer) = &outer_positions {
        excluded = outer_domain_faces(&cdt, outer)
            .into_iter()
            .map(|inside| !inside)
            .collect();
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

/// Which faces (by index) lie inside the outer rings: the parity of the outer-ring edges
/// crossed on the way from the convex hull (inner regions' rings do not count). An outer-ring
/// edge is a constraint edge between two vertices of the outer rings: the input vertices at
/// `outer` and the Steiner points refinement put on their edges, found by walking constraint
/// edges from them (rings are disjoint, so the walk never reaches an inner ring).
fn outer_domain_faces(
    cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>,
    outer: &std::collections::HashSet<[u64; 2]>,
) -> Vec<bool> {
    let mut on_outer = vec![false; cdt.num_vertices()];
    let mut stack = Vec::new();
    for v in cdt.vertices() {
        let p = v.position();
        if outer.contains(&[p.x.to_bits(), p.y.to_bits()]) {
            on_outer[v.fix().index()] = true;
            stack.push(v.fix());
        }
    }
    while let Some(v) = stack.pop() {
        for e in cdt.vertex(v).out_edges() {
            let w = e.to().fix();
            if e.is_constraint_edge() && !on_outer[w.index()] {
                on_outer[w.index()] = true;
                stack.push(w);
            }
        }
    }
    // 0-1 breadth-first search: crossing an outer-ring edge costs one layer.
    let mut layer = vec![usize::MAX; cdt.num_all_faces()];
    let mut queue = std::collections::VecDeque::new();
    let crossing_cost = |e: &spade::handles::DirectedEdgeHandle<'_, _, _, _, _>| {
        usize::from(
            e.is_constraint_edge()
                && on_outer[e.from().fix().index()]
                && on_outer[e.to().fix().index()],
        )
    };
    for hull in cdt.convex_hull() {
        let e = hull.rev();
        queue.push_back((e.fix(), crossing_cost(&e)));
    }
    while let Some((edge, depth)) = queue.pop_front() {
        let e = cdt.directed_edge(edge);
        let Some(face) = e.face().as_inner() else {
            continue;
        };
        let i = face.fix().index();
        if layer[i] <= depth {
            continue;
        }
        layer[i] = depth;
        for side in face.adjacent_edges() {
            let next = side.rev();
            if next.face().is_outer() {
                continue;
            }
            let cost = crossing_cost(&next);
            if cost == 0 {
                queue.push_front((next.fix(), depth));
            } else {
                queue.push_back((next.fix(), depth + 1));
            }
        }
    }
    layer
        .into_iter()
        .map(|d| d != usize::MAX && d % 2 == 1)
        .collect()
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
