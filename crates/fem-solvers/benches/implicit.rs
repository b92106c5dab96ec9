//! Criterion bench of one Newton iteration of the implicit stepper (gradient, projected
//! Hessian assembly, numeric sparse Cholesky factorisation with the symbolic analysis reused,
//! triangular solve, line search) on the case A beam at 16k, 64k and 256k triangles
//! (Neo-Hookean, dt = 1 ms, from rest under gravity). The split of the iteration into its parts
//! is printed by `examples/newton_split.rs`.
//!
//! `cargo bench -p fem-solvers --bench implicit`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::energy::NeoHookean;
use fem_core::material::Material;
use fem_solvers::testing::{beam_cells_for, beam_mesh, cantilever};
use fem_solvers::{ImplicitParams, ImplicitStepper, NewtonParams, State, Stepper};

fn newton_iteration(c: &mut Criterion) {
    let lame = Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let mut group = c.benchmark_group("newton_iteration");
    group.sample_size(10);
    for size in [16_000, 64_000, 256_000] {
        let (nx, ny) = beam_cells_for(size);
        let model = cantilever(beam_mesh(nx, ny).unwrap(), NeoHookean::new(lame).unwrap()).unwrap();
        // One iteration per call: the tolerance cannot be met, so the step stops after its
        // single allowed iteration and leaves the state unchanged (steady workload).
        let mut stepper = ImplicitStepper::new(
            &model,
            ImplicitParams {
                dt: 1e-3,
                newton: NewtonParams {
                    tolerance: 1e-300,
                    max_iterations: 1,
                    ..Default::default()
                },
                ..Default::default()
            },
        )
        .unwrap();
        let mut state = State::at_rest(&model);
        group.throughput(Throughput::Elements(model.mesh().n_triangles() as u64));
        group.bench_function(format!("{}", model.mesh().n_triangles()), |b| {
            b.iter(|| {
                let _ = stepper.step(&model, &mut state);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, newton_iteration);
criterion_main!(benches);
