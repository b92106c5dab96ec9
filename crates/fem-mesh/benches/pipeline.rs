//! Benchmark of the whole mesh pipeline on the MakeHuman body (13k vertices; side view about 6.8k
//! distinct projected points) to about 2k triangles (max area 2e-4 m^2, min angle 25 degrees),
//! file loading included, and of each stage on its own (load, project, alpha, simplify,
//! triangulate, quality), for the side and the front view.
//!
//! Run on one core: `taskset -c 1 cargo bench -p fem-mesh --bench pipeline`. Without the shared
//! fixture (`../shared/fixtures/human/makehuman_base.obj` beside the repository) the built-in
//! procedural body is measured instead, and the file-loading stage is skipped.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use fem_mesh::alpha::alpha_shape;
use fem_mesh::body::human_body;
use fem_mesh::camera::{Camera, project_points};
use fem_mesh::load::{LoadOptions, load_model};
use fem_mesh::pipeline::{PipelineParams, mesh_model_file, mesh_surface};
use fem_mesh::quality::QualityReport;
use fem_mesh::simplify::{SimplifyParams, simplify_polygon};
use fem_mesh::triangulate::{TriangulateParams, triangulate};

fn fixture() -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/fixtures/human/makehuman_base.obj");
    path.is_file().then_some(path)
}

fn params(camera: Camera, from_file: bool) -> PipelineParams {
    PipelineParams {
        load: LoadOptions {
            groups: if from_file {
                vec!["body".into()]
            } else {
                vec![]
            },
        },
        scale: if from_file { 0.1 } else { 1.0 },
        camera,
        triangulate: TriangulateParams {
            max_area: Some(2e-4),
            min_angle_deg: 25.0,
            ..TriangulateParams::default()
        },
        ..PipelineParams::default()
    }
}

fn bench(c: &mut Criterion) {
    let file = fixture();
    if file.is_none() {
        eprintln!("shared fixture missing: benchmarking the built-in body instead");
    }
    for (view, camera) in [("side", Camera::side(10.0)), ("front", Camera::front(10.0))] {
        let p = params(camera, file.is_some());
        let mut group = c.benchmark_group(format!("mesh_pipeline_{view}"));
        group.sample_size(30);
        let surface = match &file {
            Some(path) => {
                group.bench_function("whole_from_file", |b| {
                    b.iter(|| mesh_model_file(black_box(path), &p).unwrap())
                });
                group.bench_function("1_load", |b| {
                    b.iter(|| load_model(black_box(path), &p.load).unwrap())
                });
                let mut s = load_model(path, &p.load).unwrap();
                s.scale(p.scale);
                s
            }
            None => {
                let s = human_body();
                group.bench_function("whole_from_surface", |b| {
                    b.iter(|| mesh_surface(black_box(s.clone()), &p).unwrap())
                });
                s
            }
        };
        let out = mesh_surface(
            surface.clone(),
            &PipelineParams {
                scale: 1.0,
                ..p.clone()
            },
        )
        .unwrap();
        eprintln!(
            "{view}: {} distinct points, alpha radius {:.4}, {} -> {} polygon vertices, {} triangles",
            out.points.len(),
            out.alpha.radius,
            out.simplify_reports[0].vertices_before,
            out.simplify_reports[0].vertices_after,
            out.mesh.triangles.len()
        );
        group.bench_function("2_project", |b| {
            b.iter(|| {
                project_points(black_box(&surface.vertices), &p.camera, &p.projection).unwrap()
            })
        });
        group.bench_function("3_alpha", |b| {
            b.iter(|| alpha_shape(black_box(&out.points), &p.alpha).unwrap())
        });
        let simplify = SimplifyParams::new(out.epsilon);
        group.bench_function("4_simplify", |b| {
            b.iter(|| simplify_polygon(black_box(&out.alpha.polygons[0]), &simplify).unwrap())
        });
        group.bench_function("5_triangulate", |b| {
            b.iter(|| triangulate(black_box(&out.simplified), &p.triangulate).unwrap())
        });
        group.bench_function("6_quality", |b| {
            b.iter(|| QualityReport::of(black_box(&out.mesh), None))
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
