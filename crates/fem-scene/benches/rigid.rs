//! Criterion benches of rigid regions on case D (1617 triangles, neo-Hookean, ten rigid bones
//! by default), on one thread:
//! - `explicit-frame/rigid`: one 1/90 s frame of explicit FEM at the soft tissue's own
//!   critical step (the steps of a frame: `ceil((1/90) / dt_crit)`, 318 at 35 us): the cost of
//!   running case D explicitly in real time;
//! - `explicit-step/{rigid,elastic}`, `implicit-step/...` and `vbd-step/...`: one step of the
//!   same mesh with the bones rigid and elastic (explicit at 35 us; implicit Euler and VBD, 10
//!   sweeps, at 1/90 s from a settled state): the cost of rigid regions against the same mesh with none (the rigid run
//!   also skips the bones' elements).
//!
//! Each bench restarts from the same state every 50 steps so the workload stays steady.
//!
//! `cargo bench -p fem-scene --bench rigid`

use criterion::{Criterion, criterion_group, criterion_main};
use fem_core::energy::AnyEnergy;
use fem_scene::build::{NoFiles, build_mesh, build_model, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::{AnyStepper, Model, SolverKind, State, Stepper};

const FRAME: f64 = 1.0 / 90.0;

fn model(rigid: bool) -> Model<AnyEnergy> {
    let scene = load_case("case-d", &[format!("regions.0.rigid={rigid}")]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    build_model(&scene, mesh, energy(&scene).unwrap()).unwrap()
}

fn stepper(m: &Model<AnyEnergy>, kind: SolverKind, dt: f64) -> AnyStepper {
    let mut p = kind.default_params();
    p.set_dt(dt);
    p.build(m).unwrap()
}

/// The state after `steps` steps of implicit Euler at 1/90 s (the debris landed).
fn settled(m: &Model<AnyEnergy>, steps: usize) -> State {
    let scene = load_case("case-d", &[]).unwrap();
    let mut state = initial_state(&scene, m).unwrap();
    let mut s = stepper(m, SolverKind::Implicit, FRAME);
    for _ in 0..steps {
        s.step(m, &mut state).unwrap();
    }
    state
}

fn bench(c: &mut Criterion) {
    // One thread: the global pool, before anything uses it.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    {
        let rigid = model(true);
        let elastic = model(false);
        let dt = rigid.elastic_critical_time_step();
        let per_frame = (FRAME / dt).ceil() as usize;
        let h = FRAME / per_frame as f64;
        let mut group = c.benchmark_group("case-d");
        group.sample_size(10);
        group.measurement_time(std::time::Duration::from_secs(3));
        group.warm_up_time(std::time::Duration::from_millis(500));
        let start = State::at_rest(&rigid);
        let mut s = stepper(&rigid, SolverKind::Explicit, h);
        let mut state = start.clone();
        group.bench_function(format!("explicit-frame/rigid/{per_frame}-steps"), |b| {
            b.iter(|| {
                if state.step >= 20 * per_frame as u64 {
                    state = start.clone();
                }
                for _ in 0..per_frame {
                    s.step(&rigid, &mut state).unwrap();
                }
            })
        });
        for (name, m) in [("rigid", &rigid), ("elastic", &elastic)] {
            // Explicit on the elastic bones is unstable at this step: one step from rest stays
            // finite, which is all the timing needs.
            let start = State::at_rest(m);
            let mut s = stepper(m, SolverKind::Explicit, h);
            let mut state = start.clone();
            group.bench_function(format!("explicit-step/{name}"), |b| {
                b.iter(|| {
                    if state.step >= 1 {
                        state = start.clone();
                    }
                    s.step(m, &mut state).unwrap();
                })
            });
            let start = settled(m, 30);
            for kind in [SolverKind::Implicit, SolverKind::Vbd] {
                let mut s = stepper(m, kind, FRAME);
                let mut state = start.clone();
                group.bench_function(format!("{kind}-step/{name}"), |b| {
                    b.iter(|| {
                        if state.step >= start.step + 50 {
                            state = start.clone();
                        }
                        s.step(m, &mut state).unwrap();
                    })
                });
            }
        }
        group.finish();
    }
}

criterion_group!(rigid, bench);
criterion_main!(rigid);
