//! Douglas-Peucker simplification of polygons with holes (geo's `Simplify`), with a guarantee:
//! the output is a valid polygon (no self-intersection, no ring touching another along a line, no
//! degenerate ring), checked with geo's `Validation`.
//!
//! When a simplified polygon is invalid, the tolerance is halved and simplification retried (up
//! to [`SimplifyParams::max_retries`] times); if it is still invalid, the unsimplified polygon is
//! used (valid by construction when it comes from [`crate::alpha`]). Holes narrower than 2ε are
//! dropped. Every such decision is recorded in [`SimplifyReport::notes`].

use geo::{Coord, LineString, Polygon, Simplify, Validation};

use crate::error::{MeshError, Result};
use crate::types::{PolygonWithHoles, ring_signed_area};

/// Parameters of [`simplify_polygon`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimplifyParams {
    /// Douglas-Peucker tolerance ε (model units): every removed vertex lies within ε of the
    /// simplified boundary. 0 disables simplification. No default here; the pipeline derives one
    /// from the alpha radius.
    pub epsilon: f64,
    /// How many times ε is halved when the simplified polygon is invalid, before falling back to
    /// the unsimplified one. Default 6.
    pub max_retries: usize,
}

impl SimplifyParams {
    /// Tolerance `epsilon` with the default retry count.
    pub fn new(epsilon: f64) -> Self {
        Self {
            epsilon,
            max_retries: 6,
        }
    }
}

/// What [`simplify_polygon`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimplifyReport {
    /// Vertex count before simplification.
    pub vertices_before: usize,
    /// Vertex count after simplification.
    pub vertices_after: usize,
    /// The tolerance finally used (model units; 0 when falling back to the input).
    pub epsilon_used: f64,
    /// Human-readable notes on repairs and fallbacks (empty when nothing unusual happened).
    pub notes: Vec<String>,
}

pub(crate) fn to_geo(polygon: &PolygonWithHoles) -> Polygon<f64> {
    let ring = |r: &Vec<[f64; 2]>| {
        let mut coords: Vec<Coord<f64>> = r.iter().map(|p| Coord { x: p[0], y: p[1] }).collect();
        if let Some(&first) = coords.first() {
            coords.push(first);
        }
        LineString::new(coords)
    };
    Polygon::new(
        ring(&polygon.outer),
        polygon.holes.iter().map(ring).collect(),
    )
}

fn open_ring(ls: &LineString<f64>) -> Vec<[f64; 2]> {
    let mut v: Vec<[f64; 2]> = ls.coords().map(|c| [c.x, c.y]).collect();
    if v.len() > 1 && v.first() == v.last() {
        v.pop();
    }
    v
}

pub(crate) fn from_geo(polygon: &Polygon<f64>) -> PolygonWithHoles {
    PolygonWithHoles {
        outer: open_ring(polygon.exterior()),
        holes: polygon.interiors().iter().map(open_ring).collect(),
    }
}

fn extent(ring: &[[f64; 2]]) -> [f64; 2] {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in ring {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    [hi[0] - lo[0], hi[1] - lo[1]]
}

/// Checks a polygon with geo's validation; `Err` carries the reason.
pub fn validate_polygon(polygon: &PolygonWithHoles) -> std::result::Result<(), String> {
    if polygon.outer.len() < 3 {
        return Err(format!("outer ring has {} vertices", polygon.outer.len()));
    }
    to_geo(polygon)
        .check_validation()
        .map_err(|e| e.to_string())
}

/// Simplifies `polygon` with tolerance ε; see the module docs for the validity guarantee.
///
/// Errors when ε is not finite or negative, or when ε is at least half the smaller side of the
/// outer ring's bounding box (the shape would collapse).
pub fn simplify_polygon(
    polygon: &PolygonWithHoles,
    params: &SimplifyParams,
) -> Result<(PolygonWithHoles, SimplifyReport)> {
    let eps = params.epsilon;
    if !(eps.is_finite() && eps >= 0.0) {
        return Err(MeshError::invalid(
            "simplify",
            format!("epsilon must be finite and >= 0, got {eps}"),
        ));
    }
    let size = extent(&polygon.outer);
    let smaller = size[0].min(size[1]);
    if eps >= 0.5 * smaller {
        return Err(MeshError::invalid(
            "simplify",
            format!(
                "epsilon {eps} is larger than the shape (outer ring is {:.4e} x {:.4e}; epsilon must be below {:.4e})",
                size[0],
                size[1],
                0.5 * smaller
            ),
        ));
    }
    let mut report = SimplifyReport {
        vertices_before: polygon.vertex_count(),
        ..SimplifyReport::default()
    };
    let mut input = polygon.clone();
    let before = input.holes.len();
    input.holes.retain(|h| {
        let e = extent(h);
        e[0].min(e[1]) > 2.0 * eps
    });
    if input.holes.len() < before {
        report.notes.push(format!(
            "dropped {} hole(s) narrower than 2 epsilon = {:.4e}",
            before - input.holes.len(),
            2.0 * eps
        ));
    }
    if eps == 0.0 {
        report.vertices_after = input.vertex_count();
        return Ok((input, report));
    }
    let geo_input = to_geo(&input);
    let mut tol = eps;
    for attempt in 0..=params.max_retries {
        let mut out = from_geo(&geo_input.simplify(tol));
        orient_rings(&mut out);
        match validate_polygon(&out) {
            Ok(()) => {
                if attempt > 0 {
                    report.notes.push(format!(
                        "simplified polygon was invalid at epsilon {eps:.4e}; used {tol:.4e} instead"
                    ));
                }
                report.epsilon_used = tol;
                report.vertices_after = out.vertex_count();
                return Ok((out, report));
            }
            Err(reason) if attempt == 0 => {
                report.notes.push(format!(
                    "simplified polygon invalid ({reason}); retrying with a smaller epsilon"
                ));
            }
            Err(_) => {}
        }
        tol *= 0.5;
    }
    let mut out = input;
    orient_rings(&mut out);
    if let Err(reason) = validate_polygon(&out) {
        return Err(MeshError::invalid(
            "simplify",
            format!("input polygon is itself invalid ({reason})"),
        ));
    }
    report.notes.push(format!(
        "no valid simplification after {} retries; kept the unsimplified polygon",
        params.max_retries
    ));
    report.epsilon_used = 0.0;
    report.vertices_after = out.vertex_count();
    Ok((out, report))
}

/// Makes the outer ring counter-clockwise and the holes clockwise.
fn orient_rings(p: &mut PolygonWithHoles) {
    if ring_signed_area(&p.outer) < 0.0 {
        p.outer.reverse();
    }
    for h in &mut p.holes {
        if ring_signed_area(h) > 0.0 {
            h.reverse();
        }
    }
}
