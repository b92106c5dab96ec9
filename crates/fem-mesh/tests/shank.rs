//! The lower-leg close-up: its shape (length, depth at the calf), the tibia inside the skin
//! with 13 mm of soft tissue under the shin and at least 12 mm everywhere, and the mesh at the
//! suggested parameters: 2000-6000 triangles, triangles in their regions, region areas equal to
//! the outlines' (round-off: 1e-9 relative).

mod support;

use fem_mesh::shank::{SHANK_LENGTH, SHANK_SOFT_TISSUE, shank_params, shank_section};
use fem_mesh::triangulate::triangulate_regions;
use fem_mesh::types::ring_signed_area;
use support::{assert_region_areas, assert_triangles_stay_in_their_regions, boundary_distance};

#[test]
fn shank_section_has_an_adult_shape_with_the_tibia_close_under_the_shin() {
    let (skin, regions) = shank_section();
    assert!(
        ring_signed_area(&skin.outer) > 0.0,
        "counter-clockwise outline"
    );
    let xs = skin.outer.iter().map(|p| p[0]);
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    assert!((hi - lo - SHANK_LENGTH).abs() < 1e-12);
    // Depth at the calf: 0.10 to 0.12 m.
    let depth = |x: f64| {
        let ys: Vec<f64> = skin
            .outer
            .iter()
            .filter(|p| (p[0] - x).abs() < 1e-9)
            .map(|p| p[1])
            .collect();
        ys.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - ys.iter().copied().fold(f64::INFINITY, f64::min)
    };
    let calf = depth(0.11);
    assert!((0.10..=0.12).contains(&calf), "depth at the calf {calf}");
    assert!(depth(SHANK_LENGTH) < calf && depth(0.0) < calf);
    assert_eq!(regions.len(), 1);
    assert_eq!(regions[0].name, "tibia");
    let tibia = &regions[0].polygons[0];
    assert!(ring_signed_area(&tibia.outer) > 0.0);
    // Inside the skin, at least 12 mm from it everywhere (the cuts), 13 mm under the shin.
    let mut clearance = f64::INFINITY;
    for &p in &tibia.outer {
        assert!(skin.contains(p), "tibia vertex {p:?} outside the skin");
        clearance = clearance.min(boundary_distance(p, &skin));
    }
    assert!(clearance >= 0.012 - 1e-12, "tibia clearance {clearance}");
    // Shaft about 25 mm thick at mid-length, 13 mm of soft tissue above it: where a vertical
    // line crosses the rings.
    let at = |ring: &[[f64; 2]], x: f64| -> Vec<f64> {
        let mut ys: Vec<f64> = (0..ring.len())
            .map(|i| (ring[i], ring[(i + 1) % ring.len()]))
            .filter(|(a, b)| (a[0] > x) != (b[0] > x))
            .map(|(a, b)| a[1] + (x - a[0]) / (b[0] - a[0]) * (b[1] - a[1]))
            .collect();
        ys.sort_by(f64::total_cmp);
        ys
    };
    for x in [0.1, 0.18, 0.3] {
        let bone = at(&tibia.outer, x);
        let skin_ys = at(&skin.outer, x);
        assert_eq!((bone.len(), skin_ys.len()), (2, 2));
        let soft = skin_ys[1] - bone[1];
        // Both lines are straight between vertices: the sampling is exact up to round-off.
        assert!(
            (soft - SHANK_SOFT_TISSUE).abs() < 1e-9,
            "soft tissue {soft} at x = {x}"
        );
        let shaft = bone[1] - bone[0];
        assert!((0.024..=0.027).contains(&shaft), "shaft {shaft} at x = {x}");
    }
}

#[test]
fn shank_meshes_to_a_few_thousand_triangles_along_the_tibia() {
    let (skin, regions) = shank_section();
    let outer = [skin];
    let (mesh, report) = triangulate_regions(&outer, &regions, &shank_params()).unwrap();
    let n = mesh.triangles.len();
    assert!((2000..=6000).contains(&n), "{n} triangles");
    assert!(report.quality_met(), "{report:?}");
    assert_eq!(mesh.edge_components(), 1);
    assert_eq!(mesh.region_components(1), 1);
    assert_triangles_stay_in_their_regions(&mesh, &outer, &regions);
    let areas = assert_region_areas(&mesh, &outer, &regions, 1e-9);
    assert!(
        areas[1] > 0.2 * areas[0],
        "tibia {} vs soft tissue {}",
        areas[1],
        areas[0]
    );
}
