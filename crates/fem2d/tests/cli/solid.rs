//! `fem2d run` on 3D scenes (`dim = 3`): the built-in `case-a-3d` writes `summary.json`
//! (`dim = 3`, tetrahedra), `probes.csv` with three components, `scene.toml` that runs again
//! to the same numbers, the oblique surface picture and the VTK tetrahedra; a 3D scene file is
//! recognised by its `dim` key; 2D-only flags and keys are one-line errors that write nothing.
//! `fem2d compare` runs the energy x solver matrix on a 3D scene and writes the 2D command's
//! files, with a `uz` column per probe.

use crate::common::{arg, fem2d, json, one_line_error, read, run_ok, scratch};

#[test]
fn case_a_3d_writes_its_outputs_and_the_scene_reruns() {
    let dir = scratch("solid-case-a-3d");
    let out = dir.join("out");
    run_ok(&["case-a-3d", "--steps", "40", "--png", "--vtk"], &out);
    let s = json(&out.join("summary.json"));
    assert_eq!(s["dim"], 3);
    assert_eq!(s["tetrahedra"], 1920);
    assert_eq!(s["steps_completed"], 40);
    assert_eq!(s["blew_up"], false);
    let probes = read(&out.join("probes.csv"));
    assert!(
        probes.starts_with("step,time,tip.ux,tip.uy,tip.uz\n"),
        "{probes}"
    );
    assert_eq!(probes.lines().count(), 1 + 3);
    assert!(out.join("final.png").is_file());
    let pvd = read(&out.join("vtk/run.pvd"));
    assert_eq!(pvd.matches("<DataSet").count(), 3);
    let vtu = read(&out.join("vtk/run_000002.vtu"));
    assert!(vtu.contains("NumberOfCells=\"1920\"") && vtu.contains("Name=\"von_mises\""));
    // The written scene is a 3D scene file that reruns to the same tip.
    let again = dir.join("again");
    run_ok(&[arg(&out.join("scene.toml"))], &again);
    let t = json(&again.join("summary.json"));
    assert_eq!(
        s["probes"][0]["final_displacement"],
        t["probes"][0]["final_displacement"]
    );
}

#[test]
fn two_d_only_flags_and_keys_are_refused_in_one_line() {
    let dir = scratch("solid-refusals");
    let out = dir.join("out");
    let e = one_line_error(&["run", "case-a-3d", "--gif", "--out", arg(&out)]);
    assert_eq!(
        e,
        "error: --gif: not available for a 3D scene (built-in case-a-3d, dim = 3)"
    );
    assert!(!out.exists());
    let scene = dir.join("ground.toml");
    std::fs::write(
        &scene,
        "name = \"s\"\ndim = 3\n[mesh]\nkind = \"box\"\nwidth = 1.0\nheight = 1.0\ndepth = 1.0\nnx = 1\nny = 1\nnz = 1\n[material]\nyoungs_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n[solver]\nkind = \"explicit\"\ndt = 1e-3\nsteps = 1\n[ground]\nheight = 0.0\n",
    )
    .unwrap();
    let e = one_line_error(&["run", arg(&scene), "--out", arg(&out)]);
    assert!(
        e.starts_with(&format!(
            "error: {}: ground: not available in 3D scenes yet",
            scene.display()
        )),
        "{e}"
    );
    assert!(!out.exists());
}

/// The coarse `case-a-3d` of the compare tests: 8 x 2 x 2 cells (192 tetrahedra), 20 steps.
const COARSE_3D: [&str; 10] = [
    "--set",
    "solver.steps=20",
    "--set",
    "mesh.nx=8",
    "--set",
    "mesh.ny=2",
    "--set",
    "mesh.nz=2",
    "--set",
    "output.frame_every=10",
];

#[test]
fn compare_runs_the_matrix_on_a_3d_scene_and_writes_its_outputs() {
    let dir = scratch("solid-compare");
    let out_dir = dir.join("out");
    let mut args = vec!["compare", "case-a-3d"];
    args.extend(COARSE_3D);
    args.extend([
        "--solvers",
        "explicit,implicit,linear-implicit",
        "--energies",
        "neo-hookean",
        "--threads",
        "1",
        "--out",
        arg(&out_dir),
    ]);
    let out = fem2d(&args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.starts_with("Scene `case-a-3d`: 192 tetrahedra, dt = 5e-4 s, 20 steps."),
        "{stdout}"
    );
    assert!(
        stdout.contains("| tip ux | tip uy | tip uz | tip min uy |"),
        "{stdout}"
    );
    assert!(
        stdout.contains("| neo-hookean | implicit |  | yes |"),
        "{stdout}"
    );
    // linear-implicit has no 3D path: an error row, not a failed command.
    assert!(
        stdout.contains("| neo-hookean | linear-implicit |  | **no** |"),
        "{stdout}"
    );
    assert!(stdout.contains("has no 3D path yet"), "{stdout}");
    let md = read(&out_dir.join("compare.md"));
    assert_eq!(
        md,
        stdout
            .lines()
            .take_while(|l| !l.starts_with("wrote"))
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    );
    let j = json(&out_dir.join("compare.json"));
    assert_eq!(j["dim"], 3);
    assert_eq!(j["triangles"], 192);
    let rows = j["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[0]["stable"], true);
    assert_eq!(rows[1]["stable"], true);
    assert_eq!(rows[2]["stable"], false);
    assert!(
        rows[2]["error"]
            .as_str()
            .unwrap()
            .contains("linear-implicit")
    );
    let tip = &rows[1]["probes"][0];
    assert_eq!(tip["final_displacement"].as_array().unwrap().len(), 3);
    assert!(tip["rms_vs_explicit"].is_number(), "{tip}");
    let csv = read(&out_dir.join("compare.csv"));
    assert!(
        csv.starts_with(
            "energy,solver,variant,stable,steps_completed,tip.ux,tip.uy,tip.uz,tip.min_uy,"
        ),
        "{csv}"
    );
    assert_eq!(csv.lines().count(), 1 + 3);
    // 20 steps at frame_every 10: 3 frames.
    let curves = read(&out_dir.join("curves.csv"));
    assert_eq!(curves.lines().count(), 1 + 3);
    assert!(
        curves.starts_with("frame,time,neo-hookean/explicit:tip.ux,neo-hookean/explicit:tip.uy,neo-hookean/explicit:tip.uz,"),
        "{curves}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn compare_refuses_a_2d_only_key_on_a_3d_scene_in_one_line_before_writing() {
    // Every flag of `fem2d compare` applies in 3D; what 3D lacks is scene keys, refused as
    // `fem2d run` refuses them, before any run and before the output directory is made.
    let dir = scratch("solid-compare-refusal");
    let out = dir.join("out");
    let mut args = vec!["compare", "case-a-3d"];
    args.extend(COARSE_3D);
    args.extend(["--set", "ground.height=0.0", "--out", arg(&out)]);
    let e = one_line_error(&args);
    assert!(
        e.starts_with("error: built-in case-a-3d: ground: not available in 3D scenes yet"),
        "{e}"
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
