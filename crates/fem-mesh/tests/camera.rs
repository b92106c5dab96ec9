//! Camera projection (Eqs. 8-9): axis-aligned and rotated cameras map known points where the
//! formula says, perspective scales by depth, coincident points merge, degenerate cameras and
//! non-finite points are errors.

use fem_mesh::camera::{Camera, Projection, ProjectionParams, merge_coincident, project_points};

const TOL: f64 = 1e-12;

fn close2(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < TOL && (a[1] - b[1]).abs() < TOL
}

#[test]
fn side_camera_maps_z_to_image_x_and_y_to_image_y() {
    let cam = Camera::side(10.0);
    let out = cam.project(&[[3.0, 2.0, 1.0], [-4.0, -1.0, -2.0]]).unwrap();
    assert!(close2(out[0], [1.0, 2.0]), "{out:?}");
    assert!(close2(out[1], [-2.0, -1.0]), "{out:?}");
}

#[test]
fn front_camera_maps_x_to_image_x() {
    let cam = Camera::front(10.0);
    let out = cam.project(&[[3.0, 2.0, 1.0]]).unwrap();
    assert!(close2(out[0], [3.0, 2.0]), "{out:?}");
}

#[test]
fn camera_coordinates_follow_the_formula_for_a_rotated_camera() {
    // Camera on the diagonal looking at the origin, tilted up vector.
    let c = [2.0, 3.0, 4.0];
    let f = [0.5, -1.0, 0.25];
    let u = [0.1, 1.0, 0.3];
    let cam = Camera::new(c, f, u);
    let b = cam.basis().unwrap();
    // The formula written out independently.
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: [f64; 3]| {
        let n = dot(a, a).sqrt();
        [a[0] / n, a[1] / n, a[2] / n]
    };
    let fh = unit(sub(f, c));
    let rh = unit(cross(fh, u));
    let uh = cross(rh, fh);
    for (k, (x, y)) in [(b.right, rh), (b.up, uh), (b.forward, fh)]
        .into_iter()
        .enumerate()
    {
        for i in 0..3 {
            assert!(
                (x[i] - y[i]).abs() < TOL,
                "basis vector {k} differs: {x:?} vs {y:?}"
            );
        }
    }
    // Orthonormal and right-handed (r x u = -f, as in the camera-to-world matrix of Eq. 8).
    assert!((dot(b.right, b.up)).abs() < TOL);
    assert!((dot(b.right, b.forward)).abs() < TOL);
    let ru = cross(b.right, b.up);
    assert!(ru.iter().zip(b.forward).all(|(x, f)| (x + f).abs() < TOL));
    // The focal point sits on the optical axis at depth |f - c|.
    let q = b.camera_coordinates(f);
    let dist = dot(sub(f, c), sub(f, c)).sqrt();
    assert!(
        q[0].abs() < TOL && q[1].abs() < TOL && (q[2] + dist).abs() < TOL,
        "{q:?}"
    );
    // A known point: p = c + 2 r + 3 u + 5 f has camera coordinates (2, 3, -5).
    let p = [0, 1, 2].map(|i| c[i] + 2.0 * rh[i] + 3.0 * uh[i] + 5.0 * fh[i]);
    let q = b.camera_coordinates(p);
    assert!((q[0] - 2.0).abs() < 1e-12 && (q[1] - 3.0).abs() < 1e-12 && (q[2] + 5.0).abs() < 1e-12);
    let proj = cam.project(&[p]).unwrap();
    assert!(close2(proj[0], [2.0, 3.0]), "{proj:?}");
}

#[test]
fn camera_at_45_degrees_about_y() {
    // Looking along (1, 0, 1)/sqrt 2: r = f x y = (-1, 0, 1)/sqrt 2.
    let cam = Camera::new([-1.0, 0.0, -1.0], [0.0; 3], [0.0, 1.0, 0.0]);
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let out = cam.project(&[[1.0, 0.5, 0.0], [0.0, 0.0, 1.0]]).unwrap();
    assert!(close2(out[0], [-s, 0.5]), "{out:?}");
    assert!(close2(out[1], [s, 0.0]), "{out:?}");
}

#[test]
fn perspective_scales_by_focal_distance_over_depth() {
    let mut cam = Camera::front(10.0);
    cam.projection = Projection::Perspective;
    // On the focal plane (depth 10): unchanged. At depth 5 (z = 5): doubled.
    let out = cam.project(&[[1.0, 2.0, 0.0], [1.0, 2.0, 5.0]]).unwrap();
    assert!(close2(out[0], [1.0, 2.0]), "{out:?}");
    assert!(close2(out[1], [2.0, 4.0]), "{out:?}");
    // Behind the camera: error.
    let err = cam.project(&[[0.0, 0.0, 20.0]]).unwrap_err().to_string();
    assert!(err.contains("not in front"), "{err}");
}

#[test]
fn degenerate_cameras_are_errors() {
    let up_parallel = Camera::new([0.0, -5.0, 0.0], [0.0; 3], [0.0, 2.0, 0.0]);
    let err = up_parallel.basis().unwrap_err().to_string();
    assert!(
        err.starts_with("camera:") && err.contains("parallel"),
        "{err}"
    );
    let same = Camera::new([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [0.0, 1.0, 0.0]);
    let err = same.basis().unwrap_err().to_string();
    assert!(err.contains("coincides"), "{err}");
    let zero_up = Camera::new([0.0, 0.0, 5.0], [0.0; 3], [0.0; 3]);
    assert!(zero_up.basis().is_err());
    let nan = Camera::new([f64::NAN, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0]);
    assert!(nan.basis().is_err());
}

#[test]
fn coincident_projected_points_are_merged_in_order() {
    // Mirror twins in a side view project onto each other.
    let pts = [
        [1.0, 2.0, 3.0],
        [-1.0, 2.0, 3.0],
        [0.0, 5.0, 3.0],
        [2.0, 2.0, 3.0],
    ];
    let out = project_points(&pts, &Camera::side(10.0), &ProjectionParams::default()).unwrap();
    assert_eq!(out, vec![[3.0, 2.0], [3.0, 5.0]]);
    // Round-off twins merge by default.
    let out = merge_coincident(&[[1.0, 1.0], [1.0 + 1e-15, 1.0], [2.0, 1.0]], 1e-9);
    assert_eq!(out.len(), 2);
    // A given merge distance merges near points, keeps far ones.
    let out = merge_coincident(&[[0.0, 0.0], [0.001, 0.0], [0.5, 0.0]], 0.01);
    assert_eq!(out, vec![[0.0, 0.0], [0.5, 0.0]]);
}

#[test]
fn nan_points_are_errors() {
    let err = project_points(
        &[[0.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]],
        &Camera::side(1.0),
        &ProjectionParams::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("point 1") && err.contains("non-finite"),
        "{err}"
    );
}
