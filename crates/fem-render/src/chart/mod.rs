//! Line charts (probe curves against time) and grid charts (stability and accuracy maps), as
//! self-contained SVG and as PNG rendered from that same SVG.
//!
//! The SVG uses the font family [`crate::FONT_FAMILY`]; the PNG path renders it with resvg and
//! the carried font [`crate::FONT_TTF`] only (no system font is looked up), so a PNG made on a
//! machine without any font installed has the same text as anywhere else.
//!
//! ```no_run
//! use fem_render::chart::{LineChart, Series};
//!
//! let chart = LineChart {
//!     title: "Tip displacement".into(),
//!     x_label: "time [s]".into(),
//!     y_label: "u_y [m]".into(),
//!     series: vec![Series {
//!         label: "E = 1 kJ".into(),
//!         points: (0..100).map(|i| (i as f64 * 0.01, -(i as f64 * 0.01).powi(2))).collect(),
//!     }],
//!     ..LineChart::default()
//! };
//! let svg: String = chart.to_svg()?;
//! chart.to_png()?.write_png(std::path::Path::new("tip.png"))?;
//! # Ok::<(), fem_render::RenderError>(())
//! ```

mod grid;
mod line;
mod png;
mod svg;
mod ticks;

pub use png::{svg_to_png, svg_to_png_scaled};
pub use svg::{PALETTE, series_color, series_dash, text_color_on, text_width};
pub use ticks::{Tick, axis_ticks};

/// How values are mapped along an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Evenly spaced values, ticks at 1-2-5 steps.
    #[default]
    Linear,
    /// Evenly spaced decades, ticks at powers of ten; values `<= 0` are not drawn.
    Log,
}

/// One curve of a [`LineChart`].
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// The legend entry; an empty label leaves the series out of the legend.
    pub label: String,
    /// `(x, y)` points in drawing order. A non-finite coordinate breaks the line there; on a
    /// log axis, a point with a coordinate `<= 0` is skipped (the line joins its neighbours).
    pub points: Vec<(f64, f64)>,
}

/// A chart of one or more curves `y(x)` with axes, ticks, grid lines, a title and a legend.
#[derive(Debug, Clone)]
pub struct LineChart {
    /// The title above the plot; may be empty.
    pub title: String,
    /// The horizontal axis label with its unit, e.g. `"time [s]"`; may be empty.
    pub x_label: String,
    /// The vertical axis label with its unit, e.g. `"tip displacement [m]"`; may be empty.
    pub y_label: String,
    /// The horizontal axis scale.
    pub x_scale: Scale,
    /// The vertical axis scale.
    pub y_scale: Scale,
    /// The curves, drawn in order with [`series_color`] and [`series_dash`].
    pub series: Vec<Series>,
    /// Draws a small marker (a different shape per series) at each point, for sparse data.
    pub markers: bool,
    /// The total width in pixels (default 720).
    pub width: u32,
    /// The total height in pixels (default 420).
    pub height: u32,
}

impl Default for LineChart {
    fn default() -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            series: Vec::new(),
            markers: false,
            width: 720,
            height: 420,
        }
    }
}

/// One cell of a [`GridChart`].
#[derive(Debug, Clone, Default)]
pub struct GridCell {
    /// The fill colour (sRGB).
    pub color: [u8; 3],
    /// A short text centred in the cell (black or white, whichever contrasts more); may be empty.
    pub text: String,
}

/// A table of coloured cells with row and column headers: a stability map (one colour per
/// category, with a legend) or an accuracy map (a continuous colour per cell).
#[derive(Debug, Clone)]
pub struct GridChart {
    /// The title above the chart; may be empty.
    pub title: String,
    /// The label above the column headers, e.g. `"time step [s]"`; may be empty.
    pub x_label: String,
    /// The label left of the row headers (drawn vertically); may be empty.
    pub y_label: String,
    /// Column headers, left to right.
    pub columns: Vec<String>,
    /// Row headers, top to bottom.
    pub rows: Vec<String>,
    /// `cells[row][column]`, exactly `rows.len()` x `columns.len()`.
    pub cells: Vec<Vec<GridCell>>,
    /// Legend entries (label, colour) drawn below the grid; may be empty.
    pub legend: Vec<(String, [u8; 3])>,
    /// The size of one cell in pixels, `(width, height)` (default `(46, 26)`).
    pub cell_size: (u32, u32),
}

impl Default for GridChart {
    fn default() -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            columns: Vec::new(),
            rows: Vec::new(),
            cells: Vec::new(),
            legend: Vec::new(),
            cell_size: (46, 26),
        }
    }
}
