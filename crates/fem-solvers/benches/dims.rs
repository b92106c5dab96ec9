//! Criterion benches of the 2D and the 3D paths side by side (Neo-Hookean, case A's material):
//! - `explicit_step`: one explicit step of the 2D kernel (`ExplicitStepper`, triangles), of the
//!   dimension-generic path on the same triangles, and of the 3D path on a box of tetrahedra
//!   with about as many elements; throughput in elements, so criterion reports element-steps
//!   per second;
//! - `implicit_factorisation`: one implicit Euler step of the dimension-generic path (Newton:
//!   assembly, factorisation, solves) on a 2D beam and a 3D box of about the same number of
//!   unknowns, at three sizes, so the cost's growth with unknowns reads in each dimension.
//!
//! `cargo bench -p fem-solvers --bench dims`; the numbers are in docs/benchmarks.md.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::dim::{D2, D3, Vec3};
use fem_core::energy::NeoHookean;
use fem_core::material::Material;
use fem_core::math::Vec2;
use fem_core::simplex::SimplexMesh;
use fem_core::structured::{BoxParams, box_mesh};
use fem_solvers::nd::{self, NdModel, NdRegion, NdState, NdStepper};
use fem_solvers::testing::{beam_mesh, cantilever};
use fem_solvers::{ExplicitParams, ExplicitStepper, ImplicitParams, SolverParams, State, Stepper};

fn energy() -> NeoHookean {
    NeoHookean::new(
        Material::new(1000.0, 0.3, 1.0)
            .unwrap()
            .lame(PlaneModel::PlaneStrain),
    )
    .unwrap()
}

fn nd2(nx: usize, ny: usize) -> NdModel<D2, NeoHookean> {
    let tri = beam_mesh(nx, ny).unwrap();
    let mesh = SimplexMesh::<D2>::new(tri.vertices().to_vec(), tri.triangles().to_vec()).unwrap();
    let mut m = NdModel::with_density(mesh, energy(), 0.2).unwrap();
    m.set_gravity(Vec2::new(0.0, -9.8)).unwrap();
    m.pin(&NdRegion::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    m
}

fn nd3(nx: usize, ny: usize, nz: usize) -> NdModel<D3, NeoHookean> {
    let mesh = box_mesh(&BoxParams::new(5.0, 1.0, 1.0, nx, ny, nz)).unwrap();
    let mut m = NdModel::with_density(mesh, energy(), 0.2).unwrap();
    m.set_gravity(Vec3::new(0.0, -9.8, 0.0)).unwrap();
    m.pin(&NdRegion::in_box(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 1.0),
    ))
    .unwrap();
    m
}

fn explicit_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_step");
    let params = ExplicitParams {
        dt: 1e-5,
        ..ExplicitParams::default()
    };
    // 2D: 80 x 16 cells = 2560 triangles; 3D: 20 x 4 x 4 x 6 = 1920 and 40 x 8 x 8 x 6 = 15360.
    let model2 = cantilever(beam_mesh(80, 16).unwrap(), energy()).unwrap();
    let mut s = ExplicitStepper::new(&model2, params).unwrap();
    let mut st = State::at_rest(&model2);
    group.throughput(Throughput::Elements(model2.mesh().n_triangles() as u64));
    group.bench_function("2d-kernel/2560", |b| {
        b.iter(|| s.step(&model2, &mut st).unwrap())
    });
    let m = nd2(80, 16);
    let mut s = nd::build(&m, &SolverParams::Explicit(params), "solver").unwrap();
    let mut st = NdState::at_rest(&m);
    group.throughput(Throughput::Elements(m.mesh().n_cells() as u64));
    group.bench_function("2d-generic/2560", |b| {
        b.iter(|| s.step(&m, &mut st).unwrap())
    });
    for (nx, ny, nz) in [(20, 4, 4), (40, 8, 8)] {
        let m = nd3(nx, ny, nz);
        let mut s = nd::build(&m, &SolverParams::Explicit(params), "solver").unwrap();
        let mut st = NdState::at_rest(&m);
        group.throughput(Throughput::Elements(m.mesh().n_cells() as u64));
        group.bench_function(format!("3d/{}", m.mesh().n_cells()), |b| {
            b.iter(|| s.step(&m, &mut st).unwrap())
        });
    }
    group.finish();
}

fn implicit_factorisation(c: &mut Criterion) {
    let mut group = c.benchmark_group("implicit_step");
    group.sample_size(10);
    let params = SolverParams::Implicit(ImplicitParams {
        dt: 1e-2,
        ..ImplicitParams::default()
    });
    // About 1.5k, 6k and 24k unknowns in each dimension.
    for (nx, ny) in [(40, 8), (80, 16), (160, 32)] {
        let m = nd2(nx, ny);
        let unknowns = 2 * m.mesh().n_vertices();
        let mut s = nd::build(&m, &params, "solver").unwrap();
        let mut st = NdState::at_rest(&m);
        group.bench_with_input(BenchmarkId::new("2d", unknowns), &unknowns, |b, _| {
            b.iter(|| s.step(&m, &mut st).unwrap())
        });
    }
    for (nx, ny, nz) in [(20, 4, 4), (30, 6, 6), (50, 10, 10)] {
        let m = nd3(nx, ny, nz);
        let unknowns = 3 * m.mesh().n_vertices();
        let mut s = nd::build(&m, &params, "solver").unwrap();
        let mut st = NdState::at_rest(&m);
        group.bench_with_input(BenchmarkId::new("3d", unknowns), &unknowns, |b, _| {
            b.iter(|| s.step(&m, &mut st).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, explicit_step, implicit_factorisation);
criterion_main!(benches);
