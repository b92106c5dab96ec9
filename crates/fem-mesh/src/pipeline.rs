//! The whole model-to-mesh pipeline (paper Section 3.3, Figure 1): load, scale, project, merge,
//! alpha shape, Douglas-Peucker simplification, constrained Delaunay refinement and the quality
//! report, with the wall time of every stage.

use std::path::Path;
use std::time::Duration;

use crate::alpha::{AlphaParams, AlphaShape, alpha_shape};
use crate::camera::{Camera, ProjectionParams, project_points};
use crate::clock::Stopwatch;
use crate::error::{MeshError, Result};
use crate::load::{LoadOptions, load_model};
use crate::preview::Stages;
use crate::quality::{QualityReport, boundary_hausdorff};
use crate::simplify::{SimplifyParams, SimplifyReport, simplify_polygon};
use crate::triangulate::{TriangulateParams, TriangulateReport, triangulate};
use crate::types::{Mesh2, PolygonWithHoles, Surface3};

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
    /// The final mesh.
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
pub fn mesh_surface(mut surface: Surface3, params: &PipelineParams) -> Result<PipelineOutput> {
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
    times.simplify = t.elapsed();

    let t = Stopwatch::start();
    let (mesh, triangulate_report) = triangulate(&simplified, &params.triangulate)?;
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
        mesh,
        triangulate_report,
        quality,
        times,
    })
}
