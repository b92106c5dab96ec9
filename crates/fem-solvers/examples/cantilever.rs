//! Case A of the paper in one run: the 5 m x 1 m cantilever under gravity (left edge pinned,
//! E = 1000 Pa, nu = 0.3, 1 kg, dt = 1e-3 s, explicit symplectic Euler), once per energy, with
//! the tip's vertical displacement at frames 10, 50, 120 and 200 (one frame = 10 steps) beside
//! the paper's Table 1, and the wall time of the 2000 steps.
//!
//! Run: `cargo run --release -p fem-solvers --example cantilever [-- NX NY DAMPING]`
//! (defaults: 20 x 4 cells, damping 0 1/s). The paper gives neither its mesh, its damping nor
//! which tip node it tracked; this example tracks the bottom-right corner. The calibrated
//! reproduction of Table 1, with the sensitivity to each of those choices, belongs to the case
//! runner.

use std::time::Instant;

use fem_core::PlaneModel;
use fem_core::energy::{Energy, EnergyKind};
use fem_core::material::Material;
use fem_solvers::testing::{beam_mesh, cantilever, node_index};
use fem_solvers::{ExplicitParams, ExplicitStepper, State, Stepper};

/// Paper Table 1, tip vertical displacement in mm (downwards) at frames 10, 50, 120, 200.
const PAPER: [(&str, [f64; 4]); 3] = [
    ("stvk", [49.0, 1269.0, 1948.0, 246.0]),
    ("corotational", [49.0, 1270.0, 1880.0, 272.0]),
    ("neo-hookean", [49.0, 1271.0, 1865.0, 279.0]),
];
const FRAMES: [usize; 4] = [10, 50, 120, 200];
const STEPS_PER_FRAME: usize = 10;

fn arg(i: usize, default: f64) -> f64 {
    std::env::args()
        .nth(i)
        .map(|s| {
            s.parse().unwrap_or_else(|_| {
                eprintln!("error: argument {i} = `{s}` is not a number");
                std::process::exit(2)
            })
        })
        .unwrap_or(default)
}

fn main() {
    let (nx, ny, damping) = (arg(1, 20.0) as usize, arg(2, 4.0) as usize, arg(3, 0.0));
    let material = Material::new(1000.0, 0.3, 1.0).expect("case A material");
    let lame = material.lame(PlaneModel::PlaneStrain);
    println!(
        "case A: {nx} x {ny} cells ({} triangles), plane strain, damping {damping} 1/s, dt 1e-3 s",
        2 * nx * ny
    );
    println!("tip vertical displacement, mm (paper's Table 1 in brackets)");
    println!(
        "{:>14} {:>16} {:>16} {:>16} {:>16} {:>10}",
        "energy", "frame 10", "frame 50", "frame 120", "frame 200", "2000 steps"
    );
    for (name, paper) in PAPER {
        let kind: EnergyKind = name.parse().expect("known energy");
        let energy = kind.build(lame).expect("valid parameters");
        let mesh = match beam_mesh(nx, ny) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: mesh {nx} x {ny}: {e}");
                std::process::exit(2)
            }
        };
        let model = cantilever(mesh, energy).expect("the case A set-up is valid");
        let params = ExplicitParams {
            dt: 1e-3,
            damping,
            ..Default::default()
        };
        let mut stepper = match ExplicitStepper::new(&model, params) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(2)
            }
        };
        if let Some(w) = stepper.time_step_check().warning() {
            eprintln!("warning: {w}");
        }
        let tip = node_index(nx, 0, nx);
        let mut state = State::at_rest(&model);
        let mut row = Vec::new();
        let start = Instant::now();
        for step in 1..=2000 {
            if let Err(e) = stepper.step(&model, &mut state) {
                eprintln!("error: {}: {e}", model.energy().name());
                std::process::exit(1)
            }
            if step % STEPS_PER_FRAME == 0 && FRAMES.contains(&(step / STEPS_PER_FRAME)) {
                row.push(-1000.0 * state.displacement(&model, tip).y);
            }
        }
        let secs = start.elapsed().as_secs_f64();
        print!("{name:>14}");
        for (ours, theirs) in row.iter().zip(paper) {
            print!(" {:>16}", format!("{ours:.0} [{theirs:.0}]"));
        }
        println!(" {:>8.1} ms", 1e3 * secs);
    }
}
