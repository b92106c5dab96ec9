//! The explicit stability guard. The critical time step against the true rest-state limit
//! `2 / omega_max` (a dense eigenproblem of the assembled stiffness and the lumped masses) on
//! beams with every diagonal pattern; case A run just below the estimate; the forward Euler
//! warning.
//!
//! Symptom pinned: the former estimate `h_min / sqrt(M / rho)` gave 2.155e-3 s on the case A
//! mesh, whose true limit is 2.111e-3 s, so runs at dt = 2.12e-3 s blew up without a warning;
//! and forward Euler, unstable at every dt without enough damping, was never warned about.

use fem_core::assembly::{Stiffness, Tangent, populate_stiffness_serial};
use fem_core::energy::{Energy, EnergyOf, NeoHookean, Stvk};
use fem_core::math::Real;
use fem_solvers::testing::cantilever;
use fem_solvers::{ExplicitParams, ExplicitScheme, ExplicitStepper, Model, Solver, State, Stepper};
use nalgebra::{DMatrix, SymmetricEigen};

use crate::common::{PATTERNS, Pattern, beam, case_a_lame};

/// The true rest-state limit `2 / omega_max`, s: `omega_max^2` is the largest eigenvalue of
/// `M^-1 K` over the free degrees of freedom, solved densely as `M^-1/2 K M^-1/2`.
fn true_limit<E: Energy>(model: &Model<E>) -> Real {
    let mesh = model.mesh();
    let mut k = Stiffness::for_energy(mesh, model.energies());
    populate_stiffness_serial(
        mesh,
        model.energies(),
        mesh.vertices(),
        Tangent::Exact,
        &mut k,
    );
    let free: Vec<usize> = (0..2 * mesh.n_vertices())
        .filter(|d| model.inverse_masses()[d / 2] > 0.0)
        .collect();
    let scale: Vec<Real> = free
        .iter()
        .map(|d| model.inverse_masses()[d / 2].sqrt())
        .collect();
    let a = DMatrix::from_fn(free.len(), free.len(), |r, c| {
        scale[r] * k.matrix.get(free[r], free[c]) * scale[c]
    });
    let lambda_max = SymmetricEigen::new(a).eigenvalues.max();
    2.0 / lambda_max.sqrt()
}

/// Case A damping rate, 1/s.
const CASE_A_DAMPING: Real = 0.175;

/// Run `steps` explicit steps of `model` from rest; the step index of a blow-up, if any.
fn run<E: Energy>(model: &Model<E>, params: ExplicitParams, steps: usize) -> Option<usize> {
    let mut stepper = ExplicitStepper::new(model, params).unwrap();
    let mut state = State::at_rest(model);
    (0..steps).find(|_| stepper.step(model, &mut state).is_err())
}

/// The element bound never under-estimates `omega_max` (every estimate is at most the true
/// limit) and is within a factor of 0.75 of it on every structured beam. Measured ratios of the
/// estimate to the true limit: 0.926 (20 x 4, `/` or `\`, 1.9532e-3 s against 2.1105e-3 s),
/// 0.784 (alternating, 1.9532e-3 against 2.4924e-3), 0.784 (crossed, 1.3811e-3 against
/// 1.7614e-3); on 10 x 2 cells 0.927, 0.791 and 0.786.
#[test]
fn elastic_critical_time_step_is_conservative_and_tight_on_every_diagonal_pattern() {
    for (nx, ny) in [(20, 4), (10, 2)] {
        for pattern in PATTERNS {
            let model =
                cantilever(beam(nx, ny, pattern), Stvk::new(case_a_lame()).unwrap()).unwrap();
            let estimate = model.elastic_critical_time_step();
            let truth = true_limit(&model);
            let ratio = estimate / truth;
            assert!(
                (0.75..=1.0).contains(&ratio),
                "{nx} x {ny} {pattern:?}: estimate {estimate:e} s, true limit {truth:e} s, ratio {ratio}"
            );
            // The bound ignores the pins: it also holds for the free beam.
            let free = Model::with_total_mass(
                beam(nx, ny, pattern),
                Stvk::new(case_a_lame()).unwrap(),
                1.0,
            )
            .unwrap();
            assert_eq!(free.elastic_critical_time_step(), estimate);
            assert!(
                estimate <= true_limit(&free),
                "{nx} x {ny} {pattern:?} free"
            );
        }
    }
}

/// Case A (`\` diagonals, 1 kg, damping 0.175 1/s) at 0.99 of the estimate runs 2000 steps
/// for StVK and Neo-Hookean; the estimate lies below the true limit 2.111e-3 s, so the step
/// 2.12e-3 s the former estimate allowed (and which blows up: measured at step 1304 for StVK,
/// 367 for Neo-Hookean) is now warned about.
#[test]
fn case_a_runs_just_below_the_estimate() {
    fn check<E: Energy>(energy: E) {
        let model = cantilever(beam(20, 4, Pattern::Left), energy).unwrap();
        let estimate = model.elastic_critical_time_step();
        assert!(estimate < 2.111e-3, "{estimate:e}");
        assert!(model.check_time_step(2.12e-3).warning().is_some());
        let params = ExplicitParams {
            dt: 0.99 * estimate,
            damping: CASE_A_DAMPING,
            ..Default::default()
        };
        assert!(model.check_time_step(params.dt).warning().is_none());
        assert_eq!(
            run(&model, params, 2000),
            None,
            "blew up at 0.99 x {estimate:e} s"
        );
        let former = ExplicitParams {
            dt: 2.12e-3,
            ..params
        };
        assert!(
            run(&model, former, 2000).is_some(),
            "2.12e-3 s stayed stable"
        );
    }
    check(Stvk::new(case_a_lame()).unwrap());
    check(NeoHookean::new(case_a_lame()).unwrap());
}

/// Forward Euler on case A at dt = 1e-3 s with damping 0.175 1/s: the highest mode grows by
/// up to `sqrt(1 + (omega dt)^2) exp(-c dt / 2)` per step (1.4311 with the bound
/// `omega <= 1024 rad/s`, 1.378 with the true `omega_max = 948 rad/s`; it would take
/// c >= 717 1/s to be stable), so the stepper warns, and the run does blow up (measured: the
/// 70th step fails). Symplectic Euler at the same dt is stable and
/// does not warn.
#[test]
fn forward_euler_is_warned_about_and_blows_up() {
    let model = cantilever(
        beam(20, 4, Pattern::Left),
        Stvk::new(case_a_lame()).unwrap(),
    )
    .unwrap();
    let params = ExplicitParams {
        dt: 1e-3,
        damping: CASE_A_DAMPING,
        scheme: ExplicitScheme::ForwardEuler,
    };
    let stepper = ExplicitStepper::new(&model, params).unwrap();
    let growth = stepper
        .time_step_check()
        .forward_euler_growth(params.damping);
    assert!((growth - 1.4311).abs() < 1e-4, "{growth}");
    let warning = stepper
        .time_step_warning()
        .expect("forward Euler must warn");
    assert!(
        warning.starts_with("forward Euler (x uses the old velocity) amplifies"),
        "{warning}"
    );
    assert!(run(&model, params, 2000).is_some());

    let symplectic = ExplicitParams {
        scheme: ExplicitScheme::SymplecticEuler,
        ..params
    };
    let stepper = ExplicitStepper::new(&model, symplectic).unwrap();
    assert_eq!(stepper.time_step_warning(), None);
    assert_eq!(run(&model, symplectic, 2000), None);
}

/// With the averaged nodal pressure triangle the bound sums the elements' deviatoric bound and
/// the nodes' volumetric one: still never above the true limit, within a factor of 0.5 of it
/// on every pattern at nu = 0.3 and 0.49, and case A at 95 % of the estimate runs 2000 steps.
#[test]
fn averaged_pressure_critical_time_step_is_conservative() {
    for nu in [0.3, 0.49] {
        let lame = fem_core::material::Material::new(1000.0, nu, 1.0)
            .unwrap()
            .lame(fem_core::PlaneModel::PlaneStrain);
        for pattern in PATTERNS {
            let mut model =
                cantilever(beam(20, 4, pattern), NeoHookean::new(lame).unwrap()).unwrap();
            let plain = model.elastic_critical_time_step();
            model.set_averaged_pressure(true).unwrap();
            assert!(model.energies().nodal_pressure().is_some());
            let estimate = model.elastic_critical_time_step();
            let truth = true_limit(&model);
            let ratio = estimate / truth;
            eprintln!(
                "nu {nu} {pattern:?}: averaged pressure {estimate:e} s (true {truth:e} s, ratio {ratio:.3}), plain {plain:e} s"
            );
            assert!(
                (0.5..=1.0).contains(&ratio),
                "nu {nu} {pattern:?}: estimate {estimate:e} s, true limit {truth:e} s"
            );
            let dt = 0.95 * estimate;
            let params = ExplicitParams {
                dt,
                damping: CASE_A_DAMPING,
                ..Default::default()
            };
            assert_eq!(
                run(&model, params, 2000),
                None,
                "nu {nu} {pattern:?} at dt {dt:e}"
            );
        }
    }
}
