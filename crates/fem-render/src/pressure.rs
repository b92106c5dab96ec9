//! The contact pressure along a body's boundary, drawn over a rendered frame: each loaded
//! boundary edge (an edge used by one triangle with a positive pressure at either end) as a
//! thick line whose colour follows the pressure, linear along the edge between its two
//! vertices' values, and a small horizontal legend with its unit in the panel's top-left
//! corner. The overlay goes on top of an image from [`crate::frame::render`], in one of its
//! panels ([`crate::frame::PanelGeometry`]), so the image's size does not change.
//!
//! ```no_run
//! use fem_render::frame::{FrameStyle, MeshView, render};
//! use fem_render::pressure::{PressureOverlay, draw_pressure};
//! # fn main() -> fem_render::Result<()> {
//! let positions = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
//! let triangles = [[0, 1, 2]];
//! let pressure = [200.0, 100.0, 0.0]; // Pa per vertex
//! let mut r = render(&[MeshView::new(&positions, &triangles)], &FrameStyle::default())?;
//! let overlay = PressureOverlay::new(&positions, &triangles, &pressure);
//! draw_pressure(&mut r.image, &r.panels[0], &overlay)?;
//! # Ok(())
//! # }
//! ```

use resvg::tiny_skia as sk;

use crate::colormap::Colormap;
use crate::frame::{
    BACKGROUND, FRAME_COLOR, PanelGeometry, TEXT_COLOR, boundary_edges, panel_mask,
};
use crate::raster::Canvas;
use crate::text::{self, Align};
use crate::{Image, RenderError, Result};

/// Width of the pressure line, pixels.
pub const LINE_WIDTH: f32 = 5.0;
const LEGEND_WIDTH: u32 = 120;
const LEGEND_HEIGHT: u32 = 8;
const LEGEND_INSET: u32 = 10;
const LEGEND_TEXT: f32 = 11.0;

/// The pressure to draw and how.
#[derive(Debug, Clone)]
pub struct PressureOverlay<'a> {
    /// Vertex positions, m (the panel's current configuration).
    pub positions: &'a [[f64; 2]],
    /// Triangles as indices into `positions`; the boundary is the edges used by one triangle.
    pub triangles: &'a [[usize; 3]],
    /// Pressure per vertex, Pa (0 off contact; only boundary vertices are read).
    pub pressure: &'a [f64],
    /// Displayed value = pressure * `scale`; default 1e-3 (Pa to kPa).
    pub scale: f64,
    /// Unit of the displayed values; default "kPa".
    pub unit: String,
    /// Legend range in displayed units; `None` = 0 to the largest finite pressure (0 to 1
    /// when nothing is loaded).
    pub range: Option<(f64, f64)>,
    /// Colormap of the line; default [`Colormap::Inferno`], apart from the stress maps'
    /// default.
    pub colormap: Colormap,
}

impl<'a> PressureOverlay<'a> {
    /// The overlay of `pressure` (Pa per vertex) in kPa on [`Colormap::Inferno`].
    pub fn new(
        positions: &'a [[f64; 2]],
        triangles: &'a [[usize; 3]],
        pressure: &'a [f64],
    ) -> Self {
        PressureOverlay {
            positions,
            triangles,
            pressure,
            scale: 1e-3,
            unit: "kPa".to_owned(),
            range: None,
            colormap: Colormap::Inferno,
        }
    }

    /// The displayed range the colours use: [`PressureOverlay::range`], or 0 to the largest
    /// finite displayed pressure.
    pub fn displayed_range(&self) -> (f64, f64) {
        if let Some(r) = self.range {
            return r;
        }
        let hi = self
            .pressure
            .iter()
            .filter(|p| p.is_finite())
            .fold(0.0, |m: f64, &p| m.max(p * self.scale));
        (0.0, if hi > 0.0 { hi } else { 1.0 })
    }
}

/// Draws `overlay` over `image` inside `panel` (clipped to it), with its legend. Errors
/// ([`RenderError::Input`]): a pressure slice whose length is not the positions', a triangle
/// naming a missing vertex, or a range that is not finite and increasing.
pub fn draw_pressure(
    image: &mut Image,
    panel: &PanelGeometry,
    overlay: &PressureOverlay<'_>,
) -> Result<()> {
    let n = overlay.positions.len();
    if overlay.pressure.len() != n {
        return Err(RenderError::Input(format!(
            "contact pressure: {} values for {n} vertices",
            overlay.pressure.len()
        )));
    }
    if let Some(t) = overlay.triangles.iter().find(|t| t.iter().any(|&v| v >= n)) {
        return Err(RenderError::Input(format!(
            "contact pressure: triangle {t:?} names a vertex beyond {n}"
        )));
    }
    let (lo, hi) = overlay.displayed_range();
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(RenderError::Input(format!(
            "contact pressure: range [{lo}, {hi}] is not finite and increasing"
        )));
    }
    let colour = |p: f64| {
        overlay
            .colormap
            .sample((p * overlay.scale - lo) / (hi - lo))
    };
    let (w, h) = (image.width(), image.height());
    let mask = panel_mask(w, h, panel.rect());
    if let Some(mut pixmap) = sk::PixmapMut::from_bytes(image.as_rgba_mut(), w, h) {
        let stroke = sk::Stroke {
            width: LINE_WIDTH,
            line_cap: sk::LineCap::Round,
            ..sk::Stroke::default()
        };
        for [a, b] in boundary_edges(n, overlay.triangles) {
            let (pa, pb) = (overlay.pressure[a as usize], overlay.pressure[b as usize]);
            if !(pa.is_finite() && pb.is_finite()) || pa.max(pb) <= 0.0 {
                continue;
            }
            let qa = panel.world_to_pixel(overlay.positions[a as usize]);
            let qb = panel.world_to_pixel(overlay.positions[b as usize]);
            // Pieces of about two pixels, each in the colour of its middle's pressure.
            let len = (qb[0] - qa[0]).hypot(qb[1] - qa[1]);
            let pieces = ((len / 2.0).ceil() as usize).clamp(1, 4096);
            for k in 0..pieces {
                let (s0, s1) = (k as f64 / pieces as f64, (k + 1) as f64 / pieces as f64);
                let at = |s: f64| [qa[0] + s * (qb[0] - qa[0]), qa[1] + s * (qb[1] - qa[1])];
                let (p0, p1) = (at(s0), at(s1));
                let mut pb_ = sk::PathBuilder::new();
                pb_.move_to(p0[0] as f32, p0[1] as f32);
                pb_.line_to(p1[0] as f32, p1[1] as f32);
                let Some(path) = pb_.finish() else { continue };
                let c = colour(pa + 0.5 * (s0 + s1) * (pb - pa));
                let mut paint = sk::Paint::default();
                paint.set_color_rgba8(c[0], c[1], c[2], 255);
                paint.anti_alias = true;
                pixmap.stroke_path(
                    &path,
                    &paint,
                    &stroke,
                    sk::Transform::identity(),
                    mask.as_ref(),
                );
            }
        }
    }
    draw_legend(image, panel, overlay, (lo, hi));
    Ok(())
}

/// Where the legend's colour bar lies in `panel`: `[x0, y0, x1, y1]` pixels (the text sits
/// above it).
pub fn legend_rect(panel: &PanelGeometry) -> [u32; 4] {
    let [x0, y0, _, _] = panel.rect();
    let top = y0 + LEGEND_INSET + 14;
    let left = x0 + LEGEND_INSET;
    [left, top, left + LEGEND_WIDTH, top + LEGEND_HEIGHT]
}

fn draw_legend(image: &mut Image, panel: &PanelGeometry, o: &PressureOverlay<'_>, r: (f64, f64)) {
    let [bx0, by0, bx1, by1] = legend_rect(panel);
    let mut canvas = Canvas::new(image);
    // A white card behind the legend, framed, so it reads over the mesh.
    let (cx0, cy0) = (bx0 as i32 - 4, by0 as i32 - 16);
    let (cx1, cy1) = (bx1 as i32 + 4, by1 as i32 + 16);
    canvas.fill_rect(cx0, cy0, cx1, cy1, BACKGROUND);
    for x in cx0..cx1 {
        canvas.blend(x, cy0, FRAME_COLOR, 1.0);
        canvas.blend(x, cy1 - 1, FRAME_COLOR, 1.0);
    }
    for y in cy0..cy1 {
        canvas.blend(cx0, y, FRAME_COLOR, 1.0);
        canvas.blend(cx1 - 1, y, FRAME_COLOR, 1.0);
    }
    for x in bx0..bx1 {
        let t = (x - bx0) as f64 / (bx1 - bx0 - 1).max(1) as f64;
        canvas.fill_rect(
            x as i32,
            by0 as i32,
            x as i32 + 1,
            by1 as i32,
            o.colormap.sample(t),
        );
    }
    let label = format!("contact pressure [{}]", o.unit);
    text::draw(
        &mut canvas,
        &label,
        LEGEND_TEXT,
        bx0 as f32,
        by0 as f32 - 4.0,
        Align::Left,
        TEXT_COLOR,
    );
    let below = by1 as f32 + 12.0;
    let fmt = |v: f64| {
        if v.abs() >= 100.0 || v == 0.0 {
            format!("{v:.0}")
        } else if v.abs() >= 1.0 {
            format!("{v:.1}")
        } else {
            format!("{v:.3}")
        }
    };
    text::draw(
        &mut canvas,
        &fmt(r.0),
        LEGEND_TEXT,
        bx0 as f32,
        below,
        Align::Left,
        TEXT_COLOR,
    );
    text::draw(
        &mut canvas,
        &fmt(r.1),
        LEGEND_TEXT,
        bx1 as f32,
        below,
        Align::Right,
        TEXT_COLOR,
    );
}
