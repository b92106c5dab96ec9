//! Projective Dynamics against implicit Euler of the co-rotational energy: the fixed point of
//! the local-global iterations is Newton's step at every Poisson ratio (the area term is a
//! projective term too); the global matrix is factorised once per stepper; Chebyshev keeps the
//! fixed point.

use fem_core::PlaneModel;
use fem_core::energy::{AnyEnergy, EnergyKind};
use fem_core::material::Material;
use fem_core::math::Real;
use fem_solvers::{ImplicitParams, ImplicitStepper, Model, PdParams, PdStepper, State, Stepper};

use crate::common::cantilever;
use crate::vbd::{gap, implicit_step};

/// The cantilever (10 x 2 cells, E = 1000 Pa) with Poisson ratio `nu`, co-rotational, after
/// 20 implicit steps of 10 ms from rest.
fn swinging(nu: Real) -> (Model<AnyEnergy>, State) {
    let lame = Material::new(1000.0, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let model = cantilever(EnergyKind::Corotational.build(lame).unwrap(), 10, 2);
    let mut state = State::at_rest(&model);
    let mut implicit = ImplicitStepper::new(&model, ImplicitParams::default()).unwrap();
    for _ in 0..20 {
        implicit.step(&model, &mut state).unwrap();
    }
    (model, state)
}

fn pd_step(model: &Model<AnyEnergy>, start: &State, params: PdParams) -> State {
    let mut s = start.clone();
    PdStepper::new(model, params)
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

/// At nu = 0 (ARAP), 0.3 and 0.45 the iterations reach Newton's step: the gap shrinks with
/// the iterations to round-off. Measured (10 ms step): at nu = 0.3, 2.5e-2 after 3
/// iterations, 3.6e-3 after 10, 7e-5 after 30, round-off after 1000.
#[test]
fn iterations_converge_to_the_implicit_euler_step_at_every_poisson_ratio() {
    for nu in [0.0, 0.3, 0.45] {
        let (model, start) = swinging(nu);
        let reference = implicit_step(&model, &start, 1e-2);
        let gaps: Vec<Real> = [3, 10, 30, 1000]
            .iter()
            .map(|&iterations| {
                let params = PdParams {
                    dt: 1e-2,
                    iterations,
                    ..PdParams::default()
                };
                gap(
                    &pd_step(&model, &start, params),
                    &reference,
                    &start,
                    &reference,
                )
            })
            .collect();
        eprintln!(
            "nu {nu}: gap after 3, 10, 30, 1000 iterations: {:.2e} {:.2e} {:.2e} {:.2e}",
            gaps[0], gaps[1], gaps[2], gaps[3]
        );
        for w in gaps.windows(2) {
            assert!(w[1] < w[0] || w[1] < 1e-10, "nu {nu}: {gaps:?}");
        }
        assert!(gaps[3] < 1e-9, "nu {nu}: {gaps:?}");
    }
}

/// The global matrix is factorised when the stepper is built and never again.
#[test]
fn the_global_matrix_is_factorised_once_per_stepper() {
    let (model, mut state) = swinging(0.3);
    let mut pd = PdStepper::new(&model, PdParams::default()).unwrap();
    assert_eq!(pd.factorisations(), 1);
    for _ in 0..50 {
        pd.step(&model, &mut state).unwrap();
    }
    assert_eq!(pd.factorisations(), 1);
}

/// Chebyshev keeps the fixed point and, at a good rho, gets closer in the same iterations.
#[test]
fn chebyshev_keeps_the_fixed_point_and_a_good_rho_speeds_it_up() {
    let (model, start) = swinging(0.3);
    let reference = implicit_step(&model, &start, 1e-2);
    let run = |rho: Real, iterations: usize| {
        let params = PdParams {
            dt: 1e-2,
            iterations,
            chebyshev_rho: rho,
            ..PdParams::default()
        };
        gap(
            &pd_step(&model, &start, params),
            &reference,
            &start,
            &reference,
        )
    };
    let mut rows = Vec::new();
    for rho in [0.0, 0.5, 0.8, 0.9, 0.99] {
        rows.push((rho, run(rho, 20), run(rho, 2000)));
    }
    for (rho, at20, converged) in &rows {
        eprintln!("rho {rho}: gap {at20:.2e} after 20 iterations, {converged:.2e} after 2000");
    }
    for (rho, _, converged) in &rows[..4] {
        assert!(*converged < 1e-9, "rho {rho}: {converged:e}");
    }
    let best = rows.iter().map(|r| r.1).fold(Real::INFINITY, Real::min);
    assert!(best < 0.5 * rows[0].1, "no rho helped: {rows:?}");
}

/// Other energies are refused with a message naming the energy and the alternative.
#[test]
fn other_energies_are_refused_by_name() {
    for kind in [EnergyKind::NeoHookean, EnergyKind::Stvk] {
        let model = cantilever(kind.build(crate::common::case_a_lame()).unwrap(), 4, 1);
        let e = PdStepper::new(&model, PdParams::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!("pd.energy = {}", kind.name())) && e.contains("quasi-newton"),
            "{e}"
        );
    }
}
