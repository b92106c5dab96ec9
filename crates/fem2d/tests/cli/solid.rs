//! `fem2d run` on 3D scenes (`dim = 3`): the built-in `case-a-3d` writes `summary.json`
//! (`dim = 3`, tetrahedra), `probes.csv` with three components, `scene.toml` that runs again
//! to the same numbers, the oblique surface picture and the VTK tetrahedra; a 3D scene file is
//! recognised by its `dim` key; 2D-only flags and keys are one-line errors that write nothing.

use crate::common::{arg, json, one_line_error, read, run_ok, scratch};

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
    // The other commands take 2D scenes only, and say so.
    assert_eq!(
        one_line_error(&["compare", "case-a-3d", "--energies", "stvk"]),
        "error: `case-a-3d` is a 3D scene (dim = 3): only `fem2d run` takes 3D scenes yet"
    );
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
