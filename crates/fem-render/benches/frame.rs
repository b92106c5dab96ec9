//! Benchmarks of `fem_render::frame::render` (one 640x360 panel with a per-element field, a
//! colorbar and a title) alone and followed by PNG encoding, on structured rectangle meshes of
//! about 2.5k, 10k and 40k triangles; and of pushing such a frame into a GIF.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fem_render::frame::{FieldValues, FrameStyle, MeshView, render};
use fem_render::gif::GifWriter;

/// An `nx` x `ny` grid over a 2 m x 1 m strip, bent a little, split into `2 nx ny` triangles,
/// with a smooth synthetic per-element field (a stress-like bump and ramp, in Pa).
struct Mesh {
    positions: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
    field: Vec<f64>,
}

fn mesh(nx: usize, ny: usize) -> Mesh {
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            let (x, y) = (2.0 * i as f64 / nx as f64, j as f64 / ny as f64);
            positions.push([x, y - 0.08 * x * x]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    let field = triangles
        .iter()
        .map(|t| {
            let (mut x, mut y) = (0.0, 0.0);
            for &v in t {
                x += positions[v][0] / 3.0;
                y += positions[v][1] / 3.0;
            }
            1e5 * ((3.0 * x).sin() * (4.0 * y).cos() + 1.5) + 2e4 * x
        })
        .collect();
    Mesh {
        positions,
        triangles,
        field,
    }
}

fn style() -> FrameStyle {
    FrameStyle {
        title: "Cantilever, Neo-Hookean".into(),
        field_label: "von Mises stress".into(),
        unit: "kPa".into(),
        scale: 1e-3,
        time_label: Some("t = 0.120 s".into()),
        ..FrameStyle::default()
    }
}

fn view(m: &Mesh) -> MeshView<'_> {
    MeshView {
        field: Some(FieldValues::PerElement(&m.field)),
        caption: "Neo-Hookean",
        ..MeshView::new(&m.positions, &m.triangles)
    }
}

fn frame(c: &mut Criterion) {
    let style = style();
    let meshes = [(50, 25), (100, 50), (200, 100)].map(|(nx, ny)| mesh(nx, ny));
    let mut group = c.benchmark_group("frame");
    for m in &meshes {
        let n = m.triangles.len();
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::new("render", n), m, |b, m| {
            b.iter(|| render(black_box(&[view(m)]), &style).unwrap())
        });
        group.bench_with_input(BenchmarkId::new("render+png", n), m, |b, m| {
            b.iter(|| {
                let r = render(black_box(&[view(m)]), &style).unwrap();
                r.image.to_png().unwrap()
            })
        });
    }
    group.finish();
}

fn gif(c: &mut Criterion) {
    let m = mesh(100, 50);
    let image = render(&[view(&m)], &style()).unwrap().image;
    let mut group = c.benchmark_group("gif");
    group.throughput(Throughput::Elements(1));
    group.bench_function(
        format!("push {}x{} frame", image.width(), image.height()),
        |b| {
            let mut w = GifWriter::new(Vec::new(), image.width(), image.height(), 5).unwrap();
            b.iter(|| w.push(black_box(&image)).unwrap())
        },
    );
    group.finish();
}

criterion_group!(benches, frame, gif);
criterion_main!(benches);
