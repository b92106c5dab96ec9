//! 3D scenes (`dim = 3`, `fem_scene::solid`): the built-in `case-a-3d` runs and its tip falls
//! as case A's does; the plane-strain limit through scene files (the 3D beam with `u_z = 0` on
//! its side faces against case A under the static solver, within 1 %); 2D-only keys, a solver
//! without a 3D path, a wrong mesh kind and a bad `dim` are one-line errors naming the key; a
//! 2D tool refuses a 3D scene in one line.

use std::path::Path;

use fem_scene::run::{NoClock, RunEnv, run};
use fem_scene::scene::parse_scene;
use fem_scene::solid::{AnyScene, case_text_3d, load_case3, parse_any, parse_scene3, run3};

fn err3(text: &str) -> String {
    let e = parse_scene3(text, "s.toml", Path::new("."), &[])
        .err()
        .unwrap_or_else(|| panic!("expected an error for:\n{}", &text[text.len() - 300..]))
        .to_string();
    assert!(!e.contains('\n'), "{e}");
    e
}

#[test]
fn case_a_3d_falls_like_case_a() {
    let scene = load_case3("case-a-3d", &["solver.steps=200".into()]).unwrap();
    let r = run3(&scene, &NoClock, 1, false, None).unwrap();
    assert!(!r.summary.blew_up, "{:?}", r.summary.blow_up_message);
    assert_eq!(r.summary.dim, 3);
    assert_eq!(r.summary.tetrahedra, 6 * 20 * 4 * 4);
    // After 0.1 s the free end has fallen about g t^2 / 2 = 49 mm, as in 2D (Table 1).
    let tip = r.summary.probes[0].final_displacement;
    assert!((tip[1] + 0.049).abs() < 0.004, "{tip:?}");
    // The first frame, every 20th step and the last: 11 probe rows.
    assert_eq!(r.probe_rows.len(), 11);
    assert_eq!(r.frames.len(), 1);
    assert!(r.summary.max_von_mises > 0.0 && r.summary.min_det_f > 0.9);
}

/// The plane-strain limit through scene files: case A under the static solver (50 x 10 cells)
/// against the 3D beam with one cell through its depth and `u_z = 0` on both side faces
/// (at case A's own 20 x 4 the two discretisations still differ by 1.3 %).
#[test]
fn plane_strain_scene_matches_case_a_statically() {
    let two = fem_scene::cases::load_case(
        "case-a",
        &[
            "solver.kind=static".into(),
            "energy=neo-hookean".into(),
            "mesh.nx=50".into(),
            "mesh.ny=10".into(),
        ],
    )
    .unwrap();
    let r2 = run(&two, &mut RunEnv::default()).unwrap();
    let tip2 = r2.summary.probes[0].final_displacement[1];
    let three = load_case3(
        "case-a-3d",
        &[
            "solver.kind=static".into(),
            "energy=neo-hookean".into(),
            "mesh.depth=0.2".into(),
            "mesh.nx=50".into(),
            "mesh.ny=10".into(),
            "mesh.nz=1".into(),
            "probes.0.point=[5.0, 0.0, 0.0]".into(),
            "fixed=[{min = [0.0, 0.0, 0.0], max = [5.0, 1.0, 0.0], axes = [\"z\"]}, {min = [0.0, 0.0, 0.2], max = [5.0, 1.0, 0.2], axes = [\"z\"]}]".into(),
            "pinned.0.max=[0.0, 1.0, 0.2]".into(),
        ],
    )
    .unwrap();
    let r3 = run3(&three, &NoClock, 1, false, None).unwrap();
    let tip3 = r3.summary.probes[0].final_displacement[1];
    let gap = ((tip3 - tip2) / tip2).abs();
    eprintln!(
        "case A static tip {tip2:.5} m, 3D plane strain {tip3:.5} m, gap {:.3} %",
        100.0 * gap
    );
    assert!(gap < 0.01, "{tip2} vs {tip3}");
    assert!(r3.summary.probes[0].final_displacement[2].abs() < 1e-12);
}

#[test]
fn two_d_only_keys_and_bad_values_are_one_line_errors() {
    let base = case_text_3d("case-a-3d").unwrap();
    let e = err3(&format!("{base}\n[ground]\nheight = 0.0\n"));
    assert!(
        e.starts_with("s.toml: ground: not available in 3D scenes yet"),
        "{e}"
    );
    let e = err3(&base.replace("kind = \"explicit\"", "kind = \"linear-implicit\""));
    assert!(
        e.starts_with(
            "s.toml: solver.kind = linear-implicit: has no 3D path yet (solvers with one: explicit"
        ),
        "{e}"
    );
    let e = err3(&base.replace("kind = \"box\"", "kind = \"rectangle\""));
    assert!(
        e.starts_with("s.toml: mesh.kind = rectangle: a 3D scene's mesh is a box"),
        "{e}"
    );
    let e = err3(&base.replace("gravity = [0.0, -9.8, 0.0]", "gravity = [0.0, -9.8]"));
    assert!(e.starts_with("s.toml: gravity: "), "{e}");
    let e = err3(&format!(
        "{base}\n[[fixed]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 0.0]\naxes = [\"w\"]\n"
    ));
    assert_eq!(e, "s.toml: fixed.0.axes = w: must be x, y or z");
    assert_eq!(
        err3(&base.replace("nx = 20", "nx = 0")),
        "s.toml: mesh.nx = 0: must be >= 1"
    );
    assert_eq!(
        err3(&base.replace("depth = 1.0", "depth = -1.0")),
        "s.toml: mesh.depth = -1: must be a finite number > 0 (m)"
    );
    // Too many cells is caught when the mesh is built, in one line too.
    let scene = parse_scene3(
        &base
            .replace("nx = 20", "nx = 100000")
            .replace("ny = 4", "ny = 100000"),
        "s.toml",
        Path::new("."),
        &[],
    )
    .unwrap();
    let e = run3(&scene, &NoClock, 1, false, None)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with("s.toml: mesh: box: cell counts must be in 1..="),
        "{e}"
    );
    let e = err3(&base.replace("dim = 3", "dim = 5"));
    assert_eq!(e, "s.toml: dim = 5: must be 2 or 3");
}

#[test]
fn a_2d_tool_refuses_a_3d_scene_and_parse_any_dispatches() {
    let text = case_text_3d("case-a-3d").unwrap();
    let e = parse_scene(text, "s.toml", Path::new("."), &[])
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with("s.toml: dim = 3: a 3D scene runs with `fem2d run`"),
        "{e}"
    );
    assert!(matches!(
        parse_any(text, "s.toml", Path::new("."), &[]).unwrap(),
        AnyScene::Three(_)
    ));
    let two = fem_scene::cases::case_text("case-a").unwrap();
    assert!(matches!(
        parse_any(two, "s.toml", Path::new("."), &[]).unwrap(),
        AnyScene::Two(_)
    ));
    // `dim = 2` is the default, written or not.
    assert!(parse_scene(&format!("dim = 2\n{two}"), "s.toml", Path::new("."), &[]).is_ok());
}

/// The compiled-in `case-a-3d` is the fixture file `fixtures/scenes/case-a-3d.toml`.
#[test]
fn the_builtin_3d_case_is_its_fixture_file() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes");
    let text = std::fs::read_to_string(dir.join("case-a-3d.toml")).unwrap();
    let from_file = parse_scene3(&text, "case-a-3d.toml", &dir, &[]).unwrap();
    assert_eq!(from_file.scene, load_case3("case-a-3d", &[]).unwrap().scene);
}

/// A frame sink sees every recorded frame of a 3D run (positions, velocities, masses, stress
/// per tetrahedron), and its error ends the run with that error; implicit Euler reports its
/// largest step residual, explicit none.
#[test]
fn frame_sinks_see_every_frame_and_can_stop_a_3d_run() {
    use fem_scene::SceneError;
    use fem_scene::solid::{FrameSink3, FrameView3, RunEnv3, run3_with};
    struct Count {
        frames: Vec<u64>,
        stop_at: Option<u64>,
        mass: f64,
    }
    impl FrameSink3 for Count {
        fn frame(&mut self, f: &FrameView3<'_>) -> Result<(), SceneError> {
            assert_eq!(f.x.len(), f.v.len());
            assert_eq!(f.von_mises.len(), f.tetrahedra.len());
            self.mass = f.masses.iter().sum();
            self.frames.push(f.step);
            match self.stop_at {
                Some(s) if f.step >= s => Err(SceneError::Usage("stop".into())),
                _ => Ok(()),
            }
        }
    }
    let scene = load_case3(
        "case-a-3d",
        &[
            "solver.steps=40".into(),
            "output.frame_every=10".into(),
            "mesh.nx=4".into(),
            "mesh.ny=1".into(),
            "mesh.nz=1".into(),
        ],
    )
    .unwrap();
    let go = |scene: &fem_scene::solid::LoadedScene3, sink: &mut Count| {
        run3_with(
            scene,
            RunEnv3 {
                clock: &NoClock,
                threads: 1,
                keep_frames: false,
                progress: None,
                sinks: vec![sink],
            },
        )
    };
    let mut all = Count {
        frames: Vec::new(),
        stop_at: None,
        mass: 0.0,
    };
    let r = go(&scene, &mut all).unwrap();
    assert_eq!(all.frames, vec![0, 10, 20, 30, 40]);
    // Density 0.2 kg/m^3 over 5 m^3.
    assert!((all.mass - 1.0).abs() < 1e-12, "{}", all.mass);
    assert_eq!(r.summary.max_step_residual, None);
    let mut stopped = Count {
        frames: Vec::new(),
        stop_at: Some(20),
        mass: 0.0,
    };
    let e = go(&scene, &mut stopped).err().unwrap().to_string();
    assert!(e.contains("stop"), "{e}");
    assert_eq!(stopped.frames, vec![0, 10, 20]);
    let implicit = load_case3(
        "case-a-3d",
        &[
            "solver.kind=\"implicit\"".into(),
            "solver.dt=1e-2".into(),
            "solver.steps=3".into(),
            "mesh.nx=4".into(),
            "mesh.ny=1".into(),
            "mesh.nz=1".into(),
        ],
    )
    .unwrap();
    let mut sink = Count {
        frames: Vec::new(),
        stop_at: None,
        mass: 0.0,
    };
    let r = go(&implicit, &mut sink).unwrap();
    let residual = r.summary.max_step_residual.unwrap();
    assert!(residual.is_finite() && residual >= 0.0, "{residual}");
}
