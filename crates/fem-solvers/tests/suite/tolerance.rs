//! Residual-driven stopping of the iterative solvers (`residual_tolerance` of VBD, PD and
//! XPBD, `tolerance` of quasi-Newton): 0 is the fixed count, bit for bit; a positive tolerance
//! stops every step below it, short of the maximum; and the steps it stops at approach implicit
//! Euler's as the tolerance tightens (the oracle: Newton at the same `dt` to 1e-10).

use fem_core::energy::{AnyEnergy, Energy, EnergyKind};
use fem_core::math::Real;
use fem_solvers::testing::assert_apart;
use fem_solvers::{
    ImplicitParams, ImplicitStepper, Model, NewtonParams, PdParams, PdStepper, QuasiNewtonParams,
    QuasiNewtonStepper, State, StepReport, Stepper, VbdParams, VbdStepper, XpbdParams, XpbdStepper,
};

use crate::common::{bits, cantilever, case_a_lame};
use crate::contact::block;

/// A headset's frame step.
const DT: Real = 1.0 / 90.0;

/// The case A cantilever (10 x 2 cells, 1 kg, E = 1 kPa) under the co-rotational energy,
/// which every solver here runs (Projective Dynamics runs no other).
fn beam() -> Model<AnyEnergy> {
    cantilever(
        EnergyKind::Corotational.build(case_a_lame()).unwrap(),
        10,
        2,
    )
}

/// `steps` steps of `stepper` from rest; the final state and every step's report.
fn run<E: Energy, S: Stepper>(
    model: &Model<E>,
    mut stepper: S,
    steps: usize,
) -> (State, Vec<StepReport>) {
    let mut state = State::at_rest(model);
    let reports = (0..steps)
        .map(|_| stepper.step(model, &mut state).unwrap())
        .collect();
    (state, reports)
}

/// Largest vertex distance between two states, m.
fn distance(a: &State, b: &State) -> Real {
    (a.x.iter().zip(&b.x))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max)
}

/// Tolerance 0 (the default) is the fixed count: the default parameters report every
/// iteration, and a tolerance so small that it is never met (1e-300: the gradients are
/// evaluated and tested, but nothing stops) gives the same trajectory bit for bit, so the
/// residual test never moves a vertex and the default path is the one that existed before it.
#[test]
fn tolerance_zero_is_the_fixed_count_bit_for_bit() {
    let model = beam();
    let steps = 5;
    let never = 1e-300;
    let vbd = |tolerance| VbdParams {
        dt: DT,
        substeps: 2,
        iterations: 7,
        tolerance,
        ..VbdParams::default()
    };
    assert_eq!(VbdParams::default().tolerance, 0.0);
    let (a, ra) = run(&model, VbdStepper::new(&model, vbd(0.0)).unwrap(), steps);
    let (b, rb) = run(&model, VbdStepper::new(&model, vbd(never)).unwrap(), steps);
    assert_eq!(bits(&a.x), bits(&b.x), "vbd positions");
    assert_eq!(bits(&a.v), bits(&b.v), "vbd velocities");
    assert!(ra.iter().chain(&rb).all(|r| r.iterations == 14), "vbd");

    let pd = |tolerance| PdParams {
        dt: DT,
        iterations: 7,
        chebyshev_rho: 0.5,
        tolerance,
        ..PdParams::default()
    };
    assert_eq!(PdParams::default().tolerance, 0.0);
    let (a, ra) = run(&model, PdStepper::new(&model, pd(0.0)).unwrap(), steps);
    let (b, rb) = run(&model, PdStepper::new(&model, pd(never)).unwrap(), steps);
    assert_eq!(bits(&a.x), bits(&b.x), "pd positions");
    assert_eq!(bits(&a.v), bits(&b.v), "pd velocities");
    assert!(ra.iter().chain(&rb).all(|r| r.iterations == 7), "pd");

    let xpbd = |tolerance| XpbdParams {
        dt: DT,
        substeps: 2,
        iterations: 7,
        tolerance,
        ..XpbdParams::default()
    };
    assert_eq!(XpbdParams::default().tolerance, 0.0);
    let (a, ra) = run(&model, XpbdStepper::new(&model, xpbd(0.0)).unwrap(), steps);
    let (b, rb) = run(
        &model,
        XpbdStepper::new(&model, xpbd(never)).unwrap(),
        steps,
    );
    assert_eq!(bits(&a.x), bits(&b.x), "xpbd positions");
    assert_eq!(bits(&a.v), bits(&b.v), "xpbd velocities");
    assert!(ra.iter().chain(&rb).all(|r| r.iterations == 14), "xpbd");
    // With tolerance 0 the reports are as before: the residual is not a gradient norm.
    assert_eq!(ra, rb);
}

/// The tolerance is checked and named under its scene key.
#[test]
fn a_tolerance_outside_zero_to_one_is_refused() {
    for t in [-1e-3, 1.0, Real::NAN, Real::INFINITY] {
        let e = VbdParams {
            tolerance: t,
            ..VbdParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("vbd.residual_tolerance"), "{e}");
        let e = PdParams {
            tolerance: t,
            ..PdParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("pd.residual_tolerance"), "{e}");
        let e = XpbdParams {
            tolerance: t,
            ..XpbdParams::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("xpbd.residual_tolerance"), "{e}");
    }
}

/// With a tolerance `t` and a generous maximum, every step of VBD and PD stops short of the
/// maximum with its gradient norm at most `t` times its force scale, and every substep of XPBD
/// with its constraint residual at most `t` times the first sweep's (that of a one-sweep
/// step from the same state, the same sweep).
#[test]
fn every_step_stops_below_its_tolerance_and_short_of_the_maximum() {
    let model = beam();
    let (max, t, steps) = (10_000, 1e-4, 30);

    let mut state = State::at_rest(&model);
    let params = VbdParams {
        dt: DT,
        substeps: 2,
        iterations: max,
        tolerance: t,
        ..VbdParams::default()
    };
    let mut vbd = VbdStepper::new(&model, params).unwrap();
    let mut used = Vec::new();
    for _ in 0..steps {
        let r = vbd.step(&model, &mut state).unwrap();
        let scale = vbd.last_stats().force_scale;
        assert!(r.iterations < 2 * max, "vbd: {r:?}");
        assert!(r.residual <= t * scale, "vbd: {r:?}, scale {scale} N");
        used.push(r.iterations);
    }
    eprintln!("vbd, tolerance {t:e}: sweeps per step {used:?}");

    let mut state = State::at_rest(&model);
    let params = PdParams {
        dt: DT,
        iterations: max,
        tolerance: t,
        ..PdParams::default()
    };
    let mut pd = PdStepper::new(&model, params).unwrap();
    let mut used = Vec::new();
    for _ in 0..steps {
        let r = pd.step(&model, &mut state).unwrap();
        let scale = pd.force_scale();
        assert!(r.iterations < max, "pd: {r:?}");
        assert!(r.residual <= t * scale, "pd: {r:?}, scale {scale} N");
        used.push(r.iterations);
    }
    eprintln!("pd, tolerance {t:e}: iterations per step {used:?}");

    let xpbd = |iterations, tolerance| {
        let params = XpbdParams {
            dt: DT,
            iterations,
            tolerance,
            ..XpbdParams::default()
        };
        XpbdStepper::new(&model, params).unwrap()
    };
    let t = 1e-3;
    let mut state = State::at_rest(&model);
    let mut stepper = xpbd(max, t);
    let mut used = Vec::new();
    for _ in 0..steps {
        let first = xpbd(1, 0.0).step(&model, &mut state.clone()).unwrap();
        let r = stepper.step(&model, &mut state).unwrap();
        assert!(r.iterations < max, "xpbd: {r:?}");
        assert!(
            r.residual <= t * first.residual,
            "xpbd: {r:?}, first sweep {first:?}"
        );
        used.push(r.iterations);
    }
    eprintln!("xpbd, tolerance {t:e}: sweeps per step {used:?}");
}

/// The oracle: implicit Euler at the same `dt`, Newton to 1e-10 of the force scale.
fn implicit_rollout(model: &Model<AnyEnergy>, steps: usize) -> State {
    let params = ImplicitParams {
        dt: DT,
        newton: NewtonParams {
            tolerance: 1e-10,
            max_iterations: 200,
            ..NewtonParams::default()
        },
        ..ImplicitParams::default()
    };
    run(model, ImplicitStepper::new(model, params).unwrap(), steps).0
}

/// VBD, PD and quasi-Newton with a residual tolerance reach implicit Euler's step at the same
/// `dt` (the oracle: Newton to 1e-10 of the force scale, 5 steps of 1/90 s from rest, the
/// cantilever sagging by about 4 cm), and a looser tolerance stops farther from it.
///
/// Why 1e-8 m at tolerance 1e-8: a step stopped at gradient norm `r` lies about `|H^-1| r` from
/// the minimiser, and the incremental potential's Hessian `H` is at least `M / h^2` (the elastic
/// part adds stiffness at these small strains), so the distance is at most `r h^2 / m_min`.
/// With `r <= 1e-8` times a force scale of about the weight (9.8 N), `h^2 = 1.2e-4 s^2` and the
/// lightest vertex `m_min = 1/60 kg`, that is 7e-10 m per step (Newton's 1e-10 is 100 times
/// less); an error left in a step's positions passes to the next through the velocity, so five
/// steps carry a few times that: 3.5e-9 m if they all added up. Measured: 1.5e-10 m (VBD),
/// 2.0e-10 m (PD), 7e-11 m (quasi-Newton); at 1e-2, 1e-4 and 1e-6 the distances are about
/// 1e-4, 1e-6 and 1e-8 m, falling with the tolerance.
#[test]
fn tight_tolerances_reach_implicit_euler_and_looser_ones_stop_farther() {
    let model = beam();
    let steps = 5;
    let reference = implicit_rollout(&model, steps);
    let sag = distance(&reference, &State::at_rest(&model));
    assert!(sag > 1e-2, "the beam moves: {sag} m");
    let tolerances = [1e-2, 1e-4, 1e-6, 1e-8];
    for solver in ["vbd", "pd", "quasi-newton"] {
        let mut errors = Vec::new();
        let mut used = Vec::new();
        for &t in &tolerances {
            let (state, reports) = match solver {
                "vbd" => {
                    let p = VbdParams {
                        dt: DT,
                        iterations: 20_000,
                        tolerance: t,
                        ..VbdParams::default()
                    };
                    run(&model, VbdStepper::new(&model, p).unwrap(), steps)
                }
                "pd" => {
                    let p = PdParams {
                        dt: DT,
                        iterations: 20_000,
                        tolerance: t,
                        ..PdParams::default()
                    };
                    run(&model, PdStepper::new(&model, p).unwrap(), steps)
                }
                _ => {
                    let p = QuasiNewtonParams {
                        dt: DT,
                        iterations: 10_000,
                        tolerance: t,
                        ..QuasiNewtonParams::default()
                    };
                    run(&model, QuasiNewtonStepper::new(&model, p).unwrap(), steps)
                }
            };
            errors.push(distance(&state, &reference));
            used.push(reports.iter().map(|r| r.iterations).sum::<usize>());
        }
        eprintln!(
            "{solver}: tolerances {tolerances:?}, distance to implicit Euler {errors:?} m, iterations {used:?}"
        );
        assert!(errors[3] < 1e-8, "{solver}: {errors:?}");
        for w in errors.windows(2) {
            assert!(w[1] < w[0], "{solver}: not monotone: {errors:?}");
        }
    }
}

/// Barrier contact: the 1 kg block dropped 0.2 m on the ground at 1/90 s. With a tolerance,
/// every VBD step (falling, landing at about 0.2 s, resting) stops below it, short of the
/// maximum, and the block never touches the ground.
#[test]
fn vbd_with_barrier_contact_stops_below_its_tolerance() {
    let model = block();
    let (max, t) = (2_000, 1e-3);
    let params = VbdParams {
        dt: DT,
        iterations: max,
        damping: 2.0,
        tolerance: t,
        ..VbdParams::default()
    };
    let mut vbd = VbdStepper::new(&model, params).unwrap();
    let mut state = State::at_rest(&model);
    let mut used = Vec::new();
    let mut touched = false;
    for _ in 0..45 {
        let r = vbd.step(&model, &mut state).unwrap();
        assert_apart(&model, &state);
        let scale = vbd.last_stats().force_scale;
        assert!(r.iterations < max, "{r:?}");
        assert!(r.residual <= t * scale, "{r:?}, scale {scale} N");
        touched |= r.contacts > 0;
        used.push(r.iterations);
    }
    assert!(touched, "the block reaches the ground");
    let lowest = state.x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
    assert!(lowest > 0.0 && lowest < 1e-3, "lowest vertex at {lowest} m");
    eprintln!("vbd with contact, tolerance {t:e}: sweeps per step {used:?}");
}

/// The residual tests sum in a fixed order: 1 and 3 threads give the same states and the same
/// iteration counts (a mesh of 2304 triangles, so the element loops split into chunks).
#[test]
fn tolerance_stops_are_the_same_on_1_and_3_threads() {
    let model = cantilever(
        EnergyKind::Corotational.build(case_a_lame()).unwrap(),
        48,
        24,
    );
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let vbd = VbdParams {
                dt: DT,
                iterations: 1000,
                tolerance: 5e-2,
                ..VbdParams::default()
            };
            let pd = PdParams {
                dt: DT,
                iterations: 1000,
                tolerance: 1e-3,
                ..PdParams::default()
            };
            let xpbd = XpbdParams {
                dt: DT,
                iterations: 1000,
                tolerance: 1e-1,
                ..XpbdParams::default()
            };
            [
                run(&model, VbdStepper::new(&model, vbd).unwrap(), 2),
                run(&model, PdStepper::new(&model, pd).unwrap(), 2),
                run(&model, XpbdStepper::new(&model, xpbd).unwrap(), 2),
            ]
        })
    };
    let one = on(1);
    let three = on(3);
    for (name, (a, b)) in ["vbd", "pd", "xpbd"].iter().zip(one.iter().zip(&three)) {
        assert_eq!(bits(&a.0.x), bits(&b.0.x), "{name}");
        assert_eq!(a.1, b.1, "{name}");
        assert!(
            a.1.iter().all(|r| r.iterations < 1000),
            "{name} stops early: {:?}",
            a.1
        );
        eprintln!(
            "{name}: {:?}",
            a.1.iter().map(|r| r.iterations).collect::<Vec<_>>()
        );
    }
}
