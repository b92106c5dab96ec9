//! The iterative solvers' `residual_tolerance` (VBD, PD, XPBD) in a scene's flat `[solver]`
//! table: read, checked under its key, kept by a written scene, and stopping a run's steps
//! early. It is not Newton's `tolerance`: the table holds one value per key, and the two
//! defaults (0 and 1e-8) and ranges ([0, 1) and (0, 1)) differ.

use fem_scene::SolverSpec;
use fem_scene::build::{NoFiles, build_mesh, build_model, build_stepper, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::{SolverKind, Stepper};

fn overrides(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| (*s).to_owned()).collect()
}

#[test]
fn residual_tolerance_is_a_key_of_vbd_pd_and_xpbd_only() {
    for kind in SolverKind::ALL {
        let iterative = matches!(kind.name(), "vbd" | "pd" | "xpbd");
        assert_eq!(
            SolverSpec::accepts(kind, "residual_tolerance"),
            iterative,
            "{kind}"
        );
    }
    let scene = load_case("case-a", &overrides(&["solver.kind=\"vbd\""])).unwrap();
    assert_eq!(
        scene.scene.solver.get("residual_tolerance"),
        Some(toml::Value::Float(0.0)),
        "default: the fixed count"
    );
    // 0 is valid under every solver that reads it (Newton's `tolerance` would refuse 0).
    let mut spec = scene.scene.solver.clone();
    spec.set("residual_tolerance", 0.0).unwrap();
    spec.validate().unwrap();
}

#[test]
fn a_scene_reads_checks_and_writes_it() {
    let scene = load_case(
        "case-a",
        &overrides(&["solver.kind=\"vbd\"", "solver.residual_tolerance=1e-3"]),
    )
    .unwrap();
    let spec = &scene.scene.solver;
    assert_eq!(
        spec.get("residual_tolerance"),
        Some(toml::Value::Float(1e-3))
    );
    // Newton's tolerance keeps its own default.
    let implicit = toml::Value::try_from(spec.params_of(SolverKind::Implicit)).unwrap();
    assert_eq!(implicit.get("tolerance"), Some(&toml::Value::Float(1e-8)));
    // A written scene reads back the same, and validates.
    let text = toml::to_string(spec).unwrap();
    let back: SolverSpec = toml::from_str(&text).unwrap();
    assert_eq!(&back, spec, "{text}");
    back.validate().unwrap();
    for bad in ["1.0", "-0.001"] {
        let e = load_case(
            "case-a",
            &overrides(&[
                "solver.kind=\"vbd\"",
                &format!("solver.residual_tolerance={bad}"),
            ]),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("solver.residual_tolerance"), "{e}");
    }
}

/// Case A under VBD, PD and XPBD with at most 2000 iterations and `residual_tolerance =
/// 1e-3`: every step stops early.
#[test]
fn a_run_stops_its_steps_at_the_tolerance() {
    for solver in ["vbd", "pd", "xpbd"] {
        let scene = load_case(
            "case-a",
            &overrides(&[
                &format!("solver.kind=\"{solver}\""),
                "energy=\"corotational\"",
                "solver.iterations=2000",
                "solver.residual_tolerance=1e-3",
            ]),
        )
        .unwrap();
        let mesh = build_mesh(&scene, &NoFiles).unwrap();
        let model = build_model(&scene, mesh, energy(&scene).unwrap()).unwrap();
        let mut stepper = build_stepper(&scene, &model).unwrap();
        let mut state = initial_state(&scene, &model).unwrap();
        for _ in 0..5 {
            let r = stepper.step(&model, &mut state).unwrap();
            assert!(r.iterations < 2000, "{solver}: {r:?}");
        }
    }
}
