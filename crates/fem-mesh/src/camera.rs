//! Camera projection of 3D points onto the image plane (paper Eqs. 8-9, with the basis as the
//! BRIEF writes it):
//!
//! f̂ = (f − c)/|f − c|, r̂ = f̂ × u/|f̂ × u|, û = r̂ × f̂, and a point p has camera coordinates
//! (r̂·(p − c), û·(p − c), −f̂·(p − c)). The orthographic projection (the default) keeps the first
//! two. The perspective option divides by the depth d = f̂·(p − c) and multiplies by the focal
//! distance D = |f − c|, so points on the focal plane keep their size in model units.
//!
//! Projected points that coincide (closer than [`ProjectionParams::merge_distance`]) are merged:
//! mirror-symmetric models seen from the side put every vertex onto its twin.

use std::collections::HashMap;

use crate::error::{MeshError, Result};

/// Projection model of a [`Camera`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Projection {
    /// Keep the camera x and y coordinates (the paper's projection). Default.
    #[default]
    Orthographic,
    /// Pinhole projection through the camera position, scaled so the focal plane keeps its size.
    Perspective,
}

/// A camera: position c, focal point f, up vector u (model units), and the projection model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Camera position c (model units).
    pub position: [f64; 3],
    /// Focal point f the camera looks at (model units).
    pub focal_point: [f64; 3],
    /// Up vector u; need not be unit length nor orthogonal to the view direction, but must not be
    /// parallel to it.
    pub up: [f64; 3],
    /// Orthographic (default) or perspective.
    pub projection: Projection,
}

/// Ratio |f̂ × u| / |u| below which the up vector counts as parallel to the view direction
/// (sine of the angle between them: 1e-9 rad).
const PARALLEL_SINE: f64 = 1e-9;

/// Closest allowed depth in front of a perspective camera, relative to the focal distance.
const MIN_RELATIVE_DEPTH: f64 = 1e-6;

/// The orthonormal camera basis (r̂, û, f̂) and the camera position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraBasis {
    /// Right vector r̂.
    pub right: [f64; 3],
    /// Up vector û (orthogonal to r̂ and f̂).
    pub up: [f64; 3],
    /// Viewing direction f̂ (unit vector from the camera to the focal point).
    pub forward: [f64; 3],
    /// Camera position c.
    pub origin: [f64; 3],
    /// Focal distance |f − c|.
    pub focal_distance: f64,
}

impl Camera {
    /// An orthographic camera looking from `position` at `focal_point` with `up`.
    pub fn new(position: [f64; 3], focal_point: [f64; 3], up: [f64; 3]) -> Self {
        Self {
            position,
            focal_point,
            up,
            projection: Projection::Orthographic,
        }
    }

    /// Side view of a +Y-up, +Z-forward model from its right (−X) side at `distance`: image x is
    /// the model's z (front to the right), image y is the model's y.
    pub fn side(distance: f64) -> Self {
        Self::new([-distance, 0.0, 0.0], [0.0; 3], [0.0, 1.0, 0.0])
    }

    /// Front view of a +Y-up, +Z-forward model from +Z at `distance`: image x is the model's x,
    /// image y is the model's y.
    pub fn front(distance: f64) -> Self {
        Self::new([0.0, 0.0, distance], [0.0; 3], [0.0, 1.0, 0.0])
    }

    /// The camera basis, or an error for a degenerate camera (focal point at the camera, up
    /// parallel to the viewing direction, non-finite values).
    pub fn basis(&self) -> Result<CameraBasis> {
        let all = self
            .position
            .iter()
            .chain(&self.focal_point)
            .chain(&self.up);
        if all.clone().any(|v| !v.is_finite()) {
            return Err(MeshError::invalid(
                "camera",
                format!(
                    "position {:?}, focal point {:?}, up {:?}: every coordinate must be finite (a model with coordinates near the f64 limit overflows the preset views; scale it down with --scale)",
                    self.position, self.focal_point, self.up
                ),
            ));
        }
        let d = sub(self.focal_point, self.position);
        let dist = norm(d);
        if dist == 0.0 {
            return Err(MeshError::invalid(
                "camera",
                format!(
                    "focal point {:?} coincides with the camera position",
                    self.focal_point
                ),
            ));
        }
        let forward = scale(d, 1.0 / dist);
        let up_len = norm(self.up);
        let side = cross(forward, self.up);
        let side_len = norm(side);
        if up_len == 0.0 || side_len <= PARALLEL_SINE * up_len {
            return Err(MeshError::invalid(
                "camera",
                format!(
                    "up vector {:?} is zero or parallel to the view direction {:?}",
                    self.up, forward
                ),
            ));
        }
        let right = scale(side, 1.0 / side_len);
        let up = cross(right, forward);
        Ok(CameraBasis {
            right,
            up,
            forward,
            origin: self.position,
            focal_distance: dist,
        })
    }

    /// Projects every point to the image plane (no merging).
    pub fn project(&self, points: &[[f64; 3]]) -> Result<Vec<[f64; 2]>> {
        let basis = self.basis()?;
        let mut out = Vec::with_capacity(points.len());
        for (i, &p) in points.iter().enumerate() {
            let [x, y, z] = basis.camera_coordinates(p);
            match self.projection {
                Projection::Orthographic => out.push([x, y]),
                Projection::Perspective => {
                    let depth = -z;
                    if depth <= MIN_RELATIVE_DEPTH * basis.focal_distance {
                        return Err(MeshError::invalid(
                            "camera",
                            format!(
                                "point {i} at {p:?} is not in front of the perspective camera (depth {depth})"
                            ),
                        ));
                    }
                    let s = basis.focal_distance / depth;
                    out.push([x * s, y * s]);
                }
            }
        }
        Ok(out)
    }
}

impl CameraBasis {
    /// Camera coordinates (r̂·(p − c), û·(p − c), −f̂·(p − c)) of world point `p` (Eq. 9).
    pub fn camera_coordinates(&self, p: [f64; 3]) -> [f64; 3] {
        let q = sub(p, self.origin);
        [dot(self.right, q), dot(self.up, q), -dot(self.forward, q)]
    }
}

/// Parameters of [`project_points`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionParams {
    /// Merge distance in model units: points within about this distance merge into the first of
    /// them (see [`merge_coincident`]). Default 0.
    pub merge_distance: f64,
    /// Merge distance relative to the diagonal of the projected points' bounding box
    /// (dimensionless); the larger of the two distances applies. Default 1e-9: points that differ
    /// only by round-off (mirror twins computed along different paths) merge, anything a mesh
    /// could resolve does not.
    pub relative_merge_distance: f64,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        Self {
            merge_distance: 0.0,
            relative_merge_distance: 1e-9,
        }
    }
}

/// Projects `points` with `camera` and merges coincident results (first occurrence kept, input
/// order preserved). Errors on non-finite input points.
pub fn project_points(
    points: &[[f64; 3]],
    camera: &Camera,
    params: &ProjectionParams,
) -> Result<Vec<[f64; 2]>> {
    if let Some((i, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|c| !c.is_finite()))
    {
        return Err(MeshError::invalid(
            "projection",
            format!("point {i} has a non-finite coordinate {p:?}"),
        ));
    }
    let valid = |d: f64| d.is_finite() && d >= 0.0;
    if !(valid(params.merge_distance) && valid(params.relative_merge_distance)) {
        return Err(MeshError::invalid(
            "projection",
            format!("merge distances must be finite and >= 0, got {params:?}"),
        ));
    }
    let projected = camera.project(points)?;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in &projected {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let diagonal = if projected.is_empty() {
        0.0
    } else {
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
    };
    let distance = params
        .merge_distance
        .max(params.relative_merge_distance * diagonal);
    Ok(merge_coincident(&projected, distance))
}

/// Merges coincident points, keeping the first of each group in input order. With `distance`
/// 0 only bit-identical points merge; otherwise points that snap to the same cell of a grid of
/// spacing `distance` merge (so points much closer than `distance` merge, points farther apart
/// than `distance * sqrt(2)` never do). One hash look-up per point; the map is never iterated, so
/// the result is deterministic.
pub fn merge_coincident(points: &[[f64; 2]], distance: f64) -> Vec<[f64; 2]> {
    let mut out = Vec::with_capacity(points.len());
    let mut seen: HashMap<[u64; 2], ()> = HashMap::with_capacity(points.len());
    for &p in points {
        let key = if distance > 0.0 {
            p.map(|c| ((c / distance).round() as i64) as u64)
        } else {
            // `+ 0.0` folds -0.0 into 0.0.
            p.map(|c| (c + 0.0).to_bits())
        };
        if seen.insert(key, ()).is_none() {
            out.push(p);
        }
    }
    out
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
