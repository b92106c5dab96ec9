//! The line chart: data ranges, layout (title, axes, tick labels, legend column or rows), and
//! the SVG of the curves.

use std::fmt::Write;

use super::svg::{
    Anchor, CENTER, Text, hex, num, open_svg, push_num, series_color, series_dash, text_width,
};
use super::ticks::Axis;
use super::{LineChart, Scale};
use crate::{Image, RenderError, Result};

const PAD: f64 = 12.0;
const TITLE: f64 = 16.0;
const LABEL: f64 = 13.0;
const TICK: f64 = 12.0;
const LEGEND: f64 = 12.0;
const TICK_LEN: f64 = 5.0;
/// The length of the line sample in a legend entry.
const SWATCH: f64 = 28.0;
const LEGEND_ROW: f64 = 20.0;
const LINE_WIDTH: f64 = 1.75;
/// Cap height of DejaVu Sans per pixel of font size.
const CAP: f64 = 0.73;
const MIN_WIDTH: u32 = 200;
const MIN_HEIGHT: u32 = 150;

const FRAME: &str = "#555555";
const GRID: &str = "#e3e3e3";
const GRID_MINOR: &str = "#f1f1f1";
const ZERO: &str = "#9a9a9a";

/// Where the legend goes.
enum Legend {
    None,
    /// Columns right of the plot, `rows` entries each, filled top to bottom then left to
    /// right; each column is `column_w` wide.
    Right {
        x: f64,
        rows: usize,
        column_w: f64,
    },
    /// Rows below the x axis label: for each entry, its offset from the plot's left edge and
    /// its row.
    Below {
        y: f64,
        places: Vec<(f64, usize)>,
    },
}

struct Layout {
    /// Left, top, width, height of the plot frame (data fills it exactly).
    left: f64,
    top: f64,
    width: f64,
    height: f64,
    x: Axis,
    y: Axis,
    /// `(series index, label)` of the series with a label.
    entries: Vec<(usize, String)>,
    legend: Legend,
}

impl Layout {
    fn px(&self, x: f64) -> f64 {
        self.left + self.x.frac(x) * self.width
    }

    fn py(&self, y: f64) -> f64 {
        self.top + self.height - self.y.frac(y) * self.height
    }
}

/// A crisp 1 px line position: the pixel centre nearest to `p`.
fn snap(p: f64) -> f64 {
    (p - 0.5).round() + 0.5
}

impl LineChart {
    /// The points to draw per series, in plot order; `None` breaks the line.
    fn drawable(&self) -> Vec<Vec<Option<(f64, f64)>>> {
        let ok = |v: f64, s: Scale| v.is_finite() && (s == Scale::Linear || v > 0.0);
        let on_log = |v: f64, s: Scale| s == Scale::Log && v.is_finite() && v <= 0.0;
        self.series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter(|&&(x, y)| !on_log(x, self.x_scale) && !on_log(y, self.y_scale))
                    .map(|&(x, y)| (ok(x, self.x_scale) && ok(y, self.y_scale)).then_some((x, y)))
                    .collect()
            })
            .collect()
    }

    fn layout(&self, data: &[Vec<Option<(f64, f64)>>]) -> Result<Layout> {
        if self.width < MIN_WIDTH || self.height < MIN_HEIGHT {
            return Err(RenderError::Input(format!(
                "LineChart: a {}x{} chart is too small (at least {MIN_WIDTH}x{MIN_HEIGHT})",
                self.width, self.height
            )));
        }
        let mut range = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for &(x, y) in data.iter().flatten().flatten() {
            range = [
                range[0].min(x),
                range[1].max(x),
                range[2].min(y),
                range[3].max(y),
            ];
        }
        if range[0] > range[1] {
            let n: usize = self.series.iter().map(|s| s.points.len()).sum();
            let log = if self.x_scale == Scale::Log || self.y_scale == Scale::Log {
                " (on a log axis, values <= 0 are not drawn)"
            } else {
                ""
            };
            return Err(RenderError::Input(format!(
                "LineChart: no finite point to draw among {n} points in {} series{log}",
                self.series.len()
            )));
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));

        let mut entries: Vec<(usize, String)> = self
            .series
            .iter()
            .enumerate()
            .filter(|(_, s)| !s.label.is_empty())
            .map(|(i, s)| (i, s.label.clone()))
            .collect();
        let label_w = entries
            .iter()
            .map(|(_, l)| text_width(l, LEGEND))
            .fold(0.0, f64::max);
        let max_column_w = 0.3 * w;
        let mut column_w = 16.0 + SWATCH + 6.0 + label_w;
        let mut right_legend = !entries.is_empty() && column_w <= max_column_w;
        let mut below: Vec<(f64, usize)> = Vec::new();
        if !entries.is_empty() && !right_legend {
            let (mut x, mut row) = (0.0, 0);
            for (_, l) in &entries {
                let item = SWATCH + 6.0 + text_width(l, LEGEND);
                if x > 0.0 && x + item > w - 2.0 * PAD - 60.0 {
                    x = 0.0;
                    row += 1;
                }
                below.push((x, row));
                x += item + 20.0;
            }
        }
        let mut below_h = below
            .last()
            .map_or(0.0, |&(_, r)| 6.0 + (r + 1) as f64 * LEGEND_ROW);
        let top = PAD
            + if self.title.is_empty() {
                6.0
            } else {
                TITLE + 10.0
            };
        // Entries a right column holds between the plot's top and the chart's bottom.
        let rows_fit = (((h - PAD - (top + 10.0)) / LEGEND_ROW).floor() as usize).max(1);
        let mut legend_columns = 1;
        if below_h > 0.3 * h || (right_legend && entries.len() > rows_fit) {
            // Long labels or many series: right columns of shortened labels, as many columns
            // as the entries need, sharing the right 30 % of the chart (50 % for several
            // columns, so that labels keep a few characters).
            below.clear();
            below_h = 0.0;
            right_legend = true;
            legend_columns = entries.len().div_ceil(rows_fit);
            let share = if legend_columns > 1 {
                0.5 * w
            } else {
                max_column_w
            };
            column_w = (share / legend_columns as f64).min(column_w);
            let text_room = column_w - (16.0 + SWATCH + 6.0);
            if text_room < 3.0 * LEGEND {
                return Err(RenderError::Input(format!(
                    "LineChart: {} legend entries do not fit in a {}x{} chart; make it taller \
                     or wider, or give some series an empty label",
                    entries.len(),
                    self.width,
                    self.height
                )));
            }
            for (_, l) in &mut entries {
                *l = shorten(l, text_room, LEGEND);
            }
        }
        let x_label_h = if self.x_label.is_empty() {
            0.0
        } else {
            8.0 + LABEL
        };
        let bottom = h - PAD - below_h - x_label_h - (TICK_LEN + 3.0 + CAP * TICK);
        let plot_h = (bottom - top).floor();
        let y_ticks = ((plot_h / 32.0) as usize + 1).clamp(2, 8);
        let y = Axis::new(self.y_scale, range[2], range[3], y_ticks)?;
        let y_tick_w = y
            .major
            .iter()
            .map(|t| text_width(&t.label, TICK))
            .fold(0.0, f64::max);
        let y_label_w = if self.y_label.is_empty() {
            0.0
        } else {
            LABEL + 10.0
        };
        let left = (PAD + y_label_w + y_tick_w + 4.0 + TICK_LEN).ceil();
        let mut right = w
            - PAD
            - if right_legend {
                column_w * legend_columns as f64
            } else {
                0.0
            };
        if right - left < 60.0 || plot_h < 40.0 {
            return Err(RenderError::Input(format!(
                "LineChart: a {}x{} chart is too small for its labels and legend \
                 (the plot area would be {:.0}x{plot_h:.0})",
                self.width,
                self.height,
                right - left
            )));
        }
        // The most x ticks whose labels do not run into each other.
        let mut x_axis = None;
        for n in (2..=8).rev() {
            let axis = Axis::new(self.x_scale, range[0], range[1], n)?;
            let fits = axis.major.windows(2).all(|p| {
                let gap = (axis.frac(p[1].value) - axis.frac(p[0].value)) * (right - left);
                gap >= (text_width(&p[0].label, TICK) + text_width(&p[1].label, TICK)) / 2.0 + 12.0
            });
            let done = fits || n == 2;
            x_axis = Some(axis);
            if done {
                break;
            }
        }
        let x = x_axis.expect("the loop runs at least once");
        if !right_legend && let Some(last) = x.major.last() {
            right = right.min(w - PAD - text_width(&last.label, TICK) / 2.0);
        }
        let right = right.floor();
        let legend = if entries.is_empty() {
            Legend::None
        } else if right_legend {
            Legend::Right {
                x: right + 16.0,
                rows: entries.len().div_ceil(legend_columns),
                column_w,
            }
        } else {
            Legend::Below {
                y: h - PAD - below_h + 6.0,
                places: below,
            }
        };
        Ok(Layout {
            left: left + 0.5,
            top: top.round() + 0.5,
            width: right - left,
            height: plot_h,
            x,
            y,
            entries,
            legend,
        })
    }

    /// The plot frame `[left, top, width, height]` in pixels of the SVG and PNG: the data range
    /// (extended to the outer ticks) fills it exactly.
    pub fn plot_rect(&self) -> Result<[f64; 4]> {
        let l = self.layout(&self.drawable())?;
        Ok([l.left, l.top, l.width, l.height])
    }

    /// The chart as a self-contained SVG document of `width` x `height` pixels.
    ///
    /// Errors ([`RenderError::Input`]) when no point can be drawn (none is finite, or positive
    /// on a log axis) or when the size is too small for the axes and labels (under 200x150).
    pub fn to_svg(&self) -> Result<String> {
        let data = self.drawable();
        let l = self.layout(&data)?;
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let n_points: usize = data.iter().map(Vec::len).sum();
        let mut out = String::with_capacity(4096 + n_points * 16);
        open_svg(&mut out, w, h);
        let (left, top, right, bottom) = (l.left, l.top, l.left + l.width, l.top + l.height);

        // Grid lines: minor first, so major ones are drawn over them.
        out.push_str("<g class=\"grid\" fill=\"none\" stroke-width=\"1\">\n");
        let vline = |out: &mut String, x: f64, color: &str| {
            let x = num(snap(x));
            let _ = writeln!(
                out,
                "<line x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"{color}\"/>",
                num(top),
                num(bottom)
            );
        };
        for &v in &l.x.minor {
            vline(&mut out, l.px(v), GRID_MINOR);
        }
        for t in &l.x.major {
            vline(&mut out, l.px(t.value), GRID);
        }
        let hline = |out: &mut String, y: f64, color: &str| {
            let y = num(snap(y));
            let _ = writeln!(
                out,
                "<line x1=\"{}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"{color}\"/>",
                num(left),
                num(right)
            );
        };
        for &v in &l.y.minor {
            hline(&mut out, l.py(v), GRID_MINOR);
        }
        for t in &l.y.major {
            hline(&mut out, l.py(t.value), GRID);
        }
        if l.x.scale == Scale::Linear && l.x.lo < 0.0 && l.x.hi > 0.0 {
            vline(&mut out, l.px(0.0), ZERO);
        }
        if l.y.scale == Scale::Linear && l.y.lo < 0.0 && l.y.hi > 0.0 {
            hline(&mut out, l.py(0.0), ZERO);
        }
        out.push_str("</g>\n");

        // Curves, one path each, then markers.
        for (i, points) in data.iter().enumerate() {
            let mut d = String::with_capacity(points.len() * 16);
            let mut run = 0usize;
            for p in points {
                match *p {
                    Some((x, y)) => {
                        d.push(if run == 0 { 'M' } else { 'L' });
                        push_num(&mut d, l.px(x));
                        d.push(' ');
                        push_num(&mut d, l.py(y));
                        run += 1;
                    }
                    None => {
                        if run == 1 {
                            d.push_str("h0");
                        }
                        run = 0;
                    }
                }
            }
            if run == 1 {
                d.push_str("h0");
            }
            if d.is_empty() {
                continue;
            }
            let _ = write!(
                out,
                "<path class=\"series\" d=\"{d}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{}\" \
                 stroke-linejoin=\"round\" stroke-linecap=\"round\"",
                hex(series_color(i)),
                num(LINE_WIDTH)
            );
            if let Some(dash) = series_dash(i) {
                let _ = write!(out, " stroke-dasharray=\"{dash}\"");
            }
            out.push_str("/>\n");
        }
        if self.markers {
            for (i, points) in data.iter().enumerate() {
                let mut d = String::new();
                for &(x, y) in points.iter().flatten() {
                    marker(&mut d, i, l.px(x), l.py(y));
                }
                if !d.is_empty() {
                    let _ = writeln!(
                        out,
                        "<path class=\"markers\" d=\"{d}\" fill=\"{}\" stroke=\"#ffffff\" \
                         stroke-width=\"0.75\"/>",
                        hex(series_color(i))
                    );
                }
            }
        }

        // Frame, ticks and tick labels.
        let _ = writeln!(
            out,
            "<rect class=\"frame\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" \
             stroke=\"{FRAME}\" stroke-width=\"1\"/>",
            num(left),
            num(top),
            num(l.width),
            num(l.height)
        );
        let mut ticks = String::new();
        let mut tick = |x1: f64, y1: f64, x2: f64, y2: f64| {
            let _ = write!(ticks, "M{} {}L{} {}", num(x1), num(y1), num(x2), num(y2));
        };
        for t in &l.x.major {
            let x = snap(l.px(t.value));
            tick(x, bottom, x, bottom + TICK_LEN);
        }
        for &v in &l.x.minor {
            let x = snap(l.px(v));
            tick(x, bottom, x, bottom + TICK_LEN * 0.6);
        }
        for t in &l.y.major {
            let y = snap(l.py(t.value));
            tick(left, y, left - TICK_LEN, y);
        }
        for &v in &l.y.minor {
            let y = snap(l.py(v));
            tick(left, y, left - TICK_LEN * 0.6, y);
        }
        let _ = writeln!(
            out,
            "<path class=\"ticks\" d=\"{ticks}\" fill=\"none\" stroke=\"{FRAME}\" stroke-width=\"1\"/>"
        );
        let x_tick_base = bottom + TICK_LEN + 3.0 + CAP * TICK;
        for t in &l.x.major {
            Text::new(&t.label, l.px(t.value), x_tick_base, TICK)
                .anchor(Anchor::Middle)
                .class("tick")
                .write(&mut out);
        }
        for t in &l.y.major {
            Text::new(
                &t.label,
                left - TICK_LEN - 4.0,
                l.py(t.value) + CENTER * TICK,
                TICK,
            )
            .anchor(Anchor::End)
            .class("tick")
            .write(&mut out);
        }

        // Axis labels and title.
        let x_label_base = x_tick_base + 8.0 + 0.8 * LABEL;
        Text::new(&self.x_label, left + l.width / 2.0, x_label_base, LABEL)
            .anchor(Anchor::Middle)
            .class("x-label")
            .write(&mut out);
        Text::new(
            &self.y_label,
            PAD + 0.8 * LABEL,
            top + l.height / 2.0,
            LABEL,
        )
        .anchor(Anchor::Middle)
        .rotate(-90.0)
        .class("y-label")
        .write(&mut out);
        if !self.title.is_empty() {
            let tw = text_width(&self.title, TITLE);
            let size = if tw > w - 2.0 * PAD {
                (TITLE * (w - 2.0 * PAD) / tw).max(8.0)
            } else {
                TITLE
            };
            let half = tw * size / TITLE / 2.0;
            let cx = (left + l.width / 2.0).clamp(PAD + half, (w - PAD - half).max(PAD + half));
            Text::new(&self.title, cx, PAD + 0.8 * TITLE, size)
                .anchor(Anchor::Middle)
                .class("title")
                .write(&mut out);
        }

        // Legend.
        let entry = |out: &mut String, i: usize, label: &str, x: f64, cy: f64| {
            let cy = snap(cy);
            let color = hex(series_color(i));
            let _ = write!(
                out,
                "<path d=\"M{} {}h{}\" fill=\"none\" stroke=\"{color}\" stroke-width=\"{}\" \
                 stroke-linecap=\"butt\"",
                num(x),
                num(cy),
                num(SWATCH),
                num(LINE_WIDTH + 0.25)
            );
            if let Some(dash) = series_dash(i) {
                let _ = write!(out, " stroke-dasharray=\"{dash}\"");
            }
            out.push_str("/>\n");
            if self.markers {
                let mut d = String::new();
                marker(&mut d, i, x + SWATCH / 2.0, cy);
                let _ = writeln!(
                    out,
                    "<path d=\"{d}\" fill=\"{color}\" stroke=\"#ffffff\" stroke-width=\"0.75\"/>"
                );
            }
            Text::new(label, x + SWATCH + 6.0, cy + CENTER * LEGEND, LEGEND)
                .class("legend")
                .write(out);
        };
        match &l.legend {
            Legend::None => {}
            Legend::Right { x, rows, column_w } => {
                out.push_str("<g class=\"legend\">\n");
                for (k, (i, label)) in l.entries.iter().enumerate() {
                    let (column, row) = (k / rows, k % rows);
                    let ex = x + column as f64 * column_w;
                    entry(
                        &mut out,
                        *i,
                        label,
                        ex,
                        top + 10.0 + row as f64 * LEGEND_ROW,
                    );
                }
                out.push_str("</g>\n");
            }
            Legend::Below { y, places } => {
                out.push_str("<g class=\"legend\">\n");
                for ((i, label), (dx, row)) in l.entries.iter().zip(places) {
                    let cy = y + (*row as f64 + 0.5) * LEGEND_ROW;
                    entry(&mut out, *i, label, left + dx, cy);
                }
                out.push_str("</g>\n");
            }
        }
        out.push_str("</svg>\n");
        Ok(out)
    }

    /// The chart rendered from [`LineChart::to_svg`] with the carried font, `width` x `height`
    /// pixels.
    pub fn to_png(&self) -> Result<Image> {
        super::svg_to_png(&self.to_svg()?)
    }
}

/// `text`, cut and ended with an ellipsis to fit `width` pixels at font `size`.
fn shorten(text: &str, width: f64, size: f64) -> String {
    if text_width(text, size) <= width {
        return text.to_string();
    }
    let mut s: String = text.to_string();
    while !s.is_empty() && text_width(&s, size) + text_width("…", size) > width {
        s.pop();
    }
    s.truncate(s.trim_end().len());
    s.push('…');
    s
}

/// Appends the marker of series `i` centred at `(x, y)`: circle, square, triangle, diamond,
/// downward triangle, cycled.
fn marker(d: &mut String, i: usize, x: f64, y: f64) {
    let r = 3.2;
    let p = |d: &mut String, c: char, x: f64, y: f64| {
        d.push(c);
        push_num(d, x);
        d.push(' ');
        push_num(d, y);
    };
    match i % 5 {
        0 => {
            p(d, 'M', x - r, y);
            let _ = write!(
                d,
                "a{r} {r} 0 1 0 {} 0a{r} {r} 0 1 0 {} 0Z",
                2.0 * r,
                -2.0 * r
            );
        }
        1 => {
            let s = r * 0.85;
            p(d, 'M', x - s, y - s);
            let _ = write!(d, "h{}v{}h{}Z", num(2.0 * s), num(2.0 * s), num(-2.0 * s));
        }
        2 => {
            let s = r * 1.2;
            p(d, 'M', x, y - s);
            p(d, 'L', x + s * 0.866, y + s * 0.5);
            p(d, 'L', x - s * 0.866, y + s * 0.5);
            d.push('Z');
        }
        3 => {
            let s = r * 1.15;
            p(d, 'M', x, y - s);
            p(d, 'L', x + s, y);
            p(d, 'L', x, y + s);
            p(d, 'L', x - s, y);
            d.push('Z');
        }
        _ => {
            let s = r * 1.2;
            p(d, 'M', x, y + s);
            p(d, 'L', x + s * 0.866, y - s * 0.5);
            p(d, 'L', x - s * 0.866, y - s * 0.5);
            d.push('Z');
        }
    }
}
