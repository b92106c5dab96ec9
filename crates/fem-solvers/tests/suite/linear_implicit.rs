//! Linearly implicit Euler (`linear-implicit`): one linear solve of implicit Euler's Newton
//! system per step.
//!
//! - **One Newton iteration**: with the direct solver, a step from `(x_n, v_n)` equals the
//!   solution of `(M (1/h^2 + alpha/h) + K (1 + beta/h)) dx = M v_n / h + f(x_n)` assembled
//!   densely here from `fem_core::assembly` (projected stiffness, lumped masses) and solved by
//!   nalgebra, to round-off (1e-10 relative), with and without Rayleigh damping.
//! - **First order**: the error at a fixed time against implicit Euler at a tiny step halves
//!   with the step.
//! - **CG**: both preconditioners reach the direct step as their iterations grow.
//! - **Rigid regions and contact**: a body with a bone, dropped on the ground under a falling
//!   slab, never touches, stays finite and keeps its bone rigid, under every linear solver.
//! - **Threads**: the CG paths give the same bits on 1 and 4 threads (the battery checks the
//!   default, direct).
//! - **Bad input**: one-line errors naming `linear-implicit.<field>` and the value.

use fem_core::assembly::{Scratch, Stiffness, Tangent, populate_forces, populate_stiffness};
use fem_core::energy::{AnyEnergy, ElementEnergies, Energy, EnergyKind, NeoHookean};
use fem_core::math::{Real, Vec2};
use fem_core::structured::{RectangleParams, rectangle};
use fem_solvers::testing::assert_apart;
use fem_solvers::{
    Ground, ImplicitParams, ImplicitStepper, LinearImplicitParams, LinearImplicitStepper,
    LinearSolver, Model, NewtonParams, ObstacleMotion, SolverParams, State, Stepper,
};
use nalgebra::{DMatrix, DVector};

use crate::common::{bits, cantilever, lame};
use crate::rigid::rigidity_error;

/// A cantilever (10 x 2 cells, Neo-Hookean, E = 1e4 Pa) sagging and swinging: the state after
/// `steps` implicit Euler steps of 10 ms from rest, so every element is strained and every
/// free vertex moves.
fn swinging(steps: usize) -> (Model<NeoHookean>, State) {
    let model = cantilever(NeoHookean::new(lame(1e4)).unwrap(), 10, 2);
    let mut im = ImplicitStepper::new(
        &model,
        ImplicitParams {
            dt: 1e-2,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = State::at_rest(&model);
    for _ in 0..steps {
        im.step(&model, &mut state).unwrap();
    }
    (model, state)
}

/// The step `dx` of `(M (1/h^2 + alpha/h) + K (1 + beta/h)) dx = M v / h + f(x)` over the
/// free degrees of freedom (the kinematic vertices' rows and columns removed), assembled
/// densely and solved by nalgebra's Cholesky.
fn dense_step<E: Energy>(
    model: &Model<E>,
    state: &State,
    h: Real,
    alpha: Real,
    beta: Real,
) -> Vec<Vec2> {
    let n = model.mesh().n_vertices();
    let held: Vec<usize> = model.kinematics().vertices().collect();
    let free: Vec<usize> = (0..2 * n)
        .filter(|d| held.binary_search(&(d / 2)).is_err())
        .collect();
    let index = |d: usize| free.binary_search(&d).ok();
    let mut stiffness = Stiffness::new(model.mesh());
    let mut scratch = Scratch::new();
    populate_stiffness(
        model.mesh(),
        model.energies(),
        &state.x,
        Tangent::Projected,
        &mut stiffness,
        &mut scratch,
    );
    let mut forces = vec![Vec2::zeros(); n];
    populate_forces(
        model.mesh(),
        model.energies(),
        &state.x,
        &mut forces,
        &mut scratch,
    );
    let m = free.len();
    let mut a = DMatrix::<Real>::zeros(m, m);
    let mut b = DVector::<Real>::zeros(m);
    for (r, c, k) in stiffness.matrix.triplets() {
        if let (Some(i), Some(j)) = (index(r), index(c)) {
            a[(i, j)] += k * (1.0 + beta / h);
        }
    }
    for (i, &d) in free.iter().enumerate() {
        let (v, axis) = (d / 2, d % 2);
        let mass = model.masses()[v];
        a[(i, i)] += mass * (1.0 / (h * h) + alpha / h);
        b[i] = mass * state.v[v][axis] / h + forces[v][axis] + mass * model.gravity()[axis];
    }
    let solution = a.cholesky().expect("the dense matrix is SPD").solve(&b);
    let mut dx = vec![Vec2::zeros(); n];
    for (i, &d) in free.iter().enumerate() {
        dx[d / 2][d % 2] = solution[i];
    }
    dx
}

/// The largest vertex distance between `a` and `b` over the largest vertex length of `b`.
fn relative(a: &[Vec2], b: &[Vec2]) -> Real {
    let d = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    d / b.iter().map(|p| p.norm()).fold(0.0, Real::max)
}

/// Numbers in scientific notation, for messages.
fn sci(v: &[Real]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.2e}")).collect();
    format!("[{}]", parts.join(", "))
}

fn params(dt: Real) -> LinearImplicitParams {
    LinearImplicitParams {
        dt,
        ..Default::default()
    }
}

/// One step of `params` from `state`: the displacement `x_{n+1} - x_n` and the new state.
fn one_step<E: Energy>(
    model: &Model<E>,
    state: &State,
    params: LinearImplicitParams,
) -> (Vec<Vec2>, State) {
    let mut s = LinearImplicitStepper::new(model, params).unwrap();
    let mut next = state.clone();
    s.step(model, &mut next).unwrap();
    let dx = next.x.iter().zip(&state.x).map(|(a, b)| a - b).collect();
    (dx, next)
}

/// With the direct solver a step is one Newton iteration of implicit Euler from the step's
/// start: the same `dx` as the dense oracle to round-off (measured 2.1e-14 to 4.5e-14 relative),
/// with and without Rayleigh damping, and `v_{n+1} = dx / h`.
#[test]
fn a_direct_step_is_one_newton_iteration_from_the_start() {
    let (model, state) = swinging(7);
    let h = 1e-2;
    for (alpha, beta) in [(0.0, 0.0), (2.0, 0.0), (0.0, 1e-2), (3.0, 5e-3)] {
        let p = LinearImplicitParams {
            rayleigh_mass: alpha,
            rayleigh_stiffness: beta,
            ..params(h)
        };
        let (dx, next) = one_step(&model, &state, p);
        let want = dense_step(&model, &state, h, alpha, beta);
        let err = relative(&dx, &want);
        eprintln!("alpha {alpha}, beta {beta}: dx off the dense oracle by {err:.2e} (relative)");
        assert!(err < 1e-10, "alpha {alpha}, beta {beta}: {err:e}");
        let v: Vec<Vec2> = want.iter().map(|d| d / h).collect();
        assert!(relative(&next.v, &v) < 1e-10);
    }
    // Damping slows the step: more of it, a shorter step (the load is the same).
    let norm = |d: &[Vec2]| d.iter().map(|p| p.norm_squared()).sum::<Real>().sqrt();
    let plain = norm(&one_step(&model, &state, params(h)).0);
    let damped = norm(
        &one_step(
            &model,
            &state,
            LinearImplicitParams {
                rayleigh_mass: 3.0,
                rayleigh_stiffness: 5e-3,
                ..params(h)
            },
        )
        .0,
    );
    assert!(damped < plain, "{damped} >= {plain}");
}

/// A step's report: CG's iterations (1 for the direct solver), the norm of the implicit
/// Euler gradient at the step's end, which Newton would drive to zero and which one Newton
/// iteration leaves at about the square of the first.
#[test]
fn the_report_gives_the_residual_of_the_implicit_euler_step() {
    let (model, state) = swinging(7);
    let mut s = LinearImplicitStepper::new(&model, params(1e-2)).unwrap();
    let mut next = state.clone();
    let r = s.step(&model, &mut next).unwrap();
    let last = s.last_linear();
    assert_eq!(r.iterations, 1);
    assert_eq!(r.residual, last.residual);
    assert_eq!(last.step_fraction, 1.0);
    assert!(last.factorised);
    eprintln!(
        "residual {:.3e} N at the start, {:.3e} N at the end",
        last.start_residual, last.residual
    );
    assert!(last.residual > 0.0 && last.residual < 5e-2 * last.start_residual);
}

/// First order as dt -> 0: the largest vertex distance at t = 0.32 s to implicit Euler at
/// dt = 0.32 s / 8192 (Newton to 1e-12) halves with the step: 7.63, 4.19, 2.19 and 1.08 mm at
/// dt = 5, 2.5, 1.25 and 0.625 ms, ratios 1.82, 1.91, 2.02 (approaching 2 from below).
#[test]
fn converges_at_first_order_as_dt_halves() {
    let model = cantilever(NeoHookean::new(lame(1e4)).unwrap(), 10, 2);
    let t_end = 0.32;
    let run = |stepper: &mut dyn FnMut(&mut State), steps: usize| {
        let mut state = State::at_rest(&model);
        for _ in 0..steps {
            stepper(&mut state);
        }
        state
    };
    let fine = 8192;
    let mut reference = ImplicitStepper::new(
        &model,
        ImplicitParams {
            dt: t_end / fine as Real,
            newton: NewtonParams {
                tolerance: 1e-12,
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let reference = run(
        &mut |s: &mut State| {
            reference.step(&model, s).unwrap();
        },
        fine,
    );
    let mut errors = Vec::new();
    for steps in [64usize, 128, 256, 512] {
        let mut s = LinearImplicitStepper::new(&model, params(t_end / steps as Real)).unwrap();
        let state = run(
            &mut |st: &mut State| {
                s.step(&model, st).unwrap();
            },
            steps,
        );
        let err = state
            .x
            .iter()
            .zip(&reference.x)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        errors.push(err);
    }
    let ratios: Vec<Real> = errors.windows(2).map(|w| w[0] / w[1]).collect();
    eprintln!("errors {} m, ratios {ratios:.3?}", sci(&errors));
    for r in ratios {
        assert!(r >= 1.8, "error ratio {r} when halving dt");
    }
}

/// The displacement of one step from `late` by a stepper that first stepped from `early`
/// (so a Cholesky preconditioner refreshed every 1000 steps is `early`'s matrix).
fn stale_step<E: Energy>(
    model: &Model<E>,
    early: &State,
    late: &State,
    params: LinearImplicitParams,
) -> Vec<Vec2> {
    let mut s = LinearImplicitStepper::new(model, params).unwrap();
    s.step(model, &mut early.clone()).unwrap();
    let mut next = late.clone();
    s.step(model, &mut next).unwrap();
    next.x.iter().zip(&late.x).map(|(a, b)| a - b).collect()
}

/// CG reaches the direct step as its iterations grow, preconditioned by the diagonal or by a
/// Cholesky factor of an older matrix (the swinging cantilever five steps earlier): the
/// distance to the direct step falls to below 1e-8 (relative) and never grows threefold from
/// one count to the next (CG minimises the error in the energy norm, not in the 2-norm
/// measured here). Measured on 20 x 4 cells (200 unknowns), dt = 10 ms: Jacobi 6.2e-1,
/// 5.4e-2, 8.4e-3, 7.1e-5, 1.2e-7, 3.5e-14 after 1, 5, 10, 50, 100, 200 iterations; the
/// stale Cholesky factor 7.2e-3, 1.4e-3, 8.4e-6, 5.4e-9, 7.4e-14 after 1, 2, 3, 5, 10.
#[test]
fn cg_reaches_the_direct_step_as_iterations_grow() {
    let model = cantilever(NeoHookean::new(lame(1e4)).unwrap(), 20, 4);
    let mut im = ImplicitStepper::new(
        &model,
        ImplicitParams {
            dt: 1e-2,
            ..Default::default()
        },
    )
    .unwrap();
    let mut early = State::at_rest(&model);
    for _ in 0..5 {
        im.step(&model, &mut early).unwrap();
    }
    let mut late = early.clone();
    for _ in 0..5 {
        im.step(&model, &mut late).unwrap();
    }
    let h = 1e-2;
    let direct = one_step(&model, &late, params(h)).0;
    let cases = [
        (
            LinearSolver::CgJacobi,
            &[1usize, 2, 5, 10, 20, 50, 100, 200, 400][..],
        ),
        (LinearSolver::CgCholesky, &[1usize, 2, 3, 5, 10, 20][..]),
    ];
    for (solver, counts) in cases {
        let mut gaps = Vec::new();
        for &n in counts {
            let p = LinearImplicitParams {
                linear_solver: solver,
                cg_iterations: n,
                cg_tolerance: 0.0,
                refresh: 1000,
                ..params(h)
            };
            gaps.push(relative(&stale_step(&model, &early, &late, p), &direct));
        }
        eprintln!(
            "{solver:?}: after {counts:?} iterations, {} from the direct step",
            sci(&gaps)
        );
        for w in gaps.windows(2) {
            assert!(
                w[1] <= 3.0 * w[0] || w[1] < 1e-12,
                "{solver:?}: {}",
                sci(&gaps)
            );
        }
        assert!(*gaps.last().unwrap() < 1e-8, "{solver:?}: {}", sci(&gaps));
        assert!(gaps[0] > 1e-6, "{solver:?}: one iteration is not the solve");
    }
    // A tolerance stops CG early: the iterations reported are those taken.
    let mut s = LinearImplicitStepper::new(
        &model,
        LinearImplicitParams {
            linear_solver: LinearSolver::CgJacobi,
            cg_iterations: 1000,
            cg_tolerance: 1e-6,
            ..params(h)
        },
    )
    .unwrap();
    let r = s.step(&model, &mut late.clone()).unwrap();
    assert!(r.iterations > 1 && r.iterations < 1000, "{}", r.iterations);
    assert!(s.last_linear().cg_residual <= 1e-6);
    // A refreshed Cholesky preconditioner is the exact inverse: one iteration.
    let mut s = LinearImplicitStepper::new(
        &model,
        LinearImplicitParams {
            linear_solver: LinearSolver::CgCholesky,
            refresh: 1,
            ..params(h)
        },
    )
    .unwrap();
    let mut next = late.clone();
    let r = s.step(&model, &mut next).unwrap();
    assert_eq!(r.iterations, 1);
    let dx: Vec<Vec2> = next.x.iter().zip(&late.x).map(|(a, b)| a - b).collect();
    assert!(relative(&dx, &direct) < 1e-10);
}

/// A 1 m x 0.3 m Neo-Hookean body (E = 1e5 Pa, 100 kg/m^2) with a rigid bone in its middle,
/// 1 cm above the ground, and a 3 kg slab 1 cm above it, falling; standard gravity.
fn body_with_a_bone() -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 0.01],
        ..RectangleParams::new(1.0, 0.3, 20, 6)
    })
    .unwrap();
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
            u32::from(c.x > 0.3 && c.x < 0.7 && c.y > 0.1 && c.y < 0.22)
        })
        .collect();
    let energy = EnergyKind::NeoHookean.build(lame(1e5)).unwrap();
    let energies = ElementEnergies::new(vec![energy.clone(), energy], tags).unwrap();
    let masses = mesh
        .lumped_masses_from_densities(&vec![100.0; mesh.n_triangles()])
        .unwrap();
    let mut model = Model::with_regions(mesh, energies, masses).unwrap();
    model.make_rigid(1, 100.0).unwrap();
    model.set_standard_gravity();
    model.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    model
        .add_obstacle(
            &[
                Vec2::new(0.35, 0.32),
                Vec2::new(0.65, 0.32),
                Vec2::new(0.65, 0.42),
                Vec2::new(0.35, 0.42),
            ],
            ObstacleMotion::Dynamic {
                mass: 3.0,
                rotates: true,
            },
        )
        .unwrap();
    model
}

/// The body with its bone lands on the ground and the slab lands on it, at 1/90 s for 1.5 s,
/// under each linear solver (and with Rayleigh damping): every state apart (the brute-force
/// oracle), finite, the bone rigid to 1e-12 m; at the end the body rests on the ground within
/// the barrier's reach and the slab on the body.
#[test]
fn a_body_with_a_bone_and_a_slab_falls_on_the_ground_and_never_touches() {
    let model = body_with_a_bone();
    assert_eq!(model.rigid_bodies().len(), 1);
    let dt = 1.0 / 90.0;
    let settings = [
        ("direct", params(dt)),
        (
            "cg-jacobi",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgJacobi,
                cg_iterations: 200,
                ..params(dt)
            },
        ),
        (
            "cg-cholesky",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgCholesky,
                ..params(dt)
            },
        ),
        (
            "direct, Rayleigh damping",
            LinearImplicitParams {
                rayleigh_mass: 1.0,
                rayleigh_stiffness: 1e-3,
                ..params(dt)
            },
        ),
    ];
    for (name, p) in settings {
        let mut s = LinearImplicitStepper::new(&model, p).unwrap();
        let mut state = State::at_rest(&model);
        let (mut lowest, mut shortened, mut iterations) = (Real::INFINITY, 0, 0);
        for _ in 0..135 {
            let r = s
                .step(&model, &mut state)
                .unwrap_or_else(|e| panic!("{name}: step {}: {e}", state.step));
            lowest = lowest.min(assert_apart(&model, &state));
            assert!(r.residual.is_finite());
            assert!(
                rigidity_error(&model, &state, 0) < 1e-12,
                "{name}: the bone deformed"
            );
            shortened += usize::from(s.last_linear().step_fraction < 1.0);
            iterations += r.iterations;
        }
        let bottom = state.x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
        let slab = state.bodies[0].position.y;
        let speed = state.v.iter().map(|v| v.norm()).fold(0.0, Real::max);
        eprintln!(
            "{name}: lowest vertex {lowest:.2e} m over the run, {bottom:.2e} m at the end; slab centre {slab:.4} m; fastest vertex {speed:.2e} m/s; {shortened} steps shortened; {iterations} iterations"
        );
        assert!(bottom > 0.0 && bottom < 1e-3, "{name}: rests on the ground");
        // The slab (0.1 m thick) rests on the body's top (0.31 m at rest, a little lower
        // under its weight).
        assert!(slab > 0.33 && slab < 0.37, "{name}: slab at {slab}");
        assert!(speed < 0.05, "{name}: still moving at {speed} m/s");
    }
}

/// The CG paths give the same bits on 1 and 4 threads, on a mesh whose parallel assembly
/// splits into many chunks, with a ground in the barrier's reach.
#[test]
fn cg_steps_are_bit_identical_on_1_and_4_threads() {
    let mut model = cantilever(NeoHookean::new(lame(1e3)).unwrap(), 160, 32);
    model.set_ground(Some(Ground::horizontal(-0.0005))).unwrap();
    for solver in [LinearSolver::CgJacobi, LinearSolver::CgCholesky] {
        let run_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let p = LinearImplicitParams {
                    linear_solver: solver,
                    refresh: 2,
                    ..params(1e-3)
                };
                let mut s = LinearImplicitStepper::new(&model, p).unwrap();
                let mut state = State::at_rest(&model);
                for _ in 0..3 {
                    s.step(&model, &mut state).unwrap();
                }
                state
            })
        };
        let (one, four) = (run_on(1), run_on(4));
        assert!(
            bits(&one.x) == bits(&four.x),
            "{solver:?}: positions differ"
        );
        assert!(
            bits(&one.v) == bits(&four.v),
            "{solver:?}: velocities differ"
        );
    }
}

/// Bad parameters end in one line naming `linear-implicit.<field>` and the value.
#[test]
fn bad_parameters_are_one_line_errors_naming_the_field() {
    let model = cantilever(NeoHookean::new(lame(1e4)).unwrap(), 10, 2);
    let cases = [
        (
            LinearImplicitParams {
                rayleigh_mass: -1.0,
                ..Default::default()
            },
            "linear-implicit.rayleigh_mass = -1",
        ),
        (
            LinearImplicitParams {
                rayleigh_stiffness: -0.5,
                ..Default::default()
            },
            "linear-implicit.rayleigh_stiffness = -0.5",
        ),
        (
            LinearImplicitParams {
                cg_iterations: 0,
                ..Default::default()
            },
            "linear-implicit.cg_iterations = 0",
        ),
        (
            LinearImplicitParams {
                cg_tolerance: 1.0,
                ..Default::default()
            },
            "linear-implicit.cg_tolerance = 1",
        ),
        (
            LinearImplicitParams {
                refresh: 0,
                ..Default::default()
            },
            "linear-implicit.refresh = 0",
        ),
        (
            LinearImplicitParams {
                dt: 0.0,
                ..Default::default()
            },
            "linear-implicit.dt = 0",
        ),
    ];
    for (p, want) in cases {
        let e = LinearImplicitStepper::new(&model, p)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(want), "{e}");
        assert!(!e.contains('\n'), "{e}");
        // Through the registry, with the scene's prefix.
        let e = SolverParams::LinearImplicit(p)
            .validate_as("solver")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&want.replace("linear-implicit", "solver")),
            "{e}"
        );
    }
}

/// An unknown linear solver's name is one line listing the valid ones.
#[cfg(feature = "serde")]
#[test]
fn an_unknown_linear_solver_names_the_valid_ones() {
    let e = SolverParams::deserialize_as(
        fem_solvers::SolverKind::LinearImplicit,
        &serde_json::json!({"linear_solver": "lu"}),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown variant `lu`, expected one of `direct`, `cg-jacobi`, `cg-cholesky`"),
        "{e}"
    );
    assert!(!e.contains('\n'), "{e}");
}
