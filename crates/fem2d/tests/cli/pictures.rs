//! Pictures of runs end to end: `fem2d run --png --gif --vtk` (files decode, GIF cadence, VTK
//! values equal the run's own probes), bad picture flags, and the case D stress map, whose
//! hottest pixel must lie under the debris.

use crate::common::{arg, fem2d, one_line_error, read, run_ok, scratch};
use fem_cases::pictures::{FieldKind, FramePicture, render_side_by_side};
use fem_cases::run::{RunOptions, run_scene};
use fem_render::Image;
use fem_render::colormap::Colormap;
use fem_scene::cases::load_case;

fn gif_frames(path: &std::path::Path) -> (usize, u16, u16) {
    let file = std::fs::File::open(path).unwrap();
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options.read_info(file).unwrap();
    let (w, h) = (decoder.width(), decoder.height());
    let mut n = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        n += 1;
    }
    (n, w, h)
}

#[test]
fn run_writes_png_gif_and_vtk() {
    let dir = scratch("pictures-run");
    // 200 steps, a frame every 10: 21 recorded frames.
    run_ok(
        &["case-a", "--steps", "200", "--png", "--gif", "--vtk"],
        &dir,
    );
    let png = Image::from_png(&std::fs::read(dir.join("final.png")).unwrap()).unwrap();
    assert!(
        png.width() >= 720 && png.height() >= 400,
        "{}x{}",
        png.width(),
        png.height()
    );
    let distinct: std::collections::HashSet<[u8; 4]> = png
        .as_rgba()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    assert!(
        distinct.len() > 50,
        "final.png has {} colours",
        distinct.len()
    );
    let (frames, w, h) = gif_frames(&dir.join("animation.gif"));
    assert_eq!(frames, 21);
    assert!(w > 300 && h > 150);

    let pvd = fem_render::vtk::read_pvd(&dir.join("vtk/run.pvd")).unwrap();
    assert_eq!(pvd.len(), 21);
    assert!((pvd[20].0 - 0.2).abs() < 1e-12, "last time {}", pvd[20].0);
    let last = fem_render::vtk::read_vtu(&pvd[20].1).unwrap();
    let summary = crate::common::json(&dir.join("summary.json"));
    assert_eq!(
        last.cells.len(),
        summary["triangles"].as_u64().unwrap() as usize
    );
    // The VTK displacement of the tip vertex equals the run's own probe, bit for bit.
    let tip = &summary["probes"][0];
    let vertex = tip["vertex"].as_u64().unwrap() as usize;
    let (_, comps, u) = last
        .point_data
        .iter()
        .find(|(n, _, _)| n == "displacement")
        .expect("displacement array");
    assert_eq!(*comps, 3);
    let fd = &tip["final_displacement"];
    assert_eq!(u[3 * vertex], fd[0].as_f64().unwrap());
    assert_eq!(u[3 * vertex + 1], fd[1].as_f64().unwrap());
    let (_, comps, v) = last
        .point_data
        .iter()
        .find(|(n, _, _)| n == "velocity")
        .expect("velocity array");
    assert_eq!(*comps, 3);
    assert!(
        v.iter().any(|x| *x != 0.0),
        "the beam is moving at t = 0.2 s"
    );
    for name in ["von_mises", "det_F"] {
        let (_, _, v) = last
            .cell_data
            .iter()
            .find(|(n, _, _)| n == name)
            .unwrap_or_else(|| panic!("{name}"));
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{name}");
    }
    let stdout = read(&dir.join("summary.json"));
    assert!(stdout.contains("\"blew_up\": false"));
}

#[test]
fn gif_cadence_and_field_are_settable() {
    let dir = scratch("pictures-cadence");
    run_ok(
        &[
            "case-a",
            "--steps",
            "200",
            "--gif",
            "--gif-every",
            "5",
            "--field",
            "displacement",
        ],
        &dir,
    );
    // Recorded frames 0..=20; every 5th: 0, 5, 10, 15, 20.
    assert_eq!(gif_frames(&dir.join("animation.gif")).0, 5);
    assert!(!dir.join("vtk").exists());
}

#[test]
fn wireframe_darkens_only_edge_pixels() {
    let plain = scratch("pictures-plain");
    let wire = scratch("pictures-wire");
    run_ok(&["case-a", "--steps", "20", "--png"], &plain);
    run_ok(&["case-a", "--steps", "20", "--png", "--wireframe"], &wire);
    let load = |d: &std::path::Path| {
        Image::from_png(&std::fs::read(d.join("final.png")).unwrap()).unwrap()
    };
    let (a, b) = (load(&plain), load(&wire));
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    let mut changed = 0;
    for (p, q) in a.as_rgba().chunks_exact(4).zip(b.as_rgba().chunks_exact(4)) {
        if p != q {
            changed += 1;
            // Edges are a dark colour blended over the fill: a changed pixel only gets darker.
            let sum = |c: &[u8]| c[..3].iter().map(|&v| v as u32).sum::<u32>();
            assert!(
                sum(q) < sum(p),
                "wireframe pixel {q:?} is not darker than {p:?}"
            );
        }
    }
    // Case A's mesh has well over a hundred edges, each several pixels long.
    assert!(changed > 500, "only {changed} pixels changed");
}

#[test]
fn bad_picture_flags_are_one_line_errors() {
    let dir = scratch("pictures-bad");
    let e = one_line_error(&[
        "run",
        "case-a",
        "--png",
        "--field",
        "pressure",
        "--out",
        arg(&dir),
    ]);
    assert!(e.contains("--field") && e.contains("pressure"), "{e}");
    let e = one_line_error(&[
        "run",
        "case-a",
        "--gif",
        "--gif-every",
        "0",
        "--out",
        arg(&dir),
    ]);
    assert!(e.contains("--gif-every"), "{e}");
    let e = one_line_error(&[
        "run",
        "case-a",
        "--gif",
        "--gif-delay-ms",
        "1",
        "--out",
        arg(&dir),
    ]);
    assert!(e.contains("--gif-delay-ms"), "{e}");
    // Checked before anything is written.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    let out = fem2d(&["report", "--threads", "0", "--out", arg(&dir)]);
    assert!(!out.status.success());
}

#[test]
fn case_d_hottest_pixel_lies_under_the_debris() {
    let scene = load_case("case-d", &[]).unwrap();
    let run = run_scene(
        &scene,
        &RunOptions {
            threads: Some(1),
            snapshot_every: Some(1),
            ..RunOptions::default()
        },
    )
    .unwrap();
    let peak = run
        .snapshots
        .iter()
        .find(|s| s.step == run.summary.max_von_mises_step)
        .expect("the peak frame is kept");
    let picture = FramePicture::new(&run, peak, FieldKind::VonMises, "peak");
    let rendered =
        render_side_by_side(&[&picture], FieldKind::VonMises, "case D", (900, 260), None).unwrap();
    let panel = rendered.panels[0];
    let [x0, y0, x1, y1] = panel.rect();
    // The colour range starts at 0 and ends at the largest element stress: the hottest
    // element is drawn in the colormap's top colour.
    let top = Colormap::Viridis.sample(1.0);
    let mut hot = Vec::new();
    for y in y0..y1 {
        for x in x0..x1 {
            let p = rendered.image.pixel(x, y);
            if [p[0], p[1], p[2]] == top {
                hot.push((x as f64 + 0.5, y as f64 + 0.5));
            }
        }
    }
    assert!(!hot.is_empty(), "no pixel has the top colour {top:?}");
    // Pixel x back to world x (the map is affine with equal scales).
    let a = panel.world_to_pixel([0.0, 0.0]);
    let b = panel.world_to_pixel([1.0, 0.0]);
    let world_x = |px: f64| (px - a[0]) / (b[0] - a[0]);
    let slab = &peak.obstacles[0];
    let lo = slab.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let hi = slab.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
    // Within 5 cm of the slab's span: with the bones rigid (the scene's default) the hottest
    // element is the soft tissue's, at the slab's corner (2.4 cm beyond it; the cases' test
    // reads the summary's peak with the same margin).
    for (px, _) in &hot {
        let x = world_x(*px);
        assert!(
            x >= lo - 0.05 && x <= hi + 0.05,
            "hottest pixel at x = {x:.3} m, the slab spans {lo:.3}-{hi:.3} m"
        );
    }
}
