//! Thread-count determinism beyond the stepper battery (which checks every solver with its
//! default parameters, contact included where the solver handles it): the position-based
//! steppers' other orderings (serial Gauss-Seidel, Jacobi) and XPBD's literal form give
//! bit-identical states on 1, 2 and 4 rayon threads, with boundary conditions, gravity, a
//! ground and a dynamic obstacle.
//!
//! The mesh (160 x 32 cells, 10240 triangles) is large enough that the parallel paths split
//! the elements, the colour classes and the vertices into several fixed-size chunks.

use crate::common::{bits, cantilever, case_a_lame};
use fem_core::energy::{Energy, NeoHookean, Stvk};
use fem_core::math::Vec2;
use fem_solvers::diagnostics::{EnergyScratch, energies};
use fem_solvers::{
    Ground, Model, ObstacleMotion, Ordering, PbdParams, PbdStepper, State, Stepper, XpbdForm,
    XpbdParams, XpbdStepper,
};

/// A cantilever with a ground under its tip and a dynamic slab dropped on it, started from a
/// sheared state so every vertex moves.
fn scene<E: Energy>(energy: E) -> (Model<E>, State) {
    let mut m = cantilever(energy, 160, 32);
    m.set_ground(Some(Ground::horizontal(-0.01))).unwrap();
    m.add_obstacle(
        &[
            Vec2::new(3.0, 1.02),
            Vec2::new(4.0, 1.02),
            Vec2::new(4.0, 1.2),
            Vec2::new(3.0, 1.2),
        ],
        ObstacleMotion::Dynamic {
            mass: 0.3,
            rotates: true,
        },
    )
    .unwrap();
    let x = m
        .mesh()
        .vertices()
        .iter()
        .map(|p| Vec2::new(p.x + 0.02 * p.y * p.x / 5.0, p.y - 0.015 * p.x * p.x / 25.0))
        .collect();
    let n = m.mesh().n_vertices();
    let s = State::new(&m, x, vec![Vec2::zeros(); n]).unwrap();
    (m, s)
}

fn run_on<E: Energy, S: Stepper + Clone + Send + Sync>(
    threads: usize,
    model: &Model<E>,
    state: &State,
    stepper: &S,
    steps: usize,
) -> (State, f64) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut s = stepper.clone();
        let mut st = state.clone();
        for _ in 0..steps {
            s.step(model, &mut st).unwrap();
        }
        let e = energies(model, &st, &mut EnergyScratch::default()).total();
        (st, e)
    })
}

fn assert_thread_independent<E: Energy, S: Stepper + Clone + Send + Sync>(
    name: &str,
    model: &Model<E>,
    state: &State,
    stepper: S,
    steps: usize,
) {
    let (one, e1) = run_on(1, model, state, &stepper, steps);
    assert_ne!(bits(&one.x), bits(&state.x), "{name}: nothing moved");
    for threads in [2, 4] {
        let (other, e) = run_on(threads, model, state, &stepper, steps);
        assert!(
            bits(&one.x) == bits(&other.x),
            "{name}: positions differ on {threads} threads"
        );
        assert!(
            bits(&one.v) == bits(&other.v),
            "{name}: velocities differ on {threads} threads"
        );
        assert_eq!(
            one.bodies, other.bodies,
            "{name}: bodies differ on {threads} threads"
        );
        assert_eq!(
            e1.to_bits(),
            e.to_bits(),
            "{name}: energy differs on {threads} threads"
        );
    }
}

#[test]
fn pbd_is_bit_identical_across_thread_counts_in_every_other_ordering() {
    let (model, state) = scene(Stvk::new(case_a_lame()).unwrap());
    for (ordering, relaxation) in [(Ordering::GaussSeidel, 1.0), (Ordering::Jacobi, 1.5)] {
        let s = PbdStepper::new(
            &model,
            PbdParams {
                iterations: 4,
                ordering,
                relaxation,
                ..Default::default()
            },
        )
        .unwrap();
        assert_thread_independent(&format!("pbd {ordering:?}"), &model, &state, s, 4);
    }
}

#[test]
fn xpbd_is_bit_identical_across_thread_counts_in_every_other_ordering_and_form() {
    let (model, state) = scene(NeoHookean::new(case_a_lame()).unwrap());
    for (ordering, form) in [
        (Ordering::GaussSeidel, XpbdForm::Consistent),
        (Ordering::Coloured, XpbdForm::Literal),
        (Ordering::Jacobi, XpbdForm::Consistent),
    ] {
        let s = XpbdStepper::new(
            &model,
            XpbdParams {
                iterations: 4,
                substeps: 2,
                ordering,
                form,
                ..Default::default()
            },
        )
        .unwrap();
        assert_thread_independent(&format!("xpbd {ordering:?} {form:?}"), &model, &state, s, 4);
    }
}
