//! Force-assembly throughput table: element evaluations per second for every energy at about
//! 1k, 16k, 64k and 256k triangles on 1 and 2 threads, as a markdown table.
//!
//! Run: `cargo run --release -p fem-core --example assembly_scaling [REPEATS]`
//!
//! Each cell is the best of `REPEATS` (default 200, fewer on large meshes so a cell takes about
//! the same time) timed calls of `assembly::populate_forces` on the case A beam (5 m x 1 m,
//! structured, bent so every element is strained). Best-of-N is reported because it is the
//! figure least disturbed by other work on the machine; criterion's `benches/assembly.rs`
//! gives the full distributions.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use common::{Diagonal, rectangle};

use fem_core::assembly::{Scratch, populate_forces};
use fem_core::dispatch_energy;
use fem_core::energy::EnergyKind;
use fem_core::material::{Material, PlaneModel};
use fem_core::math::Vec2;

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("REPEATS must be a positive integer"))
        .unwrap_or(200);
    let lame = Material::new(1000.0, 0.3, 1.0)
        .expect("valid material")
        .lame(PlaneModel::PlaneStrain);
    let sizes = [(50, 10), (200, 40), (400, 80), (800, 160)];
    let kinds = [
        EnergyKind::NeoHookean,
        EnergyKind::Stvk,
        EnergyKind::Corotational,
        EnergyKind::StableNeoHookean,
        EnergyKind::Linear,
    ];
    println!("| energy | triangles | 1 thread (elem/s) | 2 threads (elem/s) | speed-up |");
    println!("|---|---:|---:|---:|---:|");
    for &(nx, ny) in &sizes {
        let mesh = rectangle(5.0, 1.0, nx, ny, Diagonal::Right);
        let x: Vec<Vec2> = mesh
            .vertices()
            .iter()
            .map(|p| Vec2::new(p.x, p.y - 0.02 * p.x * p.x))
            .collect();
        let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
        let n = mesh.n_triangles();
        let reps = (repeats * 16_000 / n).clamp(20, 20 * repeats);
        for kind in kinds {
            let energy = kind.build(lame).expect("valid parameters");
            let mut rates = [0.0; 2];
            for (slot, threads) in [1, 2].into_iter().enumerate() {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("thread pool");
                let mut scratch = Scratch::new();
                let best = pool.install(|| {
                    (0..reps)
                        .map(|_| {
                            let t = Instant::now();
                            dispatch_energy!(&energy, e => populate_forces(&mesh, e, &x, &mut f, &mut scratch));
                            t.elapsed().as_secs_f64()
                        })
                        .fold(f64::INFINITY, f64::min)
                });
                rates[slot] = n as f64 / best;
            }
            println!(
                "| {} | {} | {:.3e} | {:.3e} | {:.2} |",
                kind.name(),
                n,
                rates[0],
                rates[1],
                rates[1] / rates[0]
            );
        }
    }
}
