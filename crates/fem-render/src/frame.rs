//! One picture of a deformed 2D triangle mesh coloured by a scalar field.
//!
//! Layout, top to bottom: an optional title row (with the optional time label at its right
//! end), a caption row when any panel has a caption, then the panels left to right, all of the
//! same pixel size and sharing one world-to-pixel scale (1 m in x = 1 m in y), then on the right
//! one vertical colorbar shared by all panels with tick labels and the field label with its
//! unit. The image size depends only on the style, the number of panels and whether captions,
//! a title and a field are present (not on the data), so frames of an animation can be stacked
//! into a GIF, as long as tick labels stay within seven characters (they do unless the range is
//! unusual, e.g. tiny compared with its magnitude).
//!
//! The field is rasterised by an exact scanline fill (integer edge functions at pixel centres,
//! top-left rule): adjacent triangles share their edges pixel for pixel, so the interior of the
//! mesh has no seams. Per-element fields are flat per triangle; per-vertex fields are
//! interpolated linearly in value, then mapped through the colormap per pixel. The outer boundary
//! gets a thin anti-aliased outline, which also smooths the staircase of the fill.
//!
//! A panel may draw some triangles in one flat colour whatever the field says
//! ([`FlatElements`], e.g. bone inside soft tissue): they are left out of the automatic colour
//! range, and a labelled flat colour gets a legend row (swatch and label) under the colorbar,
//! which shortens the bar. Extra edges ([`MeshView::outline_edges`], e.g. the bones' outlines
//! from [`region_edges`]) are drawn as thin dark lines over the fill.

use resvg::tiny_skia as sk;

use crate::colormap::{Colormap, LUT_SIZE, NO_DATA};
use crate::raster::{Canvas, Clip, fill_triangle, plane, to_fixed};
use crate::text::{self, Align};
use crate::{Image, RenderError, Result};

/// The background colour of the figure.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// The fill of a mesh drawn without a field: a light steel blue.
pub const MESH_COLOR: [u8; 3] = [190, 205, 224];
/// The fill of obstacles.
pub const OBSTACLE_COLOR: [u8; 3] = [88, 88, 92];
/// The outline of obstacles.
pub const OBSTACLE_EDGE_COLOR: [u8; 3] = [30, 30, 32];
/// Text colour (title, captions, colorbar labels).
pub const TEXT_COLOR: [u8; 3] = [34, 34, 34];
/// The thin outline of the deformed mesh's boundary.
pub const OUTLINE_COLOR: [u8; 3] = [40, 40, 44];
/// The dashed outline of the rest shape.
pub const REST_OUTLINE_COLOR: [u8; 3] = [110, 110, 116];
/// Wireframe edges (blended at [`WIREFRAME_ALPHA`]).
pub const WIREFRAME_COLOR: [u8; 3] = [20, 20, 24];
/// Opacity of wireframe edges.
pub const WIREFRAME_ALPHA: f32 = 0.35;
/// The light frame around each panel's drawing area and the colorbar.
pub const FRAME_COLOR: [u8; 3] = [205, 205, 210];
/// The thin lines of [`MeshView::outline_edges`] (e.g. the outlines of bones): red, to read
/// on every colour of the map and on the plain fill.
pub const EDGE_COLOR: [u8; 3] = [205, 35, 30];
/// Opacity of [`MeshView::outline_edges`].
pub const EDGE_ALPHA: f32 = 0.85;

const MARGIN: u32 = 14;
const TITLE_SIZE: f32 = 18.0;
const TITLE_ROW: u32 = 34;
const CAPTION_SIZE: f32 = 14.0;
const CAPTION_ROW: u32 = 24;
const PANEL_GAP: u32 = 16;
const BAR_GAP: u32 = 22;
const BAR_WIDTH: u32 = 16;
const BAR_INSET: u32 = 8;
const TICK_LEN: u32 = 4;
const TICK_SIZE: f32 = 12.0;
const LABEL_SIZE: f32 = 13.0;
const LABEL_GAP: u32 = 10;
const TIME_SIZE: f32 = 13.0;
const TIME_COLOR: [u8; 3] = [80, 80, 86];
/// Height of one legend row under the colorbar (a swatch of a flat colour and its label).
const LEGEND_ROW: u32 = 22;
const LEGEND_SWATCH: u32 = 12;
/// Largest accepted panel side, in pixels.
const MAX_PANEL_SIDE: u32 = 16_384;

/// A scalar field on the mesh.
#[derive(Debug, Clone, Copy)]
pub enum FieldValues<'a> {
    /// One value per triangle, drawn flat.
    PerElement(&'a [f64]),
    /// One value per vertex, interpolated linearly over each triangle.
    PerVertex(&'a [f64]),
}

/// One panel: a mesh in its current configuration with an optional field and decorations.
#[derive(Debug, Clone, Copy)]
pub struct MeshView<'a> {
    /// Current (deformed) vertex positions in metres, y up.
    pub positions: &'a [[f64; 2]],
    /// Triangles as indices into `positions`.
    pub triangles: &'a [[usize; 3]],
    /// The field to colour by; `None` draws the mesh in the flat [`MESH_COLOR`].
    pub field: Option<FieldValues<'a>>,
    /// Rest positions (same length as `positions`); with [`FrameStyle::rest_outline`] the rest
    /// shape's boundary (edges used by exactly one triangle) is drawn as a thin dashed outline.
    pub rest_positions: Option<&'a [[f64; 2]]>,
    /// Closed polygons (e.g. falling debris), filled dark grey with an outline, over the mesh.
    /// Polygons with fewer than three points are ignored.
    pub obstacles: &'a [Vec<[f64; 2]>],
    /// Text above the panel (e.g. "Neo-Hookean"); may be empty.
    pub caption: &'a str,
    /// Triangles drawn in one flat colour instead of by the field, and left out of the
    /// automatic colour range (e.g. bone inside soft tissue, whose stress would swamp the
    /// scale). `None`: every triangle shows the field.
    pub flat: Option<FlatElements<'a>>,
    /// Edges (pairs of indices into `positions`) drawn as thin dark lines ([`EDGE_COLOR`])
    /// over the fill, e.g. the outlines of material regions ([`region_edges`]); may be empty.
    pub outline_edges: &'a [[usize; 2]],
}

impl<'a> MeshView<'a> {
    /// A panel with just a mesh: no field, no rest outline, no obstacles, no caption, no flat
    /// elements, no outline edges.
    pub fn new(positions: &'a [[f64; 2]], triangles: &'a [[usize; 3]]) -> Self {
        MeshView {
            positions,
            triangles,
            field: None,
            rest_positions: None,
            obstacles: &[],
            caption: "",
            flat: None,
            outline_edges: &[],
        }
    }
}

/// Triangles of a panel drawn in one flat colour, whatever the field says.
#[derive(Debug, Clone, Copy)]
pub struct FlatElements<'a> {
    /// One entry per triangle: `true` draws it in `color`.
    pub mask: &'a [bool],
    /// The colour of the masked triangles.
    pub color: [u8; 3],
    /// The legend entry under the colorbar (a swatch of `color` and this text), drawn when the
    /// frame has a colorbar; empty for none.
    pub label: &'a str,
}

/// The edges where `tags` change: every edge between two triangles of different tags, and
/// every boundary edge (used by one triangle) of a triangle whose tag `outline_boundary`
/// accepts, as `[smaller vertex, larger vertex]` in increasing order. With per-triangle
/// tissue tags this is the outline of every bone ([`MeshView::outline_edges`]).
///
/// # Panics
/// If `tags` and `triangles` differ in length.
pub fn region_edges(
    triangles: &[[usize; 3]],
    tags: &[u32],
    outline_boundary: impl Fn(u32) -> bool,
) -> Vec<[usize; 2]> {
    assert_eq!(
        triangles.len(),
        tags.len(),
        "region_edges: one tag per triangle"
    );
    // Every edge with its triangle's tag, sorted so the (at most two) uses of an edge meet.
    let mut uses: Vec<([usize; 2], u32)> = triangles
        .iter()
        .zip(tags)
        .flat_map(|(t, &tag)| {
            (0..3).map(move |k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                ([a.min(b), a.max(b)], tag)
            })
        })
        .collect();
    uses.sort_unstable();
    let mut out = Vec::new();
    let mut i = 0;
    while i < uses.len() {
        let edge = uses[i].0;
        let j = i + uses[i..].iter().take_while(|u| u.0 == edge).count();
        let group = &uses[i..j];
        let changes = group.iter().any(|u| u.1 != group[0].1);
        if changes || (group.len() == 1 && outline_boundary(group[0].1)) {
            out.push(edge);
        }
        i = j;
    }
    out
}

/// How a frame is drawn.
#[derive(Debug, Clone)]
pub struct FrameStyle {
    /// Width of ONE panel's drawing area in pixels (default 640).
    pub panel_width: u32,
    /// Height of ONE panel's drawing area in pixels (default 360).
    pub panel_height: u32,
    /// Figure title across the top; empty for no title row.
    pub title: String,
    /// Colormap of the field.
    pub colormap: Colormap,
    /// Colorbar label, e.g. "von Mises stress".
    pub field_label: String,
    /// Unit of the displayed values, e.g. "kPa" (shown as `von Mises stress [kPa]`).
    pub unit: String,
    /// Displayed value = field value * `scale` (e.g. 1e-3 for Pa to kPa); default 1.
    pub scale: f64,
    /// Colorbar range in displayed units; `None` = finite min..max over all panels (widened a
    /// little when min == max).
    pub range: Option<(f64, f64)>,
    /// Thin dark edges over the fill; default false.
    pub wireframe: bool,
    /// Draw the rest shape's boundary when a panel has rest positions; default true.
    pub rest_outline: bool,
    /// World window `(lo, hi)` in metres; `None` fits everything in all panels (positions, rest
    /// positions, obstacles) with a small margin. All panels share one scale with equal aspect
    /// ratio, centred.
    pub bounds: Option<([f64; 2], [f64; 2])>,
    /// E.g. "t = 0.120 s", drawn at the top right corner of the figure (in the title row).
    pub time_label: Option<String>,
}

impl Default for FrameStyle {
    fn default() -> Self {
        FrameStyle {
            panel_width: 640,
            panel_height: 360,
            title: String::new(),
            colormap: Colormap::default(),
            field_label: String::new(),
            unit: String::new(),
            scale: 1.0,
            range: None,
            wireframe: false,
            rest_outline: true,
            bounds: None,
            time_label: None,
        }
    }
}

/// A drawn frame and where things are on it.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The picture.
    pub image: Image,
    /// Geometry of each panel, in the order of the input.
    pub panels: Vec<PanelGeometry>,
    /// The colorbar's gradient rectangle; `None` when no panel has a field.
    pub colorbar: Option<ColorbarGeometry>,
    /// The displayed range actually used (`lo`, `hi`); `None` when no panel has a field.
    pub range: Option<(f64, f64)>,
    /// The legend entries under the colorbar, one per distinct labelled
    /// [`FlatElements`] (label and colour), in panel order: the label and its swatch
    /// `[x0, y0, x1, y1]` (exclusive ends) in the image.
    pub legend: Vec<(String, [u32; 4])>,
}

/// Where one panel is on the image and how world coordinates map to it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanelGeometry {
    rect: [u32; 4],
    scale: f64,
    offset: [f64; 2],
}

impl PanelGeometry {
    /// Pixel coordinates (x right, y down, in the full image; pixel `(i, j)` spans
    /// `[i, i + 1) x [j, j + 1)`, so its centre is at `(i + 0.5, j + 0.5)`) of world point `p`.
    pub fn world_to_pixel(&self, p: [f64; 2]) -> [f64; 2] {
        [
            self.offset[0] + self.scale * p[0],
            self.offset[1] - self.scale * p[1],
        ]
    }

    /// The world point at pixel coordinates `q` (inverse of [`Self::world_to_pixel`]).
    pub fn pixel_to_world(&self, q: [f64; 2]) -> [f64; 2] {
        [
            (q[0] - self.offset[0]) / self.scale,
            (self.offset[1] - q[1]) / self.scale,
        ]
    }

    /// `x0, y0, x1, y1` (x1, y1 exclusive) of the drawing area in the full image.
    pub fn rect(&self) -> [u32; 4] {
        self.rect
    }

    /// Pixels per metre (the same in x and y, and in every panel of a frame).
    pub fn pixels_per_metre(&self) -> f64 {
        self.scale
    }
}

/// The colorbar's gradient rectangle `[x0, x1) x [y0, y1)`: the top row `y0` has the colour of
/// the range maximum, the bottom row `y1 - 1` that of the minimum. Tick labels and the label
/// with its unit are drawn to its right.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ColorbarGeometry {
    /// Left column.
    pub x0: u32,
    /// Top row (colour of the maximum).
    pub y0: u32,
    /// One past the right column.
    pub x1: u32,
    /// One past the bottom row (row `y1 - 1` has the colour of the minimum).
    pub y1: u32,
}

impl ColorbarGeometry {
    /// The pixel row whose colour is that of displayed value `v` (clamped to the bar).
    pub fn row_of(&self, v: f64, range: (f64, f64)) -> u32 {
        let t = ((v - range.0) / (range.1 - range.0)).clamp(0.0, 1.0);
        let h = (self.y1 - self.y0 - 1) as f64;
        self.y0 + ((1.0 - t) * h).round() as u32
    }
}

/// `image` with `caption` written above it (left-aligned, 15 px text on a white band), for
/// composing figures from panels drawn elsewhere (e.g. the mesh pipeline's stages).
pub fn with_caption(image: &Image, caption: &str) -> Image {
    const SIZE: f32 = 15.0;
    let band = 26;
    let width = image
        .width()
        .max(text::width(caption, SIZE).ceil() as u32 + 12);
    let mut out = Image::new(
        width,
        image.height() + band,
        [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 255],
    );
    out.blit(image, 0, band);
    let mut canvas = Canvas::new(&mut out);
    text::draw(
        &mut canvas,
        caption,
        SIZE,
        6.0,
        band as f32 - 8.0,
        Align::Left,
        TEXT_COLOR,
    );
    out
}

/// Draws the panels side by side with a shared colorbar. See the module documentation for the
/// layout. Errors ([`RenderError::Input`]) name the offending panel and value.
pub fn render(panels: &[MeshView<'_>], style: &FrameStyle) -> Result<Rendered> {
    validate(panels, style)?;
    let range = field_range(panels, style);
    let (lo, hi) = match style.bounds {
        Some(b) => b,
        None => fit_bounds(panels, style),
    };
    let ticks = range.map(Ticks::new);
    let entries = legend_entries(panels);
    let layout = Layout::new(panels, style, ticks.as_ref(), entries.len());

    let mut image = Image::new(
        layout.width,
        layout.height,
        [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 255],
    );
    let (pw, ph) = (style.panel_width, style.panel_height);
    let geometries: Vec<PanelGeometry> = (0..panels.len())
        .map(|i| {
            let x0 = layout.panel_x0 + i as u32 * (pw + PANEL_GAP);
            panel_geometry([x0, layout.panel_y0, x0 + pw, layout.panel_y0 + ph], lo, hi)
        })
        .collect();

    let mut scratch = Scratch::default();
    for (view, geom) in panels.iter().zip(&geometries) {
        draw_panel(&mut image, view, geom, style, range, &mut scratch);
    }

    let mut canvas = Canvas::new(&mut image);
    for (view, geom) in panels.iter().zip(&geometries) {
        let [x0, y0, x1, y1] = geom.rect;
        frame_rect(
            &mut canvas,
            x0 as i32,
            y0 as i32,
            x1 as i32,
            y1 as i32,
            FRAME_COLOR,
        );
        if !view.caption.is_empty() {
            let cx = 0.5 * (x0 + x1) as f32;
            let baseline = y0 as f32 - 8.0;
            text::draw(
                &mut canvas,
                view.caption,
                CAPTION_SIZE,
                cx,
                baseline,
                Align::Center,
                TEXT_COLOR,
            );
        }
    }
    if let Some(baseline) = layout.title_baseline {
        let last = geometries[geometries.len() - 1].rect;
        let cx = 0.5 * (layout.panel_x0 + last[2]) as f32;
        text::draw(
            &mut canvas,
            &style.title,
            TITLE_SIZE,
            cx,
            baseline,
            Align::Center,
            TEXT_COLOR,
        );
        if let Some(t) = &style.time_label {
            let right = (layout.width - MARGIN) as f32;
            text::draw(
                &mut canvas,
                t,
                TIME_SIZE,
                right,
                baseline,
                Align::Right,
                TIME_COLOR,
            );
        }
    }
    let colorbar = match (&layout.bar, range, &ticks) {
        (Some(bar), Some(range), Some(ticks)) => {
            draw_colorbar(&mut canvas, bar, &layout, style, range, ticks);
            Some(*bar)
        }
        _ => None,
    };
    let legend = match colorbar {
        Some(bar) => draw_legend(&mut canvas, &bar, &layout, &entries),
        None => Vec::new(),
    };
    Ok(Rendered {
        image,
        panels: geometries,
        colorbar,
        range,
        legend,
    })
}

/// The distinct labelled flat colours of the panels, in panel order.
fn legend_entries<'a>(panels: &[MeshView<'a>]) -> Vec<(&'a str, [u8; 3])> {
    let mut out: Vec<(&str, [u8; 3])> = Vec::new();
    for f in panels.iter().filter_map(|p| p.flat) {
        if !f.label.is_empty() && !out.contains(&(f.label, f.color)) {
            out.push((f.label, f.color));
        }
    }
    out
}

/// Draws one row per entry under the colorbar: a framed swatch and its label.
fn draw_legend(
    canvas: &mut Canvas<'_>,
    bar: &ColorbarGeometry,
    layout: &Layout,
    entries: &[(&str, [u8; 3])],
) -> Vec<(String, [u32; 4])> {
    let cap = text::cap_height(LABEL_SIZE);
    let mut out = Vec::new();
    for (k, &(label, color)) in entries.iter().enumerate() {
        let top = bar.y1 + BAR_INSET + k as u32 * LEGEND_ROW + (LEGEND_ROW - LEGEND_SWATCH) / 2;
        let rect = [bar.x0, top, bar.x1, top + LEGEND_SWATCH];
        canvas.fill_rect(
            rect[0] as i32,
            rect[1] as i32,
            rect[2] as i32,
            rect[3] as i32,
            color,
        );
        frame_rect(
            canvas,
            rect[0] as i32,
            rect[1] as i32,
            rect[2] as i32,
            rect[3] as i32,
            [120, 120, 126],
        );
        let baseline = 0.5 * (rect[1] + rect[3]) as f32 + 0.5 * cap;
        text::draw(
            canvas,
            label,
            LABEL_SIZE,
            layout.tick_label_x as f32,
            baseline,
            Align::Left,
            TEXT_COLOR,
        );
        out.push((label.to_owned(), rect));
    }
    out
}

fn input(msg: String) -> RenderError {
    RenderError::Input(msg)
}

fn panel_name(i: usize, view: &MeshView<'_>) -> String {
    if view.caption.is_empty() {
        format!("panel {i}")
    } else {
        format!("panel {i} ({:?})", view.caption)
    }
}

fn finite2(p: [f64; 2]) -> bool {
    p[0].is_finite() && p[1].is_finite()
}

fn validate(panels: &[MeshView<'_>], style: &FrameStyle) -> Result<()> {
    if panels.is_empty() {
        return Err(input(
            "no panels to draw: pass at least one MeshView".into(),
        ));
    }
    let (pw, ph) = (style.panel_width, style.panel_height);
    if pw == 0 || ph == 0 {
        return Err(input(format!(
            "panel size {pw}x{ph} px: width and height must be > 0"
        )));
    }
    if pw > MAX_PANEL_SIDE || ph > MAX_PANEL_SIDE {
        return Err(input(format!(
            "panel size {pw}x{ph} px is too large (at most {MAX_PANEL_SIDE} px per side)"
        )));
    }
    if panels.len() > 64 {
        return Err(input(format!(
            "{} panels is too many (at most 64)",
            panels.len()
        )));
    }
    if !style.scale.is_finite() {
        return Err(input(format!("scale = {} is not finite", style.scale)));
    }
    if let Some((lo, hi)) = style.range
        && !(lo.is_finite() && hi.is_finite() && lo < hi)
    {
        return Err(input(format!(
            "range ({lo}, {hi}): need finite lo < hi (in displayed units)"
        )));
    }
    if let Some((lo, hi)) = style.bounds
        && !(finite2(lo) && finite2(hi) && lo[0] < hi[0] && lo[1] < hi[1])
    {
        return Err(input(format!(
            "bounds ({lo:?}, {hi:?}): need finite lo < hi in both x and y"
        )));
    }
    for (i, view) in panels.iter().enumerate() {
        let name = || panel_name(i, view);
        let n = view.positions.len();
        if n > u32::MAX as usize {
            return Err(input(format!("{}: {n} vertices is too many", name())));
        }
        if let Some(k) = view.positions.iter().position(|&p| !finite2(p)) {
            return Err(input(format!(
                "{}: position {k} = {:?} is not finite",
                name(),
                view.positions[k]
            )));
        }
        for (t, tri) in view.triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v >= n) {
                return Err(input(format!(
                    "{}: triangle {t} = {tri:?} uses vertex {v}, but there are only {n} positions",
                    name()
                )));
            }
        }
        match view.field {
            Some(FieldValues::PerElement(v)) if v.len() != view.triangles.len() => {
                return Err(input(format!(
                    "{}: the per-element field has {} values but the mesh has {} triangles",
                    name(),
                    v.len(),
                    view.triangles.len()
                )));
            }
            Some(FieldValues::PerVertex(v)) if v.len() != n => {
                return Err(input(format!(
                    "{}: the per-vertex field has {} values but the mesh has {n} vertices",
                    name(),
                    v.len()
                )));
            }
            _ => {}
        }
        if let Some(f) = view.flat
            && f.mask.len() != view.triangles.len()
        {
            return Err(input(format!(
                "{}: the flat-element mask has {} entries but the mesh has {} triangles",
                name(),
                f.mask.len(),
                view.triangles.len()
            )));
        }
        if let Some(e) = view.outline_edges.iter().find(|e| e[0] >= n || e[1] >= n) {
            return Err(input(format!(
                "{}: outline edge {e:?} uses a vertex beyond the {n} positions",
                name()
            )));
        }
        if let Some(rest) = view.rest_positions {
            if rest.len() != n {
                return Err(input(format!(
                    "{}: rest_positions has {} entries but positions has {n}",
                    name(),
                    rest.len()
                )));
            }
            if let Some(k) = rest.iter().position(|&p| !finite2(p)) {
                return Err(input(format!(
                    "{}: rest position {k} = {:?} is not finite",
                    name(),
                    rest[k]
                )));
            }
        }
        for (o, poly) in view.obstacles.iter().enumerate() {
            if let Some(k) = poly.iter().position(|&p| !finite2(p)) {
                return Err(input(format!(
                    "{}: obstacle {o}, point {k} = {:?} is not finite",
                    name(),
                    poly[k]
                )));
            }
        }
    }
    Ok(())
}

/// The displayed range: the style's, or the finite min..max of all fields times the scale.
/// The values of `field` a panel shows by colour: all of them without a flat `mask`; with one,
/// those of the triangles drawn by the field (per element) or of the vertices such a triangle
/// uses (per vertex). What the automatic colour range spans.
pub fn shown_values<'v>(
    field: FieldValues<'v>,
    triangles: &[[usize; 3]],
    mask: Option<&[bool]>,
) -> impl Iterator<Item = f64> + 'v {
    let (values, shown): (&[f64], Option<Vec<bool>>) = match (field, mask) {
        (FieldValues::PerElement(v) | FieldValues::PerVertex(v), None) => (v, None),
        (FieldValues::PerElement(v), Some(mask)) => (v, Some(mask.iter().map(|m| !m).collect())),
        (FieldValues::PerVertex(v), Some(mask)) => {
            let mut shown = vec![false; v.len()];
            for (t, _) in triangles.iter().zip(mask).filter(|(_, m)| !**m) {
                t.iter().for_each(|&i| shown[i] = true);
            }
            (v, Some(shown))
        }
    };
    values
        .iter()
        .enumerate()
        .filter(move |(i, _)| shown.as_ref().is_none_or(|s| s[*i]))
        .map(|(_, &v)| v)
}

fn field_range(panels: &[MeshView<'_>], style: &FrameStyle) -> Option<(f64, f64)> {
    if panels.iter().all(|p| p.field.is_none()) {
        return None;
    }
    if let Some(r) = style.range {
        return Some(r);
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut add = |v: f64| {
        let d = v * style.scale;
        if d.is_finite() {
            lo = lo.min(d);
            hi = hi.max(d);
        }
    };
    for view in panels {
        if let Some(field) = view.field {
            shown_values(field, view.triangles, view.flat.map(|f| f.mask)).for_each(&mut add);
        }
    }
    if lo > hi {
        return Some((0.0, 1.0)); // no finite value at all
    }
    if lo == hi || !(hi - lo).is_finite() {
        let d = if lo == 0.0 { 1.0 } else { lo.abs() * 0.01 };
        return Some((lo - d, lo + d));
    }
    Some((lo, hi))
}

/// Bounding box of everything drawn in all panels, with a small margin.
fn fit_bounds(panels: &[MeshView<'_>], style: &FrameStyle) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut add = |p: &[f64; 2]| {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    };
    for view in panels {
        view.positions.iter().for_each(&mut add);
        if style.rest_outline
            && let Some(rest) = view.rest_positions
        {
            rest.iter().for_each(&mut add);
        }
        view.obstacles
            .iter()
            .filter(|poly| poly.len() >= 3)
            .flatten()
            .for_each(&mut add);
    }
    if lo[0] > hi[0] {
        return ([0.0, 0.0], [1.0, 1.0]);
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let pad = if extent > 0.0 { 0.04 * extent } else { 0.5 };
    ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad])
}

fn panel_geometry(rect: [u32; 4], lo: [f64; 2], hi: [f64; 2]) -> PanelGeometry {
    let (pw, ph) = ((rect[2] - rect[0]) as f64, (rect[3] - rect[1]) as f64);
    let (wx, wy) = (hi[0] - lo[0], hi[1] - lo[1]);
    let scale = (pw / wx).min(ph / wy);
    let left = rect[0] as f64 + 0.5 * (pw - scale * wx);
    let top = rect[1] as f64 + 0.5 * (ph - scale * wy);
    PanelGeometry {
        rect,
        scale,
        offset: [left - scale * lo[0], top + scale * hi[1]],
    }
}

/// Pixel layout of the figure.
struct Layout {
    width: u32,
    height: u32,
    title_baseline: Option<f32>,
    panel_x0: u32,
    panel_y0: u32,
    bar: Option<ColorbarGeometry>,
    /// Left edge of the tick labels.
    tick_label_x: u32,
    /// Left edge (glyph tops) of the rotated field label.
    label_x: u32,
}

impl Layout {
    fn new(
        panels: &[MeshView<'_>],
        style: &FrameStyle,
        ticks: Option<&Ticks>,
        legend_rows: usize,
    ) -> Self {
        let n = panels.len() as u32;
        let has_title = !style.title.is_empty() || style.time_label.is_some();
        let has_captions = panels.iter().any(|p| !p.caption.is_empty());
        let mut y = MARGIN;
        let title_baseline = has_title.then(|| {
            let (ascent, _) = text::vertical_metrics(TITLE_SIZE);
            let b = y as f32 + ascent + 2.0;
            y += TITLE_ROW;
            b
        });
        if has_captions {
            y += CAPTION_ROW;
        } else if !has_title {
            y += 4; // room for the top tick label of the colorbar
        }
        let panel_y0 = y;
        let panel_x0 = MARGIN;
        let panels_right = panel_x0 + n * style.panel_width + (n - 1) * PANEL_GAP;
        let height = panel_y0 + style.panel_height + MARGIN + 4;
        let mut width = panels_right + MARGIN;
        let (mut bar, mut tick_label_x, mut label_x) = (None, 0, 0);
        if let Some(ticks) = ticks {
            let x0 = panels_right + BAR_GAP;
            let inset = if style.panel_height > 4 * BAR_INSET {
                BAR_INSET
            } else {
                0
            };
            // Legend rows under the bar, as long as the bar keeps half the panel's height.
            let legend = (legend_rows as u32 * LEGEND_ROW + inset).min(style.panel_height / 2);
            let b = ColorbarGeometry {
                x0,
                y0: panel_y0 + inset,
                x1: x0 + BAR_WIDTH,
                y1: panel_y0 + style.panel_height
                    - inset
                    - if legend_rows > 0 { legend } else { 0 },
            };
            tick_label_x = b.x1 + 1 + TICK_LEN + 3;
            let reserve = text::width("\u{2212}0.0000", TICK_SIZE);
            let widest = ticks
                .labels
                .iter()
                .map(|s| text::width(s, TICK_SIZE))
                .fold(reserve, f32::max);
            label_x = tick_label_x + widest.ceil() as u32 + LABEL_GAP;
            let (ascent, descent) = text::vertical_metrics(LABEL_SIZE);
            width = if bar_label(style).is_empty() {
                label_x - LABEL_GAP + MARGIN
            } else {
                label_x + (ascent - descent).ceil() as u32 + MARGIN
            };
            bar = Some(b);
        }
        Layout {
            width,
            height,
            title_baseline,
            panel_x0,
            panel_y0,
            bar,
            tick_label_x,
            label_x,
        }
    }
}

fn bar_label(style: &FrameStyle) -> String {
    match (style.field_label.is_empty(), style.unit.is_empty()) {
        (_, true) => style.field_label.clone(),
        (true, false) => format!("[{}]", style.unit),
        (false, false) => format!("{} [{}]", style.field_label, style.unit),
    }
}

/// Colorbar ticks: round values inside the range and their labels.
struct Ticks {
    values: Vec<f64>,
    labels: Vec<String>,
}

impl Ticks {
    fn new((lo, hi): (f64, f64)) -> Self {
        let raw = (hi - lo) / 4.0;
        let exp = raw.log10().floor();
        let mag = 10f64.powf(exp);
        let f = raw / mag;
        let nice = if f < 1.5 {
            1.0
        } else if f < 2.25 {
            2.0
        } else if f < 3.5 {
            2.5
        } else if f < 7.5 {
            5.0
        } else {
            10.0
        };
        let step = nice * mag;
        let step_exp = (exp as i32) + (nice == 10.0) as i32;
        let eps = 1e-9 * step;
        let first = ((lo - eps) / step).ceil() as i64;
        let last = ((hi + eps) / step).floor() as i64;
        let values: Vec<f64> = (first..=last)
            .map(|k| k as f64 * step)
            .map(|v| if v.abs() < eps { 0.0 } else { v })
            .collect();
        let m = lo.abs().max(hi.abs());
        let scientific = !(1e-3..1e5).contains(&m);
        let decimals = (-step_exp + (nice == 2.5) as i32).max(0) as usize;
        let labels = values
            .iter()
            .map(|&v| {
                let s = if v == 0.0 {
                    "0".to_string()
                } else if scientific {
                    let e = v.abs().log10().floor() as i32;
                    let d = (e - step_exp + (nice == 2.5) as i32).clamp(0, 6) as usize;
                    format!("{v:.d$e}")
                } else {
                    format!("{v:.decimals$}")
                };
                s.replace('-', "\u{2212}")
            })
            .collect();
        Ticks { values, labels }
    }
}

/// Buffers reused across panels.
#[derive(Default)]
struct Scratch {
    fixed: Vec<[i64; 2]>,
    /// Per-vertex colormap positions (LUT index as f64; NaN for no data).
    vertex_t: Vec<f64>,
    bucket_start: Vec<u32>,
    bucket: Vec<[u32; 2]>,
    boundary: Vec<[u32; 2]>,
    out_edge: Vec<u32>,
    visited: Vec<bool>,
    /// Boundary loops: vertex indices, and (start, len, closed) per loop.
    loop_vertices: Vec<u32>,
    loops: Vec<(usize, usize, bool)>,
}

/// The boundary edges of a triangle mesh (used by exactly one triangle, oriented as in it).
pub(crate) fn boundary_edges(n_vertices: usize, triangles: &[[usize; 3]]) -> Vec<[u32; 2]> {
    let mut s = Scratch::default();
    s.boundary_loops(n_vertices, triangles);
    s.boundary
}

impl Scratch {
    /// Boundary edges (used by exactly one triangle, oriented as in that triangle), chained
    /// into loops.
    fn boundary_loops(&mut self, n_vertices: usize, triangles: &[[usize; 3]]) {
        // Bucket every edge by its smaller vertex (counting sort), then count duplicates within
        // each small bucket: linear time, no hashing.
        self.bucket_start.clear();
        self.bucket_start.resize(n_vertices + 1, 0);
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                self.bucket_start[a.min(b) + 1] += 1;
            }
        }
        for i in 0..n_vertices {
            self.bucket_start[i + 1] += self.bucket_start[i];
        }
        self.bucket.clear();
        self.bucket.resize(triangles.len() * 3, [0, 0]);
        self.out_edge.clear();
        self.out_edge.resize(n_vertices, 0); // fill cursor per bucket, reused below
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let lo = a.min(b);
                let slot = self.bucket_start[lo] + self.out_edge[lo];
                self.out_edge[lo] += 1;
                self.bucket[slot as usize] = [a.max(b) as u32, a as u32];
            }
        }
        self.boundary.clear();
        for lo in 0..n_vertices {
            let s =
                &self.bucket[self.bucket_start[lo] as usize..self.bucket_start[lo + 1] as usize];
            for e in s {
                let uses = s.iter().filter(|f| f[0] == e[0]).count();
                if uses == 1 {
                    let from = e[1];
                    let to = if from as usize == lo { e[0] } else { lo as u32 };
                    self.boundary.push([from, to]);
                }
            }
        }
        // Chain: out_edge[v] = index of a boundary edge leaving v.
        self.out_edge.clear();
        self.out_edge.resize(n_vertices, u32::MAX);
        for (i, e) in self.boundary.iter().enumerate() {
            let slot = &mut self.out_edge[e[0] as usize];
            if *slot == u32::MAX {
                *slot = i as u32;
            }
        }
        self.visited.clear();
        self.visited.resize(self.boundary.len(), false);
        self.loop_vertices.clear();
        self.loops.clear();
        for first in 0..self.boundary.len() {
            if self.visited[first] {
                continue;
            }
            let start_vertex = self.boundary[first][0];
            let begin = self.loop_vertices.len();
            self.loop_vertices.push(start_vertex);
            let mut cur = first;
            let mut closed = false;
            loop {
                self.visited[cur] = true;
                let to = self.boundary[cur][1];
                if to == start_vertex {
                    closed = true;
                    break;
                }
                self.loop_vertices.push(to);
                let next = self.out_edge[to as usize];
                if next == u32::MAX || self.visited[next as usize] {
                    break;
                }
                cur = next as usize;
            }
            self.loops
                .push((begin, self.loop_vertices.len() - begin, closed));
        }
    }

    /// A path through the boundary loops at the given pixel positions.
    fn loops_path(&self, pixel: impl Fn(u32) -> [f64; 2]) -> Option<sk::Path> {
        let mut pb = sk::PathBuilder::new();
        for &(begin, len, closed) in &self.loops {
            let vs = &self.loop_vertices[begin..begin + len];
            let p = pixel(vs[0]);
            pb.move_to(p[0] as f32, p[1] as f32);
            for &v in &vs[1..] {
                let p = pixel(v);
                pb.line_to(p[0] as f32, p[1] as f32);
            }
            if closed {
                pb.close();
            }
        }
        pb.finish()
    }
}

#[inline]
fn write_span(canvas: &mut Canvas<'_>, y: i32, x0: i32, x1: i32, c: [u8; 3]) {
    let rgba = [c[0], c[1], c[2], 255];
    for p in canvas.row_span(y, x0, x1).chunks_exact_mut(4) {
        p.copy_from_slice(&rgba);
    }
}

fn draw_panel(
    image: &mut Image,
    view: &MeshView<'_>,
    geom: &PanelGeometry,
    style: &FrameStyle,
    range: Option<(f64, f64)>,
    s: &mut Scratch,
) {
    let [x0, y0, x1, y1] = geom.rect;
    let clip = Clip {
        x0: x0 as i32,
        y0: y0 as i32,
        x1: x1 as i32,
        y1: y1 as i32,
    };
    s.fixed.clear();
    s.fixed.extend(
        view.positions
            .iter()
            .map(|&p| to_fixed(geom.world_to_pixel(p))),
    );
    let fixed = &s.fixed;
    let tri_fixed = |t: &[usize; 3]| [fixed[t[0]], fixed[t[1]], fixed[t[2]]];

    let (lo, hi) = range.unwrap_or((0.0, 1.0));
    let inv = 1.0 / (hi - lo);
    let to_t = |v: f64| {
        let d = v * style.scale;
        if v.is_finite() && !d.is_nan() {
            ((d - lo) * inv).clamp(0.0, 1.0)
        } else {
            f64::NAN
        }
    };
    let cmap = style.colormap;
    {
        let mut canvas = Canvas::new(image);
        canvas.set_clip(clip);
        match view.field {
            None => {
                for t in view.triangles {
                    fill_triangle(tri_fixed(t), clip, |y, a, b| {
                        write_span(&mut canvas, y, a, b, MESH_COLOR)
                    });
                }
            }
            Some(FieldValues::PerElement(values)) => {
                for (t, &v) in view.triangles.iter().zip(values) {
                    let c = cmap.sample(to_t(v));
                    fill_triangle(tri_fixed(t), clip, |y, a, b| {
                        write_span(&mut canvas, y, a, b, c)
                    });
                }
            }
            Some(FieldValues::PerVertex(values)) => {
                let lut = cmap.lut();
                let top = (LUT_SIZE - 1) as f64;
                s.vertex_t.clear();
                s.vertex_t.extend(values.iter().map(|&v| to_t(v) * top));
                let vt = &s.vertex_t;
                for t in view.triangles {
                    let f = [vt[t[0]], vt[t[1]], vt[t[2]]];
                    let v = tri_fixed(t);
                    let flat = if f.iter().any(|x| x.is_nan()) {
                        Some(NO_DATA)
                    } else if f[0] == f[1] && f[1] == f[2] {
                        Some(lut[(f[0] + 0.5) as usize])
                    } else {
                        None
                    };
                    match (flat, plane(v, f)) {
                        (None, Some([f0, fx, fy])) => {
                            fill_triangle(v, clip, |y, a, b| {
                                let mut value = f0 + fx * (a as f64 + 0.5) + fy * (y as f64 + 0.5);
                                for p in canvas.row_span(y, a, b).chunks_exact_mut(4) {
                                    let i = (value + 0.5).clamp(0.0, top) as usize;
                                    let c = lut[i];
                                    p.copy_from_slice(&[c[0], c[1], c[2], 255]);
                                    value += fx;
                                }
                            });
                        }
                        (flat, _) => {
                            let c = flat.unwrap_or(NO_DATA);
                            fill_triangle(v, clip, |y, a, b| write_span(&mut canvas, y, a, b, c));
                        }
                    }
                }
            }
        }
        if let Some(f) = view.flat {
            for (t, _) in view.triangles.iter().zip(f.mask).filter(|(_, m)| **m) {
                fill_triangle(tri_fixed(t), clip, |y, a, b| {
                    write_span(&mut canvas, y, a, b, f.color)
                });
            }
        }
        let px = |i: usize| {
            let q = fixed[i];
            [
                q[0] as f64 / crate::raster::SUBPIXEL as f64,
                q[1] as f64 / crate::raster::SUBPIXEL as f64,
            ]
        };
        if style.wireframe {
            for t in view.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    // Interior edges appear twice (once each way): draw them once. Boundary
                    // edges the wrong way round are covered by the outline.
                    if a < b {
                        canvas.line_aa(px(a), px(b), WIREFRAME_COLOR, WIREFRAME_ALPHA);
                    }
                }
            }
        }
        for e in view.outline_edges {
            canvas.line_aa(px(e[0]), px(e[1]), EDGE_COLOR, EDGE_ALPHA);
        }
    }

    // Vector decorations with tiny-skia, straight onto the (opaque, hence also premultiplied)
    // RGBA buffer.
    let rest = view.rest_positions.filter(|_| style.rest_outline);
    let polygons = || view.obstacles.iter().filter(|p| p.len() >= 3);
    if view.triangles.is_empty() && rest.is_none() && polygons().next().is_none() {
        return;
    }
    let (w, h) = (image.width(), image.height());
    let mut inside = true;
    let mut check = |p: [f64; 2]| {
        let q = geom.world_to_pixel(p);
        inside &= q[0] >= x0 as f64 + 2.0
            && q[0] <= x1 as f64 - 2.0
            && q[1] >= y0 as f64 + 2.0
            && q[1] <= y1 as f64 - 2.0;
    };
    view.positions.iter().for_each(|&p| check(p));
    rest.iter().flat_map(|r| r.iter()).for_each(|&p| check(p));
    polygons().flatten().for_each(|&p| check(p));
    let mask = if inside {
        None
    } else {
        panel_mask(w, h, [x0, y0, x1, y1])
    };
    let Some(mut pixmap) = sk::PixmapMut::from_bytes(image.as_rgba_mut(), w, h) else {
        return;
    };
    let id = sk::Transform::identity();
    let paint = |c: [u8; 3], a: u8| {
        let mut p = sk::Paint::default();
        p.set_color_rgba8(c[0], c[1], c[2], a);
        p.anti_alias = true;
        p
    };
    let stroke = |width: f32, dash: Option<sk::StrokeDash>| sk::Stroke {
        width,
        line_join: sk::LineJoin::Round,
        line_cap: sk::LineCap::Butt,
        dash,
        ..sk::Stroke::default()
    };

    if !view.triangles.is_empty() {
        s.boundary_loops(view.positions.len(), view.triangles);
        if let Some(path) = s.loops_path(|v| geom.world_to_pixel(view.positions[v as usize])) {
            pixmap.stroke_path(
                &path,
                &paint(OUTLINE_COLOR, 235),
                &stroke(1.0, None),
                id,
                mask.as_ref(),
            );
        }
        if let Some(rest) = rest
            && let Some(path) = s.loops_path(|v| geom.world_to_pixel(rest[v as usize]))
        {
            let dash = sk::StrokeDash::new(vec![5.0, 3.5], 0.0);
            pixmap.stroke_path(
                &path,
                &paint(REST_OUTLINE_COLOR, 255),
                &stroke(1.0, dash),
                id,
                mask.as_ref(),
            );
        }
    }
    for poly in polygons() {
        let mut pb = sk::PathBuilder::new();
        for (k, &p) in poly.iter().enumerate() {
            let q = geom.world_to_pixel(p);
            if k == 0 {
                pb.move_to(q[0] as f32, q[1] as f32);
            } else {
                pb.line_to(q[0] as f32, q[1] as f32);
            }
        }
        pb.close();
        if let Some(path) = pb.finish() {
            pixmap.fill_path(
                &path,
                &paint(OBSTACLE_COLOR, 255),
                sk::FillRule::Winding,
                id,
                mask.as_ref(),
            );
            pixmap.stroke_path(
                &path,
                &paint(OBSTACLE_EDGE_COLOR, 255),
                &stroke(1.2, None),
                id,
                mask.as_ref(),
            );
        }
    }
}

/// A one-pixel frame just outside the rectangle `[x0, x1) x [y0, y1)`.
fn frame_rect(canvas: &mut Canvas<'_>, x0: i32, y0: i32, x1: i32, y1: i32, c: [u8; 3]) {
    canvas.fill_rect(x0 - 1, y0 - 1, x1 + 1, y0, c);
    canvas.fill_rect(x0 - 1, y1, x1 + 1, y1 + 1, c);
    canvas.fill_rect(x0 - 1, y0, x0, y1, c);
    canvas.fill_rect(x1, y0, x1 + 1, y1, c);
}

fn draw_colorbar(
    canvas: &mut Canvas<'_>,
    bar: &ColorbarGeometry,
    layout: &Layout,
    style: &FrameStyle,
    range: (f64, f64),
    ticks: &Ticks,
) {
    let full = canvas.bounds();
    canvas.set_clip(full);
    let h = bar.y1 - bar.y0;
    for y in bar.y0..bar.y1 {
        let t = if h > 1 {
            (bar.y1 - 1 - y) as f64 / (h - 1) as f64
        } else {
            1.0
        };
        let c = style.colormap.sample(t);
        canvas.fill_rect(bar.x0 as i32, y as i32, bar.x1 as i32, y as i32 + 1, c);
    }
    let edge = [120, 120, 126];
    frame_rect(
        canvas,
        bar.x0 as i32,
        bar.y0 as i32,
        bar.x1 as i32,
        bar.y1 as i32,
        edge,
    );
    let cap = text::cap_height(TICK_SIZE);
    for (v, label) in ticks.values.iter().zip(&ticks.labels) {
        let row = bar.row_of(*v, range) as i32;
        let x = bar.x1 as i32 + 1;
        canvas.fill_rect(x, row, x + TICK_LEN as i32, row + 1, edge);
        let baseline = row as f32 + 0.5 + 0.5 * cap;
        text::draw(
            canvas,
            label,
            TICK_SIZE,
            layout.tick_label_x as f32,
            baseline,
            Align::Left,
            TEXT_COLOR,
        );
    }
    let label = bar_label(style);
    let center = 0.5 * (bar.y0 + bar.y1) as f32;
    text::draw_vertical(
        canvas,
        &label,
        LABEL_SIZE,
        layout.label_x as f32,
        center,
        TEXT_COLOR,
    );
}

/// A clip mask of a `w` x `h` image that lets through the pixels inside `rect` (`[x0, y0, x1,
/// y1]`): what draws over a panel stays inside it.
pub(crate) fn panel_mask(w: u32, h: u32, [x0, y0, x1, y1]: [u32; 4]) -> Option<sk::Mask> {
    let mut m = sk::Mask::new(w, h);
    if let (Some(m), Some(r)) = (
        m.as_mut(),
        sk::Rect::from_ltrb(x0 as f32, y0 as f32, x1 as f32, y1 as f32),
    ) {
        m.fill_path(
            &sk::PathBuilder::from_rect(r),
            sk::FillRule::Winding,
            false,
            sk::Transform::identity(),
        );
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        let t = Ticks::new((0.0, 1.0));
        assert_eq!(t.labels, ["0", "0.25", "0.50", "0.75", "1.00"]);
        let t = Ticks::new((-3.2, 17.9));
        assert_eq!(t.labels, ["0", "5", "10", "15"]);
        let t = Ticks::new((0.99, 1.01));
        assert_eq!(t.labels, ["0.990", "0.995", "1.000", "1.005", "1.010"]);
        let t = Ticks::new((0.0, 2.4e6));
        assert_eq!(t.labels, ["0", "5e5", "1.0e6", "1.5e6", "2.0e6"]);
        let t = Ticks::new((-0.5, 0.5));
        assert_eq!(
            t.labels,
            ["\u{2212}0.50", "\u{2212}0.25", "0", "0.25", "0.50"]
        );
        for (lo, hi) in [(1.0, 1.0001), (-1e-4, 3e-4), (12.0, 1234.0), (0.1, 0.7)] {
            let t = Ticks::new((lo, hi));
            assert!(
                (2..=7).contains(&t.values.len()),
                "{lo} {hi}: {:?}",
                t.labels
            );
            assert!(t.values.iter().all(|&v| v >= lo - 1e-12 && v <= hi + 1e-12));
        }
    }

    #[test]
    fn boundary_of_a_square_is_one_closed_loop() {
        let tris = [[0, 1, 2], [0, 2, 3]];
        let mut s = Scratch::default();
        s.boundary_loops(4, &tris);
        assert_eq!(s.boundary.len(), 4);
        assert_eq!(s.loops, [(0, 4, true)]);
    }
}
