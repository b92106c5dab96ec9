//! Integration tests of `fem_render::gif`: frames written by [`GifWriter`] and [`write_gif`]
//! decode with the `gif` crate to the right count, size, loop setting and colours.

use fem_render::colormap::Colormap;
use fem_render::frame::{FieldValues, FrameStyle, MeshView, Rendered, render};
use fem_render::gif::{GifWriter, write_gif};
use fem_render::{Image, RenderError};

/// A strip of `n` x 4 cells with a per-element field ramping along x, shifted by `phase`.
fn frame(phase: f64) -> Image {
    rendered(phase).image
}

fn rendered(phase: f64) -> Rendered {
    let n = 24;
    let mut pos = Vec::new();
    for j in 0..=4 {
        for i in 0..=n {
            let x = i as f64 / n as f64 * 2.0;
            pos.push([x, j as f64 * 0.1 - 0.05 * phase * x * x]);
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..4 {
        for i in 0..n {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let field: Vec<f64> = (0..tris.len())
        .map(|k| ((k / 2) % n) as f64 + 5.0 * phase)
        .collect();
    let view = MeshView {
        field: Some(FieldValues::PerElement(&field)),
        caption: "strip",
        ..MeshView::new(&pos, &tris)
    };
    let style = FrameStyle {
        panel_width: 320,
        panel_height: 160,
        title: format!("frame {phase}"),
        field_label: "value".into(),
        range: Some((0.0, 40.0)),
        bounds: Some(([-0.1, -0.5], [2.1, 0.5])),
        time_label: Some(format!("t = {:.3} s", phase * 0.1)),
        ..FrameStyle::default()
    };
    render(&[view], &style).unwrap()
}

struct Decoded {
    width: u16,
    height: u16,
    repeat: gif::Repeat,
    frames: Vec<(u16, Vec<u8>)>,
}

fn decode(bytes: &[u8]) -> Decoded {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let mut d = opts.read_info(bytes).unwrap();
    let (width, height) = (d.width(), d.height());
    let mut frames = Vec::new();
    while let Some(f) = d.read_next_frame().unwrap() {
        assert_eq!((f.left, f.top), (0, 0));
        assert_eq!((f.width, f.height), (width, height));
        frames.push((f.delay, f.buffer.to_vec()));
    }
    Decoded {
        width,
        height,
        repeat: d.repeat(),
        frames,
    }
}

fn close(a: &[u8], b: [u8; 4], tol: i32) -> bool {
    (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= tol)
}

#[test]
fn three_frames_round_trip() {
    let rendered: Vec<Rendered> = (0..3).map(|k| rendered(k as f64)).collect();
    let images: Vec<Image> = rendered.iter().map(|r| r.image.clone()).collect();
    assert_ne!(images[0], images[1]);
    let (w, h) = (images[0].width(), images[0].height());
    let mut writer = GifWriter::new(Vec::new(), w, h, 7).unwrap();
    for img in &images {
        writer.push(img).unwrap();
    }
    assert_eq!(writer.frames(), 3);
    let bytes = writer.finish().unwrap();
    let d = decode(&bytes);
    assert_eq!((d.width as u32, d.height as u32), (w, h));
    assert_eq!(d.frames.len(), 3);
    assert_eq!(d.repeat, gif::Repeat::Infinite);
    // Background corners, the mesh, and every few rows of the colorbar's gradient.
    let bar = rendered[0].colorbar.unwrap();
    let bar_col = (bar.x0 + bar.x1) / 2;
    for (k, (delay, rgba)) in d.frames.iter().enumerate() {
        assert_eq!(*delay, 7);
        let src = &images[k];
        let mut samples: Vec<(u32, u32)> =
            vec![(0, 0), (w - 1, h - 1), (w / 4, h / 2), (w / 3, h / 2 + 10)];
        samples.extend((bar.y0..bar.y1).step_by(5).map(|y| (bar_col, y)));
        for (x, y) in samples {
            let i = ((y * w + x) * 4) as usize;
            let want = src.pixel(x, y);
            assert!(
                close(&rgba[i..i + 4], want, 12),
                "frame {k} pixel ({x}, {y}): {:?} vs {want:?}",
                &rgba[i..i + 4]
            );
        }
        // Overall fidelity: the mean error per channel is small.
        let err: u64 = rgba
            .iter()
            .zip(src.as_rgba())
            .map(|(&a, &b)| (a as i64 - b as i64).unsigned_abs())
            .sum();
        let mean = err as f64 / rgba.len() as f64;
        assert!(mean < 2.0, "frame {k}: mean error {mean}");
    }
    // The frames differ after decoding too.
    assert_ne!(d.frames[0].1, d.frames[1].1);
}

#[test]
fn gradients_of_every_colormap_survive() {
    let (w, h) = (256u32, 8u32);
    let mut frames = Vec::new();
    for cmap in Colormap::ALL {
        let mut img = Image::new(w, h, [255, 255, 255, 255]);
        for x in 0..w {
            let c = cmap.sample(x as f64 / (w - 1) as f64);
            for y in 0..h {
                img.set_pixel(x, y, [c[0], c[1], c[2], 255]);
            }
        }
        frames.push(img);
    }
    let mut writer = GifWriter::new(Vec::new(), w, h, 10).unwrap();
    for f in &frames {
        writer.push(f).unwrap();
    }
    let d = decode(&writer.finish().unwrap());
    assert_eq!(d.frames.len(), 4);
    for (k, (_, rgba)) in d.frames.iter().enumerate() {
        let mut distinct = std::collections::HashSet::new();
        for x in 0..w {
            let i = (x * 4) as usize;
            let want = frames[k].pixel(x, 0);
            assert!(
                close(&rgba[i..i + 4], want, 12),
                "{:?} x = {x}",
                Colormap::ALL[k]
            );
            distinct.insert(rgba[i..i + 3].to_vec());
        }
        assert!(
            distinct.len() >= 30,
            "{:?}: only {} colours",
            Colormap::ALL[k],
            distinct.len()
        );
    }
}

#[test]
fn translucent_pixels_are_composited_over_white() {
    let mut img = Image::new(2, 1, [0, 0, 0, 0]);
    img.set_pixel(1, 0, [0, 0, 0, 255]);
    let mut writer = GifWriter::new(Vec::new(), 2, 1, 1).unwrap();
    writer.push(&img).unwrap();
    let d = decode(&writer.finish().unwrap());
    assert_eq!(&d.frames[0].1[..3], &[255, 255, 255]);
    assert_eq!(&d.frames[0].1[4..7], &[0, 0, 0]);
}

#[test]
fn rejects_bad_sizes() {
    for (w, h) in [(0, 10), (10, 0), (70_000, 10)] {
        match GifWriter::new(Vec::new(), w, h, 5) {
            Err(RenderError::Input(msg)) => assert!(
                msg.contains(&w.max(h).to_string()) || msg.contains(" 0 "),
                "{msg}"
            ),
            Err(e) => panic!("{e:?}"),
            Ok(_) => panic!("{w}x{h} accepted"),
        }
    }
    let mut writer = GifWriter::new(Vec::new(), 10, 10, 5).unwrap();
    match writer.push(&Image::new(10, 11, [0, 0, 0, 255])) {
        Err(RenderError::Input(msg)) => {
            assert!(msg.contains("10x11") && msg.contains("10x10"), "{msg}")
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(writer.frames(), 0);
}

#[test]
fn write_gif_writes_a_file_atomically() {
    let dir = std::env::temp_dir().join(format!("fem-render-gif-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("anim.gif");
    let frames: Vec<Image> = (0..3).map(|k| frame(k as f64 * 0.5)).collect();
    write_gif(&path, &frames, 4).unwrap();
    let d = decode(&std::fs::read(&path).unwrap());
    assert_eq!(d.frames.len(), 3);
    assert_eq!(d.repeat, gif::Repeat::Infinite);
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "temporary file left behind: {names:?}");
    match write_gif(&dir.join("none.gif"), &[], 4) {
        Err(RenderError::Input(msg)) => assert!(msg.contains("no frames"), "{msg}"),
        other => panic!("{other:?}"),
    }
    assert!(!dir.join("none.gif").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
