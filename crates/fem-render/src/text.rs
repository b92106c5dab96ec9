//! Anti-aliased text with the carried DejaVu Sans: glyph coverage from `ab_glyph`, blended onto
//! the image. Text on these pictures is short (a title, captions, a handful of tick labels), so
//! glyphs are rasterised directly, without a cache.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, GlyphId, PxScale, ScaleFont, point};

use crate::raster::Canvas;

/// The parsed carried font, parsed once.
pub(crate) fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| {
        FontRef::try_from_slice(crate::FONT_TTF).expect("the carried DejaVu Sans font parses")
    })
}

/// `ab_glyph` scales by the font height (ascent - descent); `size` here is the em size in
/// pixels, as in CSS `font-size`.
fn px_scale(size: f32) -> PxScale {
    let f = font();
    let upem = f.units_per_em().unwrap_or(2048.0);
    PxScale::from(size * f.height_unscaled() / upem)
}

/// Horizontal alignment of a text run relative to its anchor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Align {
    /// The anchor is the left end.
    Left,
    /// The anchor is the centre.
    Center,
    /// The anchor is the right end.
    Right,
}

/// The advance width of `text` at em size `size`, in pixels.
pub(crate) fn width(text: &str, size: f32) -> f32 {
    let f = font();
    let sf = f.as_scaled(px_scale(size));
    let mut x = 0.0;
    let mut prev: Option<GlyphId> = None;
    for ch in text.chars() {
        let id = f.glyph_id(ch);
        if let Some(p) = prev {
            x += sf.kern(p, id);
        }
        x += sf.h_advance(id);
        prev = Some(id);
    }
    x
}

/// Ascent (positive, up) and descent (negative) of the font at em size `size`, in pixels.
pub(crate) fn vertical_metrics(size: f32) -> (f32, f32) {
    let sf = font().as_scaled(px_scale(size));
    (sf.ascent(), sf.descent())
}

/// Height of capital letters and digits above the baseline, in pixels (DejaVu Sans: 0.729 em).
pub(crate) fn cap_height(size: f32) -> f32 {
    0.729 * size
}

/// Calls `put(x, y, coverage)` for every covered pixel of `text` laid out from pen position
/// `(x, baseline)` (pixel coordinates, y down). Pixel coordinates may be negative.
fn rasterize(text: &str, size: f32, x: f32, baseline: f32, mut put: impl FnMut(i32, i32, f32)) {
    let f = font();
    let scale = px_scale(size);
    let sf = f.as_scaled(scale);
    let mut pen = x;
    let mut prev: Option<GlyphId> = None;
    for ch in text.chars() {
        let id = f.glyph_id(ch);
        if let Some(p) = prev {
            pen += sf.kern(p, id);
        }
        let glyph = id.with_scale_and_position(scale, point(pen, baseline));
        if let Some(outlined) = f.outline_glyph(glyph) {
            let b = outlined.px_bounds();
            let (ox, oy) = (b.min.x as i32, b.min.y as i32);
            outlined.draw(|gx, gy, c| put(ox + gx as i32, oy + gy as i32, c));
        }
        pen += sf.h_advance(id);
        prev = Some(id);
    }
}

/// Coverage to opacity: a slight gamma lift so that small dark text on white keeps its weight.
#[inline]
fn opacity(c: f32) -> f32 {
    c.clamp(0.0, 1.0).powf(0.8)
}

/// Draws `text` horizontally with its baseline at `baseline`, aligned on `x`.
pub(crate) fn draw(
    canvas: &mut Canvas<'_>,
    text: &str,
    size: f32,
    x: f32,
    baseline: f32,
    align: Align,
    color: [u8; 3],
) {
    if text.is_empty() {
        return;
    }
    let start = match align {
        Align::Left => x,
        Align::Center => x - 0.5 * width(text, size),
        Align::Right => x - width(text, size),
    };
    // Whole-pixel pen start keeps identical strings identical wherever they are drawn.
    rasterize(text, size, start.round(), baseline.round(), |px, py, c| {
        canvas.blend(px, py, color, opacity(c))
    });
}

/// Draws `text` rotated a quarter turn counter-clockwise (reading bottom to top), the tops of
/// the glyphs facing left at `left`, the run centred vertically on `center_y`.
pub(crate) fn draw_vertical(
    canvas: &mut Canvas<'_>,
    text: &str,
    size: f32,
    left: f32,
    center_y: f32,
    color: [u8; 3],
) {
    if text.is_empty() {
        return;
    }
    let (ascent, _) = vertical_metrics(size);
    let run = width(text, size);
    // Layout coordinates (u along the text, v down from the top of the line) map to the image
    // as x = left + v, y = bottom - u.
    let left = left.round() as i32;
    let bottom = (center_y + 0.5 * run).round() as i32;
    rasterize(text, size, 0.0, ascent.round(), |u, v, c| {
        canvas.blend(left + v, bottom - u, color, opacity(c))
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Image;

    #[test]
    fn widths_grow_with_text_and_size() {
        assert_eq!(width("", 12.0), 0.0);
        let a = width("1.5", 12.0);
        let b = width("1.50", 12.0);
        assert!(a > 10.0 && b > a, "{a} {b}");
        assert!((width("1.5", 24.0) - 2.0 * a).abs() < 0.5);
        let (asc, desc) = vertical_metrics(12.0);
        assert!(asc > 8.0 && desc < 0.0);
    }

    #[test]
    fn text_leaves_dark_pixels_where_expected() {
        let mut img = Image::new(80, 30, [255, 255, 255, 255]);
        let mut c = Canvas::new(&mut img);
        draw(&mut c, "Stress", 16.0, 40.0, 20.0, Align::Center, [0, 0, 0]);
        let dark: Vec<(u32, u32)> = (0..30)
            .flat_map(|y| (0..80).map(move |x| (x, y)))
            .filter(|&(x, y)| img.pixel(x, y)[0] < 128)
            .collect();
        assert!(dark.len() > 40);
        let (minx, maxx) = (
            dark.iter().map(|p| p.0).min().unwrap(),
            dark.iter().map(|p| p.0).max().unwrap(),
        );
        assert!(minx > 5 && maxx < 75 && (minx + maxx) / 2 >= 36 && (minx + maxx) / 2 <= 44);
        assert!(dark.iter().all(|p| p.1 <= 21), "ink below the baseline");
    }

    #[test]
    fn vertical_text_is_taller_than_wide() {
        let mut img = Image::new(30, 100, [255, 255, 255, 255]);
        let mut c = Canvas::new(&mut img);
        draw_vertical(&mut c, "Stress [kPa]", 12.0, 5.0, 50.0, [0, 0, 0]);
        let dark: Vec<(u32, u32)> = (0..100)
            .flat_map(|y| (0..30).map(move |x| (x, y)))
            .filter(|&(x, y)| img.pixel(x, y)[0] < 128)
            .collect();
        let h = dark.iter().map(|p| p.1).max().unwrap() - dark.iter().map(|p| p.1).min().unwrap();
        let w = dark.iter().map(|p| p.0).max().unwrap() - dark.iter().map(|p| p.0).min().unwrap();
        assert!(h > 3 * w, "{w} x {h}");
    }
}
