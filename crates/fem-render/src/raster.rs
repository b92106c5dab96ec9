//! Low-level drawing into an RGBA8 buffer: a clipped canvas with opaque and blended pixels,
//! an exact scanline triangle fill and anti-aliased thin lines.
//!
//! The triangle fill snaps vertices to a 1/256 pixel grid and evaluates the edge functions in
//! integers at pixel centres, with a tie-break rule that depends only on the direction of the
//! edge (a symbolic perturbation of the sample point, the classic "top-left" rule). Two
//! triangles sharing an edge therefore cover every pixel centre along it exactly once: no seams,
//! no double-drawn pixels, whatever the floating-point positions were.

use crate::Image;

/// Sub-pixel steps per pixel of the fixed-point vertex coordinates.
pub(crate) const SUBPIXEL: i64 = 256;
const HALF: i64 = SUBPIXEL / 2;
/// Fixed-point coordinates are clamped to +-2^27 (half a million pixels), which keeps every
/// product of the edge functions well inside an `i64`.
const LIMIT: f64 = (1i64 << 27) as f64;

/// A pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Clip {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl Clip {
    /// Whether pixel `(x, y)` is inside.
    #[inline]
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }
}

/// A mutable view of an [`Image`] with a clip rectangle.
pub(crate) struct Canvas<'a> {
    px: &'a mut [u8],
    width: usize,
    clip: Clip,
}

impl<'a> Canvas<'a> {
    /// The whole image, clipped to its bounds.
    pub fn new(image: &'a mut Image) -> Self {
        let (w, h) = (image.width(), image.height());
        Canvas {
            px: image.as_rgba_mut(),
            width: w as usize,
            clip: Clip {
                x0: 0,
                y0: 0,
                x1: w as i32,
                y1: h as i32,
            },
        }
    }

    /// The full-image clip rectangle.
    pub fn bounds(&self) -> Clip {
        Clip {
            x0: 0,
            y0: 0,
            x1: self.width as i32,
            y1: (self.px.len() / 4 / self.width.max(1)) as i32,
        }
    }

    /// Restricts drawing to `clip` intersected with the image.
    pub fn set_clip(&mut self, clip: Clip) {
        let b = self.bounds();
        self.clip = Clip {
            x0: clip.x0.clamp(b.x0, b.x1),
            y0: clip.y0.clamp(b.y0, b.y1),
            x1: clip.x1.clamp(b.x0, b.x1),
            y1: clip.y1.clamp(b.y0, b.y1),
        };
    }

    #[inline]
    fn index(&self, x: i32, y: i32) -> usize {
        (y as usize * self.width + x as usize) * 4
    }

    /// Blends `c` with opacity `alpha` in `[0, 1]` over the pixel (clipped).
    #[inline]
    pub fn blend(&mut self, x: i32, y: i32, c: [u8; 3], alpha: f32) {
        if alpha <= 0.0 || !self.clip.contains(x, y) {
            return;
        }
        let i = self.index(x, y);
        let a = alpha.min(1.0);
        let p = &mut self.px[i..i + 4];
        for k in 0..3 {
            let d = p[k] as f32;
            p[k] = (d + (c[k] as f32 - d) * a + 0.5) as u8;
        }
        p[3] = (p[3] as f32 + (255.0 - p[3] as f32) * a + 0.5) as u8;
    }

    /// Fills the pixel rectangle `[x0, x1) x [y0, y1)` with an opaque colour (clipped).
    pub fn fill_rect(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, c: [u8; 3]) {
        let x0 = x0.max(self.clip.x0);
        let x1 = x1.min(self.clip.x1);
        let y0 = y0.max(self.clip.y0);
        let y1 = y1.min(self.clip.y1);
        if x0 >= x1 {
            return;
        }
        let rgba = [c[0], c[1], c[2], 255];
        for y in y0..y1 {
            let (a, b) = (self.index(x0, y), self.index(x1, y));
            for p in self.px[a..b].chunks_exact_mut(4) {
                p.copy_from_slice(&rgba);
            }
        }
    }

    /// The RGBA bytes of pixels `x0..x1` of row `y` (unclipped: the caller clips).
    #[inline]
    pub fn row_span(&mut self, y: i32, x0: i32, x1: i32) -> &mut [u8] {
        let (a, b) = (self.index(x0, y), self.index(x1, y));
        &mut self.px[a..b]
    }

    /// An anti-aliased line about one pixel wide from `p0` to `p1` (pixel coordinates, pixel
    /// centres at half-integers), blended with opacity `alpha`. Each step along the major axis
    /// spreads the coverage over the two nearest pixels of the minor axis.
    pub fn line_aa(&mut self, p0: [f64; 2], p1: [f64; 2], c: [u8; 3], alpha: f32) {
        let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
        if !(dx.is_finite() && dy.is_finite()) {
            return;
        }
        let steep = dy.abs() > dx.abs();
        // Work in (u, v): u along the major axis, v along the minor.
        let (u0, v0, u1, v1) = if steep {
            (p0[1], p0[0], p1[1], p1[0])
        } else {
            (p0[0], p0[1], p1[0], p1[1])
        };
        let (u0, v0, u1, v1) = if u0 <= u1 {
            (u0, v0, u1, v1)
        } else {
            (u1, v1, u0, v0)
        };
        let du = u1 - u0;
        let slope = if du > 0.0 { (v1 - v0) / du } else { 0.0 };
        // Pixel columns whose centres (i + 0.5) lie in [u0, u1], limited to the clip.
        let (lo_clip, hi_clip) = if steep {
            (self.clip.y0, self.clip.y1 - 1)
        } else {
            (self.clip.x0, self.clip.x1 - 1)
        };
        let start = ((u0 - 0.5).ceil().max(lo_clip as f64 - 1.0)) as i64;
        let end = ((u1 - 0.5).floor().min(hi_clip as f64 + 1.0)) as i64;
        if du < 1.0 {
            // Shorter than a pixel: one dab at the midpoint, weighted by the length.
            let (um, vm) = ((u0 + u1) * 0.5, (v0 + v1) * 0.5);
            let a = alpha * (du.max(0.25) as f32);
            self.dab(steep, um.floor() as i32, vm, c, a);
            return;
        }
        for i in start..=end {
            let u = i as f64 + 0.5;
            let v = v0 + slope * (u - u0);
            self.dab(steep, i as i32, v, c, alpha);
        }
    }

    /// Coverage of a one-pixel-thick vertical (or horizontal) sample centred at `v` on the
    /// minor axis, spread over the two nearest pixels.
    #[inline]
    fn dab(&mut self, steep: bool, u: i32, v: f64, c: [u8; 3], alpha: f32) {
        let vc = v - 0.5;
        let base = vc.floor();
        let f = (vc - base) as f32;
        let b = base as i32;
        if steep {
            self.blend(b, u, c, alpha * (1.0 - f));
            self.blend(b + 1, u, c, alpha * f);
        } else {
            self.blend(u, b, c, alpha * (1.0 - f));
            self.blend(u, b + 1, c, alpha * f);
        }
    }
}

/// A point in pixel coordinates snapped to the fixed-point grid (1/[`SUBPIXEL`] pixel).
#[inline]
pub(crate) fn to_fixed(p: [f64; 2]) -> [i64; 2] {
    let s = SUBPIXEL as f64;
    [
        (p[0] * s).round().clamp(-LIMIT, LIMIT) as i64,
        (p[1] * s).round().clamp(-LIMIT, LIMIT) as i64,
    ]
}

/// One edge `p -> q` of a positively oriented triangle, as the pixel-centre test
/// `K - D * i >= bias` along a row (`i` = pixel column).
#[derive(Clone, Copy)]
struct Edge {
    p: [i64; 2],
    dx: i64,
    dy: i64,
    bias: i64,
}

impl Edge {
    fn new(p: [i64; 2], q: [i64; 2]) -> Self {
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        // The edge function is E(s) = dx (s.y - p.y) - dy (s.x - p.x), positive inside. A sample
        // exactly on the edge counts as inside when E(s + (e, e^2)) > 0 for a tiny e: that is
        // when dy < 0, or dy == 0 and dx > 0. The opposite edge of the neighbour gets the
        // opposite answer, so shared edges are owned by exactly one triangle.
        let on_edge_inside = dy < 0 || (dy == 0 && dx > 0);
        Edge {
            p,
            dx,
            dy,
            bias: if on_edge_inside { 0 } else { 1 },
        }
    }

    /// Narrows the column range `[lo, hi]` to the samples of row `y` on the inner side.
    #[inline]
    fn clip_row(&self, y: i64, lo: &mut i64, hi: &mut i64) {
        let py = y * SUBPIXEL + HALF;
        // E(i) = dx (py - p.y) - dy (i S + H - p.x) = k - d i
        let k = self.dx * (py - self.p[1]) - self.dy * (HALF - self.p[0]);
        let d = self.dy * SUBPIXEL;
        let need = k - self.bias; // condition: need - d i >= 0
        if d == 0 {
            if need < 0 {
                *lo = 1;
                *hi = 0;
            }
        } else if d > 0 {
            // i <= need / d
            *hi = (*hi).min(need.div_euclid(d));
        } else {
            // i >= need / d = (-need) / (-d), rounded up
            let (a, b) = (-need, -d);
            *lo = (*lo).max(-((-a).div_euclid(b)));
        }
    }
}

/// Calls `span(y, x0, x1)` for every run of pixels `[x0, x1)` on row `y` whose centres the
/// triangle `v` (fixed-point pixel coordinates, any orientation) covers, inside `clip`.
/// Degenerate triangles cover nothing.
#[inline]
pub(crate) fn fill_triangle(v: [[i64; 2]; 3], clip: Clip, mut span: impl FnMut(i32, i32, i32)) {
    let [a, mut b, mut c] = v;
    let area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area2 == 0 {
        return;
    }
    if area2 < 0 {
        std::mem::swap(&mut b, &mut c);
    }
    let edges = [Edge::new(a, b), Edge::new(b, c), Edge::new(c, a)];
    let min_y = a[1].min(b[1]).min(c[1]);
    let max_y = a[1].max(b[1]).max(c[1]);
    let min_x = a[0].min(b[0]).min(c[0]);
    let max_x = a[0].max(b[0]).max(c[0]);
    // Rows and columns whose centres lie in the bounding box, limited to the clip.
    let ceil_div = |n: i64| -((-n).div_euclid(SUBPIXEL));
    let y0 = ceil_div(min_y - HALF).max(clip.y0 as i64);
    let y1 = (max_y - HALF).div_euclid(SUBPIXEL).min(clip.y1 as i64 - 1);
    let x_lo = ceil_div(min_x - HALF).max(clip.x0 as i64);
    let x_hi = (max_x - HALF).div_euclid(SUBPIXEL).min(clip.x1 as i64 - 1);
    if x_lo > x_hi {
        return;
    }
    for y in y0..=y1 {
        let (mut lo, mut hi) = (x_lo, x_hi);
        for e in &edges {
            e.clip_row(y, &mut lo, &mut hi);
        }
        if lo <= hi {
            span(y as i32, lo as i32, hi as i32 + 1);
        }
    }
}

/// The affine function `f(x, y) = f0 + fx (x - x0) + fy (y - y0)` through the values `f` at the
/// three fixed-point vertices, in pixel units; `None` for degenerate triangles.
pub(crate) fn plane(v: [[i64; 2]; 3], f: [f64; 3]) -> Option<[f64; 3]> {
    let s = SUBPIXEL as f64;
    let p = v.map(|q| [q[0] as f64 / s, q[1] as f64 / s]);
    let (ax, ay) = (p[1][0] - p[0][0], p[1][1] - p[0][1]);
    let (bx, by) = (p[2][0] - p[0][0], p[2][1] - p[0][1]);
    let det = ax * by - bx * ay;
    if det == 0.0 {
        return None;
    }
    let (da, db) = (f[1] - f[0], f[2] - f[0]);
    let fx = (da * by - db * ay) / det;
    let fy = (db * ax - da * bx) / det;
    // Value at the pixel-space origin.
    Some([f[0] - fx * p[0][0] - fy * p[0][1], fx, fy])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coverage(tris: &[[[f64; 2]; 3]], w: i32, h: i32) -> Vec<u32> {
        let mut count = vec![0u32; (w * h) as usize];
        let clip = Clip {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        };
        for t in tris {
            fill_triangle(t.map(to_fixed), clip, |y, x0, x1| {
                for x in x0..x1 {
                    count[(y * w + x) as usize] += 1;
                }
            });
        }
        count
    }

    #[test]
    fn shared_edges_cover_each_pixel_once() {
        // A fan of triangles around a vertex exactly on a pixel centre, plus edges through
        // pixel centres (horizontal, vertical, diagonal) and arbitrary ones.
        let c = [10.5, 10.5];
        let ring: Vec<[f64; 2]> = (0..13)
            .map(|k| {
                let a = k as f64 / 13.0 * std::f64::consts::TAU + 0.3;
                [10.5 + 9.0 * a.cos(), 10.5 + 9.0 * a.sin()]
            })
            .collect();
        let mut tris: Vec<[[f64; 2]; 3]> =
            (0..13).map(|k| [c, ring[k], ring[(k + 1) % 13]]).collect();
        // A square split along both diagonals, with an axis-aligned edge through centres.
        tris.push([[0.5, 0.5], [20.5, 0.5], [10.5, 0.5]]); // degenerate: covers nothing
        let count = coverage(&tris, 21, 21);
        assert!(count.iter().all(|&n| n <= 1), "a pixel was covered twice");
        // Every pixel well inside the polygon is covered.
        for y in 5..16 {
            for x in 5..16 {
                assert_eq!(count[(y * 21 + x) as usize], 1, "hole at ({x}, {y})");
            }
        }
    }

    #[test]
    fn grid_of_squares_has_no_gaps_and_no_overlaps() {
        let mut tris = Vec::new();
        let n = 7;
        let step = 30.0 / n as f64;
        for j in 0..n {
            for i in 0..n {
                let p = |a: usize, b: usize| [1.0 + a as f64 * step, 1.0 + b as f64 * step];
                let (p00, p10, p01, p11) = (p(i, j), p(i + 1, j), p(i, j + 1), p(i + 1, j + 1));
                if (i + j) % 2 == 0 {
                    tris.push([p00, p10, p11]);
                    tris.push([p00, p11, p01]);
                } else {
                    tris.push([p00, p10, p01]);
                    tris.push([p10, p11, p01]);
                }
            }
        }
        let count = coverage(&tris, 32, 32);
        for y in 0..32 {
            for x in 0..32 {
                let inside = (x as f64 + 0.5) > 1.0 && (x as f64 + 0.5) < 31.0;
                let inside = inside && (y as f64 + 0.5) > 1.0 && (y as f64 + 0.5) < 31.0;
                let n = count[(y * 32 + x) as usize];
                assert_eq!(n, inside as u32, "pixel ({x}, {y}) covered {n} times");
            }
        }
    }

    #[test]
    fn plane_interpolates_vertex_values() {
        let v = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]].map(to_fixed);
        let [f0, fx, fy] = plane(v, [1.0, 3.0, 5.0]).unwrap();
        assert!((f0 - 1.0).abs() < 1e-12);
        assert!((fx - 0.2).abs() < 1e-12);
        assert!((fy - 0.4).abs() < 1e-12);
    }
}
