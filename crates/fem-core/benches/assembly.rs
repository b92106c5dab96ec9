//! Force assembly throughput per energy: element evaluations per second at about 1k, 16k and
//! 256k triangles, on 1 and 2 threads.
//!
//! Run: `cargo bench -p fem-core --bench assembly` (filter with e.g. `-- forces/neo-hookean`).
//! Criterion's "thrpt" column is elements per second (one element evaluation = F, P and the
//! three nodal forces of one triangle, gathered into the global force vector). Pin the
//! one-thread numbers to a core with `taskset -c 1` when comparing.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Duration;

use common::{Diagonal, Rng, deformed, rectangle};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fem_core::assembly::{Scratch, populate_forces};
use fem_core::dispatch_energy;
use fem_core::energy::EnergyKind;
use fem_core::material::{Material, PlaneModel};
use fem_core::math::Vec2;

fn forces(c: &mut Criterion) {
    let lame = Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    // Case A beam proportions (5:1), 2 triangles per quad.
    let sizes = [(50, 10), (200, 40), (800, 160)]; // 1000, 16000, 256000 triangles
    let mut group = c.benchmark_group("forces");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for &(nx, ny) in &sizes {
        let mesh = rectangle(5.0, 1.0, nx, ny, Diagonal::Right);
        let x = deformed(&mesh, &mut Rng::new(1), 0.05);
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        group.throughput(Throughput::Elements(mesh.n_triangles() as u64));
        for kind in [
            EnergyKind::NeoHookean,
            EnergyKind::Stvk,
            EnergyKind::Corotational,
            EnergyKind::StableNeoHookean,
            EnergyKind::Linear,
        ] {
            let energy = kind.build(lame).unwrap();
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let id =
                    BenchmarkId::new(format!("{}/{}t", kind.name(), threads), mesh.n_triangles());
                let mut scratch = Scratch::new();
                group.bench_function(id, |b| {
                    pool.install(|| {
                        b.iter(|| {
                            dispatch_energy!(&energy, e => populate_forces(&mesh, e, &x, &mut f, &mut scratch))
                        })
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, forces);
criterion_main!(benches);
