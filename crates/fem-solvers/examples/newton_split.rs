//! The cost of one Newton iteration of the implicit stepper, split into assembly (forces,
//! projected stiffness, reduction to the free degrees of freedom), numeric Cholesky
//! factorisation, triangular solves and line search, on the case A beam at about 16k, 64k and
//! 256k triangles (Neo-Hookean, E = 1000 Pa, dt = 1 ms, three steps from rest under gravity).
//!
//! ```text
//! taskset -c 1 cargo run --release -p fem-solvers --example newton_split
//! cargo run --release -p fem-solvers --example newton_split -- 16000 64000
//! cargo run --release -p fem-solvers --example newton_split -- --averaged-pressure 16000
//! ```
//!
//! `--averaged-pressure`: nu = 0.49 and the averaged nodal pressure triangle (its wider stencil
//! fills the factor more); `--nu049`: nu = 0.49 on plain triangles, to compare.
//!
//! The symbolic analysis (AMD ordering, elimination tree, supernodes) is timed separately: it
//! runs once, when the stepper is built.

use std::time::Instant;

use fem_core::PlaneModel;
use fem_core::energy::NeoHookean;
use fem_core::material::Material;
use fem_solvers::testing::{beam_cells_for, beam_mesh, cantilever};
use fem_solvers::{ImplicitParams, ImplicitStepper, State, Stepper};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let averaged = args.iter().any(|a| a == "--averaged-pressure");
    let nu = if averaged || args.iter().any(|a| a == "--nu049") {
        0.49
    } else {
        0.3
    };
    let sizes: Vec<usize> = (args.iter())
        .filter(|a| !a.starts_with("--"))
        .map(|a| a.parse().expect("triangle counts, e.g. 16000 64000"))
        .collect();
    let sizes = if sizes.is_empty() {
        vec![16_000, 64_000, 256_000]
    } else {
        sizes
    };
    let lame = Material::new(1000.0, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    println!(
        "| triangles | unknowns | symbolic (ms, once) | iterations | assembly (ms/it) | factorisation (ms/it) | solve (ms/it) | line search (ms/it) | total (ms/it) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for size in sizes {
        let (nx, ny) = beam_cells_for(size);
        let mut model =
            cantilever(beam_mesh(nx, ny).unwrap(), NeoHookean::new(lame).unwrap()).unwrap();
        model.set_averaged_pressure(averaged).unwrap();
        let start = Instant::now();
        let mut stepper = ImplicitStepper::new(
            &model,
            ImplicitParams {
                dt: 1e-3,
                ..Default::default()
            },
        )
        .unwrap();
        let symbolic = start.elapsed().as_secs_f64();
        let mut state = State::at_rest(&model);
        let (mut it, mut asm, mut fac, mut sol, mut ls) = (0, 0.0, 0.0, 0.0, 0.0);
        let wall = Instant::now();
        for _ in 0..3 {
            stepper.step(&model, &mut state).unwrap();
            let r = stepper.last_newton();
            it += r.iterations;
            asm += r.assembly_seconds;
            fac += r.factorisation_seconds;
            sol += r.solve_seconds;
            ls += r.line_search_seconds;
        }
        let total = wall.elapsed().as_secs_f64();
        let per = |s: f64| 1e3 * s / it.max(1) as f64;
        println!(
            "| {} | {} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            model.mesh().n_triangles(),
            stepper.unknowns(),
            1e3 * symbolic,
            it,
            per(asm),
            per(fac),
            per(sol),
            per(ls),
            per(total)
        );
    }
}
