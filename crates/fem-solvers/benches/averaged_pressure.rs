//! Criterion benches of the averaged nodal pressure triangle's cost against plain linear
//! triangles (Neo-Hookean, nu = 0.49, plane strain, the case A beam's shape): one explicit step
//! at 64k triangles, and one implicit Euler Newton iteration (assembly, factorisation, solve,
//! line search) at 16k and 64k triangles, on the current rayon pool.
//!
//! `cargo bench -p fem-solvers --bench averaged_pressure`; the numbers are in docs/energies.md.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::energy::NeoHookean;
use fem_core::material::Material;
use fem_solvers::testing::{self, beam_cells_for, beam_mesh, cantilever};
use fem_solvers::{
    ExplicitParams, ExplicitStepper, ImplicitParams, ImplicitStepper, Model, NewtonParams, State,
    Stepper,
};

fn model(triangles: usize, averaged: bool) -> Model<NeoHookean> {
    let lame = Material::new(1000.0, 0.49, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let (nx, ny) = beam_cells_for(triangles);
    let mut m = cantilever(beam_mesh(nx, ny).unwrap(), NeoHookean::new(lame).unwrap()).unwrap();
    m.set_averaged_pressure(averaged).unwrap();
    m
}

fn label(averaged: bool) -> &'static str {
    if averaged {
        "averaged-pressure"
    } else {
        "standard"
    }
}

fn explicit(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_step_64k");
    for averaged in [false, true] {
        let m = model(64_000, averaged);
        let dt = 0.5 * m.check_time_step(1.0).critical();
        let mut s = ExplicitStepper::new(
            &m,
            ExplicitParams {
                dt,
                damping: 1.0,
                ..Default::default()
            },
        )
        .unwrap();
        let mut state = testing::stretched(&m, 1.01).unwrap();
        group.throughput(Throughput::Elements(m.mesh().n_triangles() as u64));
        group.bench_function(label(averaged), |b| {
            b.iter(|| {
                if state.step >= 200 {
                    state = testing::stretched(&m, 1.01).unwrap();
                }
                s.step(&m, &mut state).unwrap()
            })
        });
    }
    group.finish();
}

fn newton(c: &mut Criterion) {
    let mut group = c.benchmark_group("newton_iteration_nu049");
    group.sample_size(10);
    for size in [16_000, 64_000] {
        for averaged in [false, true] {
            let m = model(size, averaged);
            // One iteration per call (the tolerance cannot be met): a steady workload.
            let mut stepper = ImplicitStepper::new(
                &m,
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
            let mut state = State::at_rest(&m);
            group.throughput(Throughput::Elements(m.mesh().n_triangles() as u64));
            group.bench_function(
                format!("{}/{}", m.mesh().n_triangles(), label(averaged)),
                |b| {
                    b.iter(|| {
                        let _ = stepper.step(&m, &mut state);
                    })
                },
            );
        }
    }
    group.finish();
}

criterion_group!(benches, explicit, newton);
criterion_main!(benches);
