//! # fem-mesh: from a 3D model to a quality 2D FEM mesh
//!
//! The mesh-conversion pipeline of the paper (Section 3.3, Figure 1), as a library:
//!
//! 1. [`load`]: read a 3D surface (OBJ with group selection, STL, PLY) into a [`Surface3`];
//! 2. [`camera`]: project it with a camera (position, focal point, up; orthographic or
//!    perspective) and merge coincident points;
//! 3. [`alpha`]: alpha shape of the 2D points (radius convention, suggested radius), boundary
//!    as polygons with holes;
//! 4. [`simplify`]: Douglas-Peucker with a validity guarantee;
//! 5. [`triangulate`]: constrained Delaunay with max-area / min-angle refinement (spade),
//!    optionally with inner regions (bones) whose edges the triangles follow, each triangle
//!    tagged with its region;
//! 6. [`quality`]: the mesh quality report.
//!
//! [`pipeline`] chains them with per-stage timings; [`io`] reads and writes the mesh JSON contract and exports Gmsh and VTK files;
//! [`preview`] draws each stage; [`body`] builds a procedural human body and its skeleton so
//! everything runs without an outside model file
//! ([`pipeline::mesh_surface_with_skeleton`] meshes the bones as regions); [`shank`] is a
//! lower-leg section with its tibia, for close-up studies of the shin.
//!
//! ```
//! use fem_mesh::{body::human_body, pipeline::{mesh_surface, PipelineParams}};
//! let mut params = PipelineParams::default(); // side view, suggested alpha, 25 degrees
//! params.triangulate.max_area = Some(2e-3);
//! let out = mesh_surface(human_body(), &params).unwrap();
//! assert_eq!(out.mesh.edge_components(), 1);
//! ```
//!
//! **What this crate does not know:** materials, elements, time stepping, boundary conditions,
//! or any other `fem-*` crate (it depends on none). Its output is a plain [`Mesh2`]; units are
//! whatever the model uses, times [`pipeline::PipelineParams::scale`].

pub mod alpha;
pub mod body;
pub mod camera;
pub mod clock;
pub mod error;
mod guard;
pub mod io;
pub mod load;
pub mod pipeline;
pub mod preview;
pub mod quality;
pub mod shank;
pub mod simplify;

pub mod triangulate;
pub mod types;

pub use error::{MeshError, Result};
pub use types::{Bone, InnerRegion, Mesh2, PolygonWithHoles, Skeleton, Surface3};

/// The types most programs need, in one import: `use fem_mesh::prelude::*;`.
///
/// The pipeline (`mesh_surface`, `mesh_model_file` and their parameters and output), the
/// procedural body, the mesh and surface types, the mesh JSON reader and writer, and the
/// crate's error.
pub mod prelude {
    pub use crate::alpha::AlphaParams;
    pub use crate::body::{human_body, human_skeleton};
    pub use crate::camera::{Camera, Projection};
    pub use crate::io::{read_mesh_json, write_mesh_json};
    pub use crate::pipeline::{
        PipelineOutput, PipelineParams, mesh_model_file, mesh_surface, mesh_surface_with_skeleton,
    };
    pub use crate::quality::QualityReport;
    pub use crate::simplify::SimplifyParams;
    pub use crate::triangulate::{TriangulateParams, triangulate_regions};
    pub use crate::{InnerRegion, Mesh2, MeshError, PolygonWithHoles, Skeleton, Surface3};
}

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
