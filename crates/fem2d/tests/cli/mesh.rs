//! `fem2d mesh` end to end: the built-in body becomes a mesh JSON (readable by the mesh JSON
//! reader), Gmsh and VTK files and four stage previews; bad input ends with a one-line error and
//! a non-zero exit code, and leaves no output file behind.

use crate::common::{arg, fem2d, one_line_error, scratch};

#[test]
fn builtin_body_to_mesh_files_and_previews() {
    let dir = scratch("ok");
    let (json, msh, vtk, preview) = (
        dir.join("body.json"),
        dir.join("body.msh"),
        dir.join("body.vtk"),
        dir.join("preview"),
    );
    let out = fem2d(&[
        "mesh",
        "--builtin-body",
        "--view",
        "front",
        "--max-area",
        "1e-3",
        "--min-angle",
        "25",
        "-o",
        arg(&json),
        "--msh",
        arg(&msh),
        "--vtk",
        arg(&vtk),
        "--preview",
        arg(&preview),
        "--preview-height",
        "200",
        "--require-quality",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "alpha radius",
        "suggested",
        "min angle",
        "aspect ratio",
        "time (ms)",
    ] {
        assert!(stdout.contains(needle), "missing {needle:?} in\n{stdout}");
    }
    let mesh = fem_mesh::io::read_mesh_json(&json).unwrap();
    assert_eq!(mesh.edge_components(), 1);
    let gmsh = std::fs::read_to_string(&msh).unwrap();
    assert!(gmsh.starts_with("$MeshFormat\n2.2 0 8\n"));
    assert!(gmsh.contains(&format!("$Elements\n{}\n", mesh.triangles.len())));
    assert!(
        std::fs::read_to_string(&vtk)
            .unwrap()
            .contains("CELL_TYPES")
    );
    for name in fem_mesh::preview::PREVIEW_FILES {
        let bytes = std::fs::read(preview.join(name)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{name}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_a_one_line_error_without_output() {
    let dir = scratch("bad");
    let json = dir.join("out.json");
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "").unwrap();
    let nan = dir.join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let flat = dir.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
    let missing = dir.join("missing.stl");
    // 200 points along a 3D line with 1e-9 m of noise: nearly collinear in every view (before,
    // 50,001 zero-angle triangles were written after a warning).
    let line = dir.join("line.obj");
    let mut text = String::new();
    let mut r = 0x9e37_79b9_u64;
    let mut noise = || {
        r = r
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((r >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e-9
    };
    for i in 0..200 {
        let t = i as f64 * 0.01;
        text.push_str(&format!(
            "v {} {} {}\n",
            t + noise(),
            0.5 * t + noise(),
            t / 3.0 + noise()
        ));
    }
    text.push_str("f 1 2 3\n");
    std::fs::write(&line, text).unwrap();
    // Coordinates near the f64 limit: the preset view overflows; the message says how to fix it
    // (before: a Rust debug dump of the camera).
    let huge = dir.join("huge.obj");
    std::fs::write(&huge, "v 1e300 0 0\nv 0 1e300 0\nv 0 0 1e300\nf 1 2 3\n").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![arg(&huge)], "every coordinate must be finite"),
        (vec![arg(&huge)], "scale it down with --scale"),
        (
            vec![arg(&line), "--epsilon", "0.001", "--view", "front"],
            "line.obj: triangulate: polygon 0 is (nearly) collinear",
        ),
        (
            vec![arg(&line), "--epsilon", "0.001", "--view", "top"],
            "(nearly) collinear",
        ),
        (vec![arg(&line), "--epsilon", "0.001"], "(nearly) collinear"),
        (vec![arg(&empty)], "empty.obj: contents: no vertices"),
        (
            vec![arg(&nan)],
            "nan.obj: line 2: vertex y \"NaN\" is not finite",
        ),
        (vec![arg(&flat), "--view", "front"], "collinear"),
        (vec![arg(&missing)], "missing.stl"),
        (
            vec!["--builtin-body", "--alpha", "1e-5"],
            "keeps no triangle",
        ),
        (
            vec!["--builtin-body", "--epsilon", "5"],
            "larger than the shape",
        ),
        (vec!["--builtin-body", "--up", "1,0,0"], "parallel"),
        (
            vec![
                "--builtin-body",
                "--focal-point",
                "1,2,3",
                "--camera-position",
                "1,2,3",
            ],
            "coincides",
        ),
        (vec!["--builtin-body", "--scale", "0"], "--scale"),
        // Negative values are values, rejected by validation naming the flag.
        (
            vec!["--builtin-body", "--alpha", "-1"],
            "--alpha -1: must be a finite number > 0",
        ),
        (
            vec!["--builtin-body", "--epsilon", "-0.5"],
            "--epsilon -0.5: must be",
        ),
        (
            vec!["--builtin-body", "--max-steiner", "18446744073709551615"],
            "--max-steiner 18446744073709551615: must be at most 10000000",
        ),
        (
            vec![
                "--builtin-body",
                "--min-angle",
                "50",
                "--max-steiner",
                "200",
                "--require-quality",
            ],
            "requested quality not met",
        ),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["mesh", "-o", arg(&json)];
        args.extend(&extra);
        let out = fem2d(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{extra:?} should fail");
        let last = stderr.trim_end().lines().last().unwrap_or("");
        assert!(
            last.starts_with("error: ") && last.contains(needle),
            "{extra:?}: {stderr}"
        );
        assert!(!json.exists(), "{extra:?} left an output file");
    }
    // Unparsable flags are clap's business: non-zero exit too.
    assert!(
        !fem2d(&["mesh", "--builtin-body", "--up", "1,x,0"])
            .status
            .success()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The mesh outputs are all or none, and only regular files are written: two outputs on one
/// path, a FIFO, a symbolic link, a directory or a preview that cannot be written are one-line
/// errors, and then no output file exists (and nothing was replaced).
#[test]
fn mesh_outputs_are_all_or_none_and_only_regular_files() {
    let dir = scratch("mesh-all-or-none");
    let json = dir.join("m.json");
    let err = one_line_error(&[
        "mesh",
        "--builtin-body",
        "-o",
        arg(&json),
        "--msh",
        arg(&json),
    ]);
    assert!(
        err.contains("--msh") && err.contains("the same file as -o"),
        "{err}"
    );
    assert!(!json.exists());

    let fifo = dir.join("fifo");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let err = one_line_error(&["mesh", "--builtin-body", "-o", arg(&fifo)]);
    assert!(err.contains("is a device, FIFO or socket"), "{err}");
    let target = dir.join("target.json");
    std::fs::write(&target, "keep").unwrap();
    let link = dir.join("link.json");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let err = one_line_error(&["mesh", "--builtin-body", "-o", arg(&link)]);
    assert!(err.contains("is a symbolic link"), "{err}");
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
    let err = one_line_error(&["mesh", "--builtin-body", "-o", arg(&dir)]);
    assert!(err.contains("is a directory"), "{err}");

    // A preview that cannot be written (its directory is a file): no mesh file either.
    let blocker = dir.join("blocker");
    std::fs::write(&blocker, "").unwrap();
    let out = fem2d(&[
        "mesh",
        "--builtin-body",
        "-o",
        arg(&json),
        "--vtk",
        arg(&dir.join("m.vtk")),
        "--preview",
        arg(&blocker),
    ]);
    assert!(!out.status.success());
    assert!(!json.exists() && !dir.join("m.vtk").exists());
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "{names:?}");
}
