//! The `integrator` key of a scene's flat `[solver]` table (`backward-euler`, the default, or
//! `bdf2`): read from a scene file and from `--set solver.integrator=...` into the parameters
//! of every solver that has it (implicit, vbd, pd, quasi-newton), kept by a written scene,
//! refused with a one-line error naming the field and the valid values, and reaching the
//! stepper a run builds.

use std::path::Path;

use fem_scene::SolverSpec;
use fem_scene::build::{NoFiles, build_mesh, build_model, build_stepper, energy, initial_state};
use fem_scene::cases::{case_text, load_case};
use fem_scene::scene::parse_scene;
use fem_solvers::{AnyStepper, Integrator, SolverKind, Stepper};

fn overrides(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| (*s).to_owned()).collect()
}

/// The solvers that minimise an incremental potential.
const WITH: [&str; 4] = ["implicit", "vbd", "pd", "quasi-newton"];

/// Every solver of `spec` with the key has integrator `expected`; the others have none.
fn check(spec: &SolverSpec, expected: Integrator) {
    for kind in SolverKind::ALL {
        let got = spec.params_of(kind).integrator();
        if WITH.contains(&kind.name()) {
            assert_eq!(got, Some(expected), "{kind}");
        } else {
            assert_eq!(got, None, "{kind}");
        }
    }
}

#[test]
fn integrator_is_a_key_of_the_solvers_that_minimise_an_incremental_potential() {
    for kind in SolverKind::ALL {
        assert_eq!(
            SolverSpec::accepts(kind, "integrator"),
            WITH.contains(&kind.name()),
            "{kind}"
        );
    }
    let scene = load_case("case-a", &overrides(&["solver.kind=\"implicit\""])).unwrap();
    assert_eq!(
        scene.scene.solver.get("integrator"),
        Some(toml::Value::String("backward-euler".into())),
        "the default"
    );
    check(&scene.scene.solver, Integrator::BackwardEuler);
}

#[test]
fn a_scene_file_and_set_reach_every_solver_and_a_written_scene_keeps_it() {
    // In the file's [solver] table.
    let text = case_text("case-a")
        .unwrap()
        .replace("[solver]\n", "[solver]\nintegrator = \"bdf2\"\n");
    assert!(text.contains("integrator = \"bdf2\""));
    let scene = parse_scene(&text, "case-a.toml", Path::new("."), &[]).unwrap();
    check(&scene.scene.solver, Integrator::Bdf2);
    // From the command line, quoted or bare, and overriding the file.
    for set in ["solver.integrator=\"bdf2\"", "solver.integrator=bdf2"] {
        let scene = load_case("case-a", &overrides(&[set])).unwrap();
        check(&scene.scene.solver, Integrator::Bdf2);
    }
    let scene = parse_scene(
        &text,
        "case-a.toml",
        Path::new("."),
        &overrides(&["solver.integrator=backward-euler"]),
    )
    .unwrap();
    check(&scene.scene.solver, Integrator::BackwardEuler);
    // The typed edit of a comparison's variants.
    let mut spec = scene.scene.solver.clone();
    spec.set("integrator", "bdf2").unwrap();
    check(&spec, Integrator::Bdf2);
    spec.validate().unwrap();
    // A written scene reads back the same.
    let written = toml::to_string(&spec).unwrap();
    assert!(written.contains("integrator = \"bdf2\""), "{written}");
    let back: SolverSpec = toml::from_str(&written).unwrap();
    assert_eq!(back, spec);
}

#[test]
fn an_unknown_integrator_is_a_one_line_error_naming_the_field_and_the_valid_values() {
    let e = load_case("case-a", &overrides(&["solver.integrator=rk4"]))
        .unwrap_err()
        .to_string();
    eprintln!("{e}");
    assert!(!e.contains('\n'), "{e}");
    assert!(e.contains("solver.integrator"), "{e}");
    assert!(e.contains("rk4"), "{e}");
    assert!(e.contains("backward-euler") && e.contains("bdf2"), "{e}");
    let text = case_text("case-a")
        .unwrap()
        .replace("[solver]\n", "[solver]\nintegrator = \"BDF2\"\n");
    let e = parse_scene(&text, "case-a.toml", Path::new("."), &[])
        .unwrap_err()
        .to_string();
    assert!(!e.contains('\n'), "{e}");
    assert!(
        e.starts_with("case-a.toml: solver.integrator: ")
            && e.contains("backward-euler")
            && e.contains("bdf2"),
        "{e}"
    );
    // The typed edit too.
    let mut spec = load_case("case-a", &[]).unwrap().scene.solver;
    let e = spec.set("integrator", "rk4").unwrap_err();
    assert!(
        e.starts_with("solver.integrator: ") && e.contains("bdf2"),
        "{e}"
    );
}

/// The stepper a scene builds takes BDF2 steps from its second step on.
#[test]
fn a_run_steps_with_bdf2() {
    for solver in WITH {
        let scene = load_case(
            "case-a",
            &overrides(&[
                &format!("solver.kind=\"{solver}\""),
                "energy=\"corotational\"",
                "solver.integrator=bdf2",
            ]),
        )
        .unwrap();
        let mesh = build_mesh(&scene, &NoFiles).unwrap();
        let model = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
        let mut stepper = build_stepper(&scene, &model).unwrap();
        let mut state = initial_state(&scene, &model).unwrap();
        let bdf2 = |s: &AnyStepper| match s {
            AnyStepper::Implicit(s) => s.last_step_bdf2(),
            AnyStepper::Vbd(s) => s.last_bdf2_substeps() > 0,
            AnyStepper::Pd(s) => s.last_step_bdf2(),
            AnyStepper::QuasiNewton(s) => s.last_step_bdf2(),
            other => panic!("{:?} has no integrator", other.kind()),
        };
        stepper.step(&model, &mut state).unwrap();
        assert!(
            !bdf2(&stepper),
            "{solver}: the first step is backward Euler"
        );
        stepper.step(&model, &mut state).unwrap();
        assert!(bdf2(&stepper), "{solver}: the second step is BDF2");
    }
}
