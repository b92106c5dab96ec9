//! SVG to raster with resvg, using only the carried font (DejaVu Sans) for every family.

use std::sync::{Arc, OnceLock};

use resvg::tiny_skia::{Pixmap, Transform};
use resvg::usvg::{self, fontdb};

use crate::{FONT_FAMILY, FONT_TTF, Image, RenderError, Result};

/// The largest picture rendered, in pixels (about 16k x 6k).
const MAX_PIXELS: u64 = 100_000_000;

/// The font database with only the carried font, which also stands in for every generic family.
fn fonts() -> &'static Arc<fontdb::Database> {
    static FONTS: OnceLock<Arc<fontdb::Database>> = OnceLock::new();
    FONTS.get_or_init(|| {
        let mut db = fontdb::Database::new();
        db.load_font_source(fontdb::Source::Binary(Arc::new(FONT_TTF)));
        db.set_sans_serif_family(FONT_FAMILY);
        db.set_serif_family(FONT_FAMILY);
        db.set_monospace_family(FONT_FAMILY);
        db.set_cursive_family(FONT_FAMILY);
        db.set_fantasy_family(FONT_FAMILY);
        Arc::new(db)
    })
}

/// Renders an SVG document at its own size (`width` and `height`, or the `viewBox`) with the
/// carried font, into a straight-alpha RGBA image. What the SVG does not paint stays
/// transparent (the charts paint a white background).
///
/// Errors are [`RenderError::Encode`] with the SVG parser's message, or naming the size when
/// it is empty or too large.
pub fn svg_to_png(svg: &str) -> Result<Image> {
    svg_to_png_scaled(svg, 1.0)
}

/// Like [`svg_to_png`], with the picture scaled by `scale` (2.0 for a high-DPI image twice as
/// wide and tall, with text and lines drawn at that resolution).
pub fn svg_to_png_scaled(svg: &str, scale: f32) -> Result<Image> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(RenderError::Input(format!(
            "the scale of an SVG rendering must be positive, got {scale}"
        )));
    }
    let options = usvg::Options {
        font_family: FONT_FAMILY.to_string(),
        fontdb: Arc::clone(fonts()),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &options)
        .map_err(|e| RenderError::Encode(format!("SVG parsing: {e}")))?;
    let size = tree.size();
    let (w, h) = (
        (size.width() * scale).round(),
        (size.height() * scale).round(),
    );
    if !(w >= 1.0 && h >= 1.0 && (w as u64) * (h as u64) <= MAX_PIXELS) {
        return Err(RenderError::Encode(format!(
            "cannot render an SVG of {}x{} pixels at scale {scale} (at most {MAX_PIXELS} pixels)",
            size.width(),
            size.height()
        )));
    }
    let (w, h) = (w as u32, h as u32);
    let mut pixmap = Pixmap::new(w, h).ok_or_else(|| {
        RenderError::Encode(format!("cannot allocate a {w}x{h} picture for an SVG"))
    })?;
    resvg::render(
        &tree,
        Transform::from_scale(w as f32 / size.width(), h as f32 / size.height()),
        &mut pixmap.as_mut(),
    );
    Image::from_rgba(w, h, pixmap.take_demultiplied())
}
