//! Quasi-Newton in 3D ([`fem_solvers::nd::NdQuasiNewton`]: L-BFGS with the Projective Dynamics
//! matrix) against Newton on the same incremental potential: its step converges to implicit
//! Euler's as the iterations grow, for all five energies; it keeps every tetrahedron uninverted
//! where the energy forbids inversion; the initial Hessian is factorised once; BDF2 is refused
//! in one line.

use fem_core::dim::{D3, Vec3};
use fem_core::energy::{AnyEnergy, EnergyKind, NeoHookean};
use fem_core::math::Real;
use fem_core::structured::{BoxParams, box_mesh};
use fem_solvers::nd::{self, NdModel, NdQuasiNewton, NdRegion, NdState, NdStepper};
use fem_solvers::{ImplicitParams, Integrator, NewtonParams, QuasiNewtonParams, SolverParams};

use crate::common::case_a_lame;

const G: Real = fem_solvers::model::STANDARD_GRAVITY;

/// Case A's beam in 3D (5 x 1 x 0.5 m, 10 x 2 x 2 cubes of 6 tetrahedra), left face pinned,
/// under gravity.
fn beam(energy: AnyEnergy) -> NdModel<D3, AnyEnergy> {
    let mesh = box_mesh(&BoxParams::new(5.0, 1.0, 0.5, 10, 2, 2)).unwrap();
    let mut model = NdModel::with_density(mesh, energy, 0.2).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.5),
        ))
        .unwrap();
    model
}

fn implicit(dt: Real) -> SolverParams {
    SolverParams::Implicit(ImplicitParams {
        dt,
        velocity_tolerance: 0.0,
        newton: NewtonParams {
            tolerance: 1e-12,
            ..NewtonParams::default()
        },
        ..ImplicitParams::default()
    })
}

/// The beam after 20 implicit steps of 10 ms from rest (swinging down).
fn swinging(model: &NdModel<D3, AnyEnergy>) -> NdState<D3> {
    let mut state = NdState::at_rest(model);
    let mut s = nd::build(model, &implicit(1e-2), "solver").unwrap();
    for _ in 0..20 {
        s.step(model, &mut state).unwrap();
    }
    state
}

/// The largest vertex distance between `a` and `reference` over the reference step's largest
/// displacement from `start`.
fn gap(a: &NdState<D3>, reference: &NdState<D3>, start: &NdState<D3>) -> Real {
    let d = (a.x.iter().zip(&reference.x))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    let moved = (reference.x.iter().zip(&start.x))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    d / moved
}

/// As the iterations grow the step reaches Newton's, for all five energies: the gap to the
/// implicit Euler step shrinks with the iterations to round-off, where the residual test (1e-11)
/// stops it; the history makes it converge in far fewer iterations than the PD matrix alone
/// (which reaches the step too, but for linear elasticity not the residual test in 1000
/// iterations). Measured (10 ms step): gap 1.2e-2, 4.0e-3, 7.2e-4, 1.6e-5 after 2, 5, 10, 20
/// iterations for every energy; converged in 81 to 83 iterations with history 5, 342 to 348
/// with none (linear: 1000, gap 2e-13).
#[test]
fn iterations_converge_to_the_implicit_euler_step_in_3d_for_every_energy() {
    for kind in EnergyKind::ALL {
        let model = beam(kind.build(case_a_lame()).unwrap());
        let start = swinging(&model);
        let mut reference = start.clone();
        nd::build(&model, &implicit(1e-2), "solver")
            .unwrap()
            .step(&model, &mut reference)
            .unwrap();
        let run = |iterations: usize, history: usize| {
            let params = QuasiNewtonParams {
                dt: 1e-2,
                iterations,
                history,
                tolerance: 1e-11,
                ..QuasiNewtonParams::default()
            };
            let mut qn = NdQuasiNewton::new(&model, params, "solver").unwrap();
            let mut s = start.clone();
            qn.step(&model, &mut s)
                .unwrap_or_else(|e| panic!("{kind}: {e}"));
            (gap(&s, &reference, &start), qn.last_report().clone())
        };
        let gaps: Vec<Real> = [2, 5, 10, 20, 1000].iter().map(|&k| run(k, 5).0).collect();
        let (_, with_history) = run(1000, 5);
        let (alone_gap, alone) = run(1000, 0);
        eprintln!(
            "{kind}: gap after 2, 5, 10, 20, 1000 iterations: {:.2e} {:.2e} {:.2e} {:.2e} {:.2e}; \
             converged in {} iterations with history 5, {} with none (gap {alone_gap:.2e})",
            gaps[0], gaps[1], gaps[2], gaps[3], gaps[4], with_history.iterations, alone.iterations
        );
        for w in gaps.windows(2) {
            assert!(w[1] < w[0] || w[1] < 1e-9, "{kind}: {gaps:?}");
        }
        assert!(with_history.converged, "{kind}");
        assert!(gaps[4] < 1e-8 && alone_gap < 1e-8, "{kind}: {gaps:?}");
        assert!(
            with_history.iterations < alone.iterations,
            "{kind}: {} vs {}",
            with_history.iterations,
            alone.iterations
        );
    }
}

/// A bar squashed to 30 % along its length and released, at a 1/90 s step, default budget:
/// under Neo-Hookean no tetrahedron is ever inverted (the line search refuses infinite
/// energy); the initial Hessian is factorised once.
#[test]
fn no_tetrahedron_inverts_under_neo_hookean() {
    let model = beam(AnyEnergy::NeoHookean(
        NeoHookean::new(case_a_lame()).unwrap(),
    ));
    let x = (model.mesh().vertices().iter())
        .map(|p| Vec3::new(0.3 * p.x, p.y, p.z))
        .collect();
    let mut state = NdState {
        x,
        v: vec![Vec3::zeros(); model.mesh().n_vertices()],
        t: 0.0,
    };
    let params = QuasiNewtonParams {
        dt: 1.0 / 90.0,
        ..QuasiNewtonParams::default()
    };
    let mut qn = NdQuasiNewton::new(&model, params, "solver").unwrap();
    let mut worst: Real = Real::INFINITY;
    let mut longest: Real = 0.0;
    for _ in 0..90 {
        let r = qn
            .step(&model, &mut state)
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.inverted, 0);
        worst = worst.min(r.min_det_f);
        longest = longest.max(state.x.iter().map(|p| p.x).fold(0.0, Real::max));
    }
    eprintln!("smallest det F over 1 s at 90 Hz: {worst:.3}; longest extent {longest:.3} m");
    assert!(worst > 0.0);
    // The bar springs back out of its squash.
    assert!(longest > 3.0, "{longest}");
    assert_eq!(qn.factorisations(), 1);
}

/// Driven beyond double precision (1e300 g: the forces at the start overflow), the step fails
/// in one line and leaves the state as it was.
#[test]
fn a_load_beyond_double_precision_fails_and_leaves_the_state() {
    let mut model = beam(AnyEnergy::NeoHookean(
        NeoHookean::new(case_a_lame()).unwrap(),
    ));
    model.set_gravity(Vec3::new(0.0, -1e300 * G, 0.0)).unwrap();
    let mut qn = NdQuasiNewton::new(&model, QuasiNewtonParams::default(), "solver").unwrap();
    let mut state = NdState::at_rest(&model);
    let before = state.clone();
    let e = qn.step(&model, &mut state).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(!e.contains('\n'), "{e}");
    assert_eq!(state, before);
}

/// BDF2 is refused in one line.
#[test]
fn bdf2_is_refused() {
    let model = beam(AnyEnergy::NeoHookean(
        NeoHookean::new(case_a_lame()).unwrap(),
    ));
    let params = SolverParams::QuasiNewton(QuasiNewtonParams {
        integrator: Integrator::Bdf2,
        ..QuasiNewtonParams::default()
    });
    let e = nd::build(&model, &params, "solver")
        .err()
        .unwrap()
        .to_string();
    assert_eq!(
        e,
        "solver.integrator = bdf2: is not available in 3d yet (use backward-euler)"
    );
}
