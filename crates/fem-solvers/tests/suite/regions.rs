//! Per-element materials: a bimaterial bar in tension under every solver of the registry.
//!
//! The bar (2 m x 0.2 m, left end pinned, a traction `t` on the right end, no gravity) is soft
//! (E1) on its left half and stiff (E2 = 100 E1) on its right half, co-rotational with
//! `nu = 0`. Then `F = diag(s_i, 1)` in region `i` with `E_i (s_i - 1) = t` is an exact
//! equilibrium of the continuum and of the discrete model alike (co-rotational with `lambda = 0`
//! is `P = 2 mu (F - R)`, `R = I` for a stretch; the interface is a mesh line, and a pinned end
//! costs nothing because `nu = 0` means no lateral contraction): two springs in series. So the
//! strain of each half must be `t / E_i`, whatever the solver, up to how far it converges:
//! - static, implicit Euler, Projective Dynamics, quasi-Newton and explicit (damped to rest):
//!   within 1e-4 of each strain (the solvers' convergence tolerances and the residual motion
//!   of the damped runs; measured below 1e-8 for explicit, implicit and static);
//! - XPBD (10 substeps of 20 iterations): within 2 % (measured 0.9 %: its iterations do not
//!   converge the stiff half);
//! - VBD (100 sweeps per step): within 0.5 % (measured 0.15 %: vertex Gauss-Seidel converges
//!   slowly across a hundredfold contrast);
//! - PBD: energy-based PBD is invariant to scaling the energy (`C = a psi` and its gradient
//!   scale alike), so Young's modulus cancels from its projection; per-element parameters
//!   still reach it: a region with another Poisson ratio changes its result.

use fem_core::PlaneModel;
use fem_core::energy::{AnyEnergy, ElementEnergies, Energy, EnergyKind};
use fem_core::material::Material;
use fem_core::math::{Real, Vec2};
use fem_core::structured::{RectangleParams, rectangle};
use fem_solvers::{Model, Region, SolverKind, SolverParams, State, Stepper};

const LENGTH: Real = 2.0;
const SOFT: Real = 1.0e4;
const STIFF: Real = 1.0e6;
const TRACTION: Real = 500.0;

fn corotational(e: Real, nu: Real) -> AnyEnergy {
    let lame = Material::new(e, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    EnergyKind::Corotational.build(lame).unwrap()
}

/// The bar with its right half in region 1 (`e2`, `nu2`), density 100 kg/m^3.
fn bar(e2: Real, nu2: Real) -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams::new(LENGTH, 0.2, 20, 2)).unwrap();
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
            u32::from(c.x > 0.5 * LENGTH)
        })
        .collect();
    let base = corotational(SOFT, 0.0);
    let stiff = corotational(e2, nu2);
    let energies = ElementEnergies::new(vec![base, stiff], tags).unwrap();
    let densities = vec![100.0; mesh.n_triangles()];
    let masses = mesh.lumped_masses_from_densities(&densities).unwrap();
    let mut model = Model::with_regions(mesh, energies, masses).unwrap();
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.2)))
        .unwrap()
        .add_traction(
            &Region::in_box(Vec2::new(LENGTH, 0.0), Vec2::new(LENGTH, 0.2)),
            Vec2::new(TRACTION, 0.0),
        )
        .unwrap();
    model
}

/// The mean x-displacement of the vertices on the line `x = at`.
fn ux_at<E: Energy>(model: &Model<E>, state: &State, at: Real) -> Real {
    let (mut sum, mut n) = (0.0, 0.0);
    for (v, p) in model.mesh().vertices().iter().enumerate() {
        if (p.x - at).abs() < 1e-9 {
            sum += state.x[v].x - p.x;
            n += 1.0;
        }
    }
    sum / n
}

/// The strains of the two halves after `kind` runs the bar to rest.
fn strains(kind: SolverKind, model: &Model<AnyEnergy>) -> (Real, Real) {
    let mut p = kind.default_params();
    // Soft wave speed 10 m/s, stiff 100 m/s; 0.1 m elements: explicit needs dt < 1e-3.
    let (dt, steps) = match kind {
        SolverKind::Explicit => (2e-4, 40_000),
        SolverKind::Static => (1.0, 1),
        _ => (1e-2, 800),
    };
    p.set_dt(dt);
    let damping = 20.0;
    match &mut p {
        SolverParams::Explicit(x) => x.damping = damping,
        // Converged steps (Newton's tolerance alone, no velocity tolerance): the analytic
        // strain is the converged equilibrium's.
        SolverParams::Implicit(x) => (x.damping, x.velocity_tolerance) = (damping, 0.0),
        SolverParams::LinearImplicit(x) => x.damping = damping,
        SolverParams::Static(_) => {}
        SolverParams::Pbd(x) => (x.iterations, x.damping) = (50, damping),
        SolverParams::Xpbd(x) => (x.substeps, x.iterations, x.damping) = (10, 20, damping),
        SolverParams::Vbd(x) => (x.iterations, x.damping) = (100, damping),
        SolverParams::Pd(x) => (x.iterations, x.damping) = (200, damping),
        SolverParams::QuasiNewton(x) => (x.iterations, x.damping) = (200, damping),
        _ => panic!("{kind}: no settings for this solver in the bimaterial test"),
    }
    let mut stepper = p.build(model).unwrap();
    let mut state = State::at_rest(model);
    let steps = match &p {
        SolverParams::Static(s) => s.load_steps,
        _ => steps,
    };
    for _ in 0..steps {
        stepper
            .step(model, &mut state)
            .unwrap_or_else(|e| panic!("{kind}: step {} failed: {e}", state.step));
    }
    let half = 0.5 * LENGTH;
    let (u1, u2) = (ux_at(model, &state, half), ux_at(model, &state, LENGTH));
    (u1 / half, (u2 - u1) / half)
}

#[test]
fn a_bimaterial_bar_in_tension_has_each_halfs_analytic_strain_under_every_solver() {
    let model = bar(STIFF, 0.0);
    let want = (TRACTION / SOFT, TRACTION / STIFF);
    for kind in SolverKind::ALL {
        let (soft, stiff) = strains(kind, &model);
        let tolerance = match kind {
            SolverKind::Pbd => continue,
            SolverKind::Xpbd => 2e-2,
            SolverKind::Vbd => 5e-3,
            _ => 1e-4,
        };
        let err = ((soft - want.0) / want.0)
            .abs()
            .max(((stiff - want.1) / want.1).abs());
        eprintln!(
            "{kind}: strains {soft:.6e} / {stiff:.6e} (analytic {:.6e} / {:.6e}), relative error {err:.2e}",
            want.0, want.1
        );
        assert!(err < tolerance, "{kind}: relative error {err:e}");
    }
}

#[test]
fn pbd_ignores_youngs_modulus_but_sees_each_regions_poisson_ratio() {
    let uniform = strains(SolverKind::Pbd, &bar(SOFT, 0.0));
    let stiff = strains(SolverKind::Pbd, &bar(STIFF, 0.0));
    // The same up to round-off (the energy's scale changes the rounding, nothing else).
    let same = |a: Real, b: Real| (a - b).abs() <= 1e-9 * a.abs();
    assert!(
        same(uniform.0, stiff.0) && same(uniform.1, stiff.1),
        "PBD's projection is invariant to the energy's scale: {uniform:?} against {stiff:?}"
    );
    let other_nu = strains(SolverKind::Pbd, &bar(SOFT, 0.45));
    eprintln!("pbd: strains {uniform:?} (E2 = E1 or 100 E1), {other_nu:?} (nu2 = 0.45)");
    assert!((other_nu.1 - uniform.1).abs() > 1e-3 * uniform.1.abs());
}

#[test]
fn the_stability_limit_is_the_stiffest_regions() {
    let soft = bar(SOFT, 0.0).elastic_critical_time_step();
    let mixed = bar(STIFF, 0.0).elastic_critical_time_step();
    // The wave speed grows tenfold with E (100 x): so does the highest frequency.
    let ratio = soft / mixed;
    assert!((ratio - 10.0).abs() < 1e-6, "ratio {ratio}");
}
