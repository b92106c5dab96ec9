//! Inner regions in the triangulation: triangle edges follow the region boundaries (every
//! triangle's corners lie in its own region), each region's meshed area is its polygons' area
//! (refinement splits boundaries but never moves them: the tolerance, 1e-9 relative, is
//! round-off), and inner polygons that leave the domain or overlap are one-line errors naming
//! the region.

mod support;

use fem_mesh::triangulate::{
    OUTER_REGION_NAME, TriangulateParams, triangulate, triangulate_regions,
};
use fem_mesh::{InnerRegion, PolygonWithHoles};
use support::{assert_region_areas, assert_triangles_stay_in_their_regions};

/// Relative tolerance on region areas: round-off of the triangle areas' sum.
const AREA_ROUND_OFF: f64 = 1e-9;

fn polygon(outer: Vec<[f64; 2]>) -> PolygonWithHoles {
    PolygonWithHoles {
        outer,
        holes: vec![],
    }
}

fn region(name: &str, outer: Vec<[f64; 2]>) -> InnerRegion {
    InnerRegion {
        name: name.into(),
        polygons: vec![polygon(outer)],
    }
}

/// A 1 m square with a convex hexagon and a non-convex notched polygon inside (every input angle
/// at least 60 degrees on both sides, so a 30 degree mesh is reachable).
fn square_with_two_regions() -> (Vec<PolygonWithHoles>, Vec<InnerRegion>) {
    let outer = vec![polygon(vec![
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
    ])];
    let hexagon = (0..6)
        .map(|i| {
            let a = std::f64::consts::PI / 3.0 * i as f64 + 0.1;
            [0.3 + 0.15 * a.cos(), 0.7 + 0.15 * a.sin()]
        })
        .collect();
    let notch = vec![
        [0.5, 0.1],
        [0.9, 0.1],
        [0.9, 0.6],
        [0.75, 0.6],
        [0.75, 0.3],
        [0.62, 0.36],
        [0.5, 0.3],
    ];
    (
        outer,
        vec![region("convex", hexagon), region("notched", notch)],
    )
}

fn params() -> TriangulateParams {
    TriangulateParams {
        max_area: Some(2e-3),
        min_angle_deg: 30.0,
        ..TriangulateParams::default()
    }
}

#[test]
fn square_with_convex_and_non_convex_regions_is_meshed_along_their_boundaries() {
    let (outer, inner) = square_with_two_regions();
    let (mesh, report) = triangulate_regions(&outer, &inner, &params()).unwrap();
    assert!(report.quality_met(), "{report:?}");
    assert_eq!(mesh.region_names[0], OUTER_REGION_NAME);
    assert_triangles_stay_in_their_regions(&mesh, &outer, &inner);
    let areas = assert_region_areas(&mesh, &outer, &inner, AREA_ROUND_OFF);
    assert!(areas.iter().all(|&a| a > 0.0));
    assert_eq!(mesh.edge_components(), 1);
    for k in 1..=2 {
        assert_eq!(mesh.region_components(k), 1, "region {k}");
    }
    // The whole square is covered.
    assert!((mesh.area() - 1.0).abs() < AREA_ROUND_OFF);
}

#[test]
fn without_inner_regions_it_is_triangulate_tagged_zero() {
    let (outer, _) = square_with_two_regions();
    let (plain, _) = triangulate(&outer, &params()).unwrap();
    let (tagged, _) = triangulate_regions(&outer, &[], &params()).unwrap();
    assert_eq!(tagged.vertices, plain.vertices);
    assert_eq!(tagged.triangles, plain.triangles);
    assert!(tagged.regions.iter().all(|&k| k == 0));
    assert_eq!(tagged.region_names, [OUTER_REGION_NAME]);
    assert!(plain.regions.is_empty() && plain.region_names.is_empty());
}

#[test]
fn a_region_inside_another_regions_hole_is_meshed_as_its_own_region() {
    let outer = vec![polygon(vec![
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
    ])];
    let ring = InnerRegion {
        name: "ring".into(),
        polygons: vec![PolygonWithHoles {
            outer: vec![[0.2, 0.2], [0.8, 0.2], [0.8, 0.8], [0.2, 0.8]],
            holes: vec![vec![[0.35, 0.35], [0.35, 0.65], [0.65, 0.65], [0.65, 0.35]]],
        }],
    };
    let core = region(
        "core",
        vec![[0.45, 0.45], [0.55, 0.45], [0.55, 0.55], [0.45, 0.55]],
    );
    let inner = vec![ring, core];
    let (mesh, _) = triangulate_regions(&outer, &inner, &params()).unwrap();
    assert_triangles_stay_in_their_regions(&mesh, &outer, &inner);
    assert_region_areas(&mesh, &outer, &inner, AREA_ROUND_OFF);
    // Soft tissue outside the ring and in its hole around the core: two components.
    assert_eq!(mesh.region_components(0), 2);
}

#[test]
fn inner_regions_outside_the_domain_or_overlapping_are_errors_naming_them() {
    let (outer, inner) = square_with_two_regions();
    let shifted = |name: &str, dx: f64, dy: f64| {
        let mut r = inner[0].clone();
        r.name = name.into();
        for p in &mut r.polygons[0].outer {
            *p = [p[0] + dx, p[1] + dy];
        }
        r
    };
    let cases = [
        (
            vec![shifted("skull", 0.0, 0.25)],
            "inner region \"skull\" is not inside the outer domain: its vertex",
        ),
        (
            vec![shifted("far", 2.0, 0.0)],
            "inner region \"far\" is not inside the outer domain",
        ),
        (
            vec![inner[1].clone(), shifted("tibia", 0.3, -0.4)],
            "inner regions \"notched\" and \"tibia\" touch or overlap",
        ),
        (
            vec![
                region("big", vec![[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]]),
                region(
                    "small",
                    vec![[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]],
                ),
            ],
            "inner regions \"big\" and \"small\" touch or overlap",
        ),
        (
            // Sharing an edge point with the outer boundary.
            vec![region("touch", vec![[0.0, 0.5], [0.2, 0.4], [0.2, 0.6]])],
            "inner region \"touch\" touches or crosses the outer boundary near (0, 0.5)",
        ),
        (
            vec![InnerRegion {
                name: "empty".into(),
                polygons: vec![],
            }],
            "inner region \"empty\" has no polygon",
        ),
    ];
    for (regions, expected) in cases {
        let err = triangulate_regions(&outer, &regions, &params())
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{err} should contain {expected}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
}
