//! A small log-log line chart in SVG (axes with decade ticks, one coloured polyline with
//! markers per series, a legend), for the plots `cargo xtask stability` writes. Hand-written
//! because xtask depends on no workspace crate (the charts of `fem-render` need one).

use std::fmt::Write as _;

/// One line of the chart.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points `(x, y)`, both > 0 (others are skipped).
    pub points: Vec<(f64, f64)>,
}

const COLOURS: [&str; 12] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#393b79", "#ad494a",
];
const DASHES: [&str; 3] = ["", "6 3", "2 2"];

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The decade range `[10^a, 10^b]` covering `values` (at least one decade).
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0, 1);
    }
    let a = lo.log10().floor() as i32;
    let b = (hi.log10().ceil() as i32).max(a + 1);
    (a, b)
}

/// A log-log chart, `width` x `height` pixels plus the legend column.
pub fn loglog(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    let (w, h) = (620.0, 420.0);
    let (left, top, legend) = (80.0, 40.0, 250.0);
    let (pw, ph) = (w - left - 20.0, h - top - 60.0);
    let all = || series.iter().flat_map(|s| s.points.iter().copied());
    let (xa, xb) = decades(all().map(|p| p.0));
    let (ya, yb) = decades(all().map(|p| p.1));
    let px = |x: f64| left + (x.log10() - xa as f64) / (xb - xa) as f64 * pw;
    let py = |y: f64| top + ph - (y.log10() - ya as f64) / (yb - ya) as f64 * ph;
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{h}" viewBox="0 0 {} {h}" font-family="DejaVu Sans, Arial, sans-serif" font-size="12">"#,
        w + legend,
        w + legend
    );
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        out,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="14" font-weight="bold">{}</text>"#,
        left + pw / 2.0,
        escape(title)
    );
    for d in xa..=xb {
        let x = px(10f64.powi(d));
        let _ = writeln!(
            out,
            r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">1e{d}</text>"##,
            top + ph,
            top + ph + 16.0
        );
    }
    for d in ya..=yb {
        let y = py(10f64.powi(d));
        let _ = writeln!(
            out,
            r##"<line x1="{left}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">1e{d}</text>"##,
            left + pw,
            left - 6.0,
            y + 4.0
        );
    }
    let _ = writeln!(
        out,
        r#"<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#
    );
    let _ = writeln!(
        out,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        left + pw / 2.0,
        top + ph + 40.0,
        escape(x_label)
    );
    let _ = writeln!(
        out,
        r#"<text x="18" y="{}" text-anchor="middle" transform="rotate(-90 18 {})">{}</text>"#,
        top + ph / 2.0,
        top + ph / 2.0,
        escape(y_label)
    );
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let dash = DASHES[(k / COLOURS.len()) % DASHES.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
            .collect();
        if pts.len() > 1 {
            let path: Vec<String> = pts
                .iter()
                .map(|p| format!("{:.1},{:.1}", px(p.0), py(p.1)))
                .collect();
            let _ = writeln!(
                out,
                r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="1.8" stroke-dasharray="{dash}"/>"#,
                path.join(" ")
            );
        }
        for p in &pts {
            let _ = writeln!(
                out,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{colour}"/>"#,
                px(p.0),
                py(p.1)
            );
        }
        let ly = top + 14.0 + 18.0 * k as f64;
        let _ = writeln!(
            out,
            r#"<line x1="{}" y1="{ly}" x2="{}" y2="{ly}" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/><text x="{}" y="{}">{}</text>"#,
            w + 5.0,
            w + 30.0,
            w + 36.0,
            ly + 4.0,
            escape(&s.label)
        );
    }
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chart_has_a_line_per_series_and_decade_ticks() {
        let svg = loglog(
            "t",
            "x",
            "y",
            &[
                Series {
                    label: "a<b".into(),
                    points: vec![(1.0, 10.0), (100.0, 1000.0)],
                },
                Series {
                    label: "c".into(),
                    points: vec![(2.0, 0.0), (3.0, 20.0), (4.0, 30.0)],
                },
            ],
        );
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("a&lt;b"));
        assert!(svg.contains(">1e0<") && svg.contains(">1e2<") && svg.contains(">1e3<"));
        // The zero point is skipped, not drawn at infinity.
        assert_eq!(svg.matches("<circle").count(), 4);
    }
}
