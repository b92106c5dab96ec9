//! The procedural body meshes without any outside file: one connected silhouette with legs from
//! the side, two separate legs and open arm gaps from the front, and the default pipeline
//! parameters meet the requested quality.

use fem_mesh::body::human_body;
use fem_mesh::camera::Camera;
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::triangulate::TriangulateParams;

fn params(camera: Camera) -> PipelineParams {
    PipelineParams {
        camera,
        triangulate: TriangulateParams {
            max_area: Some(5e-4),
            ..TriangulateParams::default()
        },
        ..PipelineParams::default()
    }
}

#[test]
fn body_is_about_1_7_m_tall_standing_on_y_0() {
    let body = human_body();
    let (lo, hi) = body.bounds().unwrap();
    assert!(lo[1].abs() < 1e-3, "soles at {}", lo[1]);
    assert!((1.65..1.75).contains(&hi[1]), "height {}", hi[1]);
    assert!(
        body.triangles
            .iter()
            .flatten()
            .all(|&i| i < body.vertices.len())
    );
}

#[test]
fn side_view_is_connected_with_legs() {
    let out = mesh_surface(human_body(), &params(Camera::side(5.0))).unwrap();
    assert_eq!(out.alpha.component_count, 1);
    assert_eq!(out.mesh.edge_components(), 1);
    assert!(
        out.triangulate_report.quality_met(),
        "{:?}",
        out.triangulate_report
    );
    // Thigh, shin, foot and head (image x = model z).
    for p in [[0.0, 0.7], [0.0, 0.3], [0.1, 0.04], [0.0, 1.6]] {
        assert!(out.mesh.contains_point(p), "{p:?} not meshed");
    }
    assert!(
        !out.mesh.contains_point([0.15, 0.4]),
        "in front of the shin"
    );
}

#[test]
fn front_view_has_two_legs_and_open_arm_gaps() {
    let out = mesh_surface(human_body(), &params(Camera::front(5.0))).unwrap();
    assert_eq!(out.mesh.edge_components(), 1);
    for p in [[-0.125, 0.3], [0.125, 0.3], [-0.4, 0.85], [0.4, 0.85]] {
        assert!(out.mesh.contains_point(p), "{p:?} not meshed");
    }
    for p in [[0.0, 0.3], [0.0, 0.6], [0.25, 1.05], [-0.25, 1.05]] {
        assert!(!out.mesh.contains_point(p), "{p:?} should be outside");
    }
}
