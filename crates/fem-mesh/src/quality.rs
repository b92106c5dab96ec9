//! Mesh quality report: counts, angle range, areas, the mesh area against the polygon area, and
//! a histogram of the aspect ratio R/(2r) (circumradius over twice the inradius: 1 for an
//! equilateral triangle, growing without bound as a triangle degenerates).

use std::fmt;

use crate::types::{Mesh2, PolygonWithHoles, triangle_signed_area};

/// Upper edges of the aspect-ratio histogram bins; the last bin is everything above.
pub const ASPECT_BINS: [f64; 6] = [1.1, 1.25, 1.5, 2.0, 3.0, 5.0];

/// Quality numbers of a 2D mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct QualityReport {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Smallest interior angle (degrees).
    pub min_angle_deg: f64,
    /// Largest interior angle (degrees).
    pub max_angle_deg: f64,
    /// Smallest triangle area (model units squared).
    pub min_area: f64,
    /// Largest triangle area (model units squared).
    pub max_area: f64,
    /// Sum of the triangle areas (model units squared).
    pub mesh_area: f64,
    /// Area of the shape the mesh should cover, when known (model units squared). The mesh
    /// pipeline gives the alpha shape's, so the difference includes what simplification
    /// removed.
    pub polygon_area: Option<f64>,
    /// Hausdorff distance between the mesh's boundary and the boundary of the shape it should
    /// cover, when known (model units; the pipeline's: simplified polygons against the alpha
    /// shape).
    pub boundary_hausdorff: Option<f64>,
    /// Triangles with non-positive signed area (clockwise or degenerate).
    pub non_positive_triangles: usize,
    /// Counts of triangles per aspect-ratio bin (bins in [`ASPECT_BINS`], plus one above).
    pub aspect_histogram: [usize; ASPECT_BINS.len() + 1],
}

/// The three interior angles of a triangle (degrees).
pub fn triangle_angles_deg([a, b, c]: [[f64; 2]; 3]) -> [f64; 3] {
    let angle = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        let u = [q[0] - p[0], q[1] - p[1]];
        let v = [r[0] - p[0], r[1] - p[1]];
        let cross = u[0] * v[1] - u[1] * v[0];
        let dot = u[0] * v[0] + u[1] * v[1];
        libm::atan2(cross.abs(), dot).to_degrees()
    };
    [angle(a, b, c), angle(b, c, a), angle(c, a, b)]
}

/// Aspect ratio R/(2r) of a triangle (1 for equilateral, infinite when degenerate).
pub fn aspect_ratio(corners: [[f64; 2]; 3]) -> f64 {
    let [a, b, c] = corners;
    let len = |p: [f64; 2], q: [f64; 2]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
    let (la, lb, lc) = (len(b, c), len(c, a), len(a, b));
    let area = triangle_signed_area(corners).abs();
    if area == 0.0 {
        return f64::INFINITY;
    }
    let s = 0.5 * (la + lb + lc);
    let r_in = area / s;
    let r_circ = la * lb * lc / (4.0 * area);
    r_circ / (2.0 * r_in)
}

impl QualityReport {
    /// Measures `mesh`; `polygon_area` is the area the mesh should cover, when known.
    pub fn of(mesh: &Mesh2, polygon_area: Option<f64>) -> Self {
        let mut report = Self {
            vertices: mesh.vertices.len(),
            triangles: mesh.triangles.len(),
            min_angle_deg: if mesh.triangles.is_empty() {
                0.0
            } else {
                180.0
            },
            max_angle_deg: 0.0,
            min_area: if mesh.triangles.is_empty() {
                0.0
            } else {
                f64::INFINITY
            },
            max_area: 0.0,
            mesh_area: 0.0,
            polygon_area,
            boundary_hausdorff: None,
            non_positive_triangles: 0,
            aspect_histogram: [0; ASPECT_BINS.len() + 1],
        };
        for t in 0..mesh.triangles.len() {
            let corners = mesh.corners(t);
            let area = triangle_signed_area(corners);
            if area <= 0.0 {
                report.non_positive_triangles += 1;
            }
            for a in triangle_angles_deg(corners) {
                report.min_angle_deg = report.min_angle_deg.min(a);
                report.max_angle_deg = report.max_angle_deg.max(a);
            }
            report.min_area = report.min_area.min(area);
            report.max_area = report.max_area.max(area);
            report.mesh_area += area;
            let q = aspect_ratio(corners);
            let bin = ASPECT_BINS
                .iter()
                .position(|&edge| q < edge)
                .unwrap_or(ASPECT_BINS.len());
            report.aspect_histogram[bin] += 1;
        }
        report
    }

    /// The same report with the Hausdorff distance between the mesh's boundary and the
    /// boundary of the shape it should cover (see [`boundary_hausdorff`]).
    pub fn with_boundary_hausdorff(mut self, distance: f64) -> Self {
        self.boundary_hausdorff = Some(distance);
        self
    }
}

/// Hausdorff distance between two sets of polygon boundaries (outer rings and holes): the
/// largest distance from a point of either to the other, sampled at every vertex and at three
/// interior points of every edge (model units).
///
/// (Not geo's `HausdorffDistance`: it measures between the two vertex sets, so an edge
/// midpoint far from the other boundary goes unseen and a vertex near the middle of the other's
/// edge counts its distance to that edge's ends.)
pub fn boundary_hausdorff(a: &[PolygonWithHoles], b: &[PolygonWithHoles]) -> f64 {
    directed(a, b).max(directed(b, a))
}

/// Smallest distance between the boundaries of `a` and `b` (model units; exact for boundaries
/// that do not cross: the nearest pair is a vertex of one and an edge of the other).
pub(crate) fn boundary_clearance(a: &[PolygonWithHoles], b: &[PolygonWithHoles]) -> f64 {
    let one_way = |a: &[PolygonWithHoles], b: &[PolygonWithHoles]| {
        rings(a)
            .flatten()
            .map(|&x| {
                rings(b)
                    .flat_map(|r| (0..r.len()).map(move |j| (r[j], r[(j + 1) % r.len()])))
                    .map(|(u, v)| segment_distance(x, u, v))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(f64::INFINITY, f64::min)
    };
    one_way(a, b).min(one_way(b, a))
}

fn rings(p: &[PolygonWithHoles]) -> impl Iterator<Item = &Vec<[f64; 2]>> {
    p.iter()
        .flat_map(|p| std::iter::once(&p.outer).chain(&p.holes))
}

fn directed(a: &[PolygonWithHoles], b: &[PolygonWithHoles]) -> f64 {
    let mut worst: f64 = 0.0;
    for ring in rings(a) {
        for (i, &p) in ring.iter().enumerate() {
            let q = ring[(i + 1) % ring.len()];
            for k in 0..4 {
                let s = k as f64 / 4.0;
                let x = [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])];
                let d = rings(b)
                    .flat_map(|r| (0..r.len()).map(move |j| (r[j], r[(j + 1) % r.len()])))
                    .map(|(u, v)| segment_distance(x, u, v))
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(d);
            }
        }
    }
    worst
}

/// Distance from `x` to the segment `uv`.
pub fn segment_distance(x: [f64; 2], u: [f64; 2], v: [f64; 2]) -> f64 {
    let (dx, dy) = (v[0] - u[0], v[1] - u[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((x[0] - u[0]) * dx + (x[1] - u[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x[0] - u[0] - t * dx).hypot(x[1] - u[1] - t * dy)
}

impl fmt::Display for QualityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "vertices {}, triangles {}",
            self.vertices, self.triangles
        )?;
        writeln!(
            f,
            "angles: min {:.2} deg, max {:.2} deg",
            self.min_angle_deg, self.max_angle_deg
        )?;
        writeln!(
            f,
            "triangle area: min {:.4e}, max {:.4e}",
            self.min_area, self.max_area
        )?;
        match self.polygon_area {
            Some(p) if p > 0.0 => writeln!(
                f,
                "mesh area {:.6e} vs polygon area {:.6e} (relative difference {:.2e})",
                self.mesh_area,
                p,
                (self.mesh_area - p).abs() / p
            )?,
            _ => writeln!(f, "mesh area {:.6e}", self.mesh_area)?,
        }
        if let Some(h) = self.boundary_hausdorff {
            writeln!(
                f,
                "boundary within {h:.3e} of the shape to cover (Hausdorff distance)"
            )?;
        }
        if self.non_positive_triangles > 0 {
            writeln!(
                f,
                "WARNING: {} clockwise or degenerate triangles",
                self.non_positive_triangles
            )?;
        }
        writeln!(f, "aspect ratio R/(2r) histogram:")?;
        let total = self.triangles.max(1) as f64;
        let mut lower = 1.0;
        for (i, &count) in self.aspect_histogram.iter().enumerate() {
            let label = match ASPECT_BINS.get(i) {
                Some(&upper) => format!("[{lower:.2}, {upper:.2})"),
                None => format!("[{lower:.2}, inf)"),
            };
            if let Some(&upper) = ASPECT_BINS.get(i) {
                lower = upper;
            }
            let bar = "#".repeat(((count as f64 / total) * 40.0).round() as usize);
            writeln!(f, "  {label:>14} {count:>7} {bar}")?;
        }
        Ok(())
    }
}
