//! Criterion bench of implicit Euler on case D (1617 triangles, Neo-Hookean soft tissue, ten
//! rigid bones, barrier contact with the ground and the debris), one thread:
//! `case-d-implicit/frame/...` is one 1/90 s frame from a settled state (30 frames in; restarted
//! every 50), under the default stopping rule (velocity tolerance 1e-3 m/s) and converged
//! (Newton's tolerance 1e-8 alone).
//!
//! Before it, the bench prints where the time goes over case D's whole run (135 frames from
//! rest) under each rule: ms a frame, Newton iterations a step and ms an iteration split into
//! assembly (forces, element tangents and their projection, the reduction to the free unknowns,
//! the rigid bodies' and contact's terms), the projection alone (timed apart over the same
//! elements: the projected tangents against the exact ones), the numeric factorisation, the
//! triangular solves and the line search.
//!
//! `cargo bench -p fem-scene --bench newton`

use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use fem_core::energy::{AnyEnergy, Energy};
use fem_scene::build::{NoFiles, build_mesh, build_model, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::implicit::VELOCITY_TOLERANCE;
use fem_solvers::{ImplicitParams, ImplicitStepper, Model, NewtonParams, Stepper};

const FRAME: f64 = 1.0 / 90.0;

fn split_table(settings: &[(f64, f64)], steps: usize) {
    let scene = load_case("case-d", &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let model: Model<AnyEnergy> = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
    println!(
        "case D: {} triangles, {} frames of 1/90 s from rest, one thread",
        model.mesh().n_triangles(),
        steps
    );
    println!(
        "| tolerance | velocity tolerance (m/s) | unknowns | ms a frame | iterations a step | ms an iteration | assembly | of which projection | factorisation | solve | line search |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for &(tolerance, velocity_tolerance) in settings {
        let params = ImplicitParams {
            dt: FRAME,
            damping: 20.0,
            velocity_tolerance,
            newton: NewtonParams {
                tolerance,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut stepper = ImplicitStepper::new(&model, params).unwrap();
        let mut state = initial_state(&scene, &model).unwrap();
        let (mut iterations, mut a, mut f, mut s, mut l) = (0, 0.0, 0.0, 0.0, 0.0);
        let mut projection = 0.0;
        let start = Instant::now();
        for _ in 0..steps {
            stepper.step(&model, &mut state).unwrap();
            let r = stepper.last_newton();
            iterations += r.iterations;
            a += r.assembly_seconds;
            f += r.factorisation_seconds;
            s += r.solve_seconds;
            l += r.line_search_seconds;
        }
        let wall = start.elapsed().as_secs_f64();
        // The projection alone: every element's projected tangent at the final state, against
        // the exact tangent, times the factorisations (one per iteration).
        let x = &state.x;
        let energies = model.elastic_energies();
        let mesh = model.elastic_mesh();
        let gradients: Vec<_> = (0..mesh.n_triangles())
            .map(|t| mesh.elements()[t].deformation_gradient(mesh.gather(t, x)))
            .collect();
        let reps = 20;
        let timed = |projected: bool| {
            let start = Instant::now();
            let mut sink = 0.0;
            for _ in 0..reps {
                for (t, f) in gradients.iter().enumerate() {
                    let e = &energies.energies()[energies.tag(t) as usize];
                    let d = if projected {
                        e.dpk1_projected(f)
                    } else {
                        e.dpk1(f)
                    };
                    sink += d[(0, 0)];
                }
            }
            std::hint::black_box(sink);
            start.elapsed().as_secs_f64() / reps as f64
        };
        let per_pass = (timed(true) - timed(false)).max(0.0);
        projection += per_pass * iterations as f64;
        let it = iterations.max(1) as f64;
        let ms = |x: f64| format!("{:.3}", 1e3 * x / it);
        println!(
            "| {tolerance:e} | {velocity_tolerance:e} | {} | {:.2} | {:.1} | {} | {} | {} | {} | {} | {} |",
            stepper.unknowns(),
            1e3 * wall / steps as f64,
            it / steps as f64,
            ms(wall),
            ms(a),
            ms(projection),
            ms(f),
            ms(s),
            ms(l)
        );
    }
}

fn bench(c: &mut Criterion) {
    // One thread: the global pool, before anything uses it.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    split_table(&[(1e-8, VELOCITY_TOLERANCE), (1e-8, 0.0)], 135);
    let scene = load_case("case-d", &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let model: Model<AnyEnergy> = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
    let params = |velocity_tolerance: f64| ImplicitParams {
        dt: FRAME,
        damping: 20.0,
        velocity_tolerance,
        ..Default::default()
    };
    let mut start = initial_state(&scene, &model).unwrap();
    let mut s = ImplicitStepper::new(&model, params(0.0)).unwrap();
    for _ in 0..30 {
        s.step(&model, &mut start).unwrap();
    }
    let mut group = c.benchmark_group("case-d-implicit");
    group.sample_size(10);
    group.measurement_time(std::time::Duration::from_secs(3));
    group.warm_up_time(std::time::Duration::from_millis(500));
    for (name, v) in [
        (
            format!("velocity-{VELOCITY_TOLERANCE:e}"),
            VELOCITY_TOLERANCE,
        ),
        ("converged-1e-8".to_owned(), 0.0),
    ] {
        let mut s = ImplicitStepper::new(&model, params(v)).unwrap();
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

criterion_group!(newton, bench);
criterion_main!(newton);
