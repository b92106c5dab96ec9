//! Criterion benches of the real-time solvers' iterations on the case A beam at 16k and 64k
//! triangles, on 1 and 2 threads: a coloured XPBD sweep, a VBD sweep, a Projective Dynamics
//! local-global iteration and an L-BFGS iteration of the quasi-Newton solver. Each bench times
//! one step of 10 iterations at dt = 1/90 s (from a 1 % stretch, restarted every 50 steps so
//! the workload stays steady); per-iteration cost is the time over 10 (the per-step work around
//! the iterations, prediction and velocity update, is one pass over the vertices). Co-rotational
//! for all four (Projective Dynamics runs only that energy) and Neo-Hookean for the other three;
//! VBD also with its (optional) line search.
//!
//! `cargo bench -p fem-solvers --bench realtime`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::energy::{AnyEnergy, EnergyKind};
use fem_core::material::Material;
use fem_solvers::testing::{self, beam_cells_for, beam_mesh, cantilever};
use fem_solvers::{Model, SolverKind, SolverParams, State, Stepper};

const DT: f64 = 1.0 / 90.0;

fn bench(c: &mut Criterion) {
    let lame = Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let mut group = c.benchmark_group("iterations10");
    group.sample_size(10);
    group.measurement_time(std::time::Duration::from_secs(2));
    group.warm_up_time(std::time::Duration::from_millis(500));
    for size in [16_000, 64_000] {
        let (nx, ny) = beam_cells_for(size);
        for energy in [EnergyKind::Corotational, EnergyKind::NeoHookean] {
            let model: Model<AnyEnergy> =
                cantilever(beam_mesh(nx, ny).unwrap(), energy.build(lame).unwrap()).unwrap();
            for (kind, variant) in [
                (SolverKind::Xpbd, ""),
                (SolverKind::Vbd, ""),
                (SolverKind::Vbd, "-line-search"),
                (SolverKind::Pd, ""),
                (SolverKind::QuasiNewton, ""),
            ] {
                if kind == SolverKind::Pd && energy != EnergyKind::Corotational {
                    continue;
                }
                let mut params = kind.default_params();
                params.set_dt(DT);
                match &mut params {
                    // Always all 10 iterations: the tolerance cannot stop it early.
                    SolverParams::QuasiNewton(p) => p.tolerance = 1e-300,
                    SolverParams::Vbd(p) => p.line_search = !variant.is_empty(),
                    _ => {}
                }
                for threads in [1, 2] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut stepper = params.build(&model).unwrap();
                    let mut state: State = testing::stretched(&model, 1.01).unwrap();
                    group.throughput(Throughput::Elements(10 * model.mesh().n_triangles() as u64));
                    let name = format!(
                        "{kind}{variant}/{}/{}/{threads}t",
                        energy.name(),
                        model.mesh().n_triangles()
                    );
                    group.bench_function(name, |b| {
                        pool.install(|| {
                            b.iter(|| {
                                if state.step >= 50 {
                                    state = testing::stretched(&model, 1.01).unwrap();
                                }
                                // A step that fails (XPBD inverting a Neo-Hookean triangle at
                                // this large step) restarts the run.
                                if stepper.step(&model, &mut state).is_err() {
                                    state = testing::stretched(&model, 1.01).unwrap();
                                }
                            })
                        })
                    });
                }
            }
        }
    }
    group.finish();
}

criterion_group!(realtime, bench);
criterion_main!(realtime);
