//! The Newton-based solvers through `fem2d`: implicit Euler on case A agrees with explicit at
//! the paper's frame 10, the static cantilever (`fixtures/scenes/cantilever-static.toml`) meets
//! Timoshenko's deflection, tractions set from the command line act (statics and dynamics),
//! load increments are frames, a Newton solve that fails stops the run like a blow-up, contact
//! and bad Newton settings are one-line errors, and `fem2d compare` takes both solvers.

use crate::common::{arg, fem2d, json, one_line_error, read, run_ok, scratch};
use std::path::{Path, PathBuf};

/// The rows of `probes.csv` (header dropped).
fn rows(path: &Path) -> Vec<Vec<f64>> {
    read(path)
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

fn cantilever() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/cantilever-static.toml")
}

/// Timoshenko's tip deflection of the fixture's cantilever (plane strain) under end load `p`
/// (N per unit thickness): `p L^3 / (3 E' I) + p L / (5/6 G H)`.
fn timoshenko(p: f64) -> f64 {
    let (l, h, e, nu) = (10.0_f64, 1.0_f64, 1.0e6, 0.3);
    let e_prime = e / (1.0 - nu * nu);
    let g = e / (2.0 * (1.0 + nu));
    let i = h.powi(3) / 12.0;
    p * l.powi(3) / (3.0 * e_prime * i) + p * l / (5.0 / 6.0 * g * h)
}

#[test]
fn implicit_case_a_agrees_with_explicit_at_frame_10() {
    let dir = scratch("implicit-a");
    let (exp, imp) = (dir.join("explicit"), dir.join("implicit"));
    run_ok(&["case-a", "--steps", "200"], &exp);
    let out = run_ok(&["case-a", "--steps", "200", "--solver", "implicit"], &imp);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Newton: "), "{stdout}");

    let s = json(&imp.join("summary.json"));
    assert_eq!(s["solver"], "implicit");
    assert_eq!(s["blew_up"], false);
    assert_eq!(s["steps_completed"], 200);
    assert!(s["time_step_warning"].is_null());
    // At least one Newton iteration per step; the residual is a force, N.
    let iterations = s["newton_iterations"].as_u64().unwrap();
    assert!((200..=200 * 50).contains(&iterations), "{iterations}");
    let residual = s["final_residual"].as_f64().unwrap();
    assert!(
        residual.is_finite() && (0.0..1e-6).contains(&residual),
        "{residual}"
    );
    let e = json(&exp.join("summary.json"));
    assert_eq!(e["newton_iterations"], 0);
    assert!(e["final_residual"].is_null());

    // Frame 10 (step 100, 0.1 s): the tip has fallen about 1/2 g t^2 = 49 mm under both.
    let (a, b) = (rows(&exp.join("probes.csv")), rows(&imp.join("probes.csv")));
    assert_eq!(a.len(), 21);
    assert_eq!(b.len(), 21);
    assert_eq!((a[10][0], b[10][0]), (100.0, 100.0));
    let (ue, ui) = (a[10][3], b[10][3]);
    eprintln!(
        "frame 10 tip uy: explicit {ue:.6} m, implicit {ui:.6} m, difference {:.3} mm",
        1e3 * (ui - ue).abs()
    );
    assert!((ue + 0.049).abs() < 0.003, "{ue}");
    assert!((ui - ue).abs() < 1e-3, "explicit {ue}, implicit {ui}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn implicit_is_stable_where_explicit_blows_up() {
    let dir = scratch("implicit-big-dt");
    // 0.05 s is more than twenty times case A's explicit limit (run_cli.rs blows up with it).
    run_ok(
        &[
            "case-a", "--dt", "0.05", "--steps", "20", "--solver", "implicit",
        ],
        &dir,
    );
    let s = json(&dir.join("summary.json"));
    assert_eq!(s["blew_up"], false);
    assert_eq!(s["steps_completed"], 20);
    let uy = s["probes"][0]["final_displacement"][1].as_f64().unwrap();
    assert!(uy < -0.1 && uy > -5.0, "{uy}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn static_cantilever_matches_timoshenko() {
    let dir = scratch("static-cantilever");
    let out_dir = dir.join("out");
    let out = run_ok(&[arg(&cantilever())], &out_dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("load increments"), "{stdout}");

    let s = json(&out_dir.join("summary.json"));
    assert_eq!(s["scene"], "cantilever-static");
    assert_eq!(s["solver"], "static");
    assert_eq!(s["energy"], "linear");
    assert_eq!(s["blew_up"], false);
    assert_eq!(
        (s["steps"].as_u64(), s["steps_completed"].as_u64()),
        (Some(1), Some(1))
    );
    assert_eq!(s["simulated_seconds"], 0.0);
    assert_eq!(s["real_time_factor"], 0.0);
    assert_eq!(s["dt"], 1e-3, "dt is reported as given");
    assert!(s["newton_iterations"].as_u64().unwrap() >= 1);
    assert!(s["final_residual"].as_f64().unwrap().is_finite());
    // 100 x 10 crossed cells.
    assert_eq!(s["triangles"], 4000);
    assert_eq!(s["probes"][0]["rest"], serde_json::json!([10.0, 0.5]));

    // probes.csv: the rest state and the equilibrium; the time column is the load factor.
    let r = rows(&out_dir.join("probes.csv"));
    assert_eq!(r.len(), 2);
    assert_eq!(r[0], [0.0, 0.0, 0.0, 0.0]);
    assert_eq!((r[1][0], r[1][1]), (1.0, 1.0));
    let deflection = -r[1][3];
    let theory = timoshenko(1.0);
    assert!((theory - 3.671e-3).abs() < 1e-6, "{theory}");
    let error = (deflection - theory) / theory;
    eprintln!(
        "static tip deflection {deflection:.6e} m, Timoshenko {theory:.6e} m, {:.2} %",
        100.0 * error
    );
    assert!(error.abs() < 0.02, "{deflection} vs {theory}");
    assert_eq!(read(&out_dir.join("frames.jsonl")).lines().count(), 2);

    // The scene as run reproduces the run.
    let again = dir.join("again");
    run_ok(&[arg(&out_dir.join("scene.toml"))], &again);
    assert_eq!(
        read(&again.join("probes.csv")),
        read(&out_dir.join("probes.csv"))
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn traction_and_load_steps_set_from_the_command_line() {
    let dir = scratch("static-set");
    let (one, two) = (dir.join("one"), dir.join("two"));
    run_ok(&[arg(&cantilever())], &one);
    // Twice the traction in four load increments: linear elasticity, twice the deflection.
    run_ok(
        &[
            arg(&cantilever()),
            "--set",
            "traction.0.traction=[0.0, -2.0]",
            "--set",
            "solver.load_steps=4",
        ],
        &two,
    );
    let as_run = fem_cases::files::load_scene_file(&two.join("scene.toml"), &[]).unwrap();
    assert_eq!(as_run.scene.traction[0].traction, [0.0, -2.0]);
    assert_eq!(
        as_run.scene.solver.get("load_steps"),
        Some(toml::Value::Integer(4))
    );
    let s = json(&two.join("summary.json"));
    assert_eq!(
        (s["steps"].as_u64(), s["steps_completed"].as_u64()),
        (Some(4), Some(4))
    );
    let (a, b) = (rows(&one.join("probes.csv")), rows(&two.join("probes.csv")));
    assert_eq!(b.len(), 5, "the rest state and one frame per increment");
    for (k, row) in b.iter().enumerate() {
        assert_eq!(row[0], k as f64);
        assert!((row[1] - 0.25 * k as f64).abs() < 1e-12, "{row:?}");
        // Linear: each increment adds the same deflection.
        let expected = 0.5 * k as f64 * a[1][3];
        assert!((row[3] - expected).abs() < 1e-6 * a[1][3].abs(), "{row:?}");
    }

    // A traction acts in a dynamic run too: case A without gravity, pulled up at its free end.
    let up = dir.join("up");
    run_ok(
        &[
            "case-a",
            "--steps",
            "100",
            "--set",
            "gravity=[0.0, 0.0]",
            "--set",
            "traction=[{min = [5.0, 0.0], max = [5.0, 1.0], traction = [0.0, 0.5]}]",
        ],
        &up,
    );
    let uy = json(&up.join("summary.json"))["probes"][0]["final_displacement"][1]
        .as_f64()
        .unwrap();
    assert!(uy > 0.0, "{uy}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn static_with_gravity_and_prescribed_motion() {
    let dir = scratch("static-b");
    // Case B statically: the bar in equilibrium with its right end moved 2 m (2 m/s for 1 s).
    run_ok(
        &[
            "case-b",
            "--solver",
            "static",
            "--set",
            "solver.load_steps=2",
        ],
        &dir,
    );
    let s = json(&dir.join("summary.json"));
    assert_eq!(s["blew_up"], false);
    assert_eq!(s["steps_completed"], 2);
    let probes = s["probes"].as_array().unwrap();
    let right = probes.iter().find(|p| p["name"] == "right").unwrap();
    let ux = right["final_displacement"][0].as_f64().unwrap();
    assert!((ux - 2.0).abs() < 1e-9, "{ux}");
    // Stretched, the bar narrows: its top moves down and its bottom up at mid-span.
    let top = probes.iter().find(|p| p["name"] == "mid_top").unwrap();
    assert!(top["final_displacement"][1].as_f64().unwrap() < 0.0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_newton_solve_that_fails_stops_the_run() {
    let dir = scratch("not-converged");
    // One iteration cannot reach the tolerance: the first step fails.
    let out_dir = dir.join("implicit");
    let error = one_line_error(&[
        "run",
        "case-a",
        "--solver",
        "implicit",
        "--steps",
        "20",
        "--set",
        "solver.max_iterations=1",
        "--out",
        arg(&out_dir),
        "-q",
    ]);
    assert!(error.contains("built-in case-a"), "{error}");
    assert!(error.contains("Newton did not converge"), "{error}");
    let s = json(&out_dir.join("summary.json"));
    assert_eq!(s["blew_up"], true);
    assert!(s["steps_completed"].as_u64().unwrap() < 20);
    assert!(
        s["blow_up_message"]
            .as_str()
            .unwrap()
            .contains("did not converge")
    );

    // Statics: an increment that fails is halved, ten times at most, then the run stops.
    let out_dir = dir.join("static");
    let error = one_line_error(&[
        "run",
        arg(&cantilever()),
        "--energy",
        "neo-hookean",
        "--set",
        "traction.0.traction=[0.0, -3000.0]",
        "--set",
        "solver.max_iterations=2",
        "--set",
        "mesh.nx=20",
        "--set",
        "mesh.ny=2",
        "--out",
        arg(&out_dir),
        "-q",
    ]);
    assert!(error.contains("load increment"), "{error}");
    assert!(error.contains("10 halvings"), "{error}");
    let s = json(&out_dir.join("summary.json"));
    assert_eq!(s["blew_up"], true);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn contact_and_bad_newton_settings_are_one_line_errors() {
    let dir = scratch("newton-errors");
    for (args, needles) in [
        (
            vec!["case-d", "--solver", "pd"],
            vec!["built-in case-d", "solver.kind = pd", "contact"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "implicit",
                "--set",
                "solver.tolerance=0",
            ],
            vec!["solver.tolerance = 0", "(0, 1)"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "implicit",
                "--set",
                "solver.tolerance=-1",
            ],
            vec!["solver.tolerance = -1"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "static",
                "--set",
                "solver.load_steps=0",
            ],
            vec!["solver.load_steps = 0", "at least 1"],
        ),
        (
            vec!["case-a", "--set", "solver.load_steps=abc"],
            vec!["solver.load_steps", "abc"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "static",
                "--set",
                "solver.max_iterations=0",
            ],
            vec!["solver.max_iterations = 0"],
        ),
    ] {
        let out_dir = dir.join("out");
        let mut all = vec!["run"];
        all.extend(&args);
        all.extend(["--out", arg(&out_dir)]);
        let error = one_line_error(&all);
        for n in &needles {
            assert!(error.contains(n), "{args:?}: {n:?} missing from {error}");
        }
        assert!(!out_dir.exists(), "{args:?} created the output directory");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn compare_takes_explicit_and_implicit() {
    let dir = scratch("compare-implicit");
    let out = fem2d(&[
        "compare",
        "case-a",
        "--solvers",
        "explicit,implicit",
        "--energies",
        "stvk",
        "--set",
        "solver.steps=100",
        "--out",
        arg(&dir),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("| stvk | implicit |  | yes |"), "{stdout}");
    let json = json(&dir.join("compare.json"));
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[1]["solver"], "implicit");
    assert_eq!(rows[1]["stable"], true);
    let rms = rows[1]["probes"][0]["rms_vs_explicit"].as_f64().unwrap();
    assert!(rms < 1e-3, "{rms}");
    std::fs::remove_dir_all(&dir).unwrap();
}
