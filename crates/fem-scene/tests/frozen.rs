//! The "nothing moved but converged" oracle: every Newton-family solver (implicit Euler,
//! statics, quasi-Newton, linearly implicit Euler, VBD) run on a loaded cantilever whose
//! scales are pushed to the edges of double precision (a region up to 1e300 times stiffer than
//! the body, gravity up to 1e200, a barrier up to 1e300) either fails with one line or moves
//! the body and reports a finite residual. A step that leaves a loaded body where it was and
//! calls that a solution is the lie this file exists to catch.

use fem_scene::run::{RunEnv, run};
use fem_scene::scene::parse_scene;
use proptest::prelude::*;

const SOLVERS: [&str; 5] = [
    "implicit",
    "static",
    "quasi-newton",
    "linear-implicit",
    "vbd",
];

/// A 2 m x 0.5 m cantilever (32 triangles) pinned on its left edge, with a region over its
/// last quarter, under gravity `g` (m/s^2, downwards); optionally a ground 0.5 mm below it
/// (inside the barrier's 1 mm reach from the start) with barrier stiffness `kappa`.
fn scene(
    solver: &str,
    energy: &str,
    base: f64,
    region: f64,
    g: f64,
    dt: f64,
    kappa: Option<f64>,
) -> String {
    let mut text = format!(
        r#"name = "frozen"
energy = "{energy}"
gravity = [0.0, {:e}]

[mesh]
kind = "rectangle"
width = 2.0
height = 0.5
nx = 8
ny = 2

[material]
youngs_modulus = {base:e}
poisson_ratio = 0.3
density = 1000.0

[[regions]]
name = "stiff"
polygon = [[1.5, -0.1], [2.1, -0.1], [2.1, 0.6], [1.5, 0.6]]
youngs_modulus = {region:e}

[solver]
kind = "{solver}"
dt = {dt:e}
steps = 3

[[pinned]]
min = [0.0, 0.0]
max = [0.0, 0.5]
"#,
        -g
    );
    if let Some(kappa) = kappa {
        text.push_str(&format!(
            "\n[ground]\nheight = -0.0005\n\n[contact]\nbarrier_stiffness = {kappa:e}\n"
        ));
    }
    text
}

/// Run `text`: `Ok(displacement, final residual)` or the error's text.
fn outcome(text: &str) -> Result<(f64, Option<f64>, Option<f64>), String> {
    let scene = parse_scene(text, "frozen.toml", std::path::Path::new("."), &[])
        .map_err(|e| e.to_string())?;
    let result = run(&scene, &mut RunEnv::default()).map_err(|e| e.to_string())?;
    let s = &result.summary;
    match &s.blow_up_message {
        Some(m) if s.blew_up => Err(m.clone()),
        _ => Ok((
            s.final_max_displacement,
            s.final_residual,
            s.max_step_residual,
        )),
    }
}

/// The oracle: a one-line error, or a run that moved the body and whose residuals are finite.
fn check(solver: &str, text: &str) -> Result<(), TestCaseError> {
    match outcome(text) {
        Err(e) => prop_assert_eq!(e.lines().count(), 1, "{}", e),
        Ok((moved, last, largest)) => {
            prop_assert!(moved > 0.0, "{solver}: converged without moving\n{text}");
            if solver != "linear-implicit" && solver != "vbd" {
                let last = last.unwrap_or(f64::NAN);
                prop_assert!(last.is_finite(), "{solver}: final_residual {last}\n{text}");
            }
            let largest = largest.unwrap_or(f64::NAN);
            prop_assert!(
                largest.is_finite(),
                "{solver}: max_step_residual {largest}\n{text}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 160, ..ProptestConfig::default() })]

    #[test]
    fn newton_family_never_converges_without_moving(
        solver in prop::sample::select(SOLVERS.to_vec()),
        energy in prop::sample::select(vec!["stvk", "neo-hookean", "corotational"]),
        base in 0.0..12.0f64,
        region in 0.0..300.0f64,
        g in -3.0..200.0f64,
        dt in -4.0..-1.0f64,
        kappa in prop::option::of(0.0..300.0f64),
    ) {
        let text = scene(
            solver,
            energy,
            10f64.powf(base),
            10f64.powf(region),
            10f64.powf(g),
            10f64.powf(dt),
            kappa.map(|k| 10f64.powf(k)),
        );
        check(solver, &text)?;
    }
}

/// The cases of the trial that found the lie, each solver: a region 1e14 times stiffer than
/// the body moves with it (the body's own floor is its own, not the region's), and regions
/// beyond what a factorisation can separate (1e30), gravity whose weight overflows (1e200) and
/// a barrier of 1e300 are one-line errors that name the field or the cause.
#[test]
fn the_extreme_scales_of_the_trial_move_the_body_or_say_why() {
    for solver in SOLVERS {
        let text = scene(solver, "stvk", 1e3, 1e14, 9.8, 1e-2, None);
        match outcome(&text) {
            Ok((moved, ..)) => assert!(moved > 1e-3, "{solver}: the tip moved {moved} m"),
            // Statics has no inertia to regularise the factorisation: the stiffness matrix's
            // entries span 1e14, beyond what Cholesky solves, and the failure names them.
            Err(e) if solver == "static" => {
                assert!(
                    e.contains("regions.0.youngs_modulus = 1e14 Pa is 1e11 times"),
                    "{e}"
                )
            }
            Err(e) => panic!("{solver}: {e}"),
        }
    }
    for (solver, text, expected) in [
        (
            "implicit",
            scene("implicit", "stvk", 1e3, 1e30, 9.8, 1e-2, None),
            "regions.0.youngs_modulus = 1e30 Pa is 1e27 times material.youngs_modulus",
        ),
        (
            "static",
            scene("static", "stvk", 1e3, 1e30, 9.8, 1e-2, None),
            "beyond what double precision can solve",
        ),
        (
            "implicit",
            scene("implicit", "stvk", 1e3, 1e3, 1e200, 1e-2, None),
            "gravity = [0, -1e200]: the body's weight is",
        ),
        (
            "quasi-newton",
            scene("quasi-newton", "stvk", 1e3, 1e3, 1e200, 1e-2, None),
            "gravity = [0, -1e200]",
        ),
        (
            "implicit",
            scene("implicit", "stvk", 1e3, 1e3, 9.8, 1e-2, Some(1e300)),
            "contact.barrier_stiffness = 1e300",
        ),
        (
            "static",
            scene("static", "stvk", 1e30, 1e30, 9.8, 1e-2, None),
            "static: the load",
        ),
    ] {
        let e = outcome(&text).expect_err(solver);
        assert!(e.contains(expected), "{solver}: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
}

/// Implicit Euler with a step so short that gravity moves nothing by an ulp of the
/// coordinates (h^2 g = 1e-22 m beside coordinates of 2 m) would repeat the rest state
/// forever, with zero velocity: refused.
#[test]
fn a_step_too_short_to_move_anything_is_refused() {
    let text = scene("implicit", "stvk", 1e3, 1e3, 9.8, 3e-12, None);
    let e = outcome(&text).expect_err("refused");
    assert!(e.contains("implicit: the load"), "{e}");
    assert!(e.contains("solver.dt = "), "{e}");
}

/// The oracle is not vacuous: over a grid of the property's scales (regions 1 to 1e12 times
/// the body's modulus, gravity 1e-3 to 1e3 m/s^2, with and without a barrier), most runs of
/// every solver succeed, so `check` tests moving runs and not only errors. (Statics, with no
/// inertia to regularise its factorisation, fails honestly on the widest spans and under the
/// heaviest load: 13 of 24 run.)
#[test]
fn most_of_the_grid_runs_and_moves() {
    for solver in SOLVERS {
        let (mut ran, mut total) = (0, 0);
        for region in [1.0, 1e4, 1e8, 1e12] {
            for g in [1e-3, 9.8, 1e3] {
                for kappa in [None, Some(1e8)] {
                    let text = scene(solver, "neo-hookean", 1e4, 1e4 * region, g, 1e-2, kappa);
                    check(solver, &text).unwrap_or_else(|e| panic!("{e}"));
                    total += 1;
                    ran += usize::from(outcome(&text).is_ok());
                }
            }
        }
        assert!(2 * ran >= total, "{solver}: {ran} of {total} ran");
    }
}

/// A pin dragged through the ground under implicit Euler: the potential is infinite at the
/// step's start (the barrier, where the pinned vertex crosses the ground), and the message says
/// which vertex and what it crosses, not only that the start is not finite.
#[test]
fn a_pin_dragged_through_the_ground_names_the_vertex_and_the_ground() {
    let text =
        scene("implicit", "stvk", 1e3, 1e3, 9.8, 1e-2, None) + "\n[ground]\nheight = -0.05\n";
    let scene = parse_scene(&text, "frozen.toml", std::path::Path::new("."), &[]).unwrap();
    let drag = fem_scene::drag::DragTrajectory::parse(
        r#"{"version": 1, "events": [
            {"t": 0.0, "action": "grab", "x": 2.0, "y": 0.0, "stiffness": 0},
            {"t": 0.01, "action": "move", "x": 2.0, "y": -1.0}]}"#,
        "drag.json",
    )
    .unwrap();
    let env = &mut RunEnv {
        drag: Some(&drag),
        ..RunEnv::default()
    };
    let result = run(&scene, env).unwrap();
    let e = result.summary.blow_up_message.expect("the step fails");
    assert!(e.contains("implicit.initial_guess = inf"), "{e}");
    assert!(e.contains("the ground"), "{e}");
    assert!(e.contains("where the contact barrier is infinite"), "{e}");
    assert_eq!(e.lines().count(), 1);
}

/// A kinematic obstacle whose move would carry it beyond squarable coordinates is refused
/// before the run, naming the move's velocity (it once ended in "the potential is not finite
/// at the starting positions" at the step the move began).
#[test]
fn an_obstacle_move_beyond_double_precision_is_refused_naming_its_velocity() {
    let set = ["obstacles.0.moves.0.velocity=[0.0, -1e300]".to_owned()];
    let e = fem_scene::cases::load_case("lower-leg", &set)
        .and_then(|s| run(&s, &mut RunEnv::default()))
        .map(|_| ())
        .expect_err("refused");
    let e = e.to_string();
    assert!(
        e.contains("obstacles.0.moves.0.velocity = [0, -1e300]: moves the obstacle"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1);
}
