//! Alpha shapes of sampled regions: an L-shape gives back its concave corner, an annulus its
//! hole, both within a stated area tolerance; bad inputs are errors, never panics.

use fem_mesh::alpha::{AlphaParams, Components, alpha_shape, suggest_radius};

/// Deterministic jitter in [-0.5, 0.5) (a small LCG, so the tests need no RNG crate).
fn jitter(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
}

/// Jittered grid samples of spacing `h` inside `inside`, over the box [lo, hi]^2. Points whose
/// eight grid neighbours are all inside (and off the box edge) are jittered by up to 10 % of h;
/// the others stay on the grid so the samples reach the true boundary.
fn sample(h: f64, lo: f64, hi: f64, inside: impl Fn(f64, f64) -> bool) -> Vec<[f64; 2]> {
    let n = ((hi - lo) / h).round() as i64;
    let mut s = 7u64;
    let mut pts = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, y) = (lo + i as f64 * h, lo + j as f64 * h);
            if !inside(x, y) {
                continue;
            }
            let (dx, dy) = (0.2 * h * jitter(&mut s), 0.2 * h * jitter(&mut s));
            let interior = i > 0
                && j > 0
                && i < n
                && j < n
                && (-1..=1).all(|a| (-1..=1).all(|b| inside(x + a as f64 * h, y + b as f64 * h)));
            pts.push(if interior { [x + dx, y + dy] } else { [x, y] });
        }
    }
    pts
}

fn distance_to_ring(p: [f64; 2], ring: &[[f64; 2]]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        let d = [b[0] - a[0], b[1] - a[1]];
        let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]))
            .clamp(0.0, 1.0);
        best =
            best.min(((p[0] - a[0] - t * d[0]).powi(2) + (p[1] - a[1] - t * d[1]).powi(2)).sqrt());
    }
    best
}

fn l_shape(x: f64, y: f64) -> bool {
    let e = 1e-9;
    (-e..=2.0 + e).contains(&x) && (-e..=2.0 + e).contains(&y) && !(x > 1.0 + e && y > 1.0 + e)
}

/// Area tolerance of these tests: 3 % of the true area (a grid of spacing h = 0.05 with 20 %
/// jitter on the interior only).
const AREA_TOL: f64 = 0.03;

#[test]
fn l_shape_keeps_its_concave_corner() {
    let pts = sample(0.05, 0.0, 2.0, l_shape);
    for radius in [Some(0.1), None] {
        let shape = alpha_shape(
            &pts,
            &AlphaParams {
                radius,
                ..AlphaParams::default()
            },
        )
        .unwrap();
        assert_eq!(shape.component_count, 1);
        let poly = &shape.polygons[0];
        assert!(poly.holes.is_empty());
        let area = poly.area();
        assert!(
            (area - 3.0).abs() < AREA_TOL * 3.0,
            "area {area} (radius {radius:?})"
        );
        // The concave corner comes back: the boundary passes within the radius of (1, 1) (an
        // alpha shape rounds a reflex corner off by at most its radius) and the notch is empty.
        let r = shape.radius;
        let gap = distance_to_ring([1.0, 1.0], &poly.outer);
        assert!(
            gap < r,
            "boundary is {gap} from the concave corner (radius {r})"
        );
        assert!(!poly.contains([1.0 + r, 1.0 + r]) && !poly.contains([1.5, 1.5]));
        assert!(poly.contains([0.5, 1.5]) && poly.contains([1.5, 0.5]));
    }
}

#[test]
fn annulus_keeps_its_hole() {
    let annulus = |x: f64, y: f64| {
        let r = (x * x + y * y).sqrt();
        (0.5..=1.0).contains(&r)
    };
    let h = 0.04;
    let mut pts = sample(h, -1.0, 1.0, annulus);
    // Samples on both circles, so the point set reaches the true boundary.
    for (radius, count) in [(1.0, 160), (0.5, 80)] {
        for k in 0..count {
            let t = 2.0 * std::f64::consts::PI * k as f64 / count as f64;
            pts.push([radius * t.cos(), radius * t.sin()]);
        }
    }
    let exact = std::f64::consts::PI * (1.0 - 0.25);
    for radius in [Some(0.08), None] {
        let shape = alpha_shape(
            &pts,
            &AlphaParams {
                radius,
                ..AlphaParams::default()
            },
        )
        .unwrap();
        assert_eq!(shape.component_count, 1, "radius {radius:?}");
        let poly = &shape.polygons[0];
        assert_eq!(poly.holes.len(), 1, "radius {radius:?}");
        let area = poly.area();
        assert!(
            (area - exact).abs() < AREA_TOL * exact,
            "area {area} vs {exact}"
        );
        assert!(!poly.contains([0.0, 0.0]) && !poly.contains([0.3, 0.0]));
        assert!(poly.contains([0.75, 0.0]) && poly.contains([0.0, -0.75]));
        // Outer counter-clockwise, hole clockwise.
        assert!(fem_mesh::types::ring_signed_area(&poly.outer) > 0.0);
        assert!(fem_mesh::types::ring_signed_area(&poly.holes[0]) < 0.0);
    }
}

#[test]
fn two_blobs_give_two_components_largest_first() {
    let big = sample(0.05, 0.0, 1.0, |_, _| true);
    let small: Vec<[f64; 2]> = sample(0.05, 0.0, 0.5, |_, _| true)
        .into_iter()
        .map(|p| [p[0] + 3.0, p[1]])
        .collect();
    let pts: Vec<[f64; 2]> = big.into_iter().chain(small).collect();
    let params = AlphaParams {
        radius: Some(0.1),
        ..AlphaParams::default()
    };
    let largest = alpha_shape(&pts, &params).unwrap();
    assert_eq!(largest.component_count, 2);
    assert_eq!(largest.polygons.len(), 1);
    assert!((largest.polygons[0].area() - 1.0).abs() < 1e-9);
    let all = alpha_shape(
        &pts,
        &AlphaParams {
            components: Components::All,
            ..params
        },
    )
    .unwrap();
    assert_eq!(all.polygons.len(), 2);
    assert!((all.polygons[1].area() - 0.25).abs() < 1e-9);
    assert!((all.total_area - 1.25).abs() < 1e-9);
    // The suggestion bridges the gap: one component.
    let s = suggest_radius(&pts, 1.1).unwrap();
    assert!(s.single_component_radius > 1.0, "{s:?}");
}

#[test]
fn bad_inputs_are_errors() {
    let p = AlphaParams {
        radius: Some(1.0),
        ..AlphaParams::default()
    };
    let e = alpha_shape(&[], &p).unwrap_err().to_string();
    assert!(e.contains("at least 3"), "{e}");
    let e = alpha_shape(&[[1.0, 1.0]; 10], &p).unwrap_err().to_string();
    assert!(e.contains("coincide"), "{e}");
    let line: Vec<[f64; 2]> = (0..10).map(|i| [i as f64, 2.0 * i as f64]).collect();
    let e = alpha_shape(&line, &p).unwrap_err().to_string();
    assert!(e.contains("collinear"), "{e}");
    let e = alpha_shape(&[[0.0, 0.0], [f64::NAN, 1.0], [1.0, 0.0]], &p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not finite"), "{e}");
    let grid = sample(0.1, 0.0, 1.0, |_, _| true);
    let tiny = AlphaParams {
        radius: Some(0.01),
        ..AlphaParams::default()
    };
    let e = alpha_shape(&grid, &tiny).unwrap_err().to_string();
    assert!(e.contains("keeps no triangle") && e.contains("0.01"), "{e}");
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = alpha_shape(
            &grid,
            &AlphaParams {
                radius: Some(bad),
                ..AlphaParams::default()
            },
        );
        assert!(e.is_err(), "radius {bad}");
    }
}

#[test]
fn pinch_vertices_are_removed() {
    // Two squares of samples touching at one corner point: the shape must not pinch.
    let a = sample(0.1, 0.0, 1.0, |_, _| true);
    let b: Vec<[f64; 2]> = sample(0.1, 0.0, 1.0, |_, _| true)
        .into_iter()
        .map(|p| [p[0] + 1.0, p[1] + 1.0])
        .collect();
    let pts: Vec<[f64; 2]> = a.into_iter().chain(b).collect();
    let shape = alpha_shape(
        &pts,
        &AlphaParams {
            radius: Some(0.2),
            components: Components::All,
            ..AlphaParams::default()
        },
    )
    .unwrap();
    for poly in &shape.polygons {
        fem_mesh::simplify::validate_polygon(poly).unwrap();
    }
}

#[test]
fn small_sampling_holes_are_filled_real_holes_kept() {
    // A regular grid (spacing h = 0.05) with one interior point missing: the gap is a hole of
    // triangles with circumradius h..h*sqrt(2), just above a radius of 0.04.
    let h = 0.05;
    let pts: Vec<[f64; 2]> = (0..=20)
        .flat_map(|i| (0..=20).map(move |j| [i as f64 * h, j as f64 * h]))
        .filter(|p| (p[0] - 0.5).abs() > 1e-9 || (p[1] - 0.5).abs() > 1e-9)
        .collect();
    let filled = alpha_shape(
        &pts,
        &AlphaParams {
            radius: Some(0.04),
            ..AlphaParams::default()
        },
    )
    .unwrap();
    assert_eq!(
        (filled.holes_filled, filled.polygons[0].holes.len()),
        (1, 0)
    );
    assert!((filled.polygons[0].area() - 1.0).abs() < 1e-9);
    let kept = alpha_shape(
        &pts,
        &AlphaParams {
            radius: Some(0.04),
            fill_holes_below: 1.0,
            ..AlphaParams::default()
        },
    )
    .unwrap();
    assert_eq!((kept.holes_filled, kept.polygons[0].holes.len()), (0, 1));
    assert!(
        alpha_shape(
            &pts,
            &AlphaParams {
                fill_holes_below: 0.5,
                ..AlphaParams::default()
            }
        )
        .is_err()
    );
}
