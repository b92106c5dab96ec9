//! The browser app's API, natively: real-time frames, grab / drag / release, switching solver
//! and energy mid-run, restarts, bad input, blow-up and recovery, and that the app steps the
//! scene exactly as `fem-scene` does (the same state, bit for bit).

use fem_core::dispatch_energy;
use fem_scene::build::{build_mesh, build_model, build_stepper, energy, initial_state};
use fem_scene::cases::load_case;
use fem_solvers::Stepper;
use fem_web::{App, Field, MemoryFiles};

/// Run whole frames of 1/60 s, taking every step each wants.
fn frames(app: &mut App, n: usize) {
    for _ in 0..n {
        let want = app.begin_frame(1.0 / 60.0);
        let took = app.step(want).unwrap();
        app.end_frame(took, 1.0, 1.0 / 60.0);
    }
}

#[test]
fn frames_follow_wall_time_and_slow_down_honestly() {
    let mut app = App::case("case-a").unwrap();
    // Case A steps 1 ms: a 60 Hz frame wants 17 steps (rounded), and the clock follows.
    assert_eq!(app.begin_frame(1.0 / 60.0), 17);
    assert_eq!(app.step(17).unwrap(), 17);
    app.end_frame(17, 2.0, 1.0 / 60.0);
    let hud = app.hud().clone();
    assert!((hud.t - 0.017).abs() < 1e-12, "t = {}", hud.t);
    assert!(!hud.slowed);
    assert!((hud.real_time_factor - 1.02).abs() < 1e-9);
    // A frame after a long pause owes at most 0.1 s; taking only 10 of its steps slows the
    // clock instead of carrying the debt.
    assert_eq!(app.begin_frame(5.0), 100);
    app.step(10).unwrap();
    app.end_frame(10, 16.0, 5.0);
    let hud = app.hud();
    assert!(hud.slowed);
    assert!((hud.real_time_factor - 0.002).abs() < 1e-12);
    assert_eq!(app.begin_frame(1.0 / 60.0), 17, "no debt carried over");
}

#[test]
fn a_pinned_grab_carries_the_tip_and_the_stress_rises_there() {
    let mut app = App::case("case-a").unwrap();
    let tip = app
        .positions()
        .iter()
        .position(|p| p.x == 5.0 && p.y == 0.5)
        .unwrap();
    let vm_before = app.field(Field::VonMises);
    // A press far off grabs nothing (and a press lets go of what the hand held before).
    assert!(
        !app.grab_at(50.0, 50.0, 0.0).unwrap(),
        "a point far off grabs nothing"
    );
    assert!(
        app.grab_at(4.99, 0.5, 0.0).unwrap(),
        "a point on the body grabs"
    );
    // Dragging up 1 m over 30 frames (the hand moves each frame).
    for k in 1..=30 {
        app.drag_to(4.99, 0.5 + k as f64 / 30.0).unwrap();
        frames(&mut app, 1);
    }
    let p = app.positions()[tip];
    assert!((p.y - 1.5).abs() < 0.02, "tip at {p:?}");
    let hud = app.hud().clone();
    let force = hud.grab_force.expect("a grab reports its force");
    // The reaction of a dynamic, stretched beam: the hand pulls it along (+x) and holds it.
    assert!(force[0] > 1.0 && force[0].is_finite(), "force {force:?}");
    // Stress near the tip rose well above its value at rest.
    let vm = app.field(Field::VonMises);
    let near: Vec<usize> = app
        .triangles()
        .iter()
        .enumerate()
        .filter(|(_, t)| t.contains(&(tip as u32)))
        .map(|(i, _)| i)
        .collect();
    assert!(near.iter().all(|&t| vm[t] > vm_before[t] + 1.0));
    app.release();
    assert!(app.hud().grab_force.is_none());
    frames(&mut app, 5);
    assert!(app.positions()[tip].y < 1.5, "released, the tip falls back");
}

#[test]
fn a_spring_grab_pulls_with_a_force_proportional_to_the_gap() {
    let mut app = App::case("case-a").unwrap();
    assert!(app.grab_at(4.9, 0.6, 20.0).unwrap());
    app.drag_to(4.9, 1.6).unwrap();
    frames(&mut app, 1);
    let f = app.hud().grab_force.unwrap();
    assert!(f[1] > 5.0 && f[1] < 20.0, "force {f:?}");
}

#[test]
fn switching_solver_and_energy_keeps_the_state_and_the_grab() {
    let mut app = App::case("case-a").unwrap();
    assert!(app.grab_at(4.99, 0.5, 0.0).unwrap());
    for k in 1..=10 {
        app.drag_to(4.99, 0.5 + 0.05 * k as f64).unwrap();
        frames(&mut app, 1);
    }
    let t = app.state().t;
    let x = app.state().x.clone();
    for (key, value, names) in [
        ("solver.kind", "\"xpbd\"", ("stvk", "xpbd")),
        ("energy", "\"neo-hookean\"", ("neo-hookean", "xpbd")),
        ("solver.kind", "\"vbd\"", ("neo-hookean", "vbd")),
        ("material.youngs_modulus", "5000.0", ("neo-hookean", "vbd")),
    ] {
        let restarted = app.set(key, value).unwrap();
        assert!(!restarted, "{key}");
        assert_eq!(app.names(), names);
        assert_eq!(app.state().t, t);
        assert_eq!(app.state().x, x);
    }
    // The grab survived: stepping on keeps the tip at the hand.
    frames(&mut app, 5);
    assert!(app.hud().grab_force.is_some());
    assert!(app.state().t > t);
    // A mesh change restarts the scene (and lets go).
    assert!(app.set("mesh.nx", "10").unwrap());
    assert_eq!(app.state().t, 0.0);
    assert!(app.hud().grab_force.is_none());
}

#[test]
fn bad_settings_and_scenes_are_one_line_errors_that_change_nothing() {
    let mut app = App::case("case-a").unwrap();
    frames(&mut app, 2);
    let before = app.state().digest();
    let e = app.set("solver.dt", "-1.0").unwrap_err();
    assert!(
        e.starts_with("built-in case-a: solver.dt = -1"),
        "message: {e}"
    );
    assert!(!e.contains('\n'));
    let e = app.set("energy", "\"rubber\"").unwrap_err();
    assert!(e.contains("rubber"), "{e}");
    assert_eq!(app.state().digest(), before);
    assert_eq!(app.names(), ("stvk", "explicit"));
    frames(&mut app, 1);
    // A dropped scene with an error, and one naming a file the page was not given.
    let e = App::scene("energy = 3", "dropped.toml", MemoryFiles::default())
        .err()
        .unwrap();
    assert!(e.starts_with("dropped.toml: "), "{e}");
    assert!(!e.contains('\n'));
    let text = "name = \"dropped\"\n[mesh]\nkind = \"file\"\npath = \"body.json\"\n[solver]\nkind = \"explicit\"\ndt = 1e-3\nsteps = 10\n[material]\nyoungs_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n";
    let e = App::scene(text, "dropped.toml", MemoryFiles::default())
        .err()
        .unwrap();
    assert!(e.contains("body.json"), "{e}");
    let e = App::case("case-z").err().unwrap();
    assert!(e.contains("case-a"), "{e}");
}

#[test]
fn a_dropped_mesh_json_is_read_from_memory() {
    let mesh = "{\"vertices\": [[0,0],[1,0],[1,1],[0,1]], \"triangles\": [[0,1,2],[0,2,3]]}";
    let mut files = MemoryFiles::default();
    files.insert("square.json", mesh.as_bytes().to_vec());
    let text = "name = \"dropped\"\ngravity = [0.0, -9.8]\n[mesh]\nkind = \"file\"\npath = \"square.json\"\n[solver]\nkind = \"xpbd\"\ndt = 0.01\nsteps = 10\n[material]\nyoungs_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n";
    let mut app = App::scene(text, "dropped.toml", files).unwrap();
    assert_eq!(app.triangles().len(), 2);
    frames(&mut app, 3);
    assert!(app.positions()[0].y < 0.0, "it falls");
}

#[test]
fn a_blow_up_stops_with_the_command_line_message_and_reset_recovers() {
    let mut app = App::case("case-a").unwrap();
    // Explicit at 20 ms is far past case A's stability limit (about 2 ms).
    app.set("solver.dt", "0.02").unwrap();
    let mut failed = None;
    for _ in 0..500 {
        let want = app.begin_frame(1.0 / 60.0);
        if let Err(e) = app.step(want) {
            failed = Some(e);
            break;
        }
        app.end_frame(want, 1.0, 1.0 / 60.0);
    }
    let e = failed.expect("explicit at 20 ms blows up");
    assert!(e.starts_with("built-in case-a: "), "{e}");
    assert!(e.contains("non-finite") || e.contains("not finite"), "{e}");
    assert_eq!(app.hud().error.as_deref(), Some(e.as_str()));
    assert_eq!(
        app.begin_frame(1.0 / 60.0),
        0,
        "a stopped run wants no steps"
    );
    assert!(app.step(1).is_err());
    app.set("solver.dt", "0.001").unwrap();
    app.reset();
    assert!(app.hud().error.is_none());
    assert_eq!(app.state().t, 0.0);
    frames(&mut app, 3);
    assert!(app.state().t > 0.0);
}

/// The app steps a scene exactly as `fem-scene` builds and steps it.
#[test]
fn the_app_steps_exactly_as_the_scene_crate() {
    for case in ["case-a", "case-d"] {
        let mut app = App::case(case).unwrap();
        let want = app.begin_frame(0.05);
        app.step(want).unwrap();
        let scene = load_case(case, &[]).unwrap();
        let mesh = build_mesh(&scene, &fem_scene::build::NoFiles).unwrap();
        let e = energy(&scene).unwrap();
        let digest = dispatch_energy!(e, e => {
            let model = build_model(&scene, mesh, e).unwrap();
            let mut stepper = build_stepper(&scene, &model).unwrap();
            let mut state = initial_state(&scene, &model).unwrap();
            for _ in 0..want {
                stepper.step(&model, &mut state).unwrap();
            }
            state.digest()
        });
        assert_eq!(app.state().digest(), digest, "{case}");
    }
}

/// A drag recorded in the app replays to the same state in the app and, offline, in
/// `fem-scene`'s run (what `fem2d run --drag` does), bit for bit.
#[test]
fn a_recorded_drag_replays_the_same_in_the_app_and_offline() {
    let mut app = App::case("case-a").unwrap();
    frames(&mut app, 3);
    app.reset();
    app.start_recording();
    frames(&mut app, 2);
    assert!(app.grab_at(4.9, 0.55, 0.0).unwrap());
    for k in 1..=20 {
        app.drag_to(4.9 - 0.01 * k as f64, 0.55 + 0.04 * k as f64)
            .unwrap();
        frames(&mut app, 1);
    }
    app.release();
    frames(&mut app, 5);
    let drag = app.stop_recording();
    assert_eq!(drag.events.len(), 22, "grab, 20 moves, release");
    let steps = app.state().step;
    let live = app.state().digest();
    let live_x = app.state().x.clone();

    // Replayed in the app, from a reset.
    app.replay(&drag);
    assert_eq!(app.state().t, 0.0);
    app.step(steps).unwrap();
    assert_eq!(app.state().digest(), live, "replay in the app");

    // Offline, through the JSON form.
    let parsed = fem_scene::drag::DragTrajectory::parse(&drag.to_json(), "drag.json").unwrap();
    assert_eq!(parsed, drag);
    let scene = load_case("case-a", &[format!("solver.steps={steps}")]).unwrap();
    let mut env = fem_scene::run::RunEnv {
        drag: Some(&parsed),
        ..fem_scene::run::RunEnv::default()
    };
    let result = fem_scene::run::run(&scene, &mut env).unwrap();
    let offline: Vec<[f64; 2]> = live_x.iter().map(|p| [p.x, p.y]).collect();
    assert_eq!(result.final_positions, offline, "offline run");
}

/// Case D's debris can be grabbed and pushed: held by the hand, it sits where the hand holds
/// it after every step, moves with the hand's velocity, and pressing it onto the leg raises
/// the stress there; released, it falls on its own.
#[test]
fn the_debris_can_be_grabbed_and_pushed_onto_the_leg() {
    // Penalty contact (explicit) lets the hand push the debris into the leg; explicit needs the
    // homogeneous body (its coarser mesh allows 0.1 ms; with bones, rigid or not, the soft
    // tissue of the finer mesh needs 35 us).
    let mut app = App::case("case-d").unwrap();
    app.set("regions", "[]").unwrap();
    app.set("mesh.skeleton", "false").unwrap();
    app.set("solver.kind", "\"explicit\"").unwrap();
    app.set("solver.dt", "1e-4").unwrap();
    let centre = |app: &App| {
        let poly = &app.obstacles()[0];
        poly.iter()
            .fold(fem_core::math::Vec2::zeros(), |a, p| a + p)
            / poly.len() as f64
    };
    let c0 = centre(&app);
    assert!(app.grab_at(c0.x, c0.y + 0.05, 0.0).unwrap());
    assert!(matches!(
        app.held(),
        fem_web::Held::Obstacle { index: 0, .. }
    ));
    // Lift it a little, hold it up for a while: it does not fall.
    app.drag_to(c0.x, c0.y + 0.1).unwrap();
    frames(&mut app, 10);
    let c = centre(&app);
    assert!(
        (c - (c0 + fem_core::math::Vec2::new(0.0, 0.05))).norm() < 1e-9,
        "{c:?}"
    );
    let body = app.state().bodies[0];
    assert!(
        body.velocity.norm() < 1e-9,
        "held still: {:?}",
        body.velocity
    );
    let calm = app.hud().peak_von_mises;
    // Push it down onto the leg, 3 cm below where it started, over 20 frames.
    for k in 1..=20 {
        app.drag_to(c0.x, c0.y + 0.05 - 0.004 * k as f64).unwrap();
        frames(&mut app, 1);
    }
    let pushed = app.hud().peak_von_mises;
    assert!(pushed > 2.0 * calm, "peak von Mises {calm} -> {pushed} Pa");
    app.release();
    assert_eq!(app.held(), fem_web::Held::Nothing);
}

/// Case D under the barrier solvers in the app: at a 90 Hz step the debris lands on the leg
/// and the body rests on the ground, the heads-up display counts the contacts, their smallest
/// gap stays positive and their force carries the body's weight once it settles.
#[test]
fn case_d_runs_under_implicit_euler_and_vbd_with_contact_in_the_hud() {
    for solver in ["implicit", "vbd"] {
        let mut app = App::case("case-d").unwrap();
        app.set("solver.kind", &format!("\"{solver}\"")).unwrap();
        app.set("solver.dt", &(1.0 / 90.0).to_string()).unwrap();
        if solver == "vbd" {
            // With rigid bones (the scene's) VBD settles the body; with elastic ones, 10^4
            // times stiffer, its vertex Gauss-Seidel does not in 1.5 s at 50 sweeps (measured:
            // a net contact force of 1809 N against the 686 N weight).
            app.set("solver.iterations", "50").unwrap();
        }
        frames(&mut app, 90);
        let hud = app.hud().clone();
        assert!(hud.error.is_none(), "{solver}: {:?}", hud.error);
        assert!(hud.contacts > 0, "{solver}: no contacts");
        assert!(
            hud.min_gap > 0.0 && hud.min_gap < 1e-3,
            "{solver}: smallest gap {} m",
            hud.min_gap
        );
        // The net contact force on the body balances its weight (70 kg) once the impact has
        // died down (1.5 s, damping 20/s): within 5 % (VBD at 50 sweeps).
        assert!(
            (hud.contact_force[1] - 70.0 * 9.8).abs() < 0.05 * 70.0 * 9.8,
            "{solver}: contact force {:?} N",
            hud.contact_force
        );
        // The pressure shown is the largest vertex pressure of the body's boundary, and the
        // contact length a part of the body's length (about 1.8 m).
        let peak = app.contact_pressure().iter().copied().fold(0.0, f64::max);
        assert!(
            hud.contact_pressure_peak > 0.0 && hud.contact_pressure_peak == peak,
            "{solver}: peak pressure {} Pa, largest vertex pressure {peak} Pa",
            hud.contact_pressure_peak
        );
        assert!(
            hud.contact_length > 0.0 && hud.contact_length < 1.8,
            "{solver}: contact length {} m",
            hud.contact_length
        );
    }
}

/// Under barrier contact the hand places a held obstacle where it is dragged; pushed into the
/// leg, the next step stops with a one-line message naming the overlap (barrier contact needs
/// the body and the obstacles apart), and reset recovers. The penalty solvers push the leg.
#[test]
fn pushing_the_debris_into_the_leg_under_implicit_euler_is_a_clear_error_and_reset_recovers() {
    let mut app = App::case("case-d").unwrap();
    app.set("solver.kind", "\"implicit\"").unwrap();
    app.set("solver.dt", &(1.0 / 90.0).to_string()).unwrap();
    let poly = app.obstacles()[0].clone();
    let c0 = poly
        .iter()
        .fold(fem_core::math::Vec2::zeros(), |a, p| a + p)
        / poly.len() as f64;
    assert!(app.grab_at(c0.x, c0.y, 0.0).unwrap());
    app.drag_to(c0.x, c0.y - 0.05).unwrap();
    // The first step moves the debris to the hand; the second finds it inside the leg.
    assert_eq!(app.step(3).unwrap(), 1);
    let e = app.hud().error.clone().unwrap();
    assert!(
        e.starts_with("built-in case-d: implicit.contact = ") && e.contains("inside"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1);
    assert_eq!(app.step(1).unwrap_err(), e);
    app.release();
    app.reset();
    assert!(app.hud().error.is_none());
    assert_eq!(app.step(3).unwrap(), 3);
}

#[test]
fn material_regions_reach_the_page_and_the_hud_gives_the_base_materials_own_peak() {
    // Case D: the bones are region 1, the soft tissue region 0; the HUD's soft tissue peak is
    // the largest von Mises stress over region 0's triangles, below the bones' after the slab
    // has landed (elastic bones: rigid ones, the scene's default, carry no stress).
    let mut app = App::case("case-d").unwrap();
    assert!(
        app.set("regions.0.rigid", "false").unwrap(),
        "rigid bodies restart"
    );
    assert_eq!(app.material_region_names(), ["soft-tissue", "bone"]);
    let regions = app.material_regions();
    assert_eq!(regions.len(), app.triangles().len());
    let bones = regions.iter().filter(|&&r| r == 1).count();
    assert!(
        bones > 100 && bones < regions.len() / 2,
        "{bones} bone triangles"
    );
    assert!(regions.iter().all(|&r| r <= 1));
    app.step(10).unwrap();
    let vm = app.field(Field::VonMises);
    let soft = vm
        .iter()
        .zip(&regions)
        .filter(|&(_, &r)| r == 0)
        .map(|(v, _)| *v)
        .fold(0.0, f64::max);
    let hud = app.hud().clone();
    assert_eq!(hud.peak_von_mises_base, soft);
    assert!(
        hud.peak_von_mises_base > 0.0 && hud.peak_von_mises_base < hud.peak_von_mises,
        "soft tissue {} Pa, body {} Pa",
        hud.peak_von_mises_base,
        hud.peak_von_mises
    );
    // Without regions every triangle is the base material and the two peaks agree.
    assert!(!app.set("regions", "[]").unwrap(), "regions do not restart");
    assert!(app.material_regions().iter().all(|&r| r == 0));
    assert_eq!(app.material_region_names(), ["soft-tissue"]);
    let hud = app.hud();
    assert_eq!(hud.peak_von_mises_base, hud.peak_von_mises);
}

/// The bones' `rigid` key reaches the app (the page's `bones` select sets it): case D starts
/// with rigid bones, and elastic ones are one `set` away; a body without regions has no key.
#[test]
fn the_bones_are_rigid_or_elastic_one_setting_away() {
    let mut app = App::case("case-d").unwrap();
    assert_eq!(app.get("regions.0.rigid").as_deref(), Some("true"));
    frames(&mut app, 3);
    assert!(app.set("regions.0.rigid", "false").unwrap(), "a restart");
    assert_eq!(app.get("regions.0.rigid").as_deref(), Some("false"));
    frames(&mut app, 3);
    assert!(app.hud().peak_von_mises > app.hud().peak_von_mises_base);
    assert!(
        App::case("case-a")
            .unwrap()
            .get("regions.0.rigid")
            .is_none()
    );
}
