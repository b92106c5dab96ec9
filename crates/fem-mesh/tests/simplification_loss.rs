//! Regression (the mesh pipeline did not report the area lost in simplification): looking down
//! a 32-sided cylinder, simplification can turn the outline into a coarser polygon, and the
//! quality report compared the mesh with that polygon (relative difference 4.7e-16). It now
//! compares the mesh with the alpha shape: the lost area and the boundary's Hausdorff distance
//! are reported.

use fem_mesh::camera::Camera;
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::types::{PolygonWithHoles, Surface3};

/// A closed 32-sided cylinder of radius 0.5 and height 1 along z.
fn cylinder() -> Surface3 {
    let n = 32;
    let mut vertices = Vec::new();
    for z in [0.0, 1.0] {
        for k in 0..n {
            let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            vertices.push([0.5 * a.cos(), 0.5 * a.sin(), z]);
        }
    }
    vertices.push([0.0, 0.0, 0.0]);
    vertices.push([0.0, 0.0, 1.0]);
    let mut triangles = Vec::new();
    for k in 0..n {
        let j = (k + 1) % n;
        triangles.push([k, j, n + j]);
        triangles.push([k, n + j, n + k]);
        triangles.push([2 * n, j, k]);
        triangles.push([2 * n + 1, n + k, n + j]);
    }
    Surface3 {
        vertices,
        triangles,
    }
}

#[test]
fn simplification_loss_is_reported_against_the_alpha_shape() {
    let params = PipelineParams {
        camera: Camera::new([0.0, 0.0, 10.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        // A coarse tolerance: the 32-gon's outline loses corners.
        epsilon: Some(0.04),
        ..PipelineParams::default()
    };
    let out = mesh_surface(cylinder(), &params).unwrap();
    let alpha: f64 = out.alpha.polygons.iter().map(PolygonWithHoles::area).sum();
    let simplified: f64 = out.simplified.iter().map(PolygonWithHoles::area).sum();
    let q = &out.quality;
    assert!(
        simplified < 0.98 * alpha,
        "simplification removed area: {simplified} of {alpha}"
    );
    assert_eq!(q.polygon_area, Some(alpha), "compared with the alpha shape");
    let loss = (q.mesh_area - alpha).abs() / alpha;
    assert!(loss > 0.02, "reported loss {loss}");
    let h = q
        .boundary_hausdorff
        .expect("the boundary distance is reported");
    assert!(h > 0.01 && h <= 0.04 + 1e-9, "Hausdorff {h} (epsilon 0.04)");
    let text = q.to_string();
    assert!(text.contains("relative difference"), "{text}");
    assert!(text.contains("Hausdorff"), "{text}");
}
