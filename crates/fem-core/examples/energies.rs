//! Compare the five energies on the loadings that tell them apart, and time force assembly on
//! the case A beam. This is the workspace's first demonstration; the case runner (`fem2d`)
//! will replace it as the main command.
//!
//! Run: `cargo run --release -p fem-core --example energies`
//!
//! Printed: (1) uniaxial stretch and compression in plane strain: the stress P_xx and the
//! lateral stress P_yy per energy, against linear elasticity; (2) a rigid rotation, where a
//! correct energy feels no stress and linear elasticity does; (3) force assembly throughput
//! (element evaluations per second) on a 16k-triangle beam, serial.

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use common::{Diagonal, rectangle};

use fem_core::assembly::populate_forces_serial;
use fem_core::dispatch_energy;
use fem_core::energy::{Energy, EnergyKind};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{Mat2, Vec2, rotation};

fn main() {
    let material = Material::new(1000.0, 0.3, 1.0).expect("case A material is valid");
    let plane = PlaneModel::PlaneStrain;
    let lame = material.lame(plane);
    println!(
        "material: E = {} Pa, nu = {}, {plane}: mu = {:.2} Pa, lambda = {:.2} Pa\n",
        material.youngs_modulus(),
        material.poisson_ratio(),
        lame.mu(),
        lame.lambda()
    );
    let energies: Vec<_> = EnergyKind::ALL
        .iter()
        .map(|k| k.build(lame).expect("valid parameters"))
        .collect();

    println!("uniaxial strain F = diag(s, 1): P_xx / P_yy in Pa");
    print!("{:>8}", "s");
    for e in &energies {
        print!("{:>22}", e.name());
    }
    println!();
    for s in [0.6, 0.8, 0.95, 1.0, 1.05, 1.2, 1.5] {
        print!("{s:>8.2}");
        let f = Mat2::new(s, 0.0, 0.0, 1.0);
        for e in &energies {
            let p = e.pk1(&f);
            print!("{:>22}", format!("{:.1} / {:.1}", p[(0, 0)], p[(1, 1)]));
        }
        println!();
    }

    println!("\nrigid rotation by 60 degrees: |P| in Pa (0 for a frame-indifferent energy)");
    let q = rotation(std::f64::consts::FRAC_PI_3);
    for e in &energies {
        println!("{:>22}: {:.3e}", e.name(), e.pk1(&q).norm());
    }

    let mesh = rectangle(5.0, 1.0, 200, 40, Diagonal::Right);
    // Bend the beam into a gentle arc so every element is strained.
    let x: Vec<Vec2> = mesh
        .vertices()
        .iter()
        .map(|p| Vec2::new(p.x, p.y - 0.02 * p.x * p.x))
        .collect();
    let mut f = vec![Vec2::zeros(); mesh.n_vertices()];
    println!(
        "\nforce assembly, {} triangles, serial:",
        mesh.n_triangles()
    );
    for e in &energies {
        let reps = 200;
        let start = Instant::now();
        for _ in 0..reps {
            dispatch_energy!(e, e => populate_forces_serial(&mesh, e, &x, &mut f));
        }
        let secs = start.elapsed().as_secs_f64();
        println!(
            "{:>22}: {:.2e} element evaluations per second",
            e.name(),
            (reps * mesh.n_triangles()) as f64 / secs
        );
    }
}
