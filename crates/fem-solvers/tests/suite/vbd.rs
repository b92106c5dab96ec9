//! Vertex Block Descent against its oracle, implicit Euler: both minimise the same incremental
//! potential, so VBD's step must reach Newton's as its sweeps grow, for every energy; the
//! definiteness fix must hold under compression (StVK indefinite); Chebyshev acceleration
//! must not change the converged answer.

use fem_core::energy::{AnyEnergy, EnergyKind, EnergyOf};
use fem_core::math::{Real, Vec2};
use fem_solvers::{
    ImplicitParams, ImplicitStepper, Model, NewtonParams, Region, State, Stepper, VbdInit,
    VbdParams, VbdStepper,
};

use crate::common::{cantilever, case_a_lame};

/// The case A cantilever (10 x 2 cells) under `kind`, swinging: a state after 20 implicit
/// steps of 10 ms from rest, so each step starts with velocity and strain.
pub fn swinging(kind: EnergyKind) -> (Model<AnyEnergy>, State) {
    let model = cantilever(kind.build(case_a_lame()).unwrap(), 10, 2);
    let mut state = State::at_rest(&model);
    let mut implicit = ImplicitStepper::new(&model, ImplicitParams::default()).unwrap();
    for _ in 0..20 {
        implicit.step(&model, &mut state).unwrap();
    }
    (model, state)
}

/// One implicit Euler step of `dt` from `state`, Newton to 1e-13.
pub fn implicit_step(model: &Model<AnyEnergy>, state: &State, dt: Real) -> State {
    let params = ImplicitParams {
        dt,
        newton: NewtonParams {
            tolerance: 1e-13,
            max_iterations: 200,
            ..NewtonParams::default()
        },
        // Newton's tolerance alone stops it (no velocity tolerance).
        velocity_tolerance: 0.0,
        ..ImplicitParams::default()
    };
    let mut s = state.clone();
    ImplicitStepper::new(model, params)
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

/// One VBD step of `dt` from `state` with `params` (dt overridden).
fn vbd_step(model: &Model<AnyEnergy>, state: &State, dt: Real, params: VbdParams) -> State {
    let mut s = state.clone();
    VbdStepper::new(model, VbdParams { dt, ..params })
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

/// Implicit Euler's incremental potential of the step of `dt` from `start`, at `x` (gravity
/// only, as in these scenes), J per unit thickness.
pub fn potential(model: &Model<AnyEnergy>, start: &State, dt: Real, x: &[Vec2]) -> Real {
    use fem_core::energy::Energy;
    let mesh = model.mesh();
    let mut e = 0.0;
    for (i, m) in model.masses().iter().enumerate() {
        let target = start.x[i] + start.v[i] * dt;
        e += 0.5 * m / (dt * dt) * (x[i] - target).norm_squared();
        e -= (model.gravity() * *m).dot(&(x[i] - mesh.vertices()[i]));
    }
    for (t, el) in mesh.elements().iter().enumerate() {
        let f = el.deformation_gradient(mesh.gather(t, x));
        e += el.area * model.energies().energy_of(t).psi(&f);
    }
    e
}

/// Largest vertex distance between `a` and `b` over the largest distance `reference` moved
/// from `start`.
pub fn gap(a: &State, b: &State, start: &State, reference: &State) -> Real {
    let d =
        a.x.iter()
            .zip(&b.x)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, Real::max);
    let moved = reference
        .x
        .iter()
        .zip(&start.x)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    d / moved
}

/// As the sweeps grow, one VBD step reaches the implicit Euler step for every energy: the gap
/// (largest vertex distance over the step's largest displacement) shrinks with the sweeps and
/// ends at round-off. Measured (10 ms step, 10 x 2 cells, Neo-Hookean): 8e-3 after 10 sweeps,
/// round-off (4e-12) from about 100.
#[test]
fn one_step_converges_to_the_implicit_euler_step_for_every_energy() {
    for kind in EnergyKind::ALL {
        let (model, start) = swinging(kind);
        let reference = implicit_step(&model, &start, 1e-2);
        let mut gaps = Vec::new();
        for iterations in [3, 10, 30, 1000] {
            let params = VbdParams {
                iterations,
                ..VbdParams::default()
            };
            let s = vbd_step(&model, &start, 1e-2, params);
            gaps.push(gap(&s, &reference, &start, &reference));
        }
        eprintln!(
            "{kind}: gap to implicit Euler after 3, 10, 30, 1000 sweeps: {:.2e} {:.2e} {:.2e} {:.2e}",
            gaps[0], gaps[1], gaps[2], gaps[3]
        );
        // Shrinking until round-off (the reference's own Newton tolerance is 1e-13).
        for w in gaps.windows(2) {
            assert!(
                w[1] < w[0] || w[1] < 1e-10,
                "{kind}: not shrinking {gaps:?}"
            );
        }
        assert!(gaps[3] < 1e-9, "{kind}: {gaps:?}");
    }
}

/// Every initial guess, with and without the line search, converges to the same step (they
/// change where and how the sweeps go, not where they end).
#[test]
fn every_initial_guess_with_or_without_line_search_converges_to_the_same_step() {
    let (model, start) = swinging(EnergyKind::NeoHookean);
    let reference = implicit_step(&model, &start, 1e-2);
    for init in [VbdInit::Previous, VbdInit::Inertia, VbdInit::Adaptive] {
        for line_search in [false, true] {
            let params = VbdParams {
                iterations: 1000,
                init,
                line_search,
                ..VbdParams::default()
            };
            let s = vbd_step(&model, &start, 1e-2, params);
            let g = gap(&s, &reference, &start, &reference);
            assert!(g < 1e-9, "{init:?}, line search {line_search}: {g:e}");
        }
    }
}

/// A bar squashed to 30 % of its length and released: StVK's Hessian is indefinite there, and
/// the projected blocks keep every update a descent step. With every energy but StVK the step
/// ends where implicit Euler's does, uninverted; with StVK it ends in another, inverted,
/// stationary point of the same (non-convex) potential.
#[test]
fn a_squashed_bar_recovers_under_every_energy() {
    for kind in EnergyKind::ALL {
        let energy = kind.build(case_a_lame()).unwrap();
        let mut model =
            Model::with_total_mass(fem_solvers::testing::beam_mesh(10, 2).unwrap(), energy, 1.0)
                .unwrap();
        model
            .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
            .unwrap();
        let x = model
            .mesh()
            .vertices()
            .iter()
            .map(|p| Vec2::new(0.3 * p.x, p.y))
            .collect();
        let start = State::new(&model, x, vec![Vec2::zeros(); model.mesh().n_vertices()]).unwrap();
        let reference = implicit_step(&model, &start, 1e-2);
        let params = VbdParams {
            iterations: 2000,
            ..VbdParams::default()
        };
        let mut s = start.clone();
        let mut vbd = VbdStepper::new(&model, VbdParams { dt: 1e-2, ..params }).unwrap();
        let report = vbd.step(&model, &mut s).unwrap();
        let g = gap(&s, &reference, &start, &reference);
        eprintln!(
            "{kind}: squashed bar, gap {g:.2e}, min det F {:.3}, {:?}",
            report.min_det_f,
            vbd.last_stats()
        );
        let (mine, newton) = (
            potential(&model, &start, 1e-2, &s.x),
            potential(&model, &start, 1e-2, &reference.x),
        );
        let initial = potential(&model, &start, 1e-2, &start.x);
        eprintln!("  potential: VBD {mine:.6e}, Newton {newton:.6e}, start {initial:.6e}");
        if kind == EnergyKind::Stvk {
            // StVK's potential is not convex here: VBD, a local descent, settles in an
            // inverted local minimum above Newton's (measured 403.9 against 359.5 J, min det F
            // -0.91): StVK's known collapse under compression. It still descended.
            assert!(mine < initial, "{mine} vs {initial}");
        } else {
            assert!(g < 1e-9, "{kind}: {g:e}");
            assert!(report.min_det_f > 0.0, "{kind}: {}", report.min_det_f);
        }
    }
}

/// Chebyshev acceleration does not change the converged step, and at a good `rho` it gets
/// there in fewer sweeps (measured after 50 sweeps: 2.1e-7 without, 1.7e-8 at rho = 0.5,
/// 8.3e-8 at 0.9); at a `rho` far above the sweeps' spectral radius it diverges (0.99: 96
/// after 3000 sweeps).
#[test]
fn chebyshev_keeps_the_converged_step_and_a_good_rho_speeds_it_up() {
    let (model, start) = swinging(EnergyKind::NeoHookean);
    let reference = implicit_step(&model, &start, 1e-2);
    let run = |rho: Real, iterations: usize| {
        let params = VbdParams {
            iterations,
            chebyshev_rho: rho,
            ..VbdParams::default()
        };
        gap(
            &vbd_step(&model, &start, 1e-2, params),
            &reference,
            &start,
            &reference,
        )
    };
    let mut rows = Vec::new();
    for rho in [0.0, 0.5, 0.9, 0.95, 0.99, 0.999] {
        rows.push((rho, run(rho, 50), run(rho, 3000)));
    }
    for (rho, at50, converged) in &rows {
        eprintln!("rho {rho}: gap {at50:.2e} after 50 sweeps, {converged:.2e} after 3000");
    }
    // Up to 0.95 the converged step is the same; at 0.99 and above (far beyond the sweeps'
    // spectral radius on this step) the extrapolation overshoots and never settles.
    for (rho, _, converged) in &rows {
        if *rho <= 0.95 {
            assert!(*converged < 1e-10, "rho {rho}: {converged:e}");
        } else {
            assert!(
                *converged > 1e-3,
                "rho {rho}: expected to diverge, {converged:e}"
            );
        }
    }
    let plain = rows[0].1;
    let best = rows.iter().map(|r| r.1).fold(Real::INFINITY, Real::min);
    assert!(best < 0.5 * plain, "no rho helped: {rows:?}");
}

/// A Neo-Hookean beam hurled against its pinned edge at 300 m/s with 10 ms steps: full Newton
/// steps would invert triangles, so vertex steps are halved (the orientation test is the exact
/// rank-one update `det(F + s g^T) = det F + s . cof(F) g`), and no triangle ever inverts.
#[test]
fn steps_that_would_invert_a_neo_hookean_triangle_are_halved() {
    let model = cantilever(
        fem_core::energy::NeoHookean::new(case_a_lame()).unwrap(),
        10,
        2,
    );
    let mut stepper = VbdStepper::new(
        &model,
        VbdParams {
            dt: 0.01,
            ..VbdParams::default()
        },
    )
    .unwrap();
    let mut state = State::at_rest(&model);
    for v in state.v.iter_mut() {
        *v = Vec2::new(-300.0, 0.0);
    }
    let mut halved = 0;
    for _ in 0..5 {
        let report = stepper.step(&model, &mut state).unwrap();
        halved += stepper.last_stats().halved;
        assert_eq!(report.inverted, 0);
        assert!(report.min_det_f > 0.0);
    }
    eprintln!("halved vertex steps: {halved}");
    assert!(
        halved > 0,
        "no step was halved: the test does not reach the orientation test"
    );
}
