//! Where a Newton iteration of implicit Euler spends its time on case D (1617 triangles,
//! Neo-Hookean soft tissue, ten rigid bones, barrier contact with the ground and the debris),
//! one thread: `steps` frames of 1/90 s from rest at each Newton tolerance, then the time per
//! frame, the iterations per step and the time per iteration split into assembly (forces,
//! element tangents, their projection, the reduction to the free unknowns, the rigid bodies'
//! and contact's terms), the projection alone (timed apart over the same elements), the
//! numeric factorisation, the triangular solves and the line search.
//!
//! ```text
//! cargo run --release -p fem-scene --example newton_case_d [-- STEPS [TOLERANCE...]]
//! ```

use std::time::Instant;

use fem_core::energy::{AnyEnergy, Energy};
use fem_scene::build::{NoFiles, build_mesh, build_model, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::{ImplicitParams, ImplicitStepper, Model, NewtonParams, Stepper};

const FRAME: f64 = 1.0 / 90.0;

fn main() {
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let mut args = std::env::args().skip(1);
    let steps: usize = args.next().map_or(45, |a| a.parse().expect("a step count"));
    let tolerances: Vec<f64> = args.map(|a| a.parse().expect("a tolerance")).collect();
    let tolerances = if tolerances.is_empty() {
        vec![NewtonParams::default().tolerance]
    } else {
        tolerances
    };
    let scene = load_case("case-d", &[]).unwrap();
    let mesh = build_mesh(&scene, &NoFiles).unwrap();
    let model: Model<AnyEnergy> = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
    println!(
        "case D: {} triangles, {} frames of 1/90 s from rest, one thread",
        model.mesh().n_triangles(),
        steps
    );
    println!(
        "| tolerance | unknowns | ms a frame | iterations a step | ms an iteration | assembly | of which projection | factorisation | solve | line search |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for tolerance in tolerances {
        let params = ImplicitParams {
            dt: FRAME,
            damping: 20.0,
            newton: NewtonParams {
                tolerance,
                ..Default::default()
            },
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
            "| {tolerance:e} | {} | {:.2} | {:.1} | {} | {} | {} | {} | {} | {} |",
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
