//! Douglas-Peucker simplification: the Hausdorff distance to the input is at most ε, the output
//! is always a valid polygon (invalid simplifications are repaired by a smaller ε, with a note),
//! and ε larger than the shape is a clear error.

use fem_mesh::PolygonWithHoles;
use fem_mesh::simplify::{SimplifyParams, simplify_polygon, validate_polygon};
use proptest::prelude::*;

fn point_segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 == 0.0 {
        0.0
    } else {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    };
    ((p[0] - a[0] - t * d[0]).powi(2) + (p[1] - a[1] - t * d[1]).powi(2)).sqrt()
}

fn distance_to_ring(p: [f64; 2], ring: &[[f64; 2]]) -> f64 {
    (0..ring.len())
        .map(|i| point_segment_distance(p, ring[i], ring[(i + 1) % ring.len()]))
        .fold(f64::INFINITY, f64::min)
}

/// Hausdorff distance between two closed polylines, evaluated at vertices (exact here because the
/// simplified vertices are a subset of the input vertices, and a segment's farthest point from a
/// polyline that contains both its ends within distance d is within d).
fn hausdorff(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    let ab = a
        .iter()
        .map(|&p| distance_to_ring(p, b))
        .fold(0.0, f64::max);
    let ba = b
        .iter()
        .map(|&p| distance_to_ring(p, a))
        .fold(0.0, f64::max);
    ab.max(ba)
}

fn wavy_disc(n: usize, amplitude: f64, waves: f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|i| {
            let t = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            let r = 1.0 + amplitude * (waves * t).sin();
            [r * t.cos(), r * t.sin()]
        })
        .collect()
}

#[test]
fn hausdorff_distance_is_within_epsilon() {
    let poly = PolygonWithHoles {
        outer: wavy_disc(400, 0.05, 7.0),
        holes: vec![],
    };
    for eps in [0.001, 0.01, 0.05, 0.2] {
        let (out, report) = simplify_polygon(&poly, &SimplifyParams::new(eps)).unwrap();
        validate_polygon(&out).unwrap();
        let h = hausdorff(&poly.outer, &out.outer);
        assert!(h <= eps * (1.0 + 1e-12), "Hausdorff {h} > epsilon {eps}");
        assert!(report.vertices_after < report.vertices_before);
        assert!(report.notes.is_empty(), "{:?}", report.notes);
    }
}

#[test]
fn self_intersecting_simplification_is_repaired_with_a_note() {
    // An outward dent of depth 0.2 on the bottom edge holds the bottom of a hole; removing the dent
    // (epsilon 0.25 > 0.2) would cut through the hole.
    let poly = PolygonWithHoles {
        outer: vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [5.0, -0.2],
            [6.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
        ],
        holes: vec![vec![[4.7, -0.1], [4.7, 5.0], [5.3, 5.0], [5.3, -0.1]]],
    };
    validate_polygon(&poly).unwrap();
    let (out, report) = simplify_polygon(&poly, &SimplifyParams::new(0.25)).unwrap();
    validate_polygon(&out).unwrap();
    assert_eq!(out.holes.len(), 1);
    assert!(report.epsilon_used < 0.2, "{report:?}");
    assert!(
        report.notes.iter().any(|n| n.contains("invalid")),
        "{report:?}"
    );
    assert!(hausdorff(&poly.outer, &out.outer) <= 0.25);
}

#[test]
fn epsilon_larger_than_the_shape_is_an_error() {
    let poly = PolygonWithHoles {
        outer: wavy_disc(50, 0.1, 3.0),
        holes: vec![],
    };
    let e = simplify_polygon(&poly, &SimplifyParams::new(5.0))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("simplify:") && e.contains("larger than the shape"),
        "{e}"
    );
    let e = simplify_polygon(&poly, &SimplifyParams::new(f64::NAN))
        .unwrap_err()
        .to_string();
    assert!(e.contains("epsilon"), "{e}");
}

#[test]
fn small_holes_are_dropped_with_a_note() {
    let outer = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
    let hole = vec![[5.0, 5.0], [5.0, 5.1], [5.1, 5.1], [5.1, 5.0]];
    let poly = PolygonWithHoles {
        outer,
        holes: vec![hole],
    };
    let (out, report) = simplify_polygon(&poly, &SimplifyParams::new(0.5)).unwrap();
    assert!(out.holes.is_empty());
    assert!(report.notes[0].contains("dropped 1 hole"), "{report:?}");
}

/// A random star-shaped (hence simple) polygon around the origin.
fn star() -> impl Strategy<Value = Vec<[f64; 2]>> {
    (8usize..80).prop_flat_map(|n| {
        proptest::collection::vec((0.3f64..1.0, 0.0f64..0.8), n).prop_map(move |rs| {
            rs.iter()
                .enumerate()
                .map(|(i, &(r, jit))| {
                    let t = 2.0 * std::f64::consts::PI * (i as f64 + jit) / n as f64;
                    [r * t.cos(), r * t.sin()]
                })
                .collect()
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]
    #[test]
    fn random_polygons_simplify_to_valid_polygons_within_epsilon(
        outer in star(),
        eps in 0.001f64..0.2,
    ) {
        let poly = PolygonWithHoles { outer, holes: vec![] };
        prop_assume!(validate_polygon(&poly).is_ok());
        let (out, _) = simplify_polygon(&poly, &SimplifyParams::new(eps)).unwrap();
        prop_assert!(validate_polygon(&out).is_ok());
        let h = hausdorff(&poly.outer, &out.outer);
        prop_assert!(h <= eps * (1.0 + 1e-12), "Hausdorff {} > {}", h, eps);
        prop_assert!(out.area() > 0.0);
    }
}
