//! SVG writing helpers shared by the charts: escaping, compact numbers, text measurement with
//! the carried font, the series palette and dash patterns.

use std::fmt::Write;
use std::sync::OnceLock;

use ab_glyph::{Font, FontRef};

use crate::{FONT_FAMILY, FONT_TTF};

/// The series colours, in order: the Okabe-Ito colour-blind-safe palette without its yellow
/// (too pale on white): blue, vermillion, bluish green, reddish purple, orange, sky blue, black.
pub const PALETTE: [[u8; 3]; 7] = [
    [0x00, 0x72, 0xB2],
    [0xD5, 0x5E, 0x00],
    [0x00, 0x9E, 0x73],
    [0xCC, 0x79, 0xA7],
    [0xE6, 0x9F, 0x00],
    [0x56, 0xB4, 0xE9],
    [0x00, 0x00, 0x00],
];

/// Dash patterns (SVG `stroke-dasharray`) for series 4 and later.
const DASHES: [&str; 6] = ["7 4", "2 3", "9 3 2 3", "4 2", "1.5 2.5", "12 3 2 3 2 3"];

/// The colour of series `index` (0-based) in a [`super::LineChart`]: [`PALETTE`], cycled.
pub fn series_color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

/// The dash pattern (SVG `stroke-dasharray`) of series `index` (0-based): `None` (solid) for
/// the first three series, then a distinct pattern per series.
pub fn series_dash(index: usize) -> Option<&'static str> {
    index.checked_sub(3).map(|i| DASHES[i % DASHES.len()])
}

/// `#rrggbb`.
pub(crate) fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// The text colour (black or white) that contrasts more with the background `c`, by WCAG
/// relative luminance.
pub fn text_color_on(c: [u8; 3]) -> [u8; 3] {
    let lin = |v: u8| {
        let v = f64::from(v) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    let l = 0.2126 * lin(c[0]) + 0.7152 * lin(c[1]) + 0.0722 * lin(c[2]);
    // Contrast with black (l + 0.05) / 0.05 against contrast with white 1.05 / (l + 0.05).
    if (l + 0.05) * (l + 0.05) >= 0.05 * 1.05 {
        [0, 0, 0]
    } else {
        [255, 255, 255]
    }
}

/// Escapes `&`, `<`, `>`, `"` and `'` for SVG text and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// Appends `v` rounded to two decimals, without trailing zeros (`12`, `3.5`, `-0.25`).
pub(crate) fn push_num(out: &mut String, v: f64) {
    let r = (v * 100.0).round();
    if !r.is_finite() || r.abs() >= 9e15 {
        let _ = write!(out, "{v}");
        return;
    }
    let r = r as i64;
    if r < 0 {
        out.push('-');
    }
    let a = r.unsigned_abs();
    let (int, frac) = (a / 100, a % 100);
    let _ = write!(out, "{int}");
    if frac != 0 {
        if frac % 10 == 0 {
            let _ = write!(out, ".{}", frac / 10);
        } else {
            let _ = write!(out, ".{frac:02}");
        }
    }
}

/// `v` as [`push_num`] writes it.
pub(crate) fn num(v: f64) -> String {
    let mut s = String::new();
    push_num(&mut s, v);
    s
}

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(FONT_TTF).expect("the carried font parses"))
}

/// The advance width in pixels of `text` set in the carried font at `size` pixels per em (what
/// the charts use to lay out labels; kerning is ignored, so it can be a pixel or two wide).
pub fn text_width(text: &str, size: f64) -> f64 {
    let f = font();
    let upem = f64::from(f.units_per_em().unwrap_or(2048.0));
    let units: f32 = text
        .chars()
        .map(|c| f.h_advance_unscaled(f.glyph_id(c)))
        .sum();
    f64::from(units) / upem * size
}

/// The opening `<svg>` tag with a white background, for a `width` x `height` picture.
pub(crate) fn open_svg(out: &mut String, width: f64, height: f64) {
    let (w, h) = (num(width), num(height));
    let _ = write!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{w}\" height=\"{h}\" \
         viewBox=\"0 0 {w} {h}\" font-family=\"'{FONT_FAMILY}', sans-serif\" font-size=\"12\">\n\
         <rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>\n"
    );
}

/// Horizontal text alignment relative to the anchor point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Anchor {
    Start,
    Middle,
    End,
}

/// One line of text.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Text<'a> {
    pub text: &'a str,
    /// The anchor point (on the baseline).
    pub x: f64,
    pub y: f64,
    pub size: f64,
    pub anchor: Anchor,
    pub fill: &'a str,
    /// Rotation in degrees about the anchor point (negative: counter-clockwise on screen).
    pub rotate: f64,
    /// The `class` attribute; empty for none.
    pub class: &'a str,
}

impl<'a> Text<'a> {
    /// Text at `(x, y)` on the baseline, `size` px, dark grey, left-aligned, not rotated.
    pub(crate) fn new(text: &'a str, x: f64, y: f64, size: f64) -> Self {
        Self {
            text,
            x,
            y,
            size,
            anchor: Anchor::Start,
            fill: TEXT,
            rotate: 0.0,
            class: "",
        }
    }

    pub(crate) fn anchor(self, anchor: Anchor) -> Self {
        Self { anchor, ..self }
    }

    pub(crate) fn fill(self, fill: &'a str) -> Self {
        Self { fill, ..self }
    }

    pub(crate) fn rotate(self, rotate: f64) -> Self {
        Self { rotate, ..self }
    }

    pub(crate) fn class(self, class: &'a str) -> Self {
        Self { class, ..self }
    }

    pub(crate) fn write(&self, out: &mut String) {
        if self.text.is_empty() {
            return;
        }
        let (x, y) = (num(self.x), num(self.y));
        out.push_str("<text");
        if !self.class.is_empty() {
            let _ = write!(out, " class=\"{}\"", self.class);
        }
        let _ = write!(out, " x=\"{x}\" y=\"{y}\" font-size=\"{}\"", num(self.size));
        match self.anchor {
            Anchor::Start => {}
            Anchor::Middle => out.push_str(" text-anchor=\"middle\""),
            Anchor::End => out.push_str(" text-anchor=\"end\""),
        }
        if self.fill != "#000000" {
            let _ = write!(out, " fill=\"{}\"", self.fill);
        }
        if self.rotate != 0.0 {
            let _ = write!(out, " transform=\"rotate({} {x} {y})\"", num(self.rotate));
        }
        let _ = writeln!(out, ">{}</text>", escape(self.text));
    }
}

/// The colour of ordinary text.
pub(crate) const TEXT: &str = "#222222";

/// How far below the middle of a line of text its baseline is, per pixel of font size (half the
/// cap height of DejaVu Sans): `baseline = middle + CENTER * size`.
pub(crate) const CENTER: f64 = 0.365;
