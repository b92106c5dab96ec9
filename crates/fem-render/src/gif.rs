//! Animated GIFs from a sequence of frames, with one fixed global palette.
//!
//! Every frame is mapped to the same 256-colour palette, so encoding is fast and deterministic
//! (no per-frame quantiser) and the colours of one value do not flicker between frames:
//!
//! - 208 entries: 52 evenly spaced samples of each of the four colormaps (viridis, inferno,
//!   cividis, coolwarm), so stress maps keep smooth gradients whichever map is used;
//! - 40 greys from black to white (text, anti-aliasing on white, the no-data grey);
//! - the 8 interface colours of [`crate::frame`] (text, outlines, obstacles, the flat mesh
//!   colour, panel frames), exactly.
//!
//! RGBA pixels (composited over white when not opaque) go to palette indices through a
//! 32 x 32 x 32 (15-bit) lookup table built once by nearest-colour search.

use std::borrow::Cow;
use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;

use crate::colormap::{Colormap, NO_DATA};
use crate::frame::{
    FRAME_COLOR, MESH_COLOR, OBSTACLE_COLOR, OBSTACLE_EDGE_COLOR, OUTLINE_COLOR,
    REST_OUTLINE_COLOR, TEXT_COLOR,
};
use crate::{Image, RenderError, Result, write_atomic};

const SAMPLES_PER_COLORMAP: usize = 52;
const GREYS: usize = 40;

/// The fixed global palette (see the module documentation), built once.
pub fn palette() -> &'static [[u8; 3]; 256] {
    static PALETTE: OnceLock<[[u8; 3]; 256]> = OnceLock::new();
    PALETTE.get_or_init(|| {
        let mut p = Vec::with_capacity(256);
        for map in Colormap::ALL {
            for i in 0..SAMPLES_PER_COLORMAP {
                p.push(map.sample(i as f64 / (SAMPLES_PER_COLORMAP - 1) as f64));
            }
        }
        for k in 0..GREYS {
            let g = (k as f64 * 255.0 / (GREYS - 1) as f64).round() as u8;
            p.push([g, g, g]);
        }
        p.extend([
            TEXT_COLOR,
            NO_DATA,
            OBSTACLE_COLOR,
            OBSTACLE_EDGE_COLOR,
            OUTLINE_COLOR,
            REST_OUTLINE_COLOR,
            MESH_COLOR,
            FRAME_COLOR,
        ]);
        p.try_into().expect("the palette has exactly 256 entries")
    })
}

/// The 15-bit lookup table: index `(r >> 3) << 10 | (g >> 3) << 5 | (b >> 3)`.
fn lookup() -> &'static [u8] {
    static LUT: OnceLock<Vec<u8>> = OnceLock::new();
    LUT.get_or_init(|| {
        let pal = palette();
        let expand = |q: usize| ((q << 3) | (q >> 2)) as i32;
        (0..1usize << 15)
            .map(|i| {
                let (r, g, b) = (expand(i >> 10), expand((i >> 5) & 31), expand(i & 31));
                let mut best = (i32::MAX, 0u8);
                for (k, c) in pal.iter().enumerate() {
                    let (dr, dg, db) = (r - c[0] as i32, g - c[1] as i32, b - c[2] as i32);
                    let d = 3 * dr * dr + 4 * dg * dg + 2 * db * db;
                    if d < best.0 {
                        best = (d, k as u8);
                    }
                }
                best.1
            })
            .collect()
    })
}

/// Palette indices of `image`'s pixels, row-major, into `out` (cleared first).
pub fn quantize(image: &Image, out: &mut Vec<u8>) {
    let lut = lookup();
    out.clear();
    out.reserve(image.width() as usize * image.height() as usize);
    out.extend(image.as_rgba().chunks_exact(4).map(|p| {
        let [r, g, b] = if p[3] == 255 {
            [p[0], p[1], p[2]]
        } else {
            // Over white.
            let a = p[3] as u32;
            [p[0], p[1], p[2]].map(|c| ((c as u32 * a + 255 * (255 - a) + 127) / 255) as u8)
        };
        lut[((r as usize >> 3) << 10) | ((g as usize >> 3) << 5) | (b as usize >> 3)]
    }));
}

fn encode_error(e: ::gif::EncodingError) -> RenderError {
    RenderError::Encode(format!("GIF encoding: {e}"))
}

/// Streams frames of one size into an animated GIF that loops forever.
pub struct GifWriter<W: Write> {
    encoder: ::gif::Encoder<W>,
    width: u16,
    height: u16,
    delay: u16,
    frames: usize,
    indices: Vec<u8>,
}

impl<W: Write> GifWriter<W> {
    /// Starts a GIF of `width` x `height` pixels (each in `1..=65535`) showing each frame for
    /// `delay_centiseconds` hundredths of a second, looping forever.
    pub fn new(out: W, width: u32, height: u32, delay_centiseconds: u16) -> Result<Self> {
        let side = |v: u32, what: &str| {
            u16::try_from(v).ok().filter(|&v| v > 0).ok_or_else(|| {
                RenderError::Input(format!(
                    "GIF {what} {v} px: must be between 1 and 65535 (size {width}x{height})"
                ))
            })
        };
        let (w, h) = (side(width, "width")?, side(height, "height")?);
        let flat: Vec<u8> = palette().iter().flatten().copied().collect();
        let mut encoder = ::gif::Encoder::new(out, w, h, &flat).map_err(encode_error)?;
        encoder
            .set_repeat(::gif::Repeat::Infinite)
            .map_err(encode_error)?;
        Ok(GifWriter {
            encoder,
            width: w,
            height: h,
            delay: delay_centiseconds,
            frames: 0,
            indices: Vec::new(),
        })
    }

    /// Appends a frame; it must have the size given to [`GifWriter::new`].
    pub fn push(&mut self, frame: &Image) -> Result<()> {
        if frame.width() != self.width as u32 || frame.height() != self.height as u32 {
            return Err(RenderError::Input(format!(
                "GIF frame {} is {}x{} px but the animation is {}x{} px",
                self.frames,
                frame.width(),
                frame.height(),
                self.width,
                self.height
            )));
        }
        quantize(frame, &mut self.indices);
        let f = ::gif::Frame {
            width: self.width,
            height: self.height,
            delay: self.delay,
            dispose: ::gif::DisposalMethod::Keep,
            buffer: Cow::Borrowed(&self.indices),
            ..::gif::Frame::default()
        };
        self.encoder.write_frame(&f).map_err(encode_error)?;
        self.frames += 1;
        Ok(())
    }

    /// Number of frames pushed so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Writes the trailer and returns the output.
    pub fn finish(self) -> Result<W> {
        self.encoder.into_inner().map_err(encode_error)
    }
}

/// Writes `frames` (all of one size) as a looping GIF to `path`, atomically (temporary file,
/// then rename).
pub fn write_gif(path: &Path, frames: &[Image], delay_centiseconds: u16) -> Result<()> {
    let first = frames
        .first()
        .ok_or_else(|| RenderError::Input(format!("{}: no frames to write", path.display())))?;
    let mut w = GifWriter::new(
        Vec::new(),
        first.width(),
        first.height(),
        delay_centiseconds,
    )?;
    for f in frames {
        w.push(f)?;
    }
    write_atomic(path, &w.finish()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_holds_exact_extremes_and_ui_colours() {
        let pal = palette();
        for c in [
            [0, 0, 0],
            [255, 255, 255],
            TEXT_COLOR,
            NO_DATA,
            OBSTACLE_COLOR,
            MESH_COLOR,
        ] {
            assert!(pal.contains(&c), "{c:?}");
        }
        for map in Colormap::ALL {
            assert!(pal.contains(&map.sample(0.0)) && pal.contains(&map.sample(1.0)));
        }
    }

    #[test]
    fn quantize_maps_white_and_gradients_closely() {
        let mut img = Image::new(64, 1, [255, 255, 255, 255]);
        for x in 1..64 {
            let c = Colormap::Viridis.sample(x as f64 / 63.0);
            img.set_pixel(x, 0, [c[0], c[1], c[2], 255]);
        }
        let mut idx = Vec::new();
        quantize(&img, &mut idx);
        let pal = palette();
        assert_eq!(pal[idx[0] as usize], [255, 255, 255]);
        for x in 1..64 {
            let want = img.pixel(x, 0);
            let got = pal[idx[x as usize] as usize];
            for k in 0..3 {
                assert!(
                    (want[k] as i32 - got[k] as i32).abs() <= 10,
                    "{want:?} {got:?}"
                );
            }
        }
    }
}
