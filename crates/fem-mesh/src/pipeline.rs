//! The whole model-to-mesh pipeline (paper Section 3.3, Figure 1): load, scale, project, merge,
//! alpha shape, Douglas-Peucker simplification, constrained Delaunay refinement and the quality
//! report, with the wall time of every stage.
//!
//! [`mesh_surface_with_skeleton`] adds bones: each bone's convex parts are projected with the
//! skin's camera, outlined by the convex hull of their projected vertices (exact for a convex
//! part, up to its tessellation), the parts of one bone are unioned (geo's boolean union: mirror
//! twins coincide in a side view), the outline is simplified with a quarter of the skin's ε,
//! and the bones are meshed as inner regions ([`crate::triangulate::triangulate_regions`]):
//! region 0 is the soft tissue, region `k + 1` bone `k`.

use std::path::Path;
use std::time::Duration;

use crate::alpha::{AlphaParams, AlphaShape, alpha_shape};
use crate::camera::{Camera, ProjectionParams, project_points};
use crate::clock::Stopwatch;
use crate::error::{MeshError, Result};
use crate::load::{LoadOptions, load_model};
use crate::preview::Stages;
use crate::quality::{QualityReport, boundary_hausdorff};
use crate::simplify::from_geo;
use crate::simplify::{SimplifyParams, SimplifyReport, simplify_polygon};
use crate::triangulate::{
    TriangulateParams, TriangulateReport, check_inner_regions, triangulate, triangulate_regions,
};
use crate::types::{InnerRegion, Mesh2, PolygonWithHoles, Skeleton, Surface3};

/// Douglas-Peucker tolerance of the bone outlines, as a fraction of the skin's ε: bones are
/// simplified lightly (their hulls are already smooth; this only drops the tessellation's
/// nearly collinear vertices).
pub const BONE_EPSILON_FRACTION: f64 = 0.25;

/// Every parameter of the pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineParams {
    /// Loader options (OBJ group selection). Default: every face.
    pub load: LoadOptions,
    /// Factor applied to the model coordinates before projection (0.1 turns decimetres into
    /// metres). Default 1.
    pub scale: f64,
    /// The camera. Default [`Camera::side`] at distance 10 (orthographic, so the distance does not
    /// matter).
    pub camera: Camera,
    /// Merging of coincident projected points. Default: exact duplicates only.
    pub projection: ProjectionParams,
    /// Alpha-shape radius (model units after scaling) and component selection. Default: suggested
    /// radius, largest component.
    pub alpha: AlphaParams,
    /// Douglas-Peucker tolerance ε (model units after scaling). `None` (default) uses
    /// [`PipelineParams::epsilon_per_radius`] times the alpha radius.
    pub epsilon: Option<f64>,
    /// ε as a fraction of the alpha radius when no ε is given (dimensionless). Default 0.25.
    pub epsilon_per_radius: f64,
    /// Refinement bounds (max area in model units squared after scaling, min angle, vertex cap).
    pub triangulate: TriangulateParams,
}

impl Default for PipelineParams {
    fn default() -> Self {
        Self {
            load: LoadOptions::default(),
            scale: 1.0,
            camera: Camera::side(10.0),
            projection: ProjectionParams::default(),
            alpha: AlphaParams::default(),
            epsilon: None,
            epsilon_per_radius: 0.25,
            triangulate: TriangulateParams::default(),
        }
    }
}

/// Wall time of each stage.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StageTimes {
    /// Reading and parsing the model file (zero when the surface was given).
    pub load: Duration,
    /// Scaling, projection and merging of coincident points.
    pub project: Duration,
    /// Delaunay triangulation, alpha shape and boundary extraction.
    pub alpha: Duration,
    /// Douglas-Peucker simplification and validation.
    pub simplify: Duration,
    /// Constrained Delaunay triangulation and refinement.
    pub triangulate: Duration,
    /// Quality report.
    pub quality: Duration,
}

impl StageTimes {
    /// Sum of all stages.
    pub fn total(&self) -> Duration {
        self.load + self.project + self.alpha + self.simplify + self.triangulate + self.quality
    }
}

/// Everything the pipeline produced, stage by stage.
#[derive(Debug, Clone)]
pub struct PipelineOutput {
    /// Vertex count of the (selected) 3D surface.
    pub surface_vertices: usize,
    /// Projected points after merging coincident ones.
    pub points: Vec<[f64; 2]>,
    /// The alpha shape (radius used, suggestion, components, boundary polygons).
    pub alpha: AlphaShape,
    /// ε used (model units).
    pub epsilon: f64,
    /// Simplified polygons, one per kept component.
    pub simplified: Vec<PolygonWithHoles>,
    /// What simplification did, per polygon.
    pub simplify_reports: Vec<SimplifyReport>,
    /// The bones' simplified outlines as meshed (region `k + 1` is `bones[k]`); empty without a
    /// skeleton.
    pub bones: Vec<InnerRegion>,
    /// Smallest distance between a bone outline and the simplified skin outline (model units);
    /// `None` without a skeleton.
    pub bone_clearance: Option<f64>,
    /// The final mesh (tagged with regions when a skeleton was given).
    pub mesh: Mesh2,
    /// What refinement achieved.
    pub triangulate_report: TriangulateReport,
    /// Quality numbers of the mesh, against the alpha shape (area and boundary distance, so
    /// what simplification removed is reported).
    pub quality: QualityReport,
    /// Wall time per stage.
    pub times: StageTimes,
}

impl PipelineOutput {
    /// The four stages, borrowed, for [`crate::preview::write_previews`].
    pub fn stages(&self) -> Stages<'_> {
        Stages {
            points: &self.points,
            alpha_triangles: &self.alpha.triangles,
            alpha_points: &self.alpha.points,
            alpha_polygons: &self.alpha.polygons,
            simplified: &self.simplified,
            mesh: &self.mesh,
        }
    }
}

/// Runs the pipeline on the model file at `path`.
pub fn mesh_model_file(path: &Path, params: &PipelineParams) -> Result<PipelineOutput> {
    let start = Stopwatch::start();
    let surface = load_model(path, &params.load)?;
    let load = start.elapsed();
    let mut out = mesh_surface(surface, params)?;
    out.times.load = load;
    Ok(out)
}

/// Runs the pipeline on an already loaded surface (it is scaled in place by `params.scale`).
pub fn mesh_surface(surface: Surface3, params: &PipelineParams) -> Result<PipelineOutput> {
    run(surface, None, params)
}

/// Runs the pipeline on a body surface with its skeleton: the bones become inner regions of the
/// mesh (see the module docs). Every bone must lie inside the simplified skin outline without
/// touching it (the outline may cut up to ε into the skin, so bones need a margin of more than
/// ε from the skin in the model); bones of different names must not touch or overlap in the
/// view. Either failure is a one-line error naming the bone.
pub fn mesh_surface_with_skeleton(
    surface: Surface3,
    skeleton: &Skeleton,
    params: &PipelineParams,
) -> Result<PipelineOutput> {
    run(surface, Some(skeleton), params)
}

/// The 2D outline of each bone: convex hulls of its parts' projections, unioned, simplified
/// with tolerance `epsilon`.
fn bone_outlines(
    skeleton: &Skeleton,
    params: &PipelineParams,
    epsilon: f64,
) -> Result<Vec<InnerRegion>> {
    use geo::{ConvexHull, MultiPoint, Point};
    let mut bones = Vec::with_capacity(skeleton.bones.len());
    for bone in &skeleton.bones {
        let mut hulls = Vec::with_capacity(bone.parts.len());
        for (i, part) in bone.parts.iter().enumerate() {
            let vertices: Vec<[f64; 3]> = part
                .vertices
                .iter()
                .map(|v| v.map(|c| c * params.scale))
                .collect();
            let projected = params.camera.project(&vertices)?;
            if projected.len() < 3
                || projected
                    .iter()
                    .any(|p| !(p[0].is_finite() && p[1].is_finite()))
            {
                return Err(MeshError::invalid(
                    "skeleton",
                    format!(
                        "bone {:?} part {i} has {} vertices or a non-finite one; a part needs at least 3 finite vertices",
                        bone.name,
                        projected.len()
                    ),
                ));
            }
            let points: MultiPoint<f64> =
                projected.iter().map(|p| Point::new(p[0], p[1])).collect();
            hulls.push(points.convex_hull());
        }
        if hulls.is_empty() {
            return Err(MeshError::invalid(
                "skeleton",
                format!("bone {:?} has no part", bone.name),
            ));
        }
        let union = geo::unary_union(hulls.iter());
        let mut polygons = Vec::with_capacity(union.0.len());
        for polygon in &union.0 {
            let mut outline = from_geo(polygon);
            // geo's union may return either orientation; the mesher wants outer rings
            // counter-clockwise and holes clockwise.
            if crate::types::ring_signed_area(&outline.outer) < 0.0 {
                outline.outer.reverse();
            }
            for h in &mut outline.holes {
                if crate::types::ring_signed_area(h) > 0.0 {
                    h.reverse();
                }
            }
            let (simplified, _) = simplify_polygon(&outline, &SimplifyParams::new(epsilon))
                .map_err(|e| {
                    MeshError::invalid("skeleton", format!("bone {:?}: {e}", bone.name))
                })?;
            polygons.push(simplified);
        }
        // A bone whose parts all project to segments unions to nothing.
        if polygons.iter().map(PolygonWithHoles::area).sum::<f64>() <= 0.0 {
            return Err(MeshError::invalid(
                "skeleton",
                format!("bone {:?} has no area in this view", bone.name),
            ));
        }
        bones.push(InnerRegion {
            name: bone.name.clone(),
            polygons,
        });
    }
    Ok(bones)
}

fn run(
    mut surface: Surface3,
    skeleton: Option<&Skeleton>,
    params: &PipelineParams,
) -> Result<PipelineOutput> {
    let mut times = StageTimes::default();
    if !(params.scale.is_finite() && params.scale > 0.0) {
        return Err(MeshError::invalid(
            "pipeline",
            format!("scale must be positive and finite, got {}", params.scale),
        ));
    }
    let t = Stopwatch::start();
    if params.scale != 1.0 {
        surface.scale(params.scale);
    }
    let points = project_points(&surface.vertices, &params.camera, &params.projection)?;
    times.project = t.elapsed();

    let t = Stopwatch::start();
    let alpha = alpha_shape(&points, &params.alpha)?;
    times.alpha = t.elapsed();

    let t = Stopwatch::start();
    let epsilon = params
        .epsilon
        .unwrap_or(params.epsilon_per_radius * alpha.radius);
    let simplify_params = SimplifyParams::new(epsilon);
    let mut simplified = Vec::with_capacity(alpha.polygons.len());
    let mut simplify_reports = Vec::with_capacity(alpha.polygons.len());
    for polygon in &alpha.polygons {
        let (p, r) = simplify_polygon(polygon, &simplify_params)?;
        simplified.push(p);
        simplify_reports.push(r);
    }

    let (bones, bone_clearance) = match skeleton {
        None => (Vec::new(), None),
        Some(skeleton) => {
            let bones = bone_outlines(skeleton, params, BONE_EPSILON_FRACTION * epsilon)?;
            check_inner_regions(&simplified, &bones).map_err(|e| {
                MeshError::invalid(
                    "skeleton",
                    format!(
                        "{}; bones must stay inside the simplified skin outline (which may cut up to epsilon = {epsilon} into the skin) and apart from each other",
                        invalid_message(e)
                    ),
                )
            })?;
            let clearance = bones
                .iter()
                .map(|b| crate::quality::boundary_clearance(&b.polygons, &simplified))
                .fold(f64::INFINITY, f64::min);
            (bones, Some(clearance))
        }
    };
    times.simplify = t.elapsed();

    let t = Stopwatch::start();
    let (mesh, triangulate_report) = if skeleton.is_some() {
        triangulate_regions(&simplified, &bones, &params.triangulate)?
    } else {
        triangulate(&simplified, &params.triangulate)?
    };
    times.triangulate = t.elapsed();

    let t = Stopwatch::start();
    // Against the alpha shape, not the simplified polygons: what simplification removed (a
    // 32-gon made an octagon loses 9.4 % of its area) shows in the report.
    let alpha_area = alpha.polygons.iter().map(PolygonWithHoles::area).sum();
    let quality = QualityReport::of(&mesh, Some(alpha_area))
        .with_boundary_hausdorff(boundary_hausdorff(&alpha.polygons, &simplified));
    times.quality = t.elapsed();

    Ok(PipelineOutput {
        surface_vertices: surface.vertices.len(),
        points,
        alpha,
        epsilon,
        simplified,
        simplify_reports,
        bones,
        bone_clearance,
        mesh,
        triangulate_report,
        quality,
        times,
    })
}

/// The message of an [`MeshError::Invalid`] (the whole text otherwise).
fn invalid_message(e: MeshError) -> String {
    match e {
        MeshError::Invalid { message, .. } => message,
        other => other.to_string(),
    }
}
