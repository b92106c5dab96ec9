//! Preview images of the pipeline stages (the paper's Figure 1 for any model): projected points,
//! alpha shape, simplified polygon and final mesh, each as a PNG panel, plus all four side by
//! side. A deliberately tiny rasteriser (points, lines, even-odd polygon fill) on an RGB buffer,
//! encoded with the `png` crate: a drawing library would be a large dependency for four pictures,
//! and the rendering crate of the workspace is where pretty pictures belong. The encoding
//! ([`Canvas::to_png`], [`write_previews`]) needs the default `png` feature; drawing does not.

#[cfg(feature = "png")]
use std::path::Path;

#[cfg(feature = "png")]
use crate::error::{MeshError, Result};
#[cfg(feature = "png")]
use crate::io::write_atomic;
use crate::types::{Mesh2, PolygonWithHoles};

/// Size of one preview panel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewParams {
    /// Panel height in pixels (the width follows the drawing's aspect ratio). Default 600.
    pub height_px: usize,
    /// Blank margin around the drawing, as a fraction of the panel height. Default 0.04.
    pub margin: f64,
}

impl Default for PreviewParams {
    fn default() -> Self {
        Self {
            height_px: 600,
            margin: 0.04,
        }
    }
}

type Rgb = [u8; 3];
const WHITE: Rgb = [255, 255, 255];
const INK: Rgb = [20, 30, 60];
const FILL: Rgb = [170, 200, 235];
const ACCENT: Rgb = [200, 40, 40];

/// An RGB raster with a world-to-pixel map.
pub struct Canvas {
    width: usize,
    height: usize,
    pixels: Vec<Rgb>,
    origin: [f64; 2],
    scale: f64,
}

impl Canvas {
    /// A white canvas showing the box `lo..hi` (world units) at `params.height_px` pixels high.
    pub fn new(lo: [f64; 2], hi: [f64; 2], params: &PreviewParams) -> Self {
        let h = params.height_px.clamp(16, 8192);
        let span = [(hi[0] - lo[0]).max(1e-300), (hi[1] - lo[1]).max(1e-300)];
        let inner = h as f64 * (1.0 - 2.0 * params.margin);
        let scale = inner / span[1].max(span[0] * 0.25);
        let margin_px = h as f64 * params.margin;
        let width = ((span[0] * scale + 2.0 * margin_px).ceil() as usize).clamp(16, 8192);
        let height = ((span[1] * scale + 2.0 * margin_px).ceil() as usize).clamp(16, 8192);
        Self {
            width,
            height,
            pixels: vec![WHITE; width * height],
            origin: [lo[0] - margin_px / scale, hi[1] + margin_px / scale],
            scale,
        }
    }

    fn to_px(&self, p: [f64; 2]) -> [f64; 2] {
        [
            (p[0] - self.origin[0]) * self.scale,
            (self.origin[1] - p[1]) * self.scale,
        ]
    }

    fn put(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.pixels[y as usize * self.width + x as usize] = c;
        }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixels, RGB, row-major with the top row first.
    pub fn pixels(&self) -> &[[u8; 3]] {
        &self.pixels
    }

    /// A square dot of `size` pixels at world point `p`.
    pub fn dot(&mut self, p: [f64; 2], size: i64, c: Rgb) {
        let [x, y] = self.to_px(p);
        let (x, y) = (x.round() as i64, y.round() as i64);
        for dy in 0..size {
            for dx in 0..size {
                self.put(x + dx - size / 2, y + dy - size / 2, c);
            }
        }
    }

    /// A one-pixel line between world points (DDA).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], c: Rgb) {
        let [x0, y0] = self.to_px(a);
        let [x1, y1] = self.to_px(b);
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().clamp(1.0, 1e5) as usize;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            self.put(
                (x0 + t * (x1 - x0)).round() as i64,
                (y0 + t * (y1 - y0)).round() as i64,
                c,
            );
        }
    }

    /// Fills the region inside an odd number of `rings` (even-odd rule, scanline).
    pub fn fill(&mut self, rings: &[&[[f64; 2]]], c: Rgb) {
        let mut xs = Vec::new();
        for row in 0..self.height {
            let y = row as f64 + 0.5;
            xs.clear();
            for ring in rings {
                let n = ring.len();
                for i in 0..n {
                    let a = self.to_px(ring[i]);
                    let b = self.to_px(ring[(i + 1) % n]);
                    if (a[1] > y) != (b[1] > y) {
                        xs.push(a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
                    }
                }
            }
            xs.sort_by(f64::total_cmp);
            for pair in xs.chunks_exact(2) {
                let from = pair[0].round().max(0.0) as i64;
                let to = pair[1].round().min(self.width as f64) as i64;
                for x in from..to {
                    self.put(x, row as i64, c);
                }
            }
        }
    }

    /// Encodes the canvas as PNG bytes.
    #[cfg(feature = "png")]
    pub fn to_png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let err = |e: png::EncodingError| MeshError::invalid("preview", e.to_string());
            let mut writer = enc.write_header().map_err(err)?;
            let flat: Vec<u8> = self.pixels.iter().flatten().copied().collect();
            writer.write_image_data(&flat).map_err(err)?;
        }
        Ok(out)
    }

    #[cfg(feature = "png")]
    fn blit(&self, into: &mut Canvas, x0: usize) {
        for y in 0..self.height.min(into.height) {
            for x in 0..self.width {
                if x0 + x < into.width {
                    into.pixels[y * into.width + x0 + x] = self.pixels[y * self.width + x];
                }
            }
        }
    }
}

/// The data of the four stages.
pub struct Stages<'a> {
    /// Projected, merged 2D points.
    pub points: &'a [[f64; 2]],
    /// Alpha-shape triangles over `alpha_points`.
    pub alpha_triangles: &'a [[usize; 3]],
    /// Points indexed by `alpha_triangles`.
    pub alpha_points: &'a [[f64; 2]],
    /// Alpha-shape boundary polygons.
    pub alpha_polygons: &'a [PolygonWithHoles],
    /// Simplified polygons.
    pub simplified: &'a [PolygonWithHoles],
    /// Final mesh.
    pub mesh: &'a Mesh2,
}

/// File names written by [`write_previews`], in stage order, then the combined figure.
pub const PREVIEW_FILES: [&str; 5] = [
    "1-points.png",
    "2-alpha-shape.png",
    "3-simplified.png",
    "4-mesh.png",
    "figure.png",
];

/// Renders the four stage panels.
pub fn render_stages(stages: &Stages<'_>, params: &PreviewParams) -> [Canvas; 4] {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in stages.points.iter().chain(&stages.mesh.vertices) {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if !(lo[0].is_finite() && hi[0].is_finite()) {
        lo = [0.0; 2];
        hi = [1.0; 2];
    }
    let mut panels = [0, 1, 2, 3].map(|_| Canvas::new(lo, hi, params));
    for &p in stages.points {
        panels[0].dot(p, 2, INK);
    }
    for t in stages.alpha_triangles {
        let ring = t.map(|i| stages.alpha_points[i]);
        panels[1].fill(&[&ring], FILL);
    }
    for poly in stages.alpha_polygons {
        for ring in poly.rings() {
            draw_ring(&mut panels[1], ring, INK);
        }
    }
    for poly in stages.simplified {
        let rings: Vec<&[[f64; 2]]> = poly.rings().map(Vec::as_slice).collect();
        panels[2].fill(&rings, FILL);
        for ring in poly.rings() {
            draw_ring(&mut panels[2], ring, INK);
            for &p in ring {
                panels[2].dot(p, 3, ACCENT);
            }
        }
    }
    for t in 0..stages.mesh.triangles.len() {
        let c = stages.mesh.corners(t);
        panels[3].fill(&[&c], FILL);
    }
    for t in 0..stages.mesh.triangles.len() {
        let c = stages.mesh.corners(t);
        draw_ring(&mut panels[3], &c, INK);
    }
    panels
}

fn draw_ring(canvas: &mut Canvas, ring: &[[f64; 2]], c: Rgb) {
    for i in 0..ring.len() {
        canvas.line(ring[i], ring[(i + 1) % ring.len()], c);
    }
}

/// Writes the four panels and the combined figure ([`PREVIEW_FILES`]) into `dir` (created if
/// missing).
#[cfg(feature = "png")]
pub fn write_previews(dir: &Path, stages: &Stages<'_>, params: &PreviewParams) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| MeshError::io(dir, e))?;
    let panels = render_stages(stages, params);
    let width: usize = panels.iter().map(|p| p.width).sum();
    let mut figure = Canvas {
        width,
        height: panels[0].height,
        pixels: vec![WHITE; width * panels[0].height],
        origin: [0.0; 2],
        scale: 1.0,
    };
    let mut x0 = 0;
    for (panel, name) in panels.iter().zip(PREVIEW_FILES) {
        panel.blit(&mut figure, x0);
        x0 += panel.width;
        write_atomic(&dir.join(name), &panel.to_png()?)?;
    }
    write_atomic(&dir.join(PREVIEW_FILES[4]), &figure.to_png()?)
}
