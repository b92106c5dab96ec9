//! Criterion bench of linearly implicit Euler on case D (1617 triangles, Neo-Hookean soft
//! tissue, ten rigid bones, barrier contact with the ground and the debris) at 1/90 s, one
//! thread: `case-d-linear-implicit/frame/{direct,cg-jacobi,cg-cholesky}` is one frame from a
//! settled state (30 frames in; restarted every 50) with each linear solver at its defaults
//! (CG: 25 iterations, the Cholesky preconditioner refreshed every 10 steps).
//!
//! Before it, the bench prints, over case D's whole run (135 frames from rest) for each linear
//! solver and against implicit Euler (Newton at the scene's settings): ms a frame and its split
//! (assembly, factorisation, solve), CG iterations and factorisations a step, the implicit
//! Euler residual the step leaves (the norm of `grad Phi` at the step's end, as a fraction of
//! the body's weight), and where the shin probe and the debris end.
//!
//! `cargo bench -p fem-scene --bench linear`

use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};

use fem_core::energy::AnyEnergy;
use fem_core::math::Vec2;
use fem_scene::build::{NoFiles, build_mesh, build_model, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::{
    ImplicitStepper, LinearImplicitParams, LinearImplicitStepper, LinearSolver, Model, SolverKind,
    SolverParams, State, Stepper,
};

const FRAME: f64 = 1.0 / 90.0;

fn split_table(steps: usize) {
    let scene = load_case("case-d", &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let model: Model<AnyEnergy> = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
    // The scene's shin probe: the vertex nearest to its point at rest.
    let probe = scene
        .scene
        .probes
        .iter()
        .find(|p| p.name == "shin")
        .unwrap();
    let at = Vec2::new(probe.point[0], probe.point[1]);
    let shin = (0..model.mesh().n_vertices())
        .min_by(|&a, &b| {
            let da = (model.mesh().vertices()[a] - at).norm();
            let db = (model.mesh().vertices()[b] - at).norm();
            da.total_cmp(&db)
        })
        .unwrap();
    let weight: f64 = model.masses().iter().sum::<f64>() * model.gravity().norm();
    let unknowns = LinearImplicitStepper::new(&model, LinearImplicitParams::default())
        .unwrap()
        .unknowns();
    println!(
        "case D: {} triangles, {unknowns} unknowns, {} frames of 1/90 s from rest, one thread (weight {weight:.0} N)",
        model.mesh().n_triangles(),
        steps
    );
    println!(
        "| solver | ms a frame | assembly | factorisation | solve | CG iterations a step | factorisations | residual / weight (mean, last) | shin uy at the end (mm) | debris y (m) | smallest gap (mm) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    // The scene's own parameters for the linearly implicit solver (its damping, 20/s).
    let base = match scene.scene.solver.params_of(SolverKind::LinearImplicit) {
        SolverParams::LinearImplicit(p) => p,
        _ => unreachable!(),
    };
    let settings = [
        ("direct", base),
        (
            "cg-jacobi, 25 iterations",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgJacobi,
                ..base
            },
        ),
        (
            "cg-jacobi, 200 iterations",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgJacobi,
                cg_iterations: 200,
                ..base
            },
        ),
        (
            "cg-cholesky, refresh 10",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgCholesky,
                ..base
            },
        ),
        (
            "cg-cholesky, refresh 1",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgCholesky,
                refresh: 1,
                ..base
            },
        ),
        (
            "cg-cholesky, refresh 30",
            LinearImplicitParams {
                linear_solver: LinearSolver::CgCholesky,
                refresh: 30,
                ..base
            },
        ),
    ];
    for (name, params) in settings {
        let mut stepper = LinearImplicitStepper::new(&model, params).unwrap();
        let mut state = initial_state(&scene, &model).unwrap();
        let (mut iterations, mut factorisations, mut residual) = (0, 0, 0.0);
        let (mut a, mut f, mut s) = (0.0, 0.0, 0.0);
        let mut gap = f64::INFINITY;
        let start = Instant::now();
        let mut last = 0.0;
        for _ in 0..steps {
            let r = stepper.step(&model, &mut state).unwrap();
            let l = stepper.last_linear();
            iterations += r.iterations;
            factorisations += usize::from(l.factorised);
            residual += r.residual;
            last = r.residual;
            a += l.assembly_seconds;
            f += l.factorisation_seconds;
            s += l.solve_seconds;
            gap = gap.min(stepper.min_distance());
        }
        let wall = start.elapsed().as_secs_f64();
        row(
            name,
            &model,
            &state,
            shin,
            wall / steps as f64,
            [a, f, s].map(|x| x / steps as f64),
            iterations as f64 / steps as f64,
            factorisations,
            (residual / steps as f64 / weight, last / weight),
            gap,
        );
    }
    // Implicit Euler (Newton) with the scene's parameters, for comparison.
    let params = match scene.scene.solver.params_of(SolverKind::Implicit) {
        SolverParams::Implicit(p) => p,
        _ => unreachable!(),
    };
    let mut stepper = ImplicitStepper::new(&model, params).unwrap();
    let mut state = initial_state(&scene, &model).unwrap();
    let (mut iterations, mut residual, mut last) = (0, 0.0, 0.0);
    let (mut a, mut f, mut s) = (0.0, 0.0, 0.0);
    let mut gap = f64::INFINITY;
    let start = Instant::now();
    for _ in 0..steps {
        let r = stepper.step(&model, &mut state).unwrap();
        let n = stepper.last_newton();
        iterations += r.iterations;
        residual += r.residual;
        last = r.residual;
        a += n.assembly_seconds + n.line_search_seconds;
        f += n.factorisation_seconds;
        s += n.solve_seconds;
        gap = gap.min(stepper.min_distance());
    }
    let wall = start.elapsed().as_secs_f64();
    row(
        "implicit (Newton)",
        &model,
        &state,
        shin,
        wall / steps as f64,
        [a, f, s].map(|x| x / steps as f64),
        iterations as f64 / steps as f64,
        iterations,
        (residual / steps as f64 / weight, last / weight),
        gap,
    );
}

#[allow(clippy::too_many_arguments)]
fn row(
    name: &str,
    model: &Model<AnyEnergy>,
    state: &State,
    shin: usize,
    frame: f64,
    [a, f, s]: [f64; 3],
    iterations: f64,
    factorisations: usize,
    (mean, last): (f64, f64),
    gap: f64,
) {
    println!(
        "| {name} | {:.2} | {:.2} | {:.2} | {:.2} | {iterations:.1} | {factorisations} | {mean:.1e}, {last:.1e} | {:.2} | {:.4} | {:.3} |",
        1e3 * frame,
        1e3 * a,
        1e3 * f,
        1e3 * s,
        1e3 * state.displacement(model, shin).y,
        state.bodies[0].position.y,
        1e3 * gap,
    );
}

fn bench(c: &mut Criterion) {
    // One thread: the global pool, before anything uses it.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    split_table(135);
    let scene = load_case("case-d", &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let model: Model<AnyEnergy> = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
    let base = match scene.scene.solver.params_of(SolverKind::LinearImplicit) {
        SolverParams::LinearImplicit(p) => LinearImplicitParams { dt: FRAME, ..p },
        _ => unreachable!(),
    };
    let mut start = initial_state(&scene, &model).unwrap();
    let mut s = LinearImplicitStepper::new(&model, base).unwrap();
    for _ in 0..30 {
        s.step(&model, &mut start).unwrap();
    }
    let mut group = c.benchmark_group("case-d-linear-implicit");
    group.sample_size(10);
    group.measurement_time(std::time::Duration::from_secs(3));
    group.warm_up_time(std::time::Duration::from_millis(500));
    for (name, linear_solver) in [
        ("direct", LinearSolver::Direct),
        ("cg-jacobi", LinearSolver::CgJacobi),
        ("cg-cholesky", LinearSolver::CgCholesky),
    ] {
        let params = LinearImplicitParams {
            linear_solver,
            ..base
        };
        let mut s = LinearImplicitStepper::new(&model, params).unwrap();
        let mut state = start.clone();
        group.bench_function(format!("frame/{name}"), |b| {
            b.iter(|| {
                if state.step >= start.step + 50 {
                    state = start.clone();
                }
                s.step(&model, &mut state).unwrap();
            })
        });
    }
    group.finish();
}

criterion_group!(linear, bench);
criterion_main!(linear);
