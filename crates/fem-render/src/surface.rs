//! A 3D body's surface drawn from a stated view by the painter's algorithm: the boundary
//! triangles that face the camera, projected orthographically and sorted far to near, become an
//! ordinary 2D [`MeshView`](crate::MeshView) whose later triangles paint over earlier ones.
//!
//! The camera looks at the body from the direction `e = (sin az cos el, sin el, cos az cos el)`
//! (azimuth `az` about the vertical y axis from +z, elevation `el` above the x-z plane), with
//! y up: the screen's x axis is `r = y x e / |y x e|`, its y axis `u = e x r`, and a point's depth
//! is `p . e` (larger is nearer). A triangle whose outward normal points away from the camera
//! (`n . e <= 0`) is culled. For a convex body culling alone is exact; for others the far-to-near
//! order of the triangles' centroids resolves most overlaps (the painter's algorithm's known
//! limit: interpenetrating or cyclically overlapping triangles may be drawn in the wrong order).
//!
//! ```
//! use fem_render::surface::{View, project};
//! // A unit tetrahedron's four outward faces, seen from the front (+z).
//! let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let faces = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
//! let s = project(&p, &faces, View::FRONT);
//! // Only the slanted face (normal (1, 1, 1)) faces +z; the three in the coordinate planes
//! // (normals -x, -y, -z) are culled.
//! assert_eq!(s.faces, vec![[1, 2, 3]]);
//! ```

/// A camera direction: azimuth and elevation, degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Azimuth about the vertical y axis, degrees from +z towards +x.
    pub azimuth_deg: f64,
    /// Elevation above the horizontal x-z plane, degrees.
    pub elevation_deg: f64,
}

impl View {
    /// From the front (+z), level.
    pub const FRONT: View = View {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
    };
    /// The report's oblique view: 30 degrees to the right of the front, 25 degrees above.
    pub const OBLIQUE: View = View {
        azimuth_deg: 30.0,
        elevation_deg: 25.0,
    };

    /// `azimuth 30 deg, elevation 25 deg`, for captions.
    pub fn describe(&self) -> String {
        format!(
            "azimuth {} deg, elevation {} deg",
            self.azimuth_deg, self.elevation_deg
        )
    }

    /// The camera's (right, up, towards-camera) unit vectors.
    pub fn axes(&self) -> [[f64; 3]; 3] {
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        let e = [az.sin() * el.cos(), el.sin(), az.cos() * el.cos()];
        // r = y x e = (e_z, 0, -e_x), normalised (el = +-90 deg is degenerate: use +x).
        let n = (e[2] * e[2] + e[0] * e[0]).sqrt();
        let r = if n > 1e-12 {
            [e[2] / n, 0.0, -e[0] / n]
        } else {
            [1.0, 0.0, 0.0]
        };
        let u = cross(e, r);
        [r, u, e]
    }
}

/// The visible surface in screen coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Projected {
    /// Every point projected to the screen plane `(p . r, p . u)`, m.
    pub positions: Vec<[f64; 2]>,
    /// The visible triangles, far to near (draw in this order).
    pub faces: Vec<[usize; 3]>,
    /// For each visible triangle, its index in the input.
    pub source: Vec<usize>,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Project the surface triangles `faces` (outward, counter-clockwise seen from outside) of the
/// points `positions` for `view`: cull the ones facing away, sort the rest far to near by
/// centroid depth (ties by input index, so the order is deterministic). Faces naming a point
/// that does not exist are skipped.
pub fn project(positions: &[[f64; 3]], faces: &[[usize; 3]], view: View) -> Projected {
    let [r, u, e] = view.axes();
    let screen = positions.iter().map(|&p| [dot(p, r), dot(p, u)]).collect();
    let mut visible: Vec<(f64, usize)> = faces
        .iter()
        .enumerate()
        .filter(|(_, f)| f.iter().all(|&i| i < positions.len()))
        .filter_map(|(k, f)| {
            let [a, b, c] = f.map(|i| positions[i]);
            let n = cross(sub(b, a), sub(c, a));
            if dot(n, e) <= 0.0 {
                return None;
            }
            let depth = (dot(a, e) + dot(b, e) + dot(c, e)) / 3.0;
            depth.is_finite().then_some((depth, k))
        })
        .collect();
    visible.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    Projected {
        positions: screen,
        faces: visible.iter().map(|&(_, k)| faces[k]).collect(),
        source: visible.iter().map(|&(_, k)| k).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_are_orthonormal_and_right_handed() {
        for view in [View::FRONT, View::OBLIQUE] {
            let [r, u, e] = view.axes();
            for (a, b) in [(r, u), (u, e), (e, r)] {
                assert!(dot(a, b).abs() < 1e-15);
            }
            for a in [r, u, e] {
                assert!((dot(a, a) - 1.0).abs() < 1e-15);
            }
            let c = cross(r, u);
            assert!(dot(c, e) > 1.0 - 1e-15);
        }
    }

    /// A unit cube's twelve outward triangles: from the oblique view three faces show (six
    /// triangles), and the nearest corner's faces come last.
    #[test]
    fn a_cube_shows_three_faces_from_an_oblique_view() {
        let p: Vec<[f64; 3]> = (0..8)
            .map(|k| [(k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64])
            .collect();
        // Quads (outward, counter-clockwise from outside) split into two triangles each.
        let quads = [
            [0, 2, 3, 1], // z = 0
            [4, 5, 7, 6], // z = 1
            [0, 1, 5, 4], // y = 0
            [2, 6, 7, 3], // y = 1
            [0, 4, 6, 2], // x = 0
            [1, 3, 7, 5], // x = 1
        ];
        let faces: Vec<[usize; 3]> = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let s = project(&p, &faces, View::OBLIQUE);
        let shown: Vec<usize> = s.source.iter().map(|k| k / 2).collect();
        assert_eq!(s.faces.len(), 6, "{shown:?}");
        // z = 1, y = 1 and x = 1 face the camera at azimuth 30, elevation 25.
        for q in [1, 3, 5] {
            assert_eq!(shown.iter().filter(|&&k| k == q).count(), 2, "{shown:?}");
        }
    }
}
