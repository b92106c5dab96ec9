//! The real-time solvers (VBD, Projective Dynamics, quasi-Newton) on cases A and C at a 90 Hz
//! frame, against implicit Euler at the same time step: they minimise the same incremental
//! potential each step, so their tip curves approach implicit Euler's as their iterations
//! grow. Run through the scene crate exactly as `fem2d run` runs them.

use fem_scene::cases::load_case;
use fem_scene::run::{RunEnv, run};

/// The tip curve of `case` with `overrides`, at dt = 1/90 s for 2 s.
fn tip(case: &str, overrides: &[&str]) -> Vec<[f64; 2]> {
    let mut all: Vec<String> = vec![
        format!("solver.dt={}", 1.0 / 90.0),
        "solver.steps=180".into(),
        "output.frame_every=1".into(),
    ];
    all.extend(overrides.iter().map(|s| s.to_string()));
    let scene = load_case(case, &all).unwrap();
    let result = run(&scene, &mut RunEnv::default()).unwrap();
    assert!(!result.summary.blew_up, "{case} {overrides:?}");
    result.probe("tip").unwrap().to_vec()
}

/// The largest distance between two tip curves over the reference's largest displacement.
fn distance(a: &[[f64; 2]], reference: &[[f64; 2]]) -> f64 {
    let d = a
        .iter()
        .zip(reference)
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    let scale = reference
        .iter()
        .map(|q| (q[0] * q[0] + q[1] * q[1]).sqrt())
        .fold(0.0, f64::max);
    d / scale
}

/// For each solver (its energy, three iteration counts): the distance to implicit Euler's
/// curve (largest tip distance over the reference's largest tip displacement, 2 s at 90 Hz)
/// shrinks as the iterations grow and ends at round-off of the steps. Measured on case A
/// (StVK; co-rotational for PD): VBD 6.0e-1 / 3.0e-3 / 6.2e-11 after 10 / 100 / 1000 sweeps,
/// PD 8.9e-3 / 1.6e-7 / 5.6e-11 after 10 / 100 / 1000 iterations, quasi-Newton 1.3e-1 / 9.0e-4
/// / 1.5e-10 after 2 / 10 / 50 iterations. Case C is case A's scene with PBD and XPBD keys
/// these solvers ignore: its curves are the same, bit for bit (checked).
#[test]
fn tip_curves_approach_implicit_euler_as_iterations_grow() {
    let solvers: [(&str, &str, [usize; 3]); 3] = [
        ("vbd", "stvk", [10, 100, 1000]),
        ("pd", "corotational", [10, 100, 1000]),
        ("quasi-newton", "stvk", [2, 10, 50]),
    ];
    let case = "case-a";
    for (solver, energy, counts) in solvers {
        let energy_key = format!("energy={energy}");
        // Converged steps: Newton's tolerance alone, no real-time velocity tolerance.
        let reference = tip(
            case,
            &[
                "solver.kind=implicit",
                "solver.velocity_tolerance=0",
                &energy_key,
            ],
        );
        let mut d = Vec::new();
        for n in counts {
            let kind = format!("solver.kind={solver}");
            let iterations = format!("solver.iterations={n}");
            d.push(distance(
                &tip(case, &[&kind, &energy_key, &iterations]),
                &reference,
            ));
        }
        eprintln!(
            "{case}, {solver} ({energy}): distance to implicit Euler after {} / {} / {} iterations: {:.2e} / {:.2e} / {:.2e}",
            counts[0], counts[1], counts[2], d[0], d[1], d[2]
        );
        assert!(d[1] < d[0] && d[2] < d[1], "{case} {solver}: {d:?}");
        assert!(d[2] < 1e-8, "{case} {solver}: {d:?}");
        let same = |c: &str| {
            tip(
                c,
                &[
                    &format!("solver.kind={solver}"),
                    &energy_key,
                    &format!("solver.iterations={}", counts[0]),
                ],
            )
        };
        assert_eq!(same("case-a"), same("case-c"), "{solver}");
    }
}
