//! `fem2d run` end to end: every output file in its contract form (`summary.json`,
//! `probes.csv`, `frames.jsonl`, `mesh.json`, `scene.toml`), the written scene reproducing the
//! run, every built-in case, the energy / solver / thread / `--set` flags, bad input ending with
//! one `error:` line and no output file, and a run that blows up.

use crate::common::{arg, fem2d, json, one_line_error, read, run_ok, scratch};
use std::path::Path;

use serde_json::Value;

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The outputs, and the marker that says fem2d wrote the directory (so it may replace it).
const OUTPUTS: [&str; 8] = [
    ".fem2d-output",
    "frames.jsonl",
    "mesh.json",
    "probes.csv",
    "regions.csv",
    "scene.toml",
    "stress.json",
    "summary.json",
];

/// `probes.csv` as a header and rows of numbers.
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = read(path);
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            let row: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            assert_eq!(row.len(), header.len(), "{l}");
            row
        })
        .collect();
    (header, rows)
}

/// The summary without the fields that measure time.
fn without_timings(mut summary: Value) -> Value {
    let map = summary.as_object_mut().unwrap();
    for key in [
        "wall_seconds",
        "step_seconds",
        "element_steps_per_second",
        "real_time_factor",
    ] {
        assert!(map.remove(key).is_some(), "{key}");
    }
    summary
}

/// Every field the BRIEF's run-output contract names, with its JSON type.
fn check_contract_fields(s: &Value) {
    for key in ["scene", "energy", "solver"] {
        assert!(s[key].is_string(), "{key}: {}", s[key]);
    }
    for key in ["steps", "vertices", "triangles", "inverted_elements"] {
        assert!(s[key].is_u64(), "{key}: {}", s[key]);
    }
    for key in [
        "dt",
        "wall_seconds",
        "element_steps_per_second",
        "max_von_mises",
        "min_det_f",
    ] {
        assert!(s[key].is_f64(), "{key}: {}", s[key]);
        assert!(s[key].as_f64().unwrap().is_finite(), "{key}");
    }
    assert!(s["blew_up"].is_boolean());
    assert!(s["wall_seconds"].as_f64().unwrap() >= 0.0);
    assert!(s["element_steps_per_second"].as_f64().unwrap() >= 0.0);
    assert!(s["max_von_mises"].as_f64().unwrap() >= 0.0);
    // Which plane model and von Mises formula the run used.
    assert!(s["plane"].is_string() && s["von_mises_formula"].is_string());
}

#[test]
fn case_a_writes_every_output_in_contract_form() {
    let dir = scratch("case-a");
    let out_dir = dir.join("out");
    let out = run_ok(&["case-a", "--steps", "200"], &out_dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("probe tip"), "{stdout}");
    assert_eq!(listing(&out_dir), OUTPUTS, "no temporary file is left");
    // stress.json: one value per triangle and per vertex, the peak matching the summary's
    // final peak.
    let stress = json(&out_dir.join("stress.json"));
    let summary = json(&out_dir.join("summary.json"));
    let per_element = stress["per_element"].as_array().unwrap();
    assert_eq!(
        per_element.len() as u64,
        summary["triangles"].as_u64().unwrap()
    );
    assert_eq!(
        stress["per_vertex"].as_array().unwrap().len() as u64,
        summary["vertices"].as_u64().unwrap()
    );
    let peak = per_element
        .iter()
        .filter_map(Value::as_f64)
        .fold(0.0, f64::max);
    assert_eq!(peak, summary["final_max_von_mises"].as_f64().unwrap());

    // summary.json
    let s = json(&out_dir.join("summary.json"));
    check_contract_fields(&s);
    assert_eq!(s["scene"], "case-a");
    assert_eq!(s["energy"], "stvk");
    assert_eq!(s["solver"], "explicit");
    assert_eq!(s["dt"], 1e-3);
    assert_eq!(s["steps"], 200);
    assert_eq!(s["steps_completed"], 200);
    assert_eq!(s["blew_up"], false);
    assert!(s["blow_up_message"].is_null());
    assert_eq!(s["plane"], "plane-strain");
    let (nv, nt) = (
        s["vertices"].as_u64().unwrap() as usize,
        s["triangles"].as_u64().unwrap() as usize,
    );
    assert_eq!((nv, nt), (21 * 5, 20 * 4 * 2));
    assert!(s["max_von_mises"].as_f64().unwrap() > 0.0);
    let min_det_f = s["min_det_f"].as_f64().unwrap();
    assert!(min_det_f > 0.5 && min_det_f < 1.0, "{min_det_f}");
    assert_eq!(s["inverted_elements"], 0);
    let probe = &s["probes"][0];
    assert_eq!(probe["name"], "tip");
    assert_eq!(probe["rest"], serde_json::json!([5.0, 0.0]));
    let tip = probe["vertex"].as_u64().unwrap() as usize;

    // probes.csv: step 0 and every 10th step, times step * dt, displacements in metres.
    let (header, rows) = csv(&out_dir.join("probes.csv"));
    assert_eq!(header, ["step", "time", "tip.ux", "tip.uy"]);
    assert_eq!(rows.len(), 21);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (10 * k) as f64);
        assert!((row[1] - row[0] * 1e-3).abs() <= 1e-12, "{row:?}");
    }
    assert_eq!(rows[0][2..], [0.0, 0.0]);
    // The cantilever falls: about 1/2 g t^2 = 49 mm at frame 10 (0.1 s).
    let uy10 = rows[10][3];
    assert!((uy10 + 0.049).abs() < 0.003, "{uy10}");
    let last = rows.last().unwrap();
    assert_eq!(
        [last[2], last[3]],
        [
            probe["final_displacement"][0].as_f64().unwrap(),
            probe["final_displacement"][1].as_f64().unwrap()
        ]
    );

    // mesh.json: the contract format, counter-clockwise triangles.
    let mesh = json(&out_dir.join("mesh.json"));
    let vertices: Vec<[f64; 2]> = serde_json::from_value(mesh["vertices"].clone()).unwrap();
    let triangles: Vec<[usize; 3]> = serde_json::from_value(mesh["triangles"].clone()).unwrap();
    assert_eq!((vertices.len(), triangles.len()), (nv, nt));
    for t in &triangles {
        let [a, b, c] = t.map(|i| vertices[i]);
        let area2 = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        assert!(area2 > 0.0, "{t:?} is not counter-clockwise");
    }
    assert_eq!(vertices[tip], [5.0, 0.0]);
    let reread = fem_mesh::io::read_mesh_json(&out_dir.join("mesh.json")).unwrap();
    assert_eq!(reread.vertices, vertices);

    // frames.jsonl: one JSON object per frame, in step with probes.csv.
    let frames = read(&out_dir.join("frames.jsonl"));
    let frames: Vec<Value> = frames
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(frames.len(), rows.len());
    for (frame, row) in frames.iter().zip(&rows) {
        assert_eq!(frame["step"].as_f64().unwrap(), row[0]);
        assert_eq!(frame["time"].as_f64().unwrap(), row[1]);
        let x: Vec<f64> = serde_json::from_value(frame["positions"].clone()).unwrap();
        assert_eq!(x.len(), 2 * nv);
        assert_eq!(frame["von_mises"].as_array().unwrap().len(), nt);
        assert_eq!(frame["obstacles"], serde_json::json!([]));
        // The probe column is the tracked vertex's displacement.
        assert_eq!(x[2 * tip] - vertices[tip][0], row[2]);
        assert_eq!(x[2 * tip + 1] - vertices[tip][1], row[3]);
    }
    let first: Vec<f64> = serde_json::from_value(frames[0]["positions"].clone()).unwrap();
    assert_eq!(first, vertices.concat(), "frame 0 is the rest mesh");

    // scene.toml reproduces the run.
    let again = dir.join("again");
    run_ok(&[arg(&out_dir.join("scene.toml"))], &again);
    assert_eq!(
        without_timings(json(&again.join("summary.json"))),
        without_timings(s)
    );
    for name in ["probes.csv", "frames.jsonl", "mesh.json", "scene.toml"] {
        assert_eq!(read(&again.join(name)), read(&out_dir.join(name)), "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cases_b_c_d_run_a_few_steps() {
    let dir = scratch("cases");
    for (case, energy, solver, rows) in [
        ("case-b", "stvk", "explicit", 3),
        ("case-c", "stvk", "explicit", 3),
        // Implicit Euler at 90 Hz, a frame every step.
        ("case-d", "neo-hookean", "implicit", 21),
    ] {
        let out_dir = dir.join(case);
        run_ok(&[case, "--steps", "20"], &out_dir);
        assert_eq!(listing(&out_dir), OUTPUTS, "{case}");
        let s = json(&out_dir.join("summary.json"));
        check_contract_fields(&s);
        assert_eq!(s["scene"], case);
        assert_eq!(s["energy"], energy);
        assert_eq!(s["solver"], solver);
        assert_eq!(s["steps"], 20);
        assert_eq!(s["blew_up"], false);
        let (header, data) = csv(&out_dir.join("probes.csv"));
        let mut expected = vec!["step".to_owned(), "time".to_owned()];
        for p in &fem_scene::cases::load_case(case, &[]).unwrap().scene.probes {
            expected.push(format!("{}.ux", p.name));
            expected.push(format!("{}.uy", p.name));
        }
        assert!(expected.len() > 2, "{case} has probes");
        assert_eq!(header, expected, "{case}");
        assert_eq!(data.len(), rows, "{case}");
        assert_eq!(data.last().unwrap()[0], 20.0, "{case}");
        let frames = read(&out_dir.join("frames.jsonl"));
        assert_eq!(frames.lines().count(), rows, "{case}");
        let nv = s["vertices"].as_u64().unwrap() as usize;
        let last: Value = serde_json::from_str(frames.lines().last().unwrap()).unwrap();
        assert_eq!(last["positions"].as_array().unwrap().len(), 2 * nv);
        let mesh = fem_mesh::io::read_mesh_json(&out_dir.join("mesh.json")).unwrap();
        assert_eq!(mesh.vertices.len(), nv, "{case}");
        if case == "case-d" {
            // The debris: one obstacle polygon of four corners in every frame.
            assert_eq!(last["obstacles"].as_array().unwrap().len(), 1);
            assert_eq!(last["obstacles"][0].as_array().unwrap().len(), 4);
        }
        if case == "case-b" {
            // The right end is pulled at 2 m/s: 0.04 m after 0.02 s.
            let column = header.iter().position(|h| h == "right.ux").unwrap();
            let right_ux = data.last().unwrap()[column];
            assert!((right_ux - 0.04).abs() < 1e-9, "{right_ux}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn energy_and_solver_flags_reach_the_run() {
    let dir = scratch("flags");
    let mut tips = Vec::new();
    for energy in [
        "stvk",
        "corotational",
        "neo-hookean",
        "stable-neo-hookean",
        "linear",
    ] {
        let out_dir = dir.join(energy);
        run_ok(&["case-a", "--steps", "30", "--energy", energy], &out_dir);
        let s = json(&out_dir.join("summary.json"));
        assert_eq!(s["energy"], energy);
        assert!(read(&out_dir.join("scene.toml")).contains(&format!("energy = \"{energy}\"")));
        tips.push(s["probes"][0]["final_displacement"][1].as_f64().unwrap());
    }
    assert!(tips.iter().all(|u| *u < 0.0), "{tips:?}");
    for solver in ["explicit", "pbd", "xpbd"] {
        let out_dir = dir.join(solver);
        run_ok(
            &[
                "case-c", "--steps", "30", "--solver", solver, "--dt", "1.5e-3",
            ],
            &out_dir,
        );
        let s = json(&out_dir.join("summary.json"));
        check_contract_fields(&s);
        assert_eq!(s["solver"], solver);
        assert_eq!(s["dt"], 1.5e-3);
        assert_eq!(s["blew_up"], false);
        let (_, rows) = csv(&out_dir.join("probes.csv"));
        assert_eq!(rows.len(), 4);
        assert!((rows[3][1] - 0.045).abs() < 1e-12);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn thread_count_does_not_change_the_numbers() {
    let dir = scratch("threads");
    for solver in ["explicit", "pbd", "xpbd", "implicit"] {
        let one = dir.join(format!("{solver}-1"));
        let two = dir.join(format!("{solver}-2"));
        let common = ["case-a", "--steps", "100", "--solver", solver];
        run_ok(&[&common[..], &["--threads", "1"]].concat(), &one);
        run_ok(&[&common[..], &["--threads", "2"]].concat(), &two);
        assert_eq!(json(&one.join("summary.json"))["threads"], 1);
        assert_eq!(json(&two.join("summary.json"))["threads"], 2);
        for name in ["probes.csv", "frames.jsonl"] {
            assert_eq!(
                read(&one.join(name)),
                read(&two.join(name)),
                "{solver}: {name} differs between 1 and 2 threads"
            );
        }
        let (a, b) = (
            without_timings(json(&one.join("summary.json"))),
            without_timings(json(&two.join("summary.json"))),
        );
        let strip = |mut v: Value| {
            v.as_object_mut().unwrap().remove("threads");
            v
        };
        assert_eq!(strip(a), strip(b), "{solver}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn set_changes_the_result() {
    let dir = scratch("set");
    let (soft, stiff) = (dir.join("soft"), dir.join("stiff"));
    run_ok(&["case-a", "--steps", "300"], &soft);
    run_ok(
        &[
            "case-a",
            "--steps",
            "300",
            "--set",
            "material.youngs_modulus=2000",
        ],
        &stiff,
    );
    assert!(read(&stiff.join("scene.toml")).contains("youngs_modulus = 2000.0"));
    let (_, a) = csv(&soft.join("probes.csv"));
    let (_, b) = csv(&stiff.join("probes.csv"));
    assert_eq!(a.len(), b.len());
    assert_ne!(a, b);
    // Twice as stiff: the tip sags less.
    let (ua, ub) = (a.last().unwrap()[3], b.last().unwrap()[3]);
    assert!(ub > ua, "stiff {ub} vs soft {ua}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn scene_file_with_a_relative_mesh_path_runs_and_reruns_from_its_copy() {
    let dir = scratch("file-mesh");
    std::fs::create_dir_all(dir.join("scenes/meshes")).unwrap();
    std::fs::write(
        dir.join("scenes/meshes/strip.json"),
        r#"{"vertices": [[0,0],[1,0],[2,0],[0,1],[1,1],[2,1]],
            "triangles": [[0,1,4],[0,4,3],[1,2,5],[1,5,4]]}"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("scenes/strip.toml"),
        r#"name = "strip"
energy = "corotational"
[mesh]
kind = "file"
path = "meshes/strip.json"
[material]
youngs_modulus = 1e4
poisson_ratio = 0.3
density = 1.0
[solver]
dt = 1e-3
steps = 20
[[pinned]]
min = [0.0, 0.0]
max = [0.0, 1.0]
[[probes]]
name = "corner"
point = [2.0, 0.0]
[output]
frame_every = 5
frames = false
"#,
    )
    .unwrap();
    let first = dir.join("first");
    run_ok(&[arg(&dir.join("scenes/strip.toml"))], &first);
    assert_eq!(
        listing(&first),
        [
            ".fem2d-output",
            "mesh.json",
            "probes.csv",
            "regions.csv",
            "scene.toml",
            "stress.json",
            "summary.json"
        ],
        "frames = false writes no frames.jsonl"
    );
    let s = json(&first.join("summary.json"));
    assert_eq!(
        (s["vertices"].as_u64(), s["triangles"].as_u64()),
        (Some(6), Some(4))
    );
    assert_eq!(s["scene"], "strip");
    let (header, rows) = csv(&first.join("probes.csv"));
    assert_eq!(header, ["step", "time", "corner.ux", "corner.uy"]);
    assert_eq!(rows.len(), 5);
    // The copy written beside the outputs finds the mesh too.
    let second = dir.join("second");
    run_ok(&[arg(&first.join("scene.toml"))], &second);
    assert_eq!(
        read(&second.join("probes.csv")),
        read(&first.join("probes.csv"))
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Bad input: non-zero exit, exactly one stderr line `error: ...` containing every needle, and
/// no output in `--out`.
#[test]
fn bad_input_is_one_error_line_and_no_output() {
    let dir = scratch("bad");
    let malformed = dir.join("malformed.toml");
    std::fs::write(
        &malformed,
        "name = \"m\"\n[mesh]\nkind = \"rectangle\"\nwidth = 5.0 x\n",
    )
    .unwrap();
    let typo = dir.join("typo.toml");
    std::fs::write(
        &typo,
        fem_scene::cases::case_text("case-a")
            .unwrap()
            .replace("youngs_modulus", "youngs_modulos"),
    )
    .unwrap();
    let no_mesh = dir.join("no-mesh.toml");
    std::fs::write(
        &no_mesh,
        fem_scene::cases::case_text("case-a").unwrap().replace(
            "kind = \"rectangle\"\nwidth = 5.0\nheight = 1.0\nnx = 20\nny = 4\ndiagonal = \"left\"\n",
            "kind = \"file\"\npath = \"absent.json\"\n",
        ),
    )
    .unwrap();
    let missing = dir.join("missing.toml");
    let malformed_s = malformed.display().to_string();
    let typo_s = typo.display().to_string();
    let missing_s = missing.display().to_string();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["case-z"], vec!["`case-z`", "case-a"]),
        (vec![arg(&missing)], vec![&missing_s, "cannot read"]),
        (vec![arg(&malformed)], vec![&malformed_s, ":4:"]),
        (
            vec![arg(&typo)],
            vec![&typo_s, "material.youngs_modulos", "unknown field"],
        ),
        (vec![arg(&no_mesh)], vec!["absent.json"]),
        (
            vec!["case-a", "--set", "material.youngs_modulus=abc"],
            vec!["built-in case-a", "material.youngs_modulus", "abc"],
        ),
        (
            vec!["case-a", "--set", "material.youngs_modulus=nan"],
            vec!["material.youngs_modulus = NaN"],
        ),
        (
            vec!["case-a", "--set", "material.youngs_modulus=5e-324"],
            vec!["material.youngs_modulus = 5e-324", "at least 1e-290 Pa"],
        ),
        (
            vec!["case-a", "--set", "material.poisson_ratio=0.5"],
            vec!["material.poisson_ratio = 0.5"],
        ),
        (vec!["case-a", "--set", "nonsense"], vec!["nonsense"]),
        (
            vec!["case-a", "--set", "pinned.2.min=[0.0, 0.0]"],
            vec!["pinned.2.min", "past the end"],
        ),
        (
            vec![
                "case-a",
                "--set",
                "pinned.0.min=[9.0, 9.0]",
                "--set",
                "pinned.0.max=[9.5, 9.5]",
            ],
            vec!["pinned.0", "[9.0, 9.0]", "contains no mesh vertex"],
        ),
        (vec!["case-a", "--dt", "-1"], vec!["solver.dt = -1"]),
        (vec!["case-a", "--dt", "0"], vec!["solver.dt = 0"]),
        (vec!["case-a", "--steps", "0"], vec!["solver.steps = 0"]),
        (
            vec!["case-a", "--energy", "foo"],
            vec!["energy", "`foo`", "stvk"],
        ),
        (
            vec!["case-d", "--solver", "pd"],
            vec!["built-in case-d", "solver.kind = pd", "contact"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "static",
                "--set",
                "solver.load_steps=0",
            ],
            vec!["solver.load_steps = 0"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "implicit",
                "--set",
                "solver.tolerance=0",
            ],
            vec!["solver.tolerance = 0"],
        ),
        (
            vec![
                "case-a",
                "--set",
                "traction=[{min = [9.0, 9.0], max = [9.5, 9.5], traction = [0.0, 1.0]}]",
            ],
            vec!["traction.0", "contains no boundary edge"],
        ),
        (
            vec!["case-a", "--solver", "euler"],
            vec!["solver.kind", "euler"],
        ),
        (vec!["case-a", "--threads", "0"], vec!["--threads"]),
        // Geometry at t = 0: the body below the ground, an obstacle inside the body, a
        // self-crossing obstacle (before: flung or blown up without a word).
        (
            vec!["case-d", "--set", "ground.height=0.05"],
            vec![
                "built-in case-d",
                "ground: vertex",
                "below the ground at t = 0",
            ],
        ),
        (
            vec![
                "case-d",
                "--set",
                "obstacles.0.polygon=[[0.5, 0.0], [0.8, 0.0], [0.8, 0.3], [0.5, 0.3]]",
            ],
            vec!["obstacles[0]: overlaps the body at t = 0", "lies inside it"],
        ),
        (
            vec![
                "case-d",
                "--set",
                "obstacles.0.polygon=[[1.3, 0.5], [1.5, 0.7], [1.5, 0.5], [1.3, 0.7]]",
            ],
            vec![
                "obstacles.0.polygon = (edges 0 and 2 cross)",
                "simple polygon",
            ],
        ),
        (
            vec![
                "case-a",
                "--set",
                "mesh.nx=200",
                "--set",
                "mesh.ny=40",
                "--set",
                "output.frame_every=1",
                "--dt",
                "1e-5",
                "--steps",
                "1000000",
            ],
            vec![
                "output.frames: 1000002 frames of 32482 numbers",
                "raise output.frame_every",
            ],
        ),
        // Upper bounds (fem_solvers::limits, fem_cases::run::MAX_THREADS, MAX_GIF_FRAMES):
        // each a one-line error naming the field, never a hang or an allocation failure.
        (
            vec!["case-a", "--threads", "100000"],
            vec!["--threads 100000: must be at most 1024"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "xpbd",
                "--set",
                "solver.iterations=4294967296",
            ],
            vec!["solver.iterations = 4294967296", "at most 100000"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "pbd",
                "--set",
                "solver.substeps=1000000000",
            ],
            vec!["solver.substeps = 1000000000", "at most 10000"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "static",
                "--set",
                "solver.load_steps=1000000000",
            ],
            vec!["solver.load_steps = 1000000000", "at most 1000000"],
        ),
        (
            vec![
                "case-a",
                "--solver",
                "implicit",
                "--set",
                "solver.max_iterations=100000000",
            ],
            vec!["solver.max_iterations = 100000000"],
        ),
        (
            vec!["case-a", "--set", "initial.scale=[1.0, 0.0]"],
            vec!["initial.scale.1 = 0: must be a finite number > 0"],
        ),
        (
            vec!["case-a", "--steps", "10000000000"],
            vec!["solver.steps = 10000000000", "at most 1000000000"],
        ),
        (
            vec![
                "case-a",
                "--set",
                "output.frames=false",
                "--steps",
                "100000000",
            ],
            vec![
                "output.frame_every = 10",
                "records 10000002 frames",
                "MAX_RECORDED_FRAMES",
            ],
        ),
        (
            vec!["case-a", "--gif", "--gif-every", "1", "--steps", "100000"],
            vec!["--gif-every 1", "10002 frames", "at most 400"],
        ),
        // Float flags that are not finite name the flag (before: `output.stress_threshold:
        // invalid type: string "NaN"`, `solver.dt: invalid type: string`).
        (
            vec!["case-a", "--stress-threshold", "nan"],
            vec!["error: --stress-threshold NaN: must be a finite number >= 0 (kPa)"],
        ),
        (
            vec!["case-a", "--stress-threshold", "-5"],
            vec!["error: --stress-threshold -5: must be a finite number >= 0 (kPa)"],
        ),
        (
            vec!["case-a", "--stress-threshold", "1e306"],
            vec![
                "error: --stress-threshold 1e306: must be a finite number >= 0 (kPa), at most 1e305",
            ],
        ),
        (
            vec!["case-a", "--dt", "nan"],
            vec!["error: --dt NaN: must be a finite number > 0 (s)"],
        ),
        (
            vec!["case-a", "--dt", "inf"],
            vec!["error: --dt inf: must be a finite number > 0 (s)"],
        ),
        // A shift so far that round-off collapses the triangles names the shift (before: a
        // degenerate triangle).
        (
            vec!["case-a", "--set", "mesh.align_min=[1e300, 0.0]"],
            vec![
                "built-in case-a: mesh.align_min = [1e300, 0]: moves the mesh where floating-point round-off breaks it",
            ],
        ),
        (
            vec!["case-a", "--set", "mesh.origin=[1e300, 0.0]"],
            vec![
                "built-in case-a: mesh.origin = [1e300, 0]: moves the rectangle where floating-point round-off breaks it",
            ],
        ),
        (
            vec!["case-a", "--set", "mesh.width=1e-300"],
            vec![
                "built-in case-a: mesh.width = 1e-300: with mesh.height = 1, nx = 20 and ny = 4 the cells are 5e-302 x 2.5e-1 m",
            ],
        ),
        // A max_area the mesher cannot reach within its Steiner points names mesh.max_area
        // and the triangles it would need (before: a partly refined mesh was run).
        (
            vec!["case-d", "--set", "mesh.max_area=1e-9"],
            vec![
                "built-in case-d: mesh.max_area = 0.000000001: the mesher stopped at its 50000 Steiner points",
                "needs about 349624764 triangles",
            ],
        ),
        (
            vec!["lower-leg", "--set", "regions.0.youngs_modulus=1e300"],
            vec!["built-in lower-leg: regions.0.youngs_modulus = 1e300: must be at most 1e290 Pa"],
        ),
        (
            vec!["lower-leg", "--set", "regions.0.density=5e-324"],
            vec![
                "built-in lower-leg: regions.0.density = 5e-324: too small: the lumped vertex masses underflow",
            ],
        ),
    ];
    for (k, (extra, needles)) in cases.iter().enumerate() {
        let out_dir = dir.join(format!("out-{k}"));
        let mut args = vec!["run"];
        args.extend(extra);
        args.extend(["--out", arg(&out_dir)]);
        let out = fem2d(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{extra:?}: {stderr}");
        assert!(lines[0].starts_with("error: "), "{extra:?}: {stderr}");
        for n in needles {
            assert!(lines[0].contains(n), "{extra:?}: {n:?} missing: {stderr}");
        }
        assert!(
            !out_dir.exists() || listing(&out_dir).is_empty(),
            "{extra:?} left {:?}",
            listing(&out_dir)
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_that_blows_up_fails_and_says_so_in_the_summary() {
    let dir = scratch("blow-up");
    let out_dir = dir.join("out");
    // 0.05 s is more than twenty times the explicit stability limit of case A.
    let out = fem2d(&[
        "run",
        "case-a",
        "--dt",
        "0.05",
        "--steps",
        "200",
        "--out",
        arg(&out_dir),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    let error = errors[0];
    assert!(error.contains("blew up") && error.contains("built-in case-a"));
    assert!(
        stderr
            .lines()
            .all(|l| l.starts_with("error:") || l.starts_with("warning:")),
        "{stderr}"
    );
    // The outputs describe the run up to the blow-up.
    assert_eq!(listing(&out_dir), OUTPUTS);
    let s = json(&out_dir.join("summary.json"));
    check_contract_fields(&s);
    assert_eq!(s["blew_up"], true);
    let message = s["blow_up_message"].as_str().unwrap();
    assert!(message.contains("step"), "{message}");
    let done = s["steps_completed"].as_u64().unwrap();
    assert!(done < 200, "{done}");
    assert!(s["time_step_warning"].is_string());
    let (_, rows) = csv(&out_dir.join("probes.csv"));
    assert_eq!(rows.first().unwrap()[0], 0.0);
    assert_eq!(
        rows.last().unwrap()[0],
        done as f64,
        "the last frame is the last good state"
    );
    assert_eq!(
        read(&out_dir.join("frames.jsonl")).lines().count(),
        rows.len()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `FEM2D_SIMD` caps the force kernel's instruction set: case A (Neo-Hookean, 300 steps, two
/// threads) writes the same probes and summary under the baseline set as under the widest set
/// of the machine, bit for bit; a value that names no set is a one-line error, exit code 2.
#[test]
fn instruction_set_cap_changes_nothing_but_speed_and_bad_values_are_rejected() {
    let run = |simd: &str, name: &str| {
        let dir = scratch(name);
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_fem2d"))
            .args(["run", "case-a", "--energy", "neo-hookean", "--steps", "300"])
            .args(["--threads", "2", "--out", arg(&dir), "-q"])
            .env("FEM2D_SIMD", simd)
            .output()
            .unwrap();
        (out, dir)
    };
    let (wide, wide_dir) = run("avx512", "simd-widest");
    let (base, base_dir) = run("baseline", "simd-baseline");
    assert!(wide.status.success() && base.status.success());
    assert_eq!(
        read(&wide_dir.join("probes.csv")),
        read(&base_dir.join("probes.csv"))
    );
    assert_eq!(
        without_timings(json(&wide_dir.join("summary.json"))),
        without_timings(json(&base_dir.join("summary.json")))
    );
    let (bad, bad_dir) = run("sse9", "simd-bad");
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: FEM2D_SIMD = `sse9`"), "{err}");
    assert!(listing(&bad_dir).is_empty());
}

/// A mesh file whose triangles repeat, fold over a neighbour, overlap or put three triangles on
/// one edge would double mass and stiffness: each is one error line naming the file and the
/// triangles, and nothing is written.
#[test]
fn mesh_files_with_repeated_folded_or_overlapping_triangles_are_refused() {
    let dir = scratch("bad-topology");
    let strip = r#"[[0,0],[1,0],[2,0],[0,1],[1,1],[2,1]"#;
    let good = "[0,1,4],[0,4,3],[1,2,5],[1,5,4]";
    let cases = [
        // The last triangle again, its vertices rotated.
        (
            "repeated",
            format!("{strip}]"),
            format!("{good},[4,1,5]"),
            "triangles[4] = [4, 1, 5] repeats triangles[3]",
        ),
        // A third triangle on the edge 1-4, beyond vertex 7 = (1.2, 0.5), inside the strip.
        (
            "three",
            format!("{strip},[1.2,0.5]]"),
            format!("{good},[1,6,4]"),
            "borders triangles[0], triangles[3] and triangles[4]",
        ),
        // A triangle far from the others' edges but on top of them.
        (
            "overlap",
            format!("{strip},[0.3,0.2],[0.6,0.2],[0.45,0.5]]"),
            format!("{good},[6,7,8]"),
            "triangles[4] = [6, 7, 8] overlaps triangles[0]",
        ),
    ];
    for (name, vertices, triangles, want) in cases {
        let mesh = dir.join(format!("{name}.json"));
        std::fs::write(
            &mesh,
            format!(r#"{{"vertices": {vertices}, "triangles": [{triangles}]}}"#),
        )
        .unwrap();
        let scene = dir.join(format!("{name}.toml"));
        std::fs::write(
            &scene,
            format!(
                "name = \"{name}\"\nenergy = \"stvk\"\n[mesh]\nkind = \"file\"\npath = \"{name}.json\"\n\
                 [material]\nyoungs_modulus = 1e4\npoisson_ratio = 0.3\ndensity = 1.0\n\
                 [solver]\ndt = 1e-3\nsteps = 2\n"
            ),
        )
        .unwrap();
        let out = dir.join(format!("{name}-out"));
        let err = one_line_error(&["run", arg(&scene), "--out", arg(&out), "-q"]);
        assert!(err.contains(&format!("{name}.json")), "{err}");
        assert!(err.contains(want), "{name}: {err}");
        assert!(!out.exists(), "{name}");
    }
}

/// `--vtk` on a run that blows up: the outputs up to the blow-up (VTK included, det F of the
/// overflowing frame written as -1e30) and the blow-up message, as without `--vtk`.
#[test]
fn vtk_on_a_run_that_blows_up_keeps_the_outputs_and_the_message() {
    let dir = scratch("vtk-blow-up");
    let out = fem2d(&[
        "run",
        "case-a",
        "--dt",
        "0.01",
        "--steps",
        "400",
        "--vtk",
        "-q",
        "--out",
        arg(&dir),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.lines()
            .last()
            .unwrap()
            .starts_with("error: the run blew up"),
        "{err}"
    );
    assert!(dir.join("summary.json").exists() && dir.join("vtk/run.pvd").exists());
    assert_eq!(json(&dir.join("summary.json"))["blew_up"], true);
}

/// `fem2d run --drag FILE` replays a recorded drag: the tip follows the hand; a bad drag file
/// is one error line naming the file and the field.
#[test]
fn a_recorded_drag_is_replayed_offline() {
    let dir = scratch("drag");
    let drag = dir.join("drag.json");
    std::fs::write(
        &drag,
        r#"{"version": 1, "events": [
            {"t": 0.0, "action": "grab", "x": 4.99, "y": 0.5, "stiffness": 0},
            {"t": 0.1, "action": "move", "x": 4.99, "y": 0.7},
            {"t": 0.2, "action": "move", "x": 4.99, "y": 0.9}
        ]}"#,
    )
    .unwrap();
    let out = dir.join("out");
    run_ok(&["case-a", "--steps", "300", "--drag", arg(&drag)], &out);
    let summary = json(&out.join("summary.json"));
    let tip = summary["probes"][0]["final_displacement"][1]
        .as_f64()
        .unwrap();
    // The tip probe is the bottom corner: it rises with the held point (0.4 m up).
    assert!(tip > 0.2, "tip moved {tip} m");
    let bad = dir.join("bad.json");
    std::fs::write(
        &bad,
        r#"{"events": [{"t": 0.2, "action": "release"}, {"t": 0.1, "action": "release"}]}"#,
    )
    .unwrap();
    let e = one_line_error(&[
        "run",
        "case-a",
        "--drag",
        arg(&bad),
        "--out",
        arg(&dir.join("o2")),
    ]);
    assert!(e.contains("bad.json: events.1.t = 0.1"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A UTF-8 byte-order mark, which some editors write first, is skipped in scene files and drag
/// files (before: "invalid JSON" for the drag, a TOML error for the scene).
#[test]
fn a_byte_order_mark_before_a_scene_or_a_drag_file_is_skipped() {
    let dir = scratch("bom");
    let scene = dir.join("bom.toml");
    let text = fem_scene::cases::case_text("case-a").unwrap();
    std::fs::write(&scene, format!("\u{feff}{text}")).unwrap();
    let drag = dir.join("drag.json");
    std::fs::write(
        &drag,
        "\u{feff}{\"events\": [{\"t\": 0.0, \"action\": \"grab\", \"x\": 4.99, \"y\": 0.5}]}",
    )
    .unwrap();
    run_ok(
        &[arg(&scene), "--steps", "5", "--drag", arg(&drag)],
        &dir.join("out"),
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A drag file of more events than `fem_scene::drag::MAX_DRAG_EVENTS` is one error line naming
/// the file, the field and the count, before the run (before: ten million events were read,
/// 0.9 GB).
#[test]
fn a_drag_file_with_more_events_than_the_bound_is_refused() {
    let dir = scratch("drag-bound");
    let drag = dir.join("long.json");
    let n = fem_scene::drag::MAX_DRAG_EVENTS + 1;
    let mut text = String::from("{\"events\": [");
    text.push_str(&"{\"t\": 0, \"action\": \"release\"},".repeat(n));
    text.pop();
    text.push_str("]}");
    std::fs::write(&drag, text).unwrap();
    let out = dir.join("out");
    let e = one_line_error(&["run", "case-a", "--drag", arg(&drag), "--out", arg(&out)]);
    assert!(
        e.contains(&format!(
            "long.json: events = ({n} events): must hold at most 324000 (fem_scene::drag::MAX_DRAG_EVENTS"
        )),
        "{e}"
    );
    assert!(!out.exists());
    // A file larger than any drag of that many events needs is refused before it is read
    // (a sparse file: nothing is written).
    let huge = dir.join("huge.json");
    let bound = fem_scene::drag::MAX_DRAG_FILE_BYTES;
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(bound + 1)
        .unwrap();
    let e = one_line_error(&["run", "case-a", "--drag", arg(&huge), "--out", arg(&out)]);
    assert!(
        e.contains(&format!(
            "huge.json: size = {} bytes: must be at most {bound} bytes (fem_scene::drag::MAX_DRAG_FILE_BYTES",
            bound + 1
        )),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
