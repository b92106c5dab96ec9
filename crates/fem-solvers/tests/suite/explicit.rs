//! Explicit stepper: energy behaviour, free fall, the stability guard, blow-up detection,
//! boundary conditions and agreement with fem-core's reference assembly.

use crate::common::{bits, cantilever, case_a_lame, free_beam, lame};
use fem_core::assembly::populate_forces_serial;
use fem_core::energy::{Corotational, NeoHookean, Stvk};
use fem_core::math::{Real, Vec2};
use fem_solvers::diagnostics::{EnergyScratch, energies};
use fem_solvers::testing::{beam_mesh, node_index};
use fem_solvers::{
    ExplicitParams, ExplicitScheme, ExplicitStepper, Model, PrescribedMotion, Region, SolverError,
    State, Stepper,
};

/// Relative drift `max |E(t) - E(0)| / E(0)` of an undamped, gravity-free run that starts
/// from a 10% stretch along x, over `t_end` seconds.
fn energy_drift(dt: Real, t_end: Real) -> Real {
    let model = free_beam(NeoHookean::new(case_a_lame()).unwrap(), 20, 4);
    let x0: Vec<Vec2> = model
        .mesh()
        .vertices()
        .iter()
        .map(|p| Vec2::new(1.1 * p.x, p.y))
        .collect();
    let n = x0.len();
    let mut state = State::new(&model, x0, vec![Vec2::zeros(); n]).unwrap();
    let mut stepper = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt,
            ..Default::default()
        },
    )
    .unwrap();
    let mut scratch = EnergyScratch::default();
    let e0 = energies(&model, &state, &mut scratch).total();
    let mut drift: Real = 0.0;
    let steps = (t_end / dt).round() as usize;
    for _ in 0..steps {
        stepper.step(&model, &mut state).unwrap();
        let e = energies(&model, &state, &mut scratch).total();
        drift = drift.max((e - e0).abs() / e0);
    }
    drift
}

#[test]
fn undamped_energy_stays_bounded_and_drift_shrinks_with_dt() {
    // Symplectic Euler conserves a modified energy: the error oscillates with an amplitude of
    // order dt and does not grow. From a 10% stretch (20 x 4 beam, Neo-Hookean, critical step
    // 2.1 ms): the drift stays below 3% at dt = 0.5 ms over 1 s (dozens of vibration periods),
    // is no more than 1.25x that over 2 s (bounded, not growing), and halving dt shrinks it by
    // at least 1.6x (first order predicts 2x; measured 2.1-2.3x).
    let coarse = energy_drift(5e-4, 1.0);
    let longer = energy_drift(5e-4, 2.0);
    let fine = energy_drift(2.5e-4, 1.0);
    assert!(coarse < 0.03, "drift {coarse:e} at dt = 5e-4");
    assert!(
        longer < 1.25 * coarse,
        "drift grows: {longer:e} over 2 s vs {coarse:e} over 1 s"
    );
    assert!(
        fine < coarse / 1.6,
        "drift {fine:e} at dt = 2.5e-4 vs {coarse:e}"
    );
}

fn free_fall(scheme: ExplicitScheme) {
    let mut model = free_beam(Stvk::new(case_a_lame()).unwrap(), 10, 2);
    model.set_standard_gravity();
    let dt = 1e-3;
    let mut stepper = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt,
            damping: 0.0,
            scheme,
        },
    )
    .unwrap();
    let mut state = State::at_rest(&model);
    // Forward Euler amplifies every vibration mode by sqrt(1 + (omega dt)^2) per step, so the
    // round-off noise of a rigid translation grows (1.1x per step here): it is checked over 100
    // steps, symplectic Euler over 500.
    let n = match scheme {
        ExplicitScheme::SymplecticEuler => 500usize,
        ExplicitScheme::ForwardEuler => 100,
        other => panic!("no discrete free-fall solution for {other:?}"),
    };
    for _ in 0..n {
        stepper.step(&model, &mut state).unwrap();
    }
    let g = 9.8;
    let t = n as Real * dt;
    // Discrete solutions: symplectic y_n = -g dt^2 n (n + 1) / 2, forward y_n = -g dt^2 n (n - 1) / 2;
    // both are 1/2 g t^2 up to an O(dt) term.
    let expected = match scheme {
        ExplicitScheme::SymplecticEuler => -g * dt * dt * (n * (n + 1)) as Real / 2.0,
        ExplicitScheme::ForwardEuler => -g * dt * dt * (n * (n - 1)) as Real / 2.0,
        other => panic!("no discrete free-fall solution for {other:?}"),
    };
    assert!((expected + 0.5 * g * t * t).abs() <= 0.5 * g * dt * t + 1e-12);
    for v in 0..model.mesh().n_vertices() {
        let u = state.displacement(&model, v);
        // Round-off: rigid translation leaves F = I up to ~1e-15, whose stress moves the
        // vertices by ~1e-11 m over 0.5 s; 1e-9 m is a comfortable bound.
        assert!(
            (u.y - expected).abs() < 1e-9,
            "vertex {v}: {} vs {expected}",
            u.y
        );
        assert!(u.x.abs() < 1e-9);
        assert!((state.v[v].y + g * t).abs() < 1e-9);
    }
}

#[test]
fn free_fall_is_exact_for_symplectic_euler() {
    free_fall(ExplicitScheme::SymplecticEuler);
}

#[test]
fn free_fall_is_exact_for_forward_euler() {
    free_fall(ExplicitScheme::ForwardEuler);
}

#[test]
fn cantilever_tip_matches_free_fall_at_frame_10() {
    // Paper Table 1: 49 mm at frame 10 (0.1 s) for every energy; the beam is still nearly
    // in free fall then. Tolerance 3 mm.
    let tip = node_index(20, 0, 20);
    for (name, y) in [
        ("stvk", tip_after(Stvk::new(case_a_lame()).unwrap(), 100)),
        (
            "corotational",
            tip_after(Corotational::new(case_a_lame()).unwrap(), 100),
        ),
        (
            "neo-hookean",
            tip_after(NeoHookean::new(case_a_lame()).unwrap(), 100),
        ),
    ] {
        assert!((y + 0.049).abs() < 0.003, "{name}: tip {y} m");
    }
    fn tip_after<E: fem_core::energy::Energy>(e: E, steps: usize) -> Real {
        let model = cantilever(e, 20, 4);
        let mut s = ExplicitStepper::new(&model, ExplicitParams::default()).unwrap();
        let mut state = State::at_rest(&model);
        for _ in 0..steps {
            s.step(&model, &mut state).unwrap();
        }
        state.displacement(&model, node_index(20, 0, 20)).y
    }
    let _ = tip;
}

#[test]
fn elastic_forces_match_the_fem_core_reference() {
    // Same formula, different association of products: 1e-12 relative to the largest force.
    let model = free_beam(NeoHookean::new(case_a_lame()).unwrap(), 12, 3);
    let x: Vec<Vec2> = model
        .mesh()
        .vertices()
        .iter()
        .map(|p| Vec2::new(p.x * (1.0 + 0.02 * p.y), p.y + 0.05 * (p.x * 0.7).sin()))
        .collect();
    let n = x.len();
    let mut reference = vec![Vec2::zeros(); n];
    populate_forces_serial(model.mesh(), model.energies(), &x, &mut reference);
    let mut stepper = ExplicitStepper::new(&model, ExplicitParams::default()).unwrap();
    let mut state = State::new(&model, x, vec![Vec2::zeros(); n]).unwrap();
    stepper.step(&model, &mut state).unwrap();
    let scale = reference.iter().map(|f| f.norm()).fold(0.0, Real::max);
    for (a, b) in stepper.forces().iter().zip(&reference) {
        assert!((a - b).norm() <= 1e-12 * scale);
    }
}

#[test]
fn stability_guard_warns_above_the_critical_step() {
    let model = cantilever(Stvk::new(case_a_lame()).unwrap(), 20, 4);
    // The element bound on the 20 x 4 `/` beam: 1.9532e-3 s, below the true rest-state limit
    // 2.1105e-3 s (see `critical_time_step.rs`).
    let check = model.check_time_step(1e-3);
    assert!((check.elastic - 1.9532e-3).abs() < 1e-7, "{check:?}");
    assert!(check.warning().is_none());
    let check = model.check_time_step(3e-3);
    let w = check.warning().unwrap();
    assert!(
        w.starts_with("dt = 3e-3 s exceeds the explicit critical time step"),
        "{w}"
    );
}

#[test]
fn blow_up_stops_with_step_and_vertex_and_keeps_the_last_good_state() {
    // E = 1e6 Pa at dt = 1 ms is ~30x over the critical step: the run must blow up, and the
    // error must arrive before any non-finite value reaches the state.
    let model = cantilever(NeoHookean::new(lame(1e6)).unwrap(), 20, 4);
    let params = ExplicitParams::default();
    assert!(model.check_time_step(params.dt).ratio() > 10.0);
    let mut stepper = ExplicitStepper::new(&model, params).unwrap();
    let mut state = State::at_rest(&model);
    let err = loop {
        let before = state.clone();
        match stepper.step(&model, &mut state) {
            Ok(_) => assert!(state.step < 10_000, "did not blow up"),
            Err(e) => {
                assert_eq!(bits(&before.x), bits(&state.x));
                assert_eq!(before.step, state.step);
                break e;
            }
        }
    };
    match &err {
        SolverError::NonFinite { step, vertex, .. } => {
            assert_eq!(*step, state.step);
            assert!(*vertex < model.mesh().n_vertices());
            assert!(state.x.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
        }
        other => panic!("unexpected error {other}"),
    }
    assert!(
        err.to_string()
            .starts_with(&format!("step {} ", state.step))
    );
}

#[test]
fn bad_parameters_are_rejected_with_field_and_value() {
    let model = cantilever(Stvk::new(case_a_lame()).unwrap(), 4, 1);
    let e = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt: 0.0,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "explicit.dt = 0: must be a finite number > 0"
    );
    let e = ExplicitStepper::new(
        &model,
        ExplicitParams {
            damping: Real::NAN,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "explicit.damping = NaN: must be a finite number >= 0"
    );
    let mut m = cantilever(Stvk::new(case_a_lame()).unwrap(), 4, 1);
    let e = m.pin(&Region::Vertices(vec![3, 99])).unwrap_err();
    assert_eq!(
        e.to_string(),
        "pinned: vertex index 99 is out of range (mesh has 10 vertices)"
    );
    let e = m.set_gravity(Vec2::new(0.0, Real::INFINITY)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "gravity = [0, inf]: components must be finite"
    );
    let e = Model::new(
        beam_mesh(2, 1).unwrap(),
        Stvk::new(case_a_lame()).unwrap(),
        vec![1.0; 3],
    )
    .unwrap_err();
    assert!(e.to_string().starts_with("masses.len() = 3"));
}

#[test]
fn prescribed_motion_stretches_by_exactly_velocity_times_window() {
    // Case B: both ends fixed, the right end pulled at 0.5 m/s during [0.1, 0.3] s: the right
    // edge ends 0.1 m further right whatever dt, and the pinned left edge does not move.
    // The windows do not align with the 0.7 ms steps; the displacement is exact to round-off
    // (1e-12 m).
    let model = {
        let mut m = free_beam(NeoHookean::new(case_a_lame()).unwrap(), 20, 4);
        m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
            .unwrap();
        m.pin(&Region::in_box(Vec2::new(5.0, 0.0), Vec2::new(5.0, 1.0)))
            .unwrap();
        m.add_prescribed_motion(PrescribedMotion {
            region: Region::in_box(Vec2::new(5.0, 0.0), Vec2::new(5.0, 1.0)),
            velocity: Vec2::new(0.5, 0.0),
            start: 0.1,
            end: 0.3,
        })
        .unwrap();
        m
    };
    let mut stepper = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt: 7e-4,
            damping: 2.0,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = State::at_rest(&model);
    while state.t < 0.5 {
        stepper.step(&model, &mut state).unwrap();
    }
    for j in 0..=4 {
        let right = state.displacement(&model, node_index(20, j, 20));
        assert!((right - Vec2::new(0.1, 0.0)).norm() < 1e-12, "{right:?}");
        assert_eq!(
            state.displacement(&model, node_index(0, j, 20)),
            Vec2::zeros()
        );
    }
    // The stretched bar contracts laterally at mid-span (Poisson effect).
    let top = state.x[node_index(10, 4, 20)].y;
    let bottom = state.x[node_index(10, 0, 20)].y;
    assert!(top - bottom < 1.0 - 1e-3, "height {}", top - bottom);
}

#[test]
fn external_force_accelerates_a_free_body_by_f_over_m() {
    // A constant 0.2 N on each of the four corners of a free 1 kg beam: the centre of mass
    // accelerates at 0.8 m/s^2 (momentum is exact to round-off: elastic forces sum to zero).
    let mut model = free_beam(Stvk::new(case_a_lame()).unwrap(), 10, 2);
    for v in [
        node_index(0, 0, 10),
        node_index(0, 2, 10),
        node_index(10, 0, 10),
        node_index(10, 2, 10),
    ] {
        model.add_external_force(v, Vec2::new(0.2, 0.0)).unwrap();
    }
    let mut stepper = ExplicitStepper::new(&model, ExplicitParams::default()).unwrap();
    let mut state = State::at_rest(&model);
    for _ in 0..200 {
        stepper.step(&model, &mut state).unwrap();
    }
    let p: Vec2 = model
        .masses()
        .iter()
        .zip(&state.v)
        .map(|(m, v)| v * *m)
        .sum();
    assert!(
        (p.x - 0.8 * 0.2).abs() < 1e-12 && p.y.abs() < 1e-12,
        "{p:?}"
    );
}

/// The explicit stepper under every instruction set this machine has (baseline SSE2, AVX2,
/// AVX-512): the same bits after 400 steps of case A bending (every element strained, the
/// logarithm of Neo-Hookean and the polar decomposition of co-rotational on every element),
/// for every energy, on one and two threads.
#[test]
fn explicit_results_do_not_depend_on_the_instruction_set() {
    use fem_core::energy::EnergyKind;
    use fem_core::simd::Isa;
    for kind in EnergyKind::ALL {
        let mut runs = Vec::new();
        for isa in Isa::supported() {
            for threads in [1, 2] {
                let mut model = cantilever(kind.build(case_a_lame()).unwrap(), 24, 6);
                model.set_isa(isa);
                let mut stepper = ExplicitStepper::new(
                    &model,
                    ExplicitParams {
                        dt: 1e-3,
                        damping: 0.5,
                        ..Default::default()
                    },
                )
                .unwrap();
                let mut state = State::at_rest(&model);
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    for _ in 0..400 {
                        stepper.step(&model, &mut state).unwrap();
                    }
                });
                runs.push((isa, threads, bits(&state.x), bits(&state.v)));
            }
        }
        let (isa0, _, x0, v0) = &runs[0];
        for (isa, threads, x, v) in &runs[1..] {
            assert!(
                x == x0 && v == v0,
                "{kind:?}: {isa} on {threads} threads differs from {isa0} on one"
            );
        }
        // The beam did bend (the comparison is not between rest states).
        let tip = runs[0]
            .2
            .iter()
            .map(|p| f64::from_bits(p[1]))
            .fold(0.0, f64::min);
        assert!(tip < -0.05, "{kind:?}: tip at {tip} m");
    }
}
