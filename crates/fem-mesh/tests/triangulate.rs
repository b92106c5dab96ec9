//! Constrained Delaunay refinement: every triangle counter-clockwise and non-degenerate, the
//! minimum angle at least the requested bound (for inputs without small corners), every area at
//! most the maximum area, total area equal to the polygon's; property tests on random polygons;
//! the vertex cap stops refinement and is reported.

use fem_mesh::quality::{QualityReport, triangle_angles_deg};
use fem_mesh::triangulate::{TriangulateParams, triangulate};
use fem_mesh::{Mesh2, PolygonWithHoles};
use proptest::prelude::*;

fn check(mesh: &Mesh2, polygons: &[PolygonWithHoles], params: &TriangulateParams, angle: bool) {
    let expected: f64 = polygons.iter().map(PolygonWithHoles::area).sum();
    let q = QualityReport::of(mesh, Some(expected));
    assert_eq!(
        q.non_positive_triangles, 0,
        "clockwise or degenerate triangles"
    );
    for t in 0..mesh.triangles.len() {
        let a = mesh.signed_area(t);
        assert!(a > 1e-12 * expected, "triangle {t} nearly degenerate: {a}");
        if let Some(max) = params.max_area {
            assert!(a <= max * (1.0 + 1e-9), "triangle {t} area {a} > {max}");
        }
        if angle {
            let min = triangle_angles_deg(mesh.corners(t))
                .into_iter()
                .fold(180.0, f64::min);
            assert!(
                min >= params.min_angle_deg - 1e-9,
                "triangle {t} angle {min}"
            );
        }
    }
    assert!(
        (q.mesh_area - expected).abs() <= 1e-9 * expected,
        "mesh area {} vs polygon area {expected}",
        q.mesh_area
    );
}

fn square(x0: f64, y0: f64, s: f64) -> Vec<[f64; 2]> {
    vec![[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]]
}

#[test]
fn square_with_hole_and_l_shape_meet_the_bounds() {
    let mut hole = square(0.4, 0.4, 0.2);
    hole.reverse();
    let with_hole = PolygonWithHoles {
        outer: square(0.0, 0.0, 1.0),
        holes: vec![hole],
    };
    let l = PolygonWithHoles {
        outer: vec![
            [2.0, 0.0],
            [4.0, 0.0],
            [4.0, 1.0],
            [3.0, 1.0],
            [3.0, 2.0],
            [2.0, 2.0],
        ],
        holes: vec![],
    };
    let polys = vec![with_hole, l];
    for (max_area, min_angle) in [(None, 20.0), (Some(0.01), 25.0), (Some(0.002), 30.0)] {
        let params = TriangulateParams {
            max_area,
            min_angle_deg: min_angle,
            ..TriangulateParams::default()
        };
        let (mesh, report) = triangulate(&polys, &params).unwrap();
        check(&mesh, &polys, &params, true);
        assert!(report.quality_met(), "{report:?}");
        // The hole stays empty.
        assert!(!mesh.contains_point([0.5, 0.5]));
        assert!(mesh.contains_point([0.2, 0.2]) && mesh.contains_point([2.5, 1.5]));
        assert!(!mesh.contains_point([3.5, 1.5]));
    }
}

#[test]
fn vertex_cap_stops_refinement_and_is_reported() {
    let polys = vec![PolygonWithHoles {
        outer: square(0.0, 0.0, 1.0),
        holes: vec![],
    }];
    let params = TriangulateParams {
        max_area: Some(1e-6),
        min_angle_deg: 25.0,
        max_steiner_points: 100,
    };
    let (mesh, report) = triangulate(&polys, &params).unwrap();
    assert!(!report.refinement_complete && !report.quality_met());
    assert!(report.steiner_points <= 100 + 4, "{report:?}");
    assert!(!mesh.triangles.is_empty());
}

#[test]
fn bad_parameters_are_errors() {
    let polys = vec![PolygonWithHoles {
        outer: square(0.0, 0.0, 1.0),
        holes: vec![],
    }];
    for params in [
        TriangulateParams {
            max_area: Some(0.0),
            ..TriangulateParams::default()
        },
        TriangulateParams {
            max_area: Some(f64::NAN),
            ..TriangulateParams::default()
        },
        TriangulateParams {
            min_angle_deg: 70.0,
            ..TriangulateParams::default()
        },
    ] {
        assert!(triangulate(&polys, &params).is_err(), "{params:?}");
    }
    assert!(triangulate(&[], &TriangulateParams::default()).is_err());
    // Crossing boundary edges (a bow tie) are an error, not a panic.
    let bow = vec![PolygonWithHoles {
        outer: vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]],
        holes: vec![],
    }];
    let e = triangulate(&bow, &TriangulateParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("intersect"), "{e}");
}

/// A random star-shaped polygon with wide corners (interior angles well above 60 degrees).
fn blob() -> impl Strategy<Value = Vec<[f64; 2]>> {
    (5usize..16).prop_flat_map(|n| {
        proptest::collection::vec(0.8f64..1.0, n).prop_map(move |rs| {
            rs.iter()
                .enumerate()
                .map(|(i, &r)| {
                    let t = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                    [r * t.cos(), r * t.sin()]
                })
                .collect()
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_polygons_triangulate_within_bounds(
        outer in blob(),
        max_area in 0.005f64..0.2,
        min_angle in 5.0f64..25.0,
    ) {
        let polys = vec![PolygonWithHoles { outer, holes: vec![] }];
        let params = TriangulateParams {
            max_area: Some(max_area),
            min_angle_deg: min_angle,
            ..TriangulateParams::default()
        };
        let (mesh, report) = triangulate(&polys, &params).unwrap();
        prop_assert!(report.refinement_complete);
        // Ruppert's bound holds for input corners of at least 60 degrees.
        let angle_guaranteed = report.smallest_input_angle_deg >= 60.0;
        check(&mesh, &polys, &params, angle_guaranteed);
    }
}
