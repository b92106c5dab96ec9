//! Integration tests of `fem_render::frame`: layout, seamless fill, colorbar mapping,
//! interpolation, obstacles, flat elements and outline edges, error messages, and a sample
//! picture for eyeballing.

use fem_render::colormap::{Colormap, NO_DATA};
use fem_render::frame::{
    EDGE_COLOR, FieldValues, FlatElements, FrameStyle, MESH_COLOR, MeshView, OBSTACLE_COLOR,
    Rendered, region_edges, render,
};
use fem_render::{Image, RenderError};

/// An `nx` x `ny` grid over `[0, w] x [0, h]` split into triangles with alternating diagonals;
/// interior nodes moved by up to `jitter` cells (deterministic pseudo-random).
fn grid(nx: usize, ny: usize, w: f64, h: f64, jitter: f64) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut rand = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let (dx, dy) = (w / nx as f64, h / ny as f64);
    let mut pos = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let interior = i > 0 && i < nx && j > 0 && j < ny;
            let (jx, jy) = if interior {
                (rand() * jitter, rand() * jitter)
            } else {
                (0.0, 0.0)
            };
            pos.push([(i as f64 + jx) * dx, (j as f64 + jy) * dy]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut tris = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            } else {
                tris.push([a, b, d]);
                tris.push([b, c, d]);
            }
        }
    }
    (pos, tris)
}

fn centroid(pos: &[[f64; 2]], t: [usize; 3]) -> [f64; 2] {
    let p = t.map(|i| pos[i]);
    [
        (p[0][0] + p[1][0] + p[2][0]) / 3.0,
        (p[0][1] + p[1][1] + p[2][1]) / 3.0,
    ]
}

fn rgb(img: &Image, x: u32, y: u32) -> [u8; 3] {
    let p = img.pixel(x, y);
    [p[0], p[1], p[2]]
}

/// The pixel containing world point `p` in panel `panel`.
fn pixel_at(r: &Rendered, panel: usize, p: [f64; 2]) -> [u8; 3] {
    let q = r.panels[panel].world_to_pixel(p);
    rgb(&r.image, q[0].floor() as u32, q[1].floor() as u32)
}

fn input_error(panels: &[MeshView<'_>], style: &FrameStyle) -> String {
    match render(panels, style) {
        Err(RenderError::Input(msg)) => {
            assert!(!msg.contains('\n'), "multi-line message: {msg}");
            msg
        }
        Err(e) => panic!("expected an Input error, got {e:?}"),
        Ok(_) => panic!("expected an error"),
    }
}

#[test]
fn image_size_matches_layout() {
    let (pos, tris) = grid(10, 5, 2.0, 1.0, 0.0);
    let field: Vec<f64> = (0..tris.len()).map(|k| k as f64).collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        caption: "one",
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        title: "Title".into(),
        field_label: "von Mises stress".into(),
        unit: "kPa".into(),
        ..FrameStyle::default()
    };
    let one = render(&[view], &style).unwrap();
    let two = render(&[view, view], &style).unwrap();
    for r in [&one, &two] {
        let (w, h) = (r.image.width(), r.image.height());
        assert_eq!(r.image.as_rgba().len(), (w * h * 4) as usize);
        let bar = r.colorbar.expect("a colorbar");
        for g in &r.panels {
            let [x0, y0, x1, y1] = g.rect();
            assert_eq!((x1 - x0, y1 - y0), (640, 360));
            assert!(
                x1 < bar.x0 && y0 > 20 && y1 < h,
                "panel {:?} in {w}x{h}",
                g.rect()
            );
        }
        assert!(bar.x1 < w && bar.y1 <= h && bar.y1 - bar.y0 > 300);
    }
    let (r0, r1) = (two.panels[0].rect(), two.panels[1].rect());
    assert_eq!(r0[1], r1[1]);
    assert!(r1[0] > r0[2], "panels overlap: {r0:?} {r1:?}");
    // The second panel adds its width plus one gap; the height does not change.
    assert_eq!(two.image.width() - one.image.width(), r1[0] - r0[0]);
    assert_eq!(two.image.height(), one.image.height());
    // Same scale in both panels, equal aspect ratio.
    assert_eq!(
        two.panels[0].pixels_per_metre(),
        two.panels[1].pixels_per_metre()
    );

    // The title row adds height; the size does not depend on the data.
    let untitled = render(
        &[view],
        &FrameStyle {
            title: String::new(),
            ..style.clone()
        },
    )
    .unwrap();
    assert!(untitled.image.height() < one.image.height());
    let other: Vec<f64> = (0..tris.len()).map(|k| -1e-3 * k as f64).collect();
    let other_view = MeshView {
        field: Some(FieldValues::PerElement(&other)),
        ..view
    };
    let again = render(&[other_view], &style).unwrap();
    assert_eq!(
        (again.image.width(), again.image.height()),
        (one.image.width(), one.image.height())
    );

    // No field: no colorbar, no range, a narrower picture.
    let plain = render(&[MeshView::new(&pos, &tris)], &style).unwrap();
    assert!(plain.colorbar.is_none() && plain.range.is_none());
    assert!(plain.image.width() < one.image.width());
}

#[test]
fn equal_aspect_ratio_and_centred() {
    let (pos, tris) = grid(4, 4, 1.0, 1.0, 0.0);
    let r = render(&[MeshView::new(&pos, &tris)], &FrameStyle::default()).unwrap();
    let g = r.panels[0];
    let a = g.world_to_pixel([0.0, 0.0]);
    let b = g.world_to_pixel([1.0, 1.0]);
    assert!(((b[0] - a[0]) - (a[1] - b[1])).abs() < 1e-9, "{a:?} {b:?}");
    assert!(b[0] > a[0] && a[1] > b[1], "y must point up");
    let [x0, y0, x1, y1] = g.rect();
    let mid = g.world_to_pixel([0.5, 0.5]);
    assert!((mid[0] - 0.5 * (x0 + x1) as f64).abs() < 1e-9);
    assert!((mid[1] - 0.5 * (y0 + y1) as f64).abs() < 1e-9);
    // Fits the height with a small margin.
    assert!((a[1] - b[1]) > 0.85 * (y1 - y0) as f64 && (a[1] - b[1]) < (y1 - y0) as f64);
    let back = g.pixel_to_world(mid);
    assert!((back[0] - 0.5).abs() < 1e-12 && (back[1] - 0.5).abs() < 1e-12);
}

#[test]
fn image_is_not_blank() {
    let (pos, tris) = grid(30, 15, 2.0, 1.0, 0.3);
    let field: Vec<f64> = tris.iter().map(|&t| centroid(&pos, t)[0]).collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        title: "Ramp".into(),
        field_label: "x".into(),
        unit: "m".into(),
        ..FrameStyle::default()
    };
    let r = render(&[view], &style).unwrap();
    let mut colours = std::collections::HashSet::new();
    for p in r.image.as_rgba().chunks_exact(4) {
        colours.insert([p[0], p[1], p[2]]);
    }
    assert!(colours.len() > 200, "only {} colours", colours.len());
    let g = r.panels[0];
    let (a, b) = (g.world_to_pixel([0.0, 1.0]), g.world_to_pixel([2.0, 0.0]));
    let (mut total, mut white) = (0, 0);
    for y in a[1].ceil() as u32..b[1].floor() as u32 {
        for x in a[0].ceil() as u32..b[0].floor() as u32 {
            total += 1;
            white += (rgb(&r.image, x, y) == [255, 255, 255]) as usize;
        }
    }
    assert!(total > 50_000, "footprint of {total} pixels");
    assert!(
        white * 100 < total,
        "{white} of {total} mesh pixels are white"
    );
}

/// Checks that every pixel whose centre is at least `inset` pixels inside the world rectangle
/// `[0, w] x [0, h]` satisfies `ok`, and returns how many were checked.
fn check_interior(r: &Rendered, w: f64, h: f64, inset: f64, ok: impl Fn([u8; 3]) -> bool) -> usize {
    let g = r.panels[0];
    let (a, b) = (g.world_to_pixel([0.0, h]), g.world_to_pixel([w, 0.0]));
    let mut n = 0;
    for y in 0..r.image.height() {
        for x in 0..r.image.width() {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            if cx > a[0] + inset && cx < b[0] - inset && cy > a[1] + inset && cy < b[1] - inset {
                let c = rgb(&r.image, x, y);
                assert!(ok(c), "pixel ({x}, {y}) has colour {c:?}");
                n += 1;
            }
        }
    }
    n
}

#[test]
fn no_seams_with_a_constant_field() {
    // A jittered grid filling the panel (edges at all angles, vertices anywhere).
    let (w, h) = (16.0, 9.0);
    let (pos, tris) = grid(64, 36, w, h, 0.6);
    let field = vec![2.0; tris.len()];
    let vfield = vec![2.0; pos.len()];
    for f in [
        FieldValues::PerElement(&field),
        FieldValues::PerVertex(&vfield),
    ] {
        let view = MeshView {
            field: Some(f),
            ..MeshView::new(&pos, &tris)
        };
        let style = FrameStyle {
            range: Some((0.0, 2.0)),
            bounds: Some(([0.0, 0.0], [w, h])),
            ..FrameStyle::default()
        };
        let r = render(&[view], &style).unwrap();
        let want = Colormap::Viridis.sample(1.0);
        let n = check_interior(&r, w, h, 3.0, |c| c == want);
        assert!(n > 200_000, "only {n} pixels checked");
    }
    // Without a field the flat mesh colour must be seamless too.
    let r = render(
        &[MeshView::new(&pos, &tris)],
        &FrameStyle {
            bounds: Some(([0.0, 0.0], [w, h])),
            ..FrameStyle::default()
        },
    )
    .unwrap();
    check_interior(&r, w, h, 3.0, |c| c == MESH_COLOR);
}

#[test]
fn no_background_inside_a_mesh_with_random_element_values() {
    let (w, h) = (2.0, 1.0);
    let (pos, tris) = grid(80, 40, w, h, 0.8);
    let field: Vec<f64> = (0..tris.len()).map(|k| ((k * 7919) % 101) as f64).collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    let allowed: std::collections::HashSet<[u8; 3]> = (0..=100)
        .map(|v| Colormap::Viridis.sample(v as f64 / 100.0))
        .collect();
    let n = check_interior(&r, w, h, 3.0, |c| allowed.contains(&c));
    assert!(n > 100_000);
}

#[test]
fn colorbar_extremes_match_the_field_extremes() {
    let (pos, tris) = grid(12, 6, 2.0, 1.0, 0.0);
    // Pa, displayed in kPa.
    let field: Vec<f64> = tris
        .iter()
        .map(|&t| 1000.0 + 5000.0 * centroid(&pos, t)[0])
        .collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    for cmap in Colormap::ALL {
        let style = FrameStyle {
            colormap: cmap,
            scale: 1e-3,
            field_label: "stress".into(),
            unit: "kPa".into(),
            ..FrameStyle::default()
        };
        let r = render(&[view], &style).unwrap();
        let (lo, hi) = r.range.unwrap();
        let (fmin, fmax) = field
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert!((lo - fmin * 1e-3).abs() < 1e-12 && (hi - fmax * 1e-3).abs() < 1e-12);
        let bar = r.colorbar.unwrap();
        let (top, bottom) = (cmap.sample(1.0), cmap.sample(0.0));
        for x in bar.x0..bar.x1 {
            assert_eq!(rgb(&r.image, x, bar.y0), top, "{cmap} top row at x = {x}");
            assert_eq!(
                rgb(&r.image, x, bar.y1 - 1),
                bottom,
                "{cmap} bottom row at x = {x}"
            );
        }
        let kmax = (0..field.len())
            .max_by(|&a, &b| field[a].total_cmp(&field[b]))
            .unwrap();
        let kmin = (0..field.len())
            .min_by(|&a, &b| field[a].total_cmp(&field[b]))
            .unwrap();
        assert_eq!(
            pixel_at(&r, 0, centroid(&pos, tris[kmax])),
            top,
            "{cmap} max element"
        );
        assert_eq!(
            pixel_at(&r, 0, centroid(&pos, tris[kmin])),
            bottom,
            "{cmap} min element"
        );
        // A middle value lands on the matching colorbar row.
        let kmid = field.len() / 2 + 3;
        let row = bar.row_of(field[kmid] * 1e-3, (lo, hi));
        let got = pixel_at(&r, 0, centroid(&pos, tris[kmid]));
        let want = rgb(&r.image, bar.x0 + 2, row);
        for c in 0..3 {
            assert!(
                (got[c] as i32 - want[c] as i32).abs() <= 3,
                "{got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn explicit_range_clamps_values() {
    let (pos, tris) = grid(4, 2, 2.0, 1.0, 0.0);
    let field: Vec<f64> = (0..tris.len()).map(|k| k as f64 * 10.0).collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        range: Some((20.0, 30.0)),
        ..FrameStyle::default()
    };
    let r = render(&[view], &style).unwrap();
    assert_eq!(r.range, Some((20.0, 30.0)));
    assert_eq!(
        pixel_at(&r, 0, centroid(&pos, tris[0])),
        Colormap::Viridis.sample(0.0)
    );
    assert_eq!(
        pixel_at(&r, 0, centroid(&pos, tris[15])),
        Colormap::Viridis.sample(1.0)
    );
}

/// Position of a colour along the colormap (nearest of 1024 samples).
fn invert(cmap: Colormap, c: [u8; 3]) -> f64 {
    (0..1024)
        .min_by_key(|&i| {
            let s = cmap.sample(i as f64 / 1023.0);
            (0..3)
                .map(|k| (s[k] as i32 - c[k] as i32).pow(2))
                .sum::<i32>()
        })
        .unwrap() as f64
        / 1023.0
}

#[test]
fn per_vertex_linear_field_is_a_monotone_gradient() {
    let (pos, tris) = grid(3, 3, 1.0, 1.0, 0.2);
    let field: Vec<f64> = pos.iter().map(|p| p[0]).collect();
    let view = MeshView {
        field: Some(FieldValues::PerVertex(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    let g = r.panels[0];
    let (a, b) = (g.world_to_pixel([0.0, 0.5]), g.world_to_pixel([1.0, 0.5]));
    let y = a[1].floor() as u32;
    let (x0, x1) = (a[0].ceil() as u32 + 2, b[0].floor() as u32 - 2);
    let mut last = -1.0;
    let mut distinct = std::collections::HashSet::new();
    for x in x0..x1 {
        let c = rgb(&r.image, x, y);
        distinct.insert(c);
        let t = invert(Colormap::Viridis, c);
        assert!(
            t >= last - 1e-9,
            "not monotone at x = {x}: {t} after {last}"
        );
        // The colour matches the exact value at the pixel centre.
        let world = g.pixel_to_world([x as f64 + 0.5, y as f64 + 0.5]);
        assert!(
            (t - world[0]).abs() < 0.01,
            "x = {x}: t = {t}, value {}",
            world[0]
        );
        last = t;
    }
    assert!(
        distinct.len() > 100,
        "only {} colours: not interpolated",
        distinct.len()
    );
}

#[test]
fn obstacles_are_drawn_over_the_mesh() {
    let (pos, tris) = grid(10, 5, 2.0, 1.0, 0.0);
    let obstacles = vec![vec![[0.8, 0.3], [1.2, 0.3], [1.2, 0.7], [0.8, 0.7]]];
    let view = MeshView {
        obstacles: &obstacles,
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    assert_eq!(pixel_at(&r, 0, [1.0, 0.5]), OBSTACLE_COLOR);
    assert_eq!(pixel_at(&r, 0, [0.85, 0.35]), OBSTACLE_COLOR);
    assert_eq!(pixel_at(&r, 0, [0.5, 0.5]), MESH_COLOR);
    assert_eq!(pixel_at(&r, 0, [1.5, 0.5]), MESH_COLOR);
    // Outside the mesh too (debris above the body).
    let obstacles = vec![vec![[0.9, 1.2], [1.1, 1.2], [1.0, 1.4]]];
    let view = MeshView {
        obstacles: &obstacles,
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    assert_eq!(pixel_at(&r, 0, [1.0, 1.27]), OBSTACLE_COLOR);
    // The automatic bounds include the obstacle.
    let q = r.panels[0].world_to_pixel([1.0, 1.4]);
    assert!(q[1] > r.panels[0].rect()[1] as f64);
}

#[test]
fn rest_outline_and_wireframe_add_lines() {
    let (rest, tris) = grid(8, 4, 2.0, 1.0, 0.0);
    // Shear the body so its rest shape sticks out.
    let pos: Vec<[f64; 2]> = rest
        .iter()
        .map(|p| [p[0] + 0.4 * p[1], p[1] * 0.8])
        .collect();
    let view = MeshView {
        rest_positions: Some(&rest),
        ..MeshView::new(&pos, &tris)
    };
    let dark = |img: &Image| {
        img.as_rgba()
            .chunks_exact(4)
            .filter(|p| p[0] < 150 && p[1] < 150)
            .count()
    };
    let plain = render(
        &[view],
        &FrameStyle {
            rest_outline: false,
            ..FrameStyle::default()
        },
    )
    .unwrap();
    let outlined = render(&[view], &FrameStyle::default()).unwrap();
    let wired = render(
        &[view],
        &FrameStyle {
            wireframe: true,
            ..FrameStyle::default()
        },
    )
    .unwrap();
    // The rest shape's top-left corner is outside the sheared body: the dashed line is there.
    let g = outlined.panels[0];
    let q = g.world_to_pixel([0.0, 0.5]);
    let mut found = false;
    for dy in -3..=3 {
        for dx in -2..=2 {
            let (x, y) = ((q[0] as i32 + dx) as u32, (q[1] as i32 + dy) as u32);
            let c = rgb(&outlined.image, x, y);
            found |= c[0] < 200 && rgb(&plain.image, x, y) == [255, 255, 255];
        }
    }
    assert!(found, "no rest outline near the rest shape's left edge");
    assert!(dark(&wired.image) > dark(&outlined.image) + 1000);
}

#[test]
fn non_finite_field_values_are_drawn_as_no_data() {
    let (pos, tris) = grid(6, 3, 2.0, 1.0, 0.0);
    let mut field: Vec<f64> = (0..tris.len()).map(|k| k as f64).collect();
    field[5] = f64::NAN;
    field[7] = f64::INFINITY;
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    assert_eq!(r.range, Some((0.0, (tris.len() - 1) as f64)));
    assert_eq!(pixel_at(&r, 0, centroid(&pos, tris[5])), NO_DATA);
    assert_eq!(pixel_at(&r, 0, centroid(&pos, tris[7])), NO_DATA);
    let mut vfield: Vec<f64> = pos.iter().map(|p| p[0]).collect();
    vfield[0] = f64::NAN;
    let view = MeshView {
        field: Some(FieldValues::PerVertex(&vfield)),
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    assert_eq!(pixel_at(&r, 0, centroid(&pos, tris[0])), NO_DATA);
    assert_ne!(pixel_at(&r, 0, centroid(&pos, tris[20])), NO_DATA);
}

#[test]
fn constant_field_range_is_widened() {
    let (pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    let field = vec![3.0; tris.len()];
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        ..MeshView::new(&pos, &tris)
    };
    let r = render(&[view], &FrameStyle::default()).unwrap();
    let (lo, hi) = r.range.unwrap();
    assert!(lo < 3.0 && hi > 3.0 && hi - lo < 1.0, "{lo} {hi}");
}

#[test]
fn error_no_panels() {
    let msg = input_error(&[], &FrameStyle::default());
    assert!(msg.contains("no panels"), "{msg}");
}

#[test]
fn error_zero_panel_size() {
    let (pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    let style = FrameStyle {
        panel_width: 0,
        ..FrameStyle::default()
    };
    let msg = input_error(&[MeshView::new(&pos, &tris)], &style);
    assert!(msg.contains("0x360"), "{msg}");
}

#[test]
fn error_triangle_index_out_of_range() {
    let (pos, mut tris) = grid(2, 2, 1.0, 1.0, 0.0);
    tris[3] = [0, 1, 99];
    let msg = input_error(&[MeshView::new(&pos, &tris)], &FrameStyle::default());
    assert!(
        msg.contains("triangle 3") && msg.contains("99") && msg.contains("9 positions"),
        "{msg}"
    );
}

#[test]
fn error_field_length_mismatch() {
    let (pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    let short = vec![1.0; 5];
    let view = MeshView {
        field: Some(FieldValues::PerElement(&short)),
        caption: "Neo-Hookean",
        ..MeshView::new(&pos, &tris)
    };
    let msg = input_error(&[view], &FrameStyle::default());
    assert!(
        msg.contains('5') && msg.contains("8 triangles") && msg.contains("Neo-Hookean"),
        "{msg}"
    );
    let view = MeshView {
        field: Some(FieldValues::PerVertex(&short)),
        ..MeshView::new(&pos, &tris)
    };
    let msg = input_error(&[view], &FrameStyle::default());
    assert!(msg.contains('5') && msg.contains("9 vertices"), "{msg}");
}

#[test]
fn error_non_finite_position() {
    let (mut pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    pos[4] = [f64::NAN, 0.5];
    let msg = input_error(&[MeshView::new(&pos, &tris)], &FrameStyle::default());
    assert!(msg.contains("position 4") && msg.contains("NaN"), "{msg}");
    let (pos, _) = grid(2, 2, 1.0, 1.0, 0.0);
    let mut rest = pos.clone();
    rest[2] = [0.0, f64::INFINITY];
    let view = MeshView {
        rest_positions: Some(&rest),
        ..MeshView::new(&pos, &tris)
    };
    let msg = input_error(&[view], &FrameStyle::default());
    assert!(
        msg.contains("rest position 2") && msg.contains("inf"),
        "{msg}"
    );
    let obstacles = vec![vec![[0.0, 0.0], [1.0, f64::NAN], [0.0, 1.0]]];
    let view = MeshView {
        obstacles: &obstacles,
        ..MeshView::new(&pos, &tris)
    };
    let msg = input_error(&[view], &FrameStyle::default());
    assert!(msg.contains("obstacle 0, point 1"), "{msg}");
}

#[test]
fn error_scale_not_finite() {
    let (pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    let style = FrameStyle {
        scale: f64::INFINITY,
        ..FrameStyle::default()
    };
    let msg = input_error(&[MeshView::new(&pos, &tris)], &style);
    assert!(msg.contains("scale") && msg.contains("inf"), "{msg}");
}

#[test]
fn error_bad_range_and_bounds() {
    let (pos, tris) = grid(2, 2, 1.0, 1.0, 0.0);
    let view = [MeshView::new(&pos, &tris)];
    for range in [
        (3.0, 1.0),
        (1.0, 1.0),
        (f64::NAN, 1.0),
        (0.0, f64::INFINITY),
    ] {
        let style = FrameStyle {
            range: Some(range),
            ..FrameStyle::default()
        };
        let msg = input_error(&view, &style);
        assert!(
            msg.contains("range") && msg.contains(&format!("{}", range.0)),
            "{msg}"
        );
    }
    let style = FrameStyle {
        bounds: Some(([0.0, 1.0], [1.0, 1.0])),
        ..FrameStyle::default()
    };
    let msg = input_error(&view, &style);
    assert!(msg.contains("bounds"), "{msg}");
}

#[test]
fn explicit_bounds_clip_to_the_panel() {
    let (pos, tris) = grid(10, 10, 10.0, 10.0, 0.0);
    let obstacles = vec![vec![[4.0, 4.0], [30.0, 4.0], [30.0, 6.0], [4.0, 6.0]]];
    let view = MeshView {
        obstacles: &obstacles,
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        bounds: Some(([2.0, 2.0], [8.0, 8.0])),
        panel_width: 200,
        panel_height: 200,
        field_label: String::new(),
        ..FrameStyle::default()
    };
    let r = render(&[view], &style).unwrap();
    let [x0, y0, x1, y1] = r.panels[0].rect();
    // Everything outside the panel rectangle (and its 1-px frame) stays white.
    for y in 0..r.image.height() {
        for x in 0..r.image.width() {
            let near = x + 1 >= x0 && x <= x1 && y + 1 >= y0 && y <= y1;
            if !near {
                assert_eq!(rgb(&r.image, x, y), [255, 255, 255], "({x}, {y})");
            }
        }
    }
    assert_eq!(rgb(&r.image, (x0 + x1) / 2, y0 + 3), MESH_COLOR);
}

/// Writes a representative picture to the temporary directory for eyeballing
/// (`fem-render-sample.png`, and `fem-render-sample-vertex.png`).
#[test]
fn write_sample_picture() {
    // A cantilever-like strip, bent downwards.
    let (rest, tris) = grid(60, 10, 3.0, 0.5, 0.0);
    let bend = |p: &[f64; 2], k: f64| {
        let x = p[0];
        [x - 0.02 * k * x * p[1], p[1] - k * 0.05 * x * x]
    };
    let pos_a: Vec<[f64; 2]> = rest.iter().map(|p| bend(p, 1.0)).collect();
    let pos_b: Vec<[f64; 2]> = rest.iter().map(|p| bend(p, 1.6)).collect();
    let stress = |pos: &[[f64; 2]], k: f64| -> Vec<f64> {
        tris.iter()
            .map(|&t| {
                let c = centroid(&rest, t);
                let _ = pos;
                k * 4.0e4 * (3.0 - c[0]) * (c[1] - 0.25).abs() * 8.0 + 2.0e3
            })
            .collect()
    };
    let sa = stress(&pos_a, 1.0);
    let sb = stress(&pos_b, 1.6);
    let debris = vec![vec![[2.4, 0.55], [2.62, 0.58], [2.58, 0.74], [2.38, 0.7]]];
    let panels = [
        MeshView {
            field: Some(FieldValues::PerElement(&sa)),
            rest_positions: Some(&rest),
            obstacles: &debris,
            caption: "Neo-Hookean",
            ..MeshView::new(&pos_a, &tris)
        },
        MeshView {
            field: Some(FieldValues::PerElement(&sb)),
            rest_positions: Some(&rest),
            caption: "St. Venant-Kirchhoff",
            ..MeshView::new(&pos_b, &tris)
        },
    ];
    let style = FrameStyle {
        panel_width: 480,
        panel_height: 300,
        title: "Cantilever under gravity".into(),
        field_label: "von Mises stress".into(),
        unit: "kPa".into(),
        scale: 1e-3,
        time_label: Some("t = 0.120 s".into()),
        ..FrameStyle::default()
    };
    let r = render(&panels, &style).unwrap();
    let dir = std::env::temp_dir();
    r.image
        .write_png(&dir.join("fem-render-sample.png"))
        .unwrap();

    let disp: Vec<f64> = rest
        .iter()
        .zip(&pos_b)
        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() * 1e3)
        .collect();
    let view = MeshView {
        field: Some(FieldValues::PerVertex(&disp)),
        rest_positions: Some(&rest),
        caption: "Displacement",
        ..MeshView::new(&pos_b, &tris)
    };
    let style = FrameStyle {
        title: "Per-vertex field, wireframe, inferno".into(),
        colormap: Colormap::Inferno,
        field_label: "|u|".into(),
        unit: "mm".into(),
        wireframe: true,
        ..FrameStyle::default()
    };
    let r = render(&[view], &style).unwrap();
    r.image
        .write_png(&dir.join("fem-render-sample-vertex.png"))
        .unwrap();
    let back = Image::from_png(&r.image.to_png().unwrap()).unwrap();
    assert_eq!(back, r.image);
}

const IVORY: [u8; 3] = [232, 224, 200];

/// Positions, triangles, a tag per triangle and a per-element field.
type TaggedMesh = (Vec<[f64; 2]>, Vec<[usize; 3]>, Vec<u32>, Vec<f64>);

/// A 10 x 4 grid whose right half (centroid x > 1) is "bone" (tag 1), with a per-element field
/// of 1 kPa-ish in the soft half and a thousand times more in the bone.
fn two_tissues() -> TaggedMesh {
    let (pos, tris) = grid(10, 4, 2.0, 0.8, 0.0);
    let tags: Vec<u32> = tris
        .iter()
        .map(|&t| u32::from(centroid(&pos, t)[0] > 1.0))
        .collect();
    let field: Vec<f64> = tris
        .iter()
        .zip(&tags)
        .map(|(&t, &tag)| centroid(&pos, t)[0] * if tag == 1 { 1e6 } else { 1e3 })
        .collect();
    (pos, tris, tags, field)
}

#[test]
fn flat_elements_take_their_colour_and_stay_out_of_the_range() {
    let (pos, tris, tags, field) = two_tissues();
    let mask: Vec<bool> = tags.iter().map(|&t| t == 1).collect();
    let soft_max = field
        .iter()
        .zip(&mask)
        .filter(|(_, m)| !**m)
        .map(|(v, _)| *v)
        .fold(0.0, f64::max);
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        flat: Some(FlatElements {
            mask: &mask,
            color: IVORY,
            label: "bone",
        }),
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        field_label: "von Mises stress".into(),
        unit: "kPa".into(),
        scale: 1e-3,
        ..FrameStyle::default()
    };
    let r = render(&[view], &style).unwrap();
    // The automatic range is the soft half's: the bone's thousandfold stress does not set it.
    let (lo, hi) = r.range.unwrap();
    assert!((hi - soft_max * 1e-3).abs() < 1e-12, "range {lo}..{hi}");
    for (t, &m) in tris.iter().zip(&mask) {
        let c = pixel_at(&r, 0, centroid(&pos, *t));
        if m {
            assert_eq!(c, IVORY, "bone triangle {t:?}");
        } else {
            assert_ne!(c, IVORY, "soft triangle {t:?}");
        }
    }
    // The soft triangle with the largest value has the colormap's top colour.
    let top = tris
        .iter()
        .zip(&field)
        .zip(&mask)
        .filter(|(_, m)| !**m)
        .max_by(|a, b| a.0.1.total_cmp(b.0.1))
        .unwrap()
        .0
        .0;
    assert_eq!(
        pixel_at(&r, 0, centroid(&pos, *top)),
        style.colormap.sample(1.0)
    );
    // One legend row under the colorbar: the swatch in the flat colour.
    assert_eq!(r.legend.len(), 1);
    let (label, [x0, y0, x1, y1]) = r.legend[0].clone();
    assert_eq!(label, "bone");
    let bar = r.colorbar.unwrap();
    assert!(
        y0 > bar.y1 && x0 == bar.x0 && x1 == bar.x1,
        "{:?} {bar:?}",
        r.legend[0]
    );
    assert_eq!(rgb(&r.image, (x0 + x1) / 2, (y0 + y1) / 2), IVORY);
    // The bar is shorter than without a legend; the picture is the same size.
    let without = render(
        &[MeshView {
            field: Some(FieldValues::PerElement(&field)),
            ..MeshView::new(&pos, &tris)
        }],
        &style,
    )
    .unwrap();
    let full = without.colorbar.unwrap();
    assert!(bar.y1 < full.y1 && bar.y0 == full.y0);
    assert_eq!(
        (r.image.width(), r.image.height()),
        (without.image.width(), without.image.height())
    );
    assert!(without.legend.is_empty());
    // Without a field the flat triangles still show (a scene's set-up), with no legend.
    let plain = render(
        &[MeshView {
            field: None,
            ..view
        }],
        &style,
    )
    .unwrap();
    assert!(plain.legend.is_empty() && plain.colorbar.is_none());
    assert_eq!(pixel_at(&plain, 0, [1.55, 0.45]), IVORY);
    assert_eq!(pixel_at(&plain, 0, [0.45, 0.45]), MESH_COLOR);
    // A mask of the wrong length is an input error naming the counts.
    let short = [true; 3];
    let m = input_error(
        &[MeshView {
            flat: Some(FlatElements {
                mask: &short,
                color: IVORY,
                label: "",
            }),
            ..view
        }],
        &style,
    );
    assert!(
        m.contains("3 entries") && m.contains(&format!("{} triangles", tris.len())),
        "{m}"
    );
}

#[test]
fn region_edges_are_where_tags_change_and_the_outlined_boundary() {
    let (pos, tris, tags, _) = two_tissues();
    let inner = region_edges(&tris, &tags, |_| false);
    // The interface x = 1 between the halves: 4 cells high, one edge per cell.
    assert_eq!(inner.len(), 4);
    for e in &inner {
        assert!(pos[e[0]][0] == 1.0 && pos[e[1]][0] == 1.0, "{e:?}");
        assert!(e[0] < e[1]);
    }
    // With the bone's own boundary: its top, bottom and right sides too (5 + 5 + 4 edges).
    let bone = region_edges(&tris, &tags, |t| t == 1);
    assert_eq!(bone.len(), 4 + 14);
    assert!(bone.windows(2).all(|w| w[0] < w[1]), "sorted, no repeats");
    assert!(inner.iter().all(|e| bone.contains(e)));
    // One tag: no edge inside; every boundary edge when outlined.
    let same = vec![0; tris.len()];
    assert!(region_edges(&tris, &same, |_| false).is_empty());
    assert_eq!(region_edges(&tris, &same, |_| true).len(), 2 * (10 + 4));
}

#[test]
fn outline_edges_are_drawn_dark_over_the_fill() {
    let (pos, tris, tags, _) = two_tissues();
    let edges = region_edges(&tris, &tags, |_| false);
    let without = render(&[MeshView::new(&pos, &tris)], &FrameStyle::default()).unwrap();
    let r = render(
        &[MeshView {
            outline_edges: &edges,
            ..MeshView::new(&pos, &tris)
        }],
        &FrameStyle::default(),
    )
    .unwrap();
    let lum = |c: [u8; 3]| c.iter().map(|&v| v as f64).sum::<f64>();
    // On the interface (x = 1): a line about one pixel wide (anti-aliased, so spread over the
    // two pixels nearest to it) darkens the row by most of one pixel's worth of edge colour;
    // away from it, nothing changes.
    for y in [0.1, 0.3, 0.5, 0.7] {
        let q = r.panels[0].world_to_pixel([1.0, y]);
        let (x, row) = (q[0].floor() as u32, q[1].floor() as u32);
        let darkening: f64 = (x - 1..=x + 1)
            .map(|i| lum(rgb(&without.image, i, row)) - lum(rgb(&r.image, i, row)))
            .sum();
        let full = lum(MESH_COLOR) - lum(EDGE_COLOR);
        assert!(
            darkening > 0.7 * full && darkening < 1.05 * full,
            "interface at y = {y}: darkening {darkening}, one pixel of edge colour {full}"
        );
        for x in [0.5, 1.5] {
            assert_eq!(pixel_at(&r, 0, [x, y]), pixel_at(&without, 0, [x, y]));
        }
    }
    // An edge naming a missing vertex is an input error.
    let bad = [[0, pos.len()]];
    let m = input_error(
        &[MeshView {
            outline_edges: &bad,
            ..MeshView::new(&pos, &tris)
        }],
        &FrameStyle::default(),
    );
    assert!(m.contains("outline edge"), "{m}");
}
