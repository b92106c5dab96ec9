//! The solver registry as a scene uses it: parameters validated under the scene's field names,
//! built into an `AnyStepper` by name, and (with the `serde` feature) read from the flat
//! `[solver]` keys.

use crate::common::{cantilever, case_a_lame};
use fem_core::energy::{Corotational, NeoHookean};
use fem_solvers::{Ordering, SolverKind, SolverParams, Stepper};

/// A solver, a way to spoil one of its parameters, and the message that names it.
type Spoiled = (SolverKind, fn(&mut SolverParams), &'static str);

/// One rule per field, reported under the prefix the caller gives (a scene passes `solver`),
/// or under the solver's own name when built directly.
#[test]
fn errors_name_the_scene_field() {
    let cases: [Spoiled; 5] = [
        (
            SolverKind::Pbd,
            |p| {
                if let SolverParams::Pbd(p) = p {
                    p.iterations = 0;
                }
            },
            "iterations = 0: must be at least 1",
        ),
        (
            SolverKind::Xpbd,
            |p| {
                if let SolverParams::Xpbd(p) = p {
                    p.ordering = Ordering::GaussSeidel;
                    p.relaxation = 2.0;
                }
            },
            "relaxation = 2: must lie in the open interval (0, 2)",
        ),
        (
            SolverKind::Implicit,
            |p| {
                if let SolverParams::Implicit(p) = p {
                    p.newton.tolerance = 1.0;
                }
            },
            "tolerance = 1: must lie in the open interval (0, 1) (relative to the force scale)",
        ),
        (
            SolverKind::Static,
            |p| {
                if let SolverParams::Static(p) = p {
                    p.load_steps = 0;
                }
            },
            "load_steps = 0: must be at least 1",
        ),
        (
            SolverKind::Explicit,
            |p| p.set_dt(-1.0),
            "dt = -1: must be a finite number > 0",
        ),
    ];
    let model = cantilever(NeoHookean::new(case_a_lame()).unwrap(), 10, 2);
    for (kind, spoil, message) in cases {
        let mut p = kind.default_params();
        spoil(&mut p);
        assert_eq!(
            p.validate_as("solver").unwrap_err().to_string(),
            format!("solver.{message}")
        );
        assert_eq!(
            p.build(&model).unwrap_err().to_string(),
            format!("{kind}.{message}")
        );
    }
}

#[test]
fn any_stepper_knows_its_kind_and_warns_only_for_an_unstable_explicit_step() {
    let model = cantilever(NeoHookean::new(case_a_lame()).unwrap(), 10, 2);
    // Projective Dynamics runs the co-rotational energy only.
    let corotational = cantilever(Corotational::new(case_a_lame()).unwrap(), 10, 2);
    for kind in SolverKind::ALL {
        let mut p = kind.default_params();
        p.set_dt(1.0);
        let s = if kind == SolverKind::Pd {
            p.build(&corotational).unwrap()
        } else {
            p.build(&model).unwrap()
        };
        assert_eq!(s.kind(), kind);
        assert_eq!(
            s.time_step_warning().is_some(),
            kind == SolverKind::Explicit,
            "{kind}"
        );
        let expected = p.dt().unwrap_or(1.0);
        assert_eq!(s.dt(), expected, "{kind}");
    }
}

#[cfg(feature = "serde")]
mod serde_keys {
    use super::*;
    use fem_solvers::{ExplicitScheme, XpbdForm, XpbdParams};
    use serde_json::json;

    /// A scene's flat `[solver]` table holds the keys of every solver (and the scene's own):
    /// each solver reads its own and ignores the others.
    #[test]
    fn each_solver_reads_its_own_keys_from_the_flat_table() {
        let table = json!({
            "kind": "xpbd", "steps": 100, "dt": 2e-3, "iterations": 20, "substeps": 2,
            "compliance": 0.5, "xpbd_form": "literal", "ordering": "jacobi", "relaxation": 1.5,
            "scheme": "forward-euler", "tolerance": 1e-6, "load_steps": 4, "stiffness": 0.5,
        });
        let xpbd = SolverParams::deserialize_as(SolverKind::Xpbd, &table).unwrap();
        assert_eq!(
            xpbd,
            SolverParams::Xpbd(XpbdParams {
                dt: 2e-3,
                substeps: 2,
                iterations: 20,
                compliance: 0.5,
                form: XpbdForm::Literal,
                ordering: Ordering::Jacobi,
                relaxation: 1.5,
                ..XpbdParams::default()
            })
        );
        match SolverParams::deserialize_as(SolverKind::Explicit, &table).unwrap() {
            SolverParams::Explicit(p) => {
                assert_eq!((p.dt, p.scheme), (2e-3, ExplicitScheme::ForwardEuler))
            }
            other => panic!("{other:?}"),
        }
        match SolverParams::deserialize_as(SolverKind::Implicit, &table).unwrap() {
            SolverParams::Implicit(p) => assert_eq!((p.dt, p.newton.tolerance), (2e-3, 1e-6)),
            other => panic!("{other:?}"),
        }
        match SolverParams::deserialize_as(SolverKind::Static, &table).unwrap() {
            SolverParams::Static(p) => {
                assert_eq!((p.load_steps, p.newton.tolerance), (4, 1e-6))
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn parameters_serialise_as_their_scene_keys() {
        let keys = |kind: SolverKind| -> Vec<String> {
            let v = serde_json::to_value(kind.default_params()).unwrap();
            let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
            k.sort();
            k
        };
        assert_eq!(keys(SolverKind::Explicit), ["damping", "dt", "scheme"]);
        assert_eq!(
            keys(SolverKind::Xpbd),
            [
                "compliance",
                "damping",
                "dt",
                "iterations",
                "ordering",
                "relaxation",
                "residual_tolerance",
                "rest_threshold",
                "substeps",
                "xpbd_form",
                "xpbd_lambda_reset",
                "xpbd_schedule"
            ]
        );
        assert_eq!(
            keys(SolverKind::Static),
            [
                "load_steps",
                "max_bisections",
                "max_halvings",
                "max_iterations",
                "tolerance"
            ]
        );
        let v = serde_json::to_value(SolverKind::Pbd.default_params()).unwrap();
        assert_eq!(v["ordering"], "coloured");
        let v = serde_json::to_value(SolverKind::Explicit.default_params()).unwrap();
        assert_eq!(v["scheme"], "symplectic");
    }

    #[test]
    fn a_bad_value_names_the_valid_ones() {
        let e = SolverParams::deserialize_as(SolverKind::Pbd, &json!({"ordering": "red-black"}))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(
                "unknown variant `red-black`, expected one of `gauss-seidel`, `coloured`, `jacobi`"
            ),
            "{e}"
        );
    }
}

/// Regression (a stepper silently kept the model it was built for): a stepper built on a
/// pinned cantilever and stepped with the unpinned beam of the same mesh uses the model it is
/// given, for every solver: its state equals that of a stepper built on the unpinned model.
#[test]
fn a_stepper_uses_the_model_it_is_given_not_the_one_it_was_built_for() {
    use fem_solvers::testing::beam_mesh;
    use fem_solvers::{Model, Region, State};
    let lame = case_a_lame();
    let free = || {
        let mut model = Model::with_total_mass(
            beam_mesh(10, 2).unwrap(),
            Corotational::new(lame).unwrap(),
            1.0,
        )
        .unwrap();
        model.set_standard_gravity();
        model
    };
    let mut pinned = free();
    pinned
        .pin(&Region::in_box(
            fem_core::math::Vec2::new(0.0, 0.0),
            fem_core::math::Vec2::new(0.0, 1.0),
        ))
        .unwrap();
    let unpinned = free();
    for kind in SolverKind::ALL {
        if kind.capabilities().clock != fem_solvers::Clock::Time {
            // The static solver has no equilibrium without a pin.
            continue;
        }
        let mut params = kind.default_params();
        params.set_dt(1e-3);
        let mut swapped = params.build(&pinned).unwrap();
        let mut fresh = params.build(&unpinned).unwrap();
        let (mut a, mut b) = (State::at_rest(&unpinned), State::at_rest(&unpinned));
        for _ in 0..5 {
            swapped.step(&unpinned, &mut a).unwrap();
            fresh.step(&unpinned, &mut b).unwrap();
        }
        assert_eq!(
            a.x, b.x,
            "{kind}: the stepper used the model it was built for"
        );
        // Vertex 0 was pinned in the old model: it falls now.
        assert!(a.x[0].y < 0.0, "{kind}");
    }
}
