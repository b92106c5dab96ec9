//! Criterion bench of barrier contact at a headset's frame step (dt = 1/90 s): a soft strip of
//! case D's size (532 triangles, E = 1.85 MPa, Neo-Hookean, 20 kg) lying 0.5 mm above the
//! ground under a 95 kg rigid slab resting on it (two-way coupled). Each sample is one step of
//! the settled scene, where every contact is active: implicit Euler (Newton to 1e-8) and VBD
//! (10 sweeps). Element-steps per second are reported; the real-time factor on one core is
//! `dt / time per step`. Run with one thread (`RAYON_NUM_THREADS=1`) to compare with the
//! one-core budget.
//!
//! `cargo bench -p fem-solvers --bench barrier`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::energy::NeoHookean;
use fem_core::material::Material;
use fem_core::math::Vec2;
use fem_solvers::testing::{RectangleParams, rectangle};
use fem_solvers::{
    Ground, ImplicitParams, ImplicitStepper, Model, ObstacleMotion, State, Stepper, VbdParams,
    VbdStepper,
};

const DT: f64 = 1.0 / 90.0;

/// The strip (1 m x 0.12 m, 38 x 7 cells) and the slab (0.22 m x 0.18 m) 2 mm above its middle.
fn scene() -> Model<NeoHookean> {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 5e-4],
        ..RectangleParams::new(1.0, 0.12, 38, 7)
    })
    .unwrap();
    let lame = Material::new(1.85e6, 0.3, 1000.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame).unwrap(), 20.0).unwrap();
    m.set_standard_gravity();
    m.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    let y = 0.1225;
    m.add_obstacle(
        &[
            Vec2::new(0.39, y),
            Vec2::new(0.61, y),
            Vec2::new(0.61, y + 0.18),
            Vec2::new(0.39, y + 0.18),
        ],
        ObstacleMotion::Dynamic {
            mass: 95.0,
            rotates: true,
        },
    )
    .unwrap();
    m
}

/// The scene after 1 s under `stepper` (the slab has landed and the contacts are active).
fn settled<S: Stepper>(model: &Model<NeoHookean>, stepper: &mut S) -> State {
    let mut state = State::at_rest(model);
    for _ in 0..90 {
        stepper.step(model, &mut state).unwrap();
    }
    assert!(!stepper.contacts().is_empty());
    state
}

fn barrier_step(c: &mut Criterion) {
    let model = scene();
    let mut group = c.benchmark_group("barrier_contact_step");
    group.sample_size(20);
    group.throughput(Throughput::Elements(model.mesh().n_triangles() as u64));
    let mut implicit = ImplicitStepper::new(
        &model,
        ImplicitParams {
            dt: DT,
            damping: 20.0,
            ..Default::default()
        },
    )
    .unwrap();
    let start = settled(&model, &mut implicit);
    group.bench_function("implicit", |b| {
        b.iter_batched(
            || start.clone(),
            |mut s| implicit.step(&model, &mut s).unwrap(),
            criterion::BatchSize::SmallInput,
        )
    });
    let mut vbd = VbdStepper::new(
        &model,
        VbdParams {
            dt: DT,
            iterations: 10,
            damping: 20.0,
            ..Default::default()
        },
    )
    .unwrap();
    let start = settled(&model, &mut vbd);
    group.bench_function("vbd_10_sweeps", |b| {
        b.iter_batched(
            || start.clone(),
            |mut s| vbd.step(&model, &mut s).unwrap(),
            criterion::BatchSize::SmallInput,
        )
    });
    group.finish();
}

criterion_group!(benches, barrier_step);
criterion_main!(benches);
