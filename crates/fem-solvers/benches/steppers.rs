//! Criterion benches of one step of each stepper on the case A beam (16k triangles, current
//! rayon pool): explicit with Neo-Hookean, StVK and co-rotational, and PBD / XPBD (StVK,
//! 10 coloured Gauss-Seidel iterations, from a 1% stretch so every constraint is active).
//!
//! `cargo bench -p fem-solvers` (or `cargo xtask bench -- steppers`); for element-steps per
//! second across sizes and thread counts see `examples/throughput.rs`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use fem_core::PlaneModel;
use fem_core::energy::{Corotational, Energy, NeoHookean, Stvk};
use fem_core::material::Material;
use fem_core::math::Vec2;
use fem_solvers::testing::{beam_cells_for, beam_mesh};
use fem_solvers::{
    ExplicitParams, ExplicitStepper, Model, PbdParams, PbdStepper, Region, State, Stepper,
    XpbdParams, XpbdStepper,
};

const TRIANGLES: usize = 16_000;

fn model<E: Energy>(energy: E) -> Model<E> {
    let (nx, ny) = beam_cells_for(TRIANGLES);
    let mut m = Model::with_total_mass(beam_mesh(nx, ny).unwrap(), energy, 1.0)
        .unwrap()
        .with_standard_gravity();
    m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    m
}

fn stretched<E: Energy>(m: &Model<E>) -> State {
    let x = m
        .mesh()
        .vertices()
        .iter()
        .map(|p| Vec2::new(1.01 * p.x, p.y))
        .collect();
    State::new(m, x, vec![Vec2::zeros(); m.mesh().n_vertices()]).unwrap()
}

fn bench_stepper<E: Energy, S: Stepper>(c: &mut Criterion, name: &str, m: &Model<E>, mut s: S) {
    let mut group = c.benchmark_group("step");
    group.throughput(Throughput::Elements(m.mesh().n_triangles() as u64));
    let mut state = stretched(m);
    group.bench_function(name, |b| {
        b.iter(|| {
            // Restart before the stretched beam has moved far, keeping the workload steady.
            if state.step >= 200 {
                state = stretched(m);
            }
            s.step(m, &mut state).unwrap()
        })
    });
    group.finish();
}

fn explicit<E: Energy>(c: &mut Criterion, energy: E) {
    let m = model(energy);
    let dt = 0.5 * m.check_time_step(1.0).critical();
    let s = ExplicitStepper::new(
        &m,
        ExplicitParams {
            dt,
            damping: 1.0,
            ..Default::default()
        },
    )
    .unwrap();
    let name = format!("explicit/{}", m.energy().name());
    bench_stepper(c, &name, &m, s);
}

fn benches(c: &mut Criterion) {
    let lame = Material::new(1000.0, 0.3, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    explicit(c, NeoHookean::new(lame));
    explicit(c, Stvk::new(lame));
    explicit(c, Corotational::new(lame));
    let m = model(Stvk::new(lame));
    bench_stepper(
        c,
        "pbd/stvk",
        &m,
        PbdStepper::new(&m, PbdParams::default()).unwrap(),
    );
    bench_stepper(
        c,
        "xpbd/stvk",
        &m,
        XpbdStepper::new(&m, XpbdParams::default()).unwrap(),
    );
}

criterion_group!(steppers, benches);
criterion_main!(steppers);
