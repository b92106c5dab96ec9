//! Oracles shared by the region tests: a triangle of region `k` has its three corners inside or
//! on region `k`'s polygons, and each region's meshed area is its polygons' area.

#![allow(dead_code)]

use fem_mesh::quality::segment_distance;
use fem_mesh::{InnerRegion, Mesh2, PolygonWithHoles};

/// Distance from `p` to the nearest ring edge of `polygon`.
pub fn boundary_distance(p: [f64; 2], polygon: &PolygonWithHoles) -> f64 {
    polygon
        .rings()
        .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
        .map(|(u, v)| segment_distance(p, u, v))
        .fold(f64::INFINITY, f64::min)
}

fn inside_or_on(p: [f64; 2], polygons: &[PolygonWithHoles], tol: f64) -> bool {
    polygons
        .iter()
        .any(|q| q.contains(p) || boundary_distance(p, q) <= tol)
}

fn strictly_inside(p: [f64; 2], polygons: &[PolygonWithHoles], tol: f64) -> bool {
    polygons
        .iter()
        .any(|q| q.contains(p) && boundary_distance(p, q) > tol)
}

/// Asserts that `mesh` is tagged with `1 + inner.len()` regions named as given and that every
/// triangle's corners lie inside or on its own region: region 0 inside-or-on the outer polygons
/// and not strictly inside any inner one, region `k + 1` inside-or-on `inner[k]`. Points within
/// `1e-12` times the domain's extent of a boundary count as on it.
pub fn assert_triangles_stay_in_their_regions(
    mesh: &Mesh2,
    outer: &[PolygonWithHoles],
    inner: &[InnerRegion],
) {
    assert_eq!(mesh.regions.len(), mesh.triangles.len());
    assert_eq!(mesh.region_names.len(), inner.len() + 1);
    for (k, r) in inner.iter().enumerate() {
        assert_eq!(mesh.region_names[k + 1], r.name);
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in outer.iter().flat_map(|p| &p.outer) {
        lo = [lo[0].min(p[0]), lo[1].min(p[1])];
        hi = [hi[0].max(p[0]), hi[1].max(p[1])];
    }
    let tol = 1e-12 * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    for t in 0..mesh.triangles.len() {
        let k = mesh.region_of(t) as usize;
        for p in mesh.corners(t) {
            if k == 0 {
                assert!(
                    inside_or_on(p, outer, tol),
                    "triangle {t} (soft tissue) has corner {p:?} outside the outer domain"
                );
                for r in inner {
                    assert!(
                        !strictly_inside(p, &r.polygons, tol),
                        "triangle {t} (soft tissue) has corner {p:?} inside region {:?}",
                        r.name
                    );
                }
            } else {
                assert!(
                    inside_or_on(p, &inner[k - 1].polygons, tol),
                    "triangle {t} of region {:?} has corner {p:?} outside it",
                    inner[k - 1].name
                );
            }
        }
    }
}

/// Asserts that each region's meshed area matches its polygons' area within `rel` (relative),
/// region 0 being the outer area minus the inner ones; returns the meshed areas.
pub fn assert_region_areas(
    mesh: &Mesh2,
    outer: &[PolygonWithHoles],
    inner: &[InnerRegion],
    rel: f64,
) -> Vec<f64> {
    let inner_total: f64 = inner.iter().map(InnerRegion::area).sum();
    let outer_area: f64 = outer.iter().map(PolygonWithHoles::area).sum();
    let expected: Vec<f64> = std::iter::once(outer_area - inner_total)
        .chain(inner.iter().map(InnerRegion::area))
        .collect();
    let mut areas = Vec::new();
    for (k, &want) in expected.iter().enumerate() {
        let got = mesh.region_area(k as u32);
        assert!(
            (got - want).abs() <= rel * want,
            "region {k} ({}): meshed area {got:e} vs polygon area {want:e} (relative {:.2e}, tolerance {rel:e})",
            mesh.region_names[k],
            (got - want).abs() / want
        );
        areas.push(got);
    }
    areas
}
