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
use fem_solvers::testing::{self, beam_cells_for, beam_mesh, cantilever};
use fem_solvers::{
    ExplicitParams, ExplicitStepper, Model, PbdParams, PbdStepper, State, Stepper, XpbdParams,
    XpbdStepper,
};

const TRIANGLES: usize = 16_000;

fn model<E: Energy>(energy: E) -> Model<E> {
    let (nx, ny) = beam_cells_for(TRIANGLES);
    cantilever(beam_mesh(nx, ny).unwrap(), energy).unwrap()
}

fn stretched<E: Energy>(m: &Model<E>) -> State {
    testing::stretched(m, 1.01).unwrap()
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
    explicit(c, NeoHookean::new(lame).unwrap());
    explicit(c, Stvk::new(lame).unwrap());
    explicit(c, Corotational::new(lame).unwrap());
    let m = model(Stvk::new(lame).unwrap());
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
