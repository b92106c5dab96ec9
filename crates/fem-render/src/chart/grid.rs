//! The grid chart: a table of coloured cells with row headers on the left, column headers on
//! top (rotated when they are wider than a cell), axis labels and a legend below.

use std::fmt::Write;

use super::GridChart;
use super::svg::{Anchor, CENTER, Text, escape, hex, num, open_svg, text_color_on, text_width};
use crate::{Image, RenderError, Result};

const PAD: f64 = 12.0;
const TITLE: f64 = 16.0;
const LABEL: f64 = 13.0;
const HEAD: f64 = 11.5;
const LEGEND: f64 = 12.0;
const LEGEND_ROW: f64 = 20.0;
const SWATCH: f64 = 13.0;
/// Cap height of DejaVu Sans per pixel of font size.
const CAP: f64 = 0.73;
const SIN45: f64 = std::f64::consts::FRAC_1_SQRT_2;
const MIN_CELL: u32 = 4;

struct Layout {
    /// Top-left corner of the grid.
    x0: f64,
    y0: f64,
    cw: f64,
    ch: f64,
    width: f64,
    height: f64,
    /// Column headers at -45 degrees (else horizontal).
    rotated: bool,
    title_y: f64,
    x_label_y: f64,
    /// Legend entries: `(x, row)`, rows from `legend_y`.
    legend: Vec<(f64, usize)>,
    legend_y: f64,
}

impl GridChart {
    fn layout(&self) -> Layout {
        let (cw, ch) = (
            f64::from(self.cell_size.0.max(1)),
            f64::from(self.cell_size.1.max(1)),
        );
        let (ncols, nrows) = (self.columns.len() as f64, self.rows.len() as f64);
        let head_w: Vec<f64> = self.columns.iter().map(|c| text_width(c, HEAD)).collect();
        let head_max = head_w.iter().copied().fold(0.0, f64::max);
        let rotated = head_max > cw - 6.0;
        let header_h = if rotated {
            head_max * SIN45 + CAP * HEAD + 8.0
        } else {
            HEAD + 6.0
        };
        let row_w = self
            .rows
            .iter()
            .map(|r| text_width(r, HEAD))
            .fold(0.0, f64::max);
        let y_label_w = if self.y_label.is_empty() {
            0.0
        } else {
            LABEL + 10.0
        };
        let x0 = (PAD + y_label_w + row_w + 8.0).ceil();
        let mut y = PAD;
        let title_y = y + 0.8 * TITLE;
        if !self.title.is_empty() {
            y += TITLE + 10.0;
        }
        let x_label_y = y + 0.8 * LABEL;
        if !self.x_label.is_empty() {
            y += LABEL + 8.0;
        }
        let y0 = (y + header_h).ceil();
        let grid_w = ncols * cw;
        let grid_h = nrows * ch;
        // Rotated headers stick out to the right of their column.
        let overhang = if rotated {
            head_w
                .iter()
                .enumerate()
                .map(|(c, w)| (c as f64 + 0.5) * cw + (w + HEAD * 0.5) * SIN45 - grid_w)
                .fold(0.0, f64::max)
        } else {
            0.0
        };
        let mut width = x0 + grid_w + overhang + PAD;
        width = width.max(text_width(&self.title, TITLE) + 2.0 * PAD);
        width = width.max(x0 + text_width(&self.x_label, LABEL) + PAD);
        // Legend rows, wrapped to the chart width (or to 640 px when the grid is narrower).
        let items: Vec<f64> = self
            .legend
            .iter()
            .map(|(l, _)| SWATCH + 6.0 + text_width(l, LEGEND))
            .collect();
        let one_row: f64 = items.iter().map(|w| w + 18.0).sum::<f64>() - 18.0;
        let avail = (width - 2.0 * PAD).max(one_row.min(640.0));
        let mut legend = Vec::with_capacity(items.len());
        let (mut x, mut row) = (0.0, 0);
        for w in &items {
            if x > 0.0 && x + w > avail {
                x = 0.0;
                row += 1;
            }
            legend.push((PAD + x, row));
            x += w + 18.0;
        }
        let legend_w = legend
            .iter()
            .zip(&items)
            .map(|(&(x, _), w)| x + w)
            .fold(0.0, f64::max);
        width = width.max(legend_w + PAD);
        // Under the grid when it fits there.
        if legend_w + x0 - PAD <= width - PAD {
            for (x, _) in &mut legend {
                *x += x0 - PAD;
            }
        }
        let legend_y = y0 + grid_h + 12.0;
        let height = if legend.is_empty() {
            y0 + grid_h + PAD
        } else {
            legend_y + (row + 1) as f64 * LEGEND_ROW + PAD - 4.0
        };
        Layout {
            x0,
            y0,
            cw,
            ch,
            width: width.ceil(),
            height: height.ceil(),
            rotated,
            title_y,
            x_label_y,
            legend,
            legend_y,
        }
    }

    /// The filled rectangle `[x, y, width, height]` of cell `(row, col)` in pixels of the SVG
    /// and the PNG (cells are `cell_size` apart; the last pixel column and row of each slot is a
    /// white separator). Indexes past the grid give the rectangle where such a cell would be.
    pub fn cell_rect(&self, row: usize, col: usize) -> [f64; 4] {
        let l = self.layout();
        [
            l.x0 + col as f64 * l.cw,
            l.y0 + row as f64 * l.ch,
            (l.cw - 1.0).max(1.0),
            (l.ch - 1.0).max(1.0),
        ]
    }

    /// The total size `(width, height)` in pixels the chart will have.
    pub fn size(&self) -> (u32, u32) {
        let l = self.layout();
        (l.width as u32, l.height as u32)
    }

    fn check(&self) -> Result<()> {
        let (r, c) = (self.rows.len(), self.columns.len());
        if r == 0 || c == 0 {
            return Err(RenderError::Input(format!(
                "GridChart: nothing to draw with {r} rows x {c} columns"
            )));
        }
        if self.cells.len() != r {
            return Err(RenderError::Input(format!(
                "GridChart: cells has {} rows but there are {r} row headers \
                 (cells must be {r} x {c}, rows x columns)",
                self.cells.len()
            )));
        }
        if let Some((i, bad)) = self.cells.iter().enumerate().find(|(_, v)| v.len() != c) {
            return Err(RenderError::Input(format!(
                "GridChart: cells[{i}] has {} cells but there are {c} column headers \
                 (cells must be {r} x {c}, rows x columns)",
                bad.len()
            )));
        }
        let (cw, ch) = self.cell_size;
        if cw < MIN_CELL || ch < MIN_CELL {
            return Err(RenderError::Input(format!(
                "GridChart: a cell of {cw}x{ch} pixels is too small \
                 (at least {MIN_CELL}x{MIN_CELL})"
            )));
        }
        Ok(())
    }

    /// The chart as a self-contained SVG document (its size is [`GridChart::size`]).
    ///
    /// Errors ([`RenderError::Input`]) when `cells` is not `rows.len()` x `columns.len()`
    /// (the message names both sizes), when there is no row or no column, or when `cell_size`
    /// is under 4x4.
    pub fn to_svg(&self) -> Result<String> {
        self.check()?;
        let l = self.layout();
        let mut out = String::with_capacity(2048 + self.rows.len() * self.columns.len() * 200);
        open_svg(&mut out, l.width, l.height);
        let grid_w = self.columns.len() as f64 * l.cw;
        let grid_h = self.rows.len() as f64 * l.ch;

        if !self.title.is_empty() {
            let half = text_width(&self.title, TITLE) / 2.0;
            let cx =
                (l.x0 + grid_w / 2.0).clamp(PAD + half, (l.width - PAD - half).max(PAD + half));
            Text::new(&self.title, cx, l.title_y, TITLE)
                .anchor(Anchor::Middle)
                .class("title")
                .write(&mut out);
        }
        let half = text_width(&self.x_label, LABEL) / 2.0;
        let cx = (l.x0 + grid_w / 2.0).clamp(l.x0 + half, (l.width - PAD - half).max(l.x0 + half));
        Text::new(&self.x_label, cx, l.x_label_y, LABEL)
            .anchor(Anchor::Middle)
            .class("x-label")
            .write(&mut out);
        Text::new(&self.y_label, PAD + 0.8 * LABEL, l.y0 + grid_h / 2.0, LABEL)
            .anchor(Anchor::Middle)
            .rotate(-90.0)
            .class("y-label")
            .write(&mut out);

        for (c, head) in self.columns.iter().enumerate() {
            let cx = l.x0 + (c as f64 + 0.5) * l.cw;
            let t = if l.rotated {
                Text::new(head, cx - 0.2 * HEAD, l.y0 - 6.0, HEAD).rotate(-45.0)
            } else {
                Text::new(head, cx, l.y0 - 6.0, HEAD).anchor(Anchor::Middle)
            };
            t.class("column").write(&mut out);
        }
        for (r, head) in self.rows.iter().enumerate() {
            let cy = l.y0 + (r as f64 + 0.5) * l.ch - 0.5;
            Text::new(head, l.x0 - 8.0, cy + CENTER * HEAD, HEAD)
                .anchor(Anchor::End)
                .class("row")
                .write(&mut out);
        }

        out.push_str("<g class=\"cells\">\n");
        let (fw, fh) = ((l.cw - 1.0).max(1.0), (l.ch - 1.0).max(1.0));
        for (r, cells) in self.cells.iter().enumerate() {
            for (c, cell) in cells.iter().enumerate() {
                let (x, y) = (l.x0 + c as f64 * l.cw, l.y0 + r as f64 * l.ch);
                let _ = write!(
                    out,
                    "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"><title>{}, {}",
                    num(x),
                    num(y),
                    num(fw),
                    num(fh),
                    hex(cell.color),
                    escape(&self.rows[r]),
                    escape(&self.columns[c]),
                );
                if !cell.text.is_empty() {
                    let _ = write!(out, ": {}", escape(&cell.text));
                }
                out.push_str("</title></rect>\n");
                if cell.text.is_empty() {
                    continue;
                }
                let mut size = (l.ch * 0.5).min(11.5);
                let tw = text_width(&cell.text, size);
                if tw > fw - 4.0 {
                    size = (size * (fw - 4.0) / tw).max(6.0);
                }
                let fill = hex(text_color_on(cell.color));
                Text::new(&cell.text, x + fw / 2.0, y + fh / 2.0 + CENTER * size, size)
                    .anchor(Anchor::Middle)
                    .fill(&fill)
                    .class("cell")
                    .write(&mut out);
            }
        }
        out.push_str("</g>\n");

        if !self.legend.is_empty() {
            out.push_str("<g class=\"legend\">\n");
            for ((label, color), &(x, row)) in self.legend.iter().zip(&l.legend) {
                let cy = l.legend_y + (row as f64 + 0.5) * LEGEND_ROW;
                let top = (cy - SWATCH / 2.0).round();
                let _ = writeln!(
                    out,
                    "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" \
                     stroke=\"#000000\" stroke-opacity=\"0.3\" stroke-width=\"1\"/>",
                    num(x.round() + 0.5),
                    num(top + 0.5),
                    num(SWATCH - 1.0),
                    num(SWATCH - 1.0),
                    hex(*color)
                );
                Text::new(
                    label,
                    x + SWATCH + 6.0,
                    top + SWATCH / 2.0 + CENTER * LEGEND,
                    LEGEND,
                )
                .class("legend")
                .write(&mut out);
            }
            out.push_str("</g>\n");
        }
        out.push_str("</svg>\n");
        Ok(out)
    }

    /// The chart rendered from [`GridChart::to_svg`] with the carried font.
    pub fn to_png(&self) -> Result<Image> {
        super::svg_to_png(&self.to_svg()?)
    }
}
