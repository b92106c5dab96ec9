//! The procedural body and its skeleton mesh without any outside file, with case D's mesh
//! parameters: one connected mesh from the side and from the front, every bone inside the skin
//! with at least 1 cm of soft tissue, triangles that stay in their regions and region areas
//! equal to the outlines' (round-off: 1e-9 relative), two distinct legs in the side view, the
//! tibia 1-1.5 cm under the shin, and mirror-symmetric arms in the front view.

mod support;

use fem_mesh::alpha::AlphaParams;
use fem_mesh::body::{SHIN_SOFT_TISSUE, human_body, human_skeleton};
use fem_mesh::camera::Camera;
use fem_mesh::pipeline::{
    PipelineOutput, PipelineParams, mesh_surface, mesh_surface_with_skeleton,
};
use fem_mesh::triangulate::TriangulateParams;
use support::{assert_region_areas, assert_triangles_stay_in_their_regions};

/// Case D's mesh parameters.
fn params(camera: Camera) -> PipelineParams {
    PipelineParams {
        camera,
        alpha: AlphaParams {
            radius: Some(0.02),
            ..AlphaParams::default()
        },
        epsilon: Some(0.012),
        triangulate: TriangulateParams {
            max_area: Some(8e-4),
            min_angle_deg: 30.0,
            ..TriangulateParams::default()
        },
        ..PipelineParams::default()
    }
}

fn with_skeleton(camera: Camera) -> PipelineOutput {
    mesh_surface_with_skeleton(human_body(), &human_skeleton(), &params(camera)).unwrap()
}

/// Sorted x where the horizontal line at height `y` crosses the rings of `out`'s skin outline
/// (`bone == None`) or of the named bone.
fn crossings(out: &PipelineOutput, bone: Option<&str>, y: f64) -> Vec<f64> {
    let polygons = match bone {
        None => &out.simplified,
        Some(name) => {
            &out.bones
                .iter()
                .find(|b| b.name == name)
                .unwrap_or_else(|| panic!("no bone {name}"))
                .polygons
        }
    };
    let mut xs: Vec<f64> = polygons
        .iter()
        .flat_map(|p| p.rings())
        .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
        .filter(|(a, b)| (a[1] > y) != (b[1] > y))
        .map(|(a, b)| a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]))
        .collect();
    xs.sort_by(f64::total_cmp);
    xs
}

#[test]
fn body_is_about_1_75_m_tall_with_a_sole_on_y_0() {
    let body = human_body();
    let (lo, hi) = body.bounds().unwrap();
    assert!(lo[1].abs() < 1e-3, "soles at {}", lo[1]);
    assert!((1.72..1.78).contains(&hi[1]), "height {}", hi[1]);
    assert!(
        body.triangles
            .iter()
            .flatten()
            .all(|&i| i < body.vertices.len())
    );
}

#[test]
fn side_and_front_views_mesh_to_one_component_with_every_bone_inside_the_skin() {
    for camera in [Camera::side(5.0), Camera::front(5.0)] {
        let out = with_skeleton(camera);
        let mesh = &out.mesh;
        assert_eq!(out.alpha.component_count, 1);
        assert_eq!(mesh.edge_components(), 1, "{camera:?}");
        // Every bone strictly inside the skin outline, with at least 1 cm of soft tissue.
        let clearance = out.bone_clearance.unwrap();
        assert!(
            clearance >= 0.01,
            "bone clearance {clearance} m ({camera:?})"
        );
        for bone in &out.bones {
            for p in bone.polygons.iter().flat_map(|p| p.rings()).flatten() {
                assert!(
                    out.simplified.iter().any(|q| q.contains(*p)),
                    "{} vertex {p:?} outside the skin",
                    bone.name
                );
            }
        }
        assert_triangles_stay_in_their_regions(mesh, &out.simplified, &out.bones);
        assert_region_areas(mesh, &out.simplified, &out.bones, 1e-9);
        // Every named bone is meshed with a nonzero area.
        let names = [
            "skull", "spine", "pelvis", "femur", "tibia", "fibula", "humerus",
        ];
        assert_eq!(mesh.region_names[1..], names);
        for name in names {
            let k = mesh.region_index(name).unwrap();
            assert!(mesh.region_area(k) > 0.0, "{name} has no area ({camera:?})");
        }
        assert!(out.triangulate_report.refinement_complete);
        assert!(out.triangulate_report.max_area_met);
    }
}

#[test]
fn side_view_shows_two_distinct_legs_and_the_tibia_close_under_the_shin() {
    let out = with_skeleton(Camera::side(5.0));
    let mesh = &out.mesh;
    // The two tibiae (and fibulae) are separate region components, far apart: the bent leg's
    // shank is up by the knee (image y above 0.55), the straight one below 0.5.
    for name in ["tibia", "fibula"] {
        let k = mesh.region_index(name).unwrap();
        assert_eq!(mesh.region_components(k), 2, "{name}");
    }
    let tibia_k = mesh.region_index("tibia").unwrap();
    let (mut low, mut high) = (false, false);
    for t in (0..mesh.triangles.len()).filter(|&t| mesh.region_of(t) == tibia_k) {
        let y = mesh.corners(t).iter().map(|c| c[1]).sum::<f64>() / 3.0;
        low |= y < 0.5;
        high |= y > 0.55;
    }
    assert!(low && high, "one tibia per leg");
    // The legs do not coincide: a horizontal line through the bent knee and the straight
    // thigh crosses the outline in two separate intervals.
    let skin = crossings(&out, None, 0.75);
    assert_eq!(skin.len(), 4, "outline crossings at y = 0.75: {skin:?}");
    let gap = skin[2] - skin[1];
    assert!(gap > 0.03, "gap between the legs {gap} m");
    // Image x is the model's z (front to the right). At mid-shin only the straight (right)
    // leg is cut; its shin's skin is SHIN_SOFT_TISSUE (13 mm) in front of the tibia, up to the
    // tessellation and the outline's simplification (epsilon 12 mm): 1 to 1.8 cm (measured
    // 16.2 mm at this height).
    let skin = crossings(&out, None, 0.3);
    assert_eq!(skin.len(), 2, "outline crossings at y = 0.3: {skin:?}");
    let tibia = crossings(&out, Some("tibia"), 0.3);
    assert_eq!(tibia.len(), 2, "tibia crossings at y = 0.3: {tibia:?}");
    let soft = skin[1] - tibia[1];
    assert!(
        (0.010..=0.018).contains(&soft),
        "soft tissue in front of the tibia {soft} m (model {SHIN_SOFT_TISSUE} m)"
    );
    // The fibula is behind the tibia, not overlapping it.
    let fibula = crossings(&out, Some("fibula"), 0.3);
    assert!(fibula[1] < tibia[0], "fibula {fibula:?} tibia {tibia:?}");
}

#[test]
fn front_view_has_mirror_symmetric_arms_and_two_legs() {
    let out = with_skeleton(Camera::front(5.0));
    let mesh = &out.mesh;
    // The humeri are mirror images: the left and right halves of the region have equal areas
    // (within 1 %; the outlines are exact mirrors, so it is round-off).
    let humerus = mesh.region_index("humerus").unwrap();
    let (mut left, mut right) = (0.0, 0.0);
    for t in (0..mesh.triangles.len()).filter(|&t| mesh.region_of(t) == humerus) {
        let c = mesh.corners(t);
        let x = (c[0][0] + c[1][0] + c[2][0]) / 3.0;
        *(if x > 0.0 { &mut left } else { &mut right }) += mesh.signed_area(t);
    }
    assert!(left > 0.0 && right > 0.0);
    assert!(
        (left - right).abs() < 0.01 * left,
        "humerus areas {left} / {right}"
    );
    // The outline is symmetric above the hips: the crossings at chest and upper-arm height
    // mirror each other.
    for y in [1.2, 1.3] {
        let xs = crossings(&out, None, y);
        assert!(xs.len() >= 2 && xs.len().is_multiple_of(2), "{xs:?}");
        for (a, b) in xs.iter().zip(xs.iter().rev()) {
            // Within epsilon = 0.012 m: simplification may keep different vertices per side.
            assert!(
                (a + b).abs() < 0.012,
                "crossings at y = {y} not symmetric: {xs:?}"
            );
        }
    }
    // Two legs (a gap between the straight thigh and the bent shank) and open arm gaps.
    assert_eq!(crossings(&out, None, 0.6).len(), 4);
    for p in [[0.0, 0.6], [0.25, 1.05], [-0.25, 1.05]] {
        assert!(!mesh.contains_point(p), "{p:?} should be outside");
    }
}

#[test]
fn without_a_skeleton_the_body_still_meshes_untagged() {
    let out = mesh_surface(human_body(), &params(Camera::side(5.0))).unwrap();
    assert_eq!(out.mesh.edge_components(), 1);
    assert!(out.mesh.regions.is_empty() && out.bones.is_empty());
    assert!(out.bone_clearance.is_none());
}

#[test]
fn a_bone_reaching_the_skin_or_another_bone_is_an_error_naming_it() {
    // A bone that reaches through the skin (the skull moved 8 cm forward), then two bones
    // that overlap (the pelvis again under another name).
    let mut through = human_skeleton();
    for v in &mut through.bones[0].parts[0].vertices {
        v[2] += 0.08;
    }
    let mut overlapping = human_skeleton();
    let mut twin = overlapping.bones[2].clone();
    twin.name = "sacrum".into();
    overlapping.bones.push(twin);
    for (skeleton, expected) in [
        (through, "skeleton: inner region \"skull\""),
        (
            overlapping,
            "skeleton: inner regions \"pelvis\" and \"sacrum\" touch or overlap",
        ),
    ] {
        let err = mesh_surface_with_skeleton(human_body(), &skeleton, &params(Camera::side(5.0)))
            .unwrap_err()
            .to_string();
        assert!(err.starts_with(expected), "{err}");
        assert!(err.contains("bones must stay inside"), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
}
