//! Quasi-Newton with barrier contact and rigid regions (the coupled path,
//! `steppers/quasi_newton/coupled.rs`): L-BFGS on implicit Euler's potential with the barrier,
//! the moving obstacles' poses and the free rigid bodies' poses as unknowns.
//!
//! - **Never penetrates**: the block dropped on the ground and the slab dropped on the strip at
//!   90 Hz (`barrier_contact.rs`'s scenes), checked after every step by the brute-force oracle
//!   of `testing` (and every contact gap positive), at the default budget of 10 iterations (a
//!   step that stops short of the tolerance still never crosses: the CCD bounds every line
//!   search) and at 300; with 300 the block and the slab come to rest on their weight within
//!   1 %, as under implicit Euler.
//! - **One solver against another**: from states in contact (the slab resting on the strip, the
//!   wedge pushing the coarse strip, a block with a rigid core resting on the ground) and from a
//!   swinging cantilever with a free rigid block, one quasi-Newton step with enough iterations
//!   is implicit Euler's step (Newton to 1e-12) within 1e-9 m; the exception, a short history
//!   stalling against a kinematic wedge, is measured and bounded.
//! - **Rigid regions with contact**: a block with a rigid core dropped on the ground stays apart,
//!   its core rigid, and comes to rest on its weight; a strip with a rigid core under a dynamic
//!   slab gives the same bits on 1, 2 and 4 threads.
//!
//! The initial Hessian itself (the Schur complement is the PD model in the bodies' reduced
//! coordinates, to round-off) is checked in `coupled.rs`. Free fall of a rigid region, the rigid
//! series bar, momentum, the rollout near implicit Euler and thread independence without
//! contact are in `rigid.rs` (every solver that moves rigid regions); thread independence with
//! a ground and a dynamic obstacle in the battery (every solver with contact), under backward
//! Euler and BDF2; BDF2 with contact and with a rigid block in `integrator.rs`.

use crate::barrier_contact::{coarse_strip_and_wedge, run_with};
use crate::common::bits;
use crate::contact::{block, strip_and_slab};
use crate::rigid::{cantilever_with_a_rigid_block, neo_hookean, rigidity_error, with_region};
use fem_core::energy::{AnyEnergy, Energy};
use fem_core::math::{Real, Vec2};
use fem_core::structured::{RectangleParams, rectangle};
use fem_solvers::testing::assert_apart;
use fem_solvers::{
    BodyState, ContactKind, Ground, ImplicitParams, ImplicitStepper, Model, NewtonParams,
    ObstacleMotion, QuasiNewtonParams, QuasiNewtonReport, QuasiNewtonStepper, State, Stepper,
};

const DT: Real = 1.0 / 90.0;

/// Quasi-Newton at `dt` with `iterations`, damping 2/s (as the implicit runs of
/// `barrier_contact.rs`).
fn params(dt: Real, iterations: usize) -> QuasiNewtonParams {
    QuasiNewtonParams {
        dt,
        damping: 2.0,
        iterations,
        ..Default::default()
    }
}

/// Step quasi-Newton at 90 Hz for `t_end` seconds with the oracle after every step; returns
/// the state, the stepper, the smallest distance and the mean iterations a step.
fn run_qn<E: Energy>(
    model: &Model<E>,
    t_end: Real,
    iterations: usize,
) -> (State, QuasiNewtonStepper, Real, Real) {
    let s = QuasiNewtonStepper::new(model, params(DT, iterations)).unwrap();
    let used = std::cell::Cell::new((0usize, 0usize));
    let (state, s, min) = run_with(model, s, t_end, |s| {
        let (sum, steps) = used.get();
        used.set((sum + s.last_report().iterations, steps + 1));
        s.min_distance()
    });
    let (sum, steps) = used.get();
    (state, s, min, sum as Real / steps as Real)
}

/// The net contact force on the soft body from the contacts `filter` keeps, N.
fn force(s: &impl Stepper, filter: impl Fn(&ContactKind) -> bool) -> Vec2 {
    (s.contacts().iter())
        .filter(|c| filter(&c.kind))
        .map(|c| c.normal * c.force)
        .sum()
}

#[test]
fn block_and_slab_dropped_at_90_hz_never_penetrate_at_the_default_budget() {
    // 10 iterations a step, far from converged in contact (the block's ground force ends
    // about 20 % off its weight): the oracle holds after every step all the same.
    let iterations = QuasiNewtonParams::default().iterations;
    let model = block();
    let (state, _, min, mean) = run_qn(&model, 3.0, iterations);
    assert!(min > 0.0);
    let lowest = state.x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
    assert!(lowest > 0.0 && lowest < 1e-3, "lowest vertex at {lowest} m");
    let (model, slab) = strip_and_slab();
    let (state, _, min, mean_slab) = run_qn(&model, 3.0, iterations);
    assert!(min > 0.0);
    assert!(state.bodies[slab].position.y < 0.7, "the slab never landed");
    eprintln!("10 iterations: block {mean:.1}, slab {mean_slab:.1} a step");
}

#[test]
fn block_and_slab_dropped_at_90_hz_rest_on_their_weight() {
    // The checks of `barrier_contact.rs` under implicit Euler, with the budget to converge at
    // rest (measured: 136 and 133 iterations a step on average with the default history of 5).
    let model = block();
    let (state, s, min, mean) = run_qn(&model, 3.0, 300);
    assert!(min > 0.0);
    let speed = state.v.iter().map(|v| v.norm()).fold(0.0, Real::max);
    assert!(speed < 1e-2, "still moving at {speed} m/s");
    let total = force(&s, |k| matches!(k, ContactKind::VertexGround { .. }));
    assert!(
        (total.y - 9.8).abs() < 0.01 * 9.8,
        "ground force {total:?} N, weight 9.8 N"
    );
    assert!(s.last_report().converged);
    let (model, slab) = strip_and_slab();
    let (state, s, min, mean_slab) = run_qn(&model, 3.0, 300);
    assert!(min > 0.0);
    let b = state.bodies[slab];
    assert!(b.velocity.norm() < 1e-2, "slab velocity {:?}", b.velocity);
    assert!(b.angle.abs() < 1e-3, "slab angle {}", b.angle);
    let total = force(&s, |_| true);
    assert!(
        (total.y + 4.9).abs() < 0.01 * 4.9,
        "force on the strip {total:?} N, slab weight 4.9 N"
    );
    eprintln!("300 iterations: block {mean:.1}, slab {mean_slab:.1} a step");
}

/// Implicit Euler's step of `dt` from `state`, Newton to 1e-12 (no velocity tolerance).
fn implicit_step<E: Energy>(model: &Model<E>, state: &State, dt: Real) -> State {
    let p = ImplicitParams {
        dt,
        damping: 2.0,
        velocity_tolerance: 0.0,
        newton: NewtonParams {
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut s = state.clone();
    ImplicitStepper::new(model, p)
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

/// Quasi-Newton's step of `dt` from `state` with up to 2000 iterations and `history` pairs,
/// to the tolerance 1e-10; and its report.
fn qn_step<E: Energy>(
    model: &Model<E>,
    state: &State,
    dt: Real,
    history: usize,
) -> (State, QuasiNewtonReport) {
    let p = QuasiNewtonParams {
        iterations: 2_000,
        history,
        tolerance: 1e-10,
        ..params(dt, 0)
    };
    let mut s = state.clone();
    let mut qn = QuasiNewtonStepper::new(model, p).unwrap();
    qn.step(model, &mut s).unwrap();
    (s, qn.last_report().clone())
}

/// The largest distance between two states' vertices, obstacle centroids and rigid
/// centroids (and, times `radius`, their angles), m.
fn distance(a: &State, b: &State, radius: Real) -> Real {
    let pose = |p: &BodyState, q: &BodyState| {
        (p.position - q.position)
            .norm()
            .max(radius * (p.angle - q.angle).abs())
    };
    (a.x.iter().zip(&b.x))
        .map(|(p, q)| (p - q).norm())
        .chain(a.bodies.iter().zip(&b.bodies).map(|(p, q)| pose(p, q)))
        .chain(a.rigid.iter().zip(&b.rigid).map(|(p, q)| pose(p, q)))
        .fold(0.0, Real::max)
}

/// `model` stepped by implicit Euler (Newton's defaults, damping 2/s) at 90 Hz for `t` s.
fn after<E: Energy>(model: &Model<E>, t: Real) -> State {
    let p = ImplicitParams {
        dt: DT,
        damping: 2.0,
        ..Default::default()
    };
    let mut s = ImplicitStepper::new(model, p).unwrap();
    let mut state = State::at_rest(model);
    while state.t < t {
        s.step(model, &mut state).unwrap();
    }
    state
}

/// One quasi-Newton step against implicit Euler's from `start`, for each `(history, distance,
/// residual)`: within `distance` m of it, its gradient at most `residual` times the force
/// scale at the end.
fn check_step<E: Energy>(
    what: &str,
    model: &Model<E>,
    start: &State,
    cases: &[(usize, Real, Real)],
) {
    let reference = implicit_step(model, start, DT);
    let motion = distance(&reference, start, 1.0);
    for &(history, tolerance, most) in cases {
        let (qn, r) = qn_step(model, start, DT, history);
        let d = distance(&qn, &reference, 1.0);
        let residual = r.residuals.last().unwrap() / r.force_scale;
        eprintln!(
            "{what}, history {history}: {} iterations, residual {residual:.1e} of the force scale, {d:.2e} m from implicit Euler's step (which moves {motion:.2e} m)",
            r.iterations
        );
        assert!(
            residual <= most,
            "{what}, history {history}: residual {residual:e}"
        );
        assert!(d < tolerance, "{what}, history {history}: {d:e} m");
    }
}

/// With enough iterations (to the tolerance 1e-10, against Newton's 1e-12) a step in contact
/// is implicit Euler's: the slab resting on the strip (a dynamic obstacle, friction 0.5): within
/// 1e-9 m (measured 1.9e-13 m, 161 iterations with 5 pairs, 97 with 20), the gap `r / k`
/// between the two minimisers of a residual `r` of 1e-10 of the force scale over the stiffness
/// `k` the step sees. The wedge (a kinematic obstacle, tethered to its schedule at 1e6 times the
/// modulus) driven 1.5 cm into the coarse strip needs the longer history: with 20 pairs it
/// reaches 1.1e-10 of the force scale in 62 iterations (its line search then fails at the
/// potential's round-off), 1.0e-13 m from Newton's step; with 5 the pairs cannot hold the barrier's
/// curvature (its tip on the soft edge is stiffer than the PD matrix by about nine orders), the
/// line searches halve to the potential's round-off and L-BFGS stalls, 2000 iterations ending
/// at 3.7e-3 of the force scale (2 N), 3.6e-7 m from Newton's step (the step moves 7.7e-4 m):
/// within 1e-6 m, not converged.
#[test]
fn a_contact_step_reaches_implicit_eulers_step() {
    let (model, _) = strip_and_slab();
    let start = after(&model, 1.5);
    // Landed: its centroid starts at 0.7 m, rests near 0.6 m.
    assert!(start.bodies[0].position.y < 0.61);
    check_step(
        "slab on the strip",
        &model,
        &start,
        &[(5, 1e-9, 1e-10), (20, 1e-9, 1e-10)],
    );
    let model = coarse_strip_and_wedge();
    let start = after(&model, 0.5);
    check_step(
        "wedge in the strip",
        &model,
        &start,
        &[(5, 1e-6, 1e-2), (20, 1e-9, 1e-9)],
    );
}

/// A block (1 m square, 8 x 8 cells, Neo-Hookean E = 1e4 Pa, 100 kg/m^2) with a rigid core
/// (0.5 m x 0.5 m) 0.2 m above the ground.
fn block_with_a_rigid_core() -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 0.2],
        ..RectangleParams::new(1.0, 1.0, 8, 8)
    })
    .unwrap();
    let mut m = with_region(
        mesh,
        neo_hookean(1.0e4, 0.3),
        |c| (c.x - 0.5).abs() < 0.25 && (c.y - 0.7).abs() < 0.25,
        true,
    );
    m.set_standard_gravity();
    m.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    m
}

/// Rigid regions: one step of the swinging cantilever with a free rigid block (no contact;
/// measured 1.1e-12 m in 31 iterations with 5 pairs), and one of the block with a rigid core
/// resting on the ground (contact; 2.1e-12 m in 862 iterations with 5 pairs, 411 with 20; a
/// line search that fails with pairs restarts from the initial Hessian), reach implicit
/// Euler's step within 1e-9 m, the bodies' poses included.
#[test]
fn a_step_with_rigid_bodies_reaches_implicit_eulers_step() {
    let model = cantilever_with_a_rigid_block();
    let start = after(&model, 0.3);
    assert!(start.rigid[0].angular_velocity.abs() > 1e-3);
    check_step(
        "cantilever with a rigid block",
        &model,
        &start,
        &[(5, 1e-9, 1e-10), (20, 1e-9, 1e-10)],
    );
    let model = block_with_a_rigid_core();
    let start = after(&model, 1.0);
    check_step(
        "block with a rigid core on the ground",
        &model,
        &start,
        &[(5, 1e-9, 1e-10), (20, 1e-9, 1e-10)],
    );
}

/// The block with a rigid core dropped on the ground at 90 Hz (300 iterations): apart after
/// every step, the core rigid, at rest on the barrier carrying the whole weight (the core's
/// through the soft tissue under it) within 1 %.
#[test]
fn a_block_with_a_rigid_core_dropped_on_the_ground_rests_on_its_weight() {
    let model = block_with_a_rigid_core();
    let (state, s, min, mean) = run_qn(&model, 3.0, 300);
    assert!(min > 0.0);
    let rigid = rigidity_error(&model, &state, 0);
    assert!(rigid < 1e-12, "the core deformed by {rigid:e} m");
    let weight = 9.8 * model.masses().iter().sum::<Real>();
    let total = force(&s, |_| true);
    eprintln!(
        "block with a rigid core: {mean:.1} iterations a step, ground force {total:?} N, weight {weight} N"
    );
    assert!(
        (total.y - weight).abs() < 0.01 * weight,
        "ground force {total:?} N, weight {weight} N"
    );
    assert!(state.rigid[0].velocity.norm() < 1e-2);
}

/// Contact and a rigid region together give the same bits on 1, 2 and 4 threads: a 2 m x 0.5 m
/// strip (80 x 20 cells, 3200 triangles, so the parallel assembly splits) with a rigid core,
/// 0.5 mm above the ground, a dynamic slab dropped on it.
#[test]
fn contact_with_rigid_regions_gives_the_same_bits_on_1_2_and_4_threads() {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 5e-4],
        ..RectangleParams::new(2.0, 0.5, 80, 20)
    })
    .unwrap();
    let mut model = with_region(
        mesh,
        neo_hookean(1.0e4, 0.3),
        |c| (c.x - 1.0).abs() < 0.4 && (c.y - 0.25).abs() < 0.1,
        true,
    );
    model.set_standard_gravity();
    model.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    model
        .add_obstacle(
            &[
                Vec2::new(0.5, 0.51),
                Vec2::new(1.5, 0.51),
                Vec2::new(1.5, 0.6),
                Vec2::new(0.5, 0.6),
            ],
            ObstacleMotion::Dynamic {
                mass: 5.0,
                rotates: true,
            },
        )
        .unwrap();
    assert!(model.rigid_bodies()[0].is_free());
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut s = QuasiNewtonStepper::new(&model, params(DT, 20)).unwrap();
            let mut state = State::at_rest(&model);
            for _ in 0..6 {
                s.step(&model, &mut state).unwrap();
                assert_apart(&model, &state);
            }
            state
        })
    };
    let one = run(1);
    assert!(one.bodies[0].position.y < 0.555, "the slab did not fall");
    for threads in [2, 4] {
        let other = run(threads);
        assert_eq!(bits(&one.x), bits(&other.x), "{threads} threads");
        assert_eq!(bits(&one.v), bits(&other.v), "{threads} threads");
        assert_eq!(one.rigid, other.rigid, "{threads} threads");
        assert_eq!(one.bodies, other.bodies, "{threads} threads");
    }
}
