//! An RGBA8 raster (straight alpha, row-major, top row first) and its PNG encoding.

use std::path::Path;

use crate::error::{RenderError, Result, write_atomic};

/// An 8-bit RGBA colour (straight, not premultiplied, alpha).
pub type Rgba = [u8; 4];

/// An RGBA8 image, row-major with the top row first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

impl Image {
    /// A `width` x `height` image filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgba) -> Self {
        let n = width as usize * height as usize;
        let mut rgba = Vec::with_capacity(n * 4);
        for _ in 0..n {
            rgba.extend_from_slice(&background);
        }
        Self {
            width,
            height,
            rgba,
        }
    }

    /// Wraps an RGBA8 buffer of `width * height * 4` bytes.
    pub fn from_rgba(width: u32, height: u32, rgba: Vec<u8>) -> Result<Self> {
        if rgba.len() != width as usize * height as usize * 4 {
            return Err(RenderError::Input(format!(
                "an RGBA buffer of {} bytes does not fit a {width}x{height} image",
                rgba.len()
            )));
        }
        Ok(Self {
            width,
            height,
            rgba,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel at column `x`, row `y` (row 0 at the top). Panics when out of bounds.
    pub fn pixel(&self, x: u32, y: u32) -> Rgba {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) is outside the image"
        );
        let i = (y as usize * self.width as usize + x as usize) * 4;
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Sets the pixel at column `x`, row `y`; outside the image nothing happens.
    pub fn set_pixel(&mut self, x: u32, y: u32, c: Rgba) {
        if x < self.width && y < self.height {
            let i = (y as usize * self.width as usize + x as usize) * 4;
            self.rgba[i..i + 4].copy_from_slice(&c);
        }
    }

    /// The raw RGBA8 bytes.
    pub fn as_rgba(&self) -> &[u8] {
        &self.rgba
    }

    /// The raw RGBA8 bytes, mutable.
    pub fn as_rgba_mut(&mut self) -> &mut [u8] {
        &mut self.rgba
    }

    /// Copies `src` into this image with its top-left corner at `(x, y)`, clipped.
    pub fn blit(&mut self, src: &Image, x: u32, y: u32) {
        if x >= self.width || y >= self.height {
            return;
        }
        let w = src.width.min(self.width - x) as usize;
        let h = src.height.min(self.height - y);
        for row in 0..h {
            let s = row as usize * src.width as usize * 4;
            let d = ((y + row) as usize * self.width as usize + x as usize) * 4;
            self.rgba[d..d + w * 4].copy_from_slice(&src.rgba[s..s + w * 4]);
        }
    }

    /// Images side by side (top-aligned), `gap` pixels apart, on `background`.
    pub fn hstack(images: &[Image], gap: u32, background: Rgba) -> Image {
        let width = images.iter().map(|i| i.width).sum::<u32>()
            + gap * images.len().saturating_sub(1) as u32;
        let height = images.iter().map(|i| i.height).max().unwrap_or(0);
        let mut out = Image::new(width, height, background);
        let mut x = 0;
        for img in images {
            out.blit(img, x, 0);
            x += img.width + gap;
        }
        out
    }

    /// Images one above the other (left-aligned), `gap` pixels apart, on `background`.
    pub fn vstack(images: &[Image], gap: u32, background: Rgba) -> Image {
        let height = images.iter().map(|i| i.height).sum::<u32>()
            + gap * images.len().saturating_sub(1) as u32;
        let width = images.iter().map(|i| i.width).max().unwrap_or(0);
        let mut out = Image::new(width, height, background);
        let mut y = 0;
        for img in images {
            out.blit(img, 0, y);
            y += img.height + gap;
        }
        out
    }

    /// PNG bytes (8-bit RGBA, fast deflate: a 1280x720 frame encodes in a few milliseconds).
    pub fn to_png(&self) -> Result<Vec<u8>> {
        if self.width == 0 || self.height == 0 {
            return Err(RenderError::Input(format!(
                "cannot encode an empty {}x{} image as PNG",
                self.width, self.height
            )));
        }
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.width, self.height);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        let encode = |e: png::EncodingError| RenderError::Encode(format!("PNG encoding: {e}"));
        let mut w = enc.write_header().map_err(encode)?;
        w.write_image_data(&self.rgba).map_err(encode)?;
        w.finish().map_err(encode)?;
        Ok(out)
    }

    /// Writes the PNG to `path` atomically (temporary file, then rename).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        write_atomic(path, &self.to_png()?)
    }

    /// Decodes an 8-bit RGB or RGBA PNG (what [`Image::to_png`] writes, and what browsers
    /// screenshot), for tests and for composing figures from files.
    pub fn from_png(bytes: &[u8]) -> Result<Image> {
        let decode = |e: png::DecodingError| RenderError::Encode(format!("PNG decoding: {e}"));
        let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
        dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = dec.read_info().map_err(decode)?;
        let size = reader.output_buffer_size().ok_or_else(|| {
            RenderError::Encode("PNG decoding: the image is too large".to_string())
        })?;
        let mut buf = vec![0; size];
        let info = reader.next_frame(&mut buf).map_err(decode)?;
        buf.truncate(info.buffer_size());
        let rgba = match info.color_type {
            png::ColorType::Rgba => buf,
            png::ColorType::Rgb => buf
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect(),
            png::ColorType::Grayscale => buf.iter().flat_map(|&g| [g, g, g, 255]).collect(),
            png::ColorType::GrayscaleAlpha => buf
                .chunks_exact(2)
                .flat_map(|c| [c[0], c[0], c[0], c[1]])
                .collect(),
            other => {
                return Err(RenderError::Encode(format!(
                    "PNG decoding: unsupported colour type {other:?}"
                )));
            }
        };
        Image::from_rgba(info.width, info.height, rgba)
    }
}
