//! Integration tests of `fem_render::pressure`: the loaded boundary is drawn in the colour of
//! its pressure (exactly, where the line covers a pixel whole), linear along an edge, the
//! unloaded boundary is left alone, the legend shows the colormap's ends, and bad input is an
//! error, not a panic.

use fem_render::Colormap;
use fem_render::frame::{FrameStyle, MeshView, Rendered, render};
use fem_render::pressure::{PressureOverlay, draw_pressure, legend_rect};

/// A 2 m x 1 m rectangle of two triangles.
const POSITIONS: [[f64; 2]; 4] = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]];
const TRIANGLES: [[usize; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

fn plain() -> Rendered {
    render(
        &[MeshView::new(&POSITIONS, &TRIANGLES)],
        &FrameStyle::default(),
    )
    .unwrap()
}

fn pixel(r: &Rendered, world: [f64; 2]) -> [u8; 3] {
    let q = r.panels[0].world_to_pixel(world);
    let p = r.image.pixel(q[0] as u32, q[1] as u32);
    [p[0], p[1], p[2]]
}

#[test]
fn loaded_bottom_edge_takes_the_pressure_colour_and_the_top_stays() {
    let before = plain();
    let mut r = plain();
    // 2 kPa at both bottom vertices; the range is 0 to 2 kPa, so the line is the colormap's
    // top colour along the whole edge.
    let pressure = [2000.0, 2000.0, 0.0, 0.0];
    let o = PressureOverlay::new(&POSITIONS, &TRIANGLES, &pressure);
    assert_eq!(o.displayed_range(), (0.0, 2.0));
    draw_pressure(&mut r.image, &r.panels[0], &o).unwrap();
    let top = Colormap::Inferno.sample(1.0);
    for x in [0.5, 1.0, 1.5] {
        assert_eq!(pixel(&r, [x, 0.0]), top, "bottom edge at x = {x}");
        assert_eq!(
            pixel(&r, [x, 1.0]),
            pixel(&before, [x, 1.0]),
            "top edge at x = {x}"
        );
    }
    // The sides are loaded at their bottom vertex only: the pressure falls linearly to 0 at
    // the top, so near the top (5 % of the range left) the line has the colormap's low end.
    let side = pixel(&r, [2.0, 0.95]);
    let low = Colormap::Inferno.sample(0.05);
    assert!(
        (0..3).all(|k| (side[k] as i32 - low[k] as i32).abs() <= 8),
        "side near the top {side:?}, want about {low:?}"
    );
    // The legend: its colour bar runs from the colormap's bottom to its top.
    let [x0, y0, x1, y1] = legend_rect(&r.panels[0]);
    let y = (y0 + y1) / 2;
    let p = |x: u32| {
        let c = r.image.pixel(x, y);
        [c[0], c[1], c[2]]
    };
    assert_eq!(p(x0), Colormap::Inferno.sample(0.0));
    assert_eq!(p(x1 - 1), top);
}

#[test]
fn pressure_varies_linearly_along_an_edge() {
    let mut r = plain();
    // 0 at the left bottom vertex, 4 kPa at the right one: at x = 1.5 m (three quarters) the
    // colour is the colormap's at 0.75, within the half-piece of colour quantisation (one
    // piece is two pixels, about 0.6 % of the edge) and the lookup table's step.
    let pressure = [0.0, 4000.0, 0.0, 0.0];
    let o = PressureOverlay::new(&POSITIONS, &TRIANGLES, &pressure);
    draw_pressure(&mut r.image, &r.panels[0], &o).unwrap();
    let got = pixel(&r, [1.5, 0.0]);
    let want = Colormap::Inferno.sample(0.75);
    let far = Colormap::Inferno.sample(0.65);
    let dist = |a: [u8; 3], b: [u8; 3]| {
        (0..3)
            .map(|k| (a[k] as i32 - b[k] as i32).abs())
            .max()
            .unwrap()
    };
    assert!(dist(got, want) <= 6, "got {got:?}, want {want:?}");
    assert!(
        dist(want, far) > 6,
        "the check could not tell 0.65 from 0.75"
    );
}

#[test]
fn bad_input_is_an_error() {
    let mut r = plain();
    let short = [1.0, 2.0];
    let e = draw_pressure(
        &mut r.image,
        &r.panels[0],
        &PressureOverlay::new(&POSITIONS, &TRIANGLES, &short),
    )
    .unwrap_err();
    assert!(e.to_string().contains("2 values for 4 vertices"), "{e}");
    let pressure = [1.0; 4];
    let mut o = PressureOverlay::new(&POSITIONS, &TRIANGLES, &pressure);
    o.range = Some((1.0, 1.0));
    assert!(draw_pressure(&mut r.image, &r.panels[0], &o).is_err());
}
