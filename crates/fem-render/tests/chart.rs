//! Tests of the line and grid charts: SVG structure, ticks, PNG rendering with the carried font.

use fem_render::chart::{
    GridCell, GridChart, LineChart, Scale, Series, axis_ticks, series_color, svg_to_png,
    text_color_on,
};
use fem_render::{Image, RenderError};

/// Three probe curves (damped oscillations) with `n` points each, over t in [0, 2] s.
fn probe_chart(n: usize) -> LineChart {
    let series = [(1.0, "E = 1 kJ"), (0.6, "E = 10 kJ"), (1.37, "E = 100 kJ")]
        .iter()
        .map(|&(a, label)| Series {
            label: label.to_string(),
            points: (0..n)
                .map(|i| {
                    let t = 2.0 * i as f64 / (n - 1) as f64;
                    (t, -a * (1.0 - (-2.0 * t).exp() * (9.0 * t / a).cos()))
                })
                .collect(),
        })
        .collect();
    LineChart {
        title: "Tip vertical displacement".to_string(),
        x_label: "time [s]".to_string(),
        y_label: "u_y at the tip [m]".to_string(),
        series,
        ..LineChart::default()
    }
}

/// A 12 x 13 stability map with three categories and a short text in some cells.
fn stability_grid() -> GridChart {
    let stable = [0x4c, 0xaf, 0x50];
    let blew_up = [0xd7, 0x30, 0x27];
    let slow = [0xfe, 0xe0, 0x8b];
    let columns: Vec<String> = (0..13)
        .map(|c| format!("{}", [1e-4, 2e-4, 5e-4][c % 3] * 10f64.powi(c as i32 / 3)))
        .collect();
    let mut rows = Vec::new();
    for e in ["1 J", "10 J", "100 J"] {
        for y in ["1 MPa", "10 MPa", "100 MPa", "1 GPa"] {
            rows.push(format!("{e}, {y}"));
        }
    }
    let cells = (0..rows.len())
        .map(|r| {
            (0..columns.len())
                .map(|c| {
                    if c + r / 2 > 10 {
                        GridCell {
                            color: blew_up,
                            text: "NaN".to_string(),
                        }
                    } else if c + r / 3 > 8 {
                        GridCell {
                            color: slow,
                            text: format!("{}", 40 + r + c),
                        }
                    } else {
                        GridCell {
                            color: stable,
                            text: String::new(),
                        }
                    }
                })
                .collect()
        })
        .collect();
    GridChart {
        title: "Stability of the explicit solver".to_string(),
        x_label: "time step [s]".to_string(),
        y_label: "energy, Young's modulus".to_string(),
        columns,
        rows,
        cells,
        legend: vec![
            ("stable".to_string(), stable),
            ("slow (iterations shown)".to_string(), slow),
            ("blew up".to_string(), blew_up),
        ],
        ..GridChart::default()
    }
}

/// All text content of the SVG, one string per `<text>` element.
fn texts(doc: &roxmltree::Document) -> Vec<String> {
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| n.text().unwrap_or("").to_string())
        .collect()
}

fn with_class(doc: &roxmltree::Document, tag: &str, class: &str) -> usize {
    doc.descendants()
        .filter(|n| n.has_tag_name(tag) && n.attribute("class") == Some(class))
        .count()
}

fn near(p: [u8; 4], c: [u8; 3], tol: i32) -> bool {
    (0..3).all(|i| (i32::from(p[i]) - i32::from(c[i])).abs() <= tol) && p[3] == 255
}

/// Pixels of `img` within the rectangle `[x0, x1) x [y0, y1)` that satisfy `f`.
fn count(
    img: &Image,
    (x0, x1, y0, y1): (u32, u32, u32, u32),
    f: impl Fn([u8; 4]) -> bool,
) -> usize {
    let mut n = 0;
    for y in y0..y1.min(img.height()) {
        for x in x0..x1.min(img.width()) {
            if f(img.pixel(x, y)) {
                n += 1;
            }
        }
    }
    n
}

fn all(img: &Image) -> (u32, u32, u32, u32) {
    (0, img.width(), 0, img.height())
}

fn dark(p: [u8; 4]) -> bool {
    p[3] > 200 && p[0] < 110 && p[1] < 110 && p[2] < 110
}

#[test]
fn line_svg_has_size_title_labels_and_one_path_per_series() {
    let mut chart = probe_chart(200);
    chart.width = 800;
    chart.height = 450;
    let svg = chart.to_svg().unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!(root.attribute("width"), Some("800"));
    assert_eq!(root.attribute("height"), Some("450"));
    assert!(
        root.attribute("font-family")
            .unwrap()
            .contains("DejaVu Sans")
    );
    let t = texts(&doc);
    for want in [
        "Tip vertical displacement",
        "time [s]",
        "u_y at the tip [m]",
        "E = 1 kJ",
        "E = 10 kJ",
        "E = 100 kJ",
    ] {
        assert!(t.iter().any(|s| s == want), "{want:?} missing from {t:?}");
    }
    assert_eq!(with_class(&doc, "path", "series"), 3);
    assert_eq!(with_class(&doc, "path", "markers"), 0);
    // The curve colours are the palette's, in order.
    let strokes: Vec<&str> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("series"))
        .map(|n| n.attribute("stroke").unwrap())
        .collect();
    assert_eq!(strokes, ["#0072b2", "#d55e00", "#009e73"]);
}

#[test]
fn text_is_escaped_and_markers_are_drawn() {
    let chart = LineChart {
        title: "a < b & c > d".to_string(),
        x_label: "x \"quoted\" 'single'".to_string(),
        series: vec![
            Series {
                label: "<script>".to_string(),
                points: vec![(0.0, 1.0), (1.0, 2.0), (2.0, 1.5)],
            },
            Series {
                label: String::new(),
                points: vec![(0.0, 0.0), (1.0, 1.0)],
            },
        ],
        markers: true,
        ..LineChart::default()
    };
    let svg = chart.to_svg().unwrap();
    assert!(!svg.contains("<script>"));
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let t = texts(&doc);
    assert!(t.iter().any(|s| s == "a < b & c > d"), "{t:?}");
    assert!(t.iter().any(|s| s == "x \"quoted\" 'single'"), "{t:?}");
    assert!(t.iter().any(|s| s == "<script>"), "{t:?}");
    assert_eq!(with_class(&doc, "path", "series"), 2);
    assert_eq!(with_class(&doc, "path", "markers"), 2);
    // Only the labelled series is in the legend.
    assert_eq!(with_class(&doc, "text", "legend"), 1);
}

#[test]
fn non_finite_points_break_the_line_and_log_axes_skip_non_positive_values() {
    let chart = LineChart {
        series: vec![Series {
            label: "s".to_string(),
            points: vec![
                (0.0, 1.0),
                (1.0, 2.0),
                (2.0, f64::NAN),
                (3.0, 3.0),
                (4.0, 1.0),
                (f64::INFINITY, 1.0),
                (5.0, 2.0),
                (6.0, 4.0),
            ],
        }],
        ..LineChart::default()
    };
    let svg = chart.to_svg().unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let d = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("series"))
        .unwrap()
        .attribute("d")
        .unwrap();
    assert_eq!(d.matches('M').count(), 3, "{d}");
    assert_eq!(d.matches('L').count(), 3, "{d}");

    let log = LineChart {
        y_scale: Scale::Log,
        series: vec![Series {
            label: "s".to_string(),
            points: vec![(0.0, 1e-3), (1.0, 0.0), (2.0, -1.0), (3.0, 1e-1)],
        }],
        ..LineChart::default()
    };
    let svg = log.to_svg().unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let d = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("series"))
        .unwrap()
        .attribute("d")
        .unwrap();
    assert_eq!(
        (d.matches('M').count(), d.matches('L').count()),
        (1, 1),
        "{d}"
    );
    let t = texts(&doc);
    for want in ["10⁻³", "10⁻²", "10⁻¹"] {
        assert!(t.iter().any(|s| s == want), "{want} missing from {t:?}");
    }
}

fn is_nice_step(step: f64) -> bool {
    let k = step.log10().floor();
    let m = step / 10f64.powf(k);
    [1.0, 2.0, 5.0, 10.0].iter().any(|n| (m - n).abs() < 1e-9)
}

#[test]
fn linear_ticks_are_nice_cover_the_data_and_print_without_noise() {
    let ticks = axis_ticks(Scale::Linear, -1.37, 0.2).unwrap();
    let values: Vec<f64> = ticks.iter().map(|t| t.value).collect();
    assert_eq!(values, [-1.5, -1.0, -0.5, 0.0, 0.5]);
    let labels: Vec<&str> = ticks.iter().map(|t| t.label.as_str()).collect();
    assert_eq!(labels, ["−1.5", "−1.0", "−0.5", "0.0", "0.5"]);

    for (lo, hi) in [
        (0.0, 0.9),
        (0.1, 0.7),
        (-3.3e-4, 1.2e-4),
        (0.0, 2.0),
        (1234.0, 98765.0),
        (-7.0, -6.99),
        (5.0, 5.0),
        (0.0, 0.0),
        (2.5e6, 9.1e7),
    ] {
        let ticks = axis_ticks(Scale::Linear, lo, hi).unwrap();
        let v: Vec<f64> = ticks.iter().map(|t| t.value).collect();
        assert!((4..=8).contains(&v.len()), "[{lo}, {hi}]: {v:?}");
        assert!(v[0] <= lo && v[v.len() - 1] >= hi, "[{lo}, {hi}]: {v:?}");
        let step = v[1] - v[0];
        assert!(is_nice_step(step), "[{lo}, {hi}]: step {step} in {v:?}");
        for w in v.windows(2) {
            assert!(((w[1] - w[0]) - step).abs() < step * 1e-9, "{v:?}");
        }
        for t in &ticks {
            assert!(
                t.label.chars().count() <= 7,
                "[{lo}, {hi}]: label {:?}",
                t.label
            );
            let back: f64 = t.label.replace('−', "-").parse().unwrap();
            assert_eq!(back, t.value, "[{lo}, {hi}]: label {:?}", t.label);
        }
    }
    let labels: Vec<String> = axis_ticks(Scale::Linear, 0.1, 0.7)
        .unwrap()
        .into_iter()
        .map(|t| t.label)
        .collect();
    assert!(labels.contains(&"0.3".to_string()), "{labels:?}");
    let labels: Vec<String> = axis_ticks(Scale::Linear, 0.0, 4e-5)
        .unwrap()
        .into_iter()
        .map(|t| t.label)
        .collect();
    assert!(labels.contains(&"1e−5".to_string()), "{labels:?}");
}

#[test]
fn log_ticks_are_decades() {
    let ticks = axis_ticks(Scale::Log, 3e-5, 2e-3).unwrap();
    let values: Vec<f64> = ticks.iter().map(|t| t.value).collect();
    assert_eq!(values, [1e-5, 1e-4, 1e-3, 1e-2]);
    let labels: Vec<&str> = ticks.iter().map(|t| t.label.as_str()).collect();
    assert_eq!(labels, ["10⁻⁵", "10⁻⁴", "10⁻³", "10⁻²"]);

    // Twenty decades: every third one, still covering the data.
    let ticks = axis_ticks(Scale::Log, 1e-12, 1e8).unwrap();
    assert!(ticks.len() <= 8, "{ticks:?}");
    assert!(ticks[0].value <= 1e-12 && ticks[ticks.len() - 1].value >= 1e8);
    // Within one decade: 1, 2, 5, 10.
    let values: Vec<f64> = axis_ticks(Scale::Log, 2.0, 8.0)
        .unwrap()
        .iter()
        .map(|t| t.value)
        .collect();
    assert_eq!(values, [1.0, 2.0, 5.0, 10.0]);

    assert!(matches!(
        axis_ticks(Scale::Log, 0.0, 1.0),
        Err(RenderError::Input(_))
    ));
    assert!(matches!(
        axis_ticks(Scale::Linear, 0.0, f64::NAN),
        Err(RenderError::Input(_))
    ));
}

#[test]
fn line_png_has_the_size_the_series_colours_and_dark_text() {
    let chart = probe_chart(400);
    let img = chart.to_png().unwrap();
    assert_eq!((img.width(), img.height()), (720, 420));
    let non_white = count(&img, all(&img), |p| p[0] < 240 || p[1] < 240 || p[2] < 240);
    assert!(non_white > 3000, "{non_white} non-white pixels");
    let [left, top, width, height] = chart.plot_rect().unwrap();
    let plot = (
        left as u32 + 2,
        (left + width) as u32 - 1,
        top as u32 + 2,
        (top + height) as u32 - 1,
    );
    for i in 0..3 {
        let c = series_color(i);
        let n = count(&img, plot, |p| near(p, c, 40));
        assert!(n > 150, "series {i} colour {c:?}: {n} pixels in the plot");
    }
    // Black tick labels and axis labels left of and below the plot.
    let n = count(&img, (0, left as u32 - 6, 0, img.height()), dark);
    assert!(n > 150, "{n} dark pixels left of the plot");
    let n = count(
        &img,
        (0, img.width(), (top + height) as u32 + 6, img.height()),
        dark,
    );
    assert!(n > 150, "{n} dark pixels below the plot");
}

#[test]
fn text_is_drawn_with_the_carried_font() {
    // Text alone, no other shape: without the font, nothing would be drawn.
    let svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"200\" height=\"40\">\
         <rect width=\"200\" height=\"40\" fill=\"white\"/>\
         <text x=\"10\" y=\"28\" font-family=\"{}\" font-size=\"20\">Hello 10⁻³</text>\
         <text x=\"150\" y=\"28\" font-family=\"sans-serif\" font-size=\"20\">Ab</text></svg>",
        fem_render::FONT_FAMILY
    );
    let img = svg_to_png(&svg).unwrap();
    assert_eq!((img.width(), img.height()), (200, 40));
    let n = count(&img, (0, 140, 0, 40), dark);
    assert!(n > 60, "{n} dark pixels in the DejaVu Sans text");
    let n = count(&img, (145, 200, 0, 40), dark);
    assert!(n > 30, "{n} dark pixels in the sans-serif text");

    // The title region of a chart.
    let chart = probe_chart(50);
    let img = chart.to_png().unwrap();
    let [left, top, width, _] = chart.plot_rect().unwrap();
    let mid = (left + width / 2.0) as u32;
    let n = count(&img, (mid - 120, mid + 120, 0, top as u32 - 2), dark);
    assert!(n > 200, "{n} dark pixels in the title");
}

#[test]
fn svg_to_png_reports_parse_errors_as_encode_errors() {
    match svg_to_png("<svg><rect") {
        Err(RenderError::Encode(m)) => assert!(m.contains("SVG"), "{m}"),
        other => panic!("expected an encode error, got {other:?}"),
    }
    assert!(matches!(
        svg_to_png("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"0\" height=\"10\"/>"),
        Err(RenderError::Encode(_))
    ));
}

#[test]
fn charts_without_drawable_points_or_room_are_errors() {
    let empty = LineChart::default();
    assert!(matches!(empty.to_svg(), Err(RenderError::Input(_))));
    let nan = LineChart {
        series: vec![Series {
            label: "nan".to_string(),
            points: vec![(0.0, f64::NAN), (f64::INFINITY, 1.0)],
        }],
        ..LineChart::default()
    };
    match nan.to_svg() {
        Err(RenderError::Input(m)) => assert!(m.contains("no finite point"), "{m}"),
        other => panic!("expected an input error, got {other:?}"),
    }
    assert!(matches!(nan.to_png(), Err(RenderError::Input(_))));
    let log = LineChart {
        x_scale: Scale::Log,
        series: vec![Series {
            label: "s".to_string(),
            points: vec![(0.0, 1.0), (-1.0, 2.0)],
        }],
        ..LineChart::default()
    };
    assert!(matches!(log.to_svg(), Err(RenderError::Input(_))));
    let mut small = probe_chart(10);
    small.width = 100;
    match small.to_svg() {
        Err(RenderError::Input(m)) => assert!(m.contains("100x420"), "{m}"),
        other => panic!("expected an input error, got {other:?}"),
    }
}

#[test]
fn grid_png_cell_centres_have_the_cell_colours() {
    let grid = stability_grid();
    let img = grid.to_png().unwrap();
    assert_eq!((img.width(), img.height()), grid.size());
    for r in 0..grid.rows.len() {
        for c in 0..grid.columns.len() {
            let [x, y, w, h] = grid.cell_rect(r, c);
            let want = grid.cells[r][c].color;
            // The centre, and a point off the text near the corner.
            for (px, py) in [(x + w / 2.0, y + h / 2.0), (x + 2.5, y + 2.5)] {
                let got = img.pixel(px as u32, py as u32);
                if grid.cells[r][c].text.is_empty() || py < y + h / 2.0 - 1.0 {
                    assert_eq!(got, [want[0], want[1], want[2], 255], "cell ({r}, {c})");
                }
            }
            // The separator right of the cell is white.
            let sep = img.pixel((x + w) as u32, (y + h / 2.0) as u32);
            assert_eq!(sep, [255, 255, 255, 255], "separator right of ({r}, {c})");
        }
    }
    // Cell text: white on the dark red cells, black on the pale yellow ones.
    let [x, y, w, h] = grid.cell_rect(11, 12);
    assert_eq!(grid.cells[11][12].text, "NaN");
    let n = count(
        &img,
        (x as u32, (x + w) as u32, y as u32, (y + h) as u32),
        |p| p[0] > 230 && p[1] > 230 && p[2] > 230,
    );
    assert!(n > 8, "{n} white text pixels in a dark cell");
    let svg = grid.to_svg().unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(
        doc.root_element().attribute("width").unwrap(),
        grid.size().0.to_string()
    );
    let t = texts(&doc);
    for want in grid
        .rows
        .iter()
        .chain(&grid.columns)
        .chain([&grid.title, &grid.x_label, &grid.y_label])
        .chain(grid.legend.iter().map(|(l, _)| l))
    {
        assert!(t.contains(want), "{want:?} missing");
    }
    assert_eq!(
        doc.descendants()
            .filter(|n| n.has_tag_name("rect"))
            .filter(|n| n.parent().and_then(|p| p.attribute("class")) == Some("cells"))
            .count(),
        12 * 13
    );
}

#[test]
fn grid_size_mismatch_names_both_sizes() {
    let mut grid = stability_grid();
    grid.cells.pop();
    match grid.to_svg() {
        Err(RenderError::Input(m)) => {
            assert!(m.contains("11 rows") && m.contains("12 x 13"), "{m}")
        }
        other => panic!("expected an input error, got {other:?}"),
    }
    let mut grid = stability_grid();
    grid.cells[4].pop();
    match grid.to_png() {
        Err(RenderError::Input(m)) => {
            assert!(
                m.contains("cells[4] has 12") && m.contains("12 x 13"),
                "{m}"
            )
        }
        other => panic!("expected an input error, got {other:?}"),
    }
    let empty = GridChart::default();
    assert!(matches!(empty.to_svg(), Err(RenderError::Input(_))));
}

#[test]
fn cell_text_contrasts_with_the_cell() {
    assert_eq!(text_color_on([0, 0, 0]), [255, 255, 255]);
    assert_eq!(text_color_on([0x21, 0x66, 0xac]), [255, 255, 255]);
    assert_eq!(text_color_on([255, 255, 255]), [0, 0, 0]);
    assert_eq!(text_color_on([0xfe, 0xe0, 0x8b]), [0, 0, 0]);
}

/// Writes sample pictures to the temporary directory, to look at.
#[test]
fn samples_are_written_to_the_temp_dir() {
    let dir = std::env::temp_dir();
    let mut chart = probe_chart(300);
    chart.series.push(Series {
        label: "reference (implicit)".to_string(),
        points: (0..30)
            .map(|i| {
                let t = i as f64 * 2.0 / 29.0;
                (t, -0.8 * (1.0 - (-1.5 * t).exp()))
            })
            .collect(),
    });
    let img = chart.to_png().unwrap();
    img.write_png(&dir.join("fem-render-line-chart.png"))
        .unwrap();
    std::fs::write(
        dir.join("fem-render-line-chart.svg"),
        chart.to_svg().unwrap(),
    )
    .unwrap();

    let log = LineChart {
        title: "Energy drift".to_string(),
        x_label: "time step [s]".to_string(),
        y_label: "relative energy error".to_string(),
        x_scale: Scale::Log,
        y_scale: Scale::Log,
        markers: true,
        series: ["explicit", "implicit", "symplectic", "RK4", "Newmark"]
            .iter()
            .enumerate()
            .map(|(k, name)| Series {
                label: name.to_string(),
                points: (0..7)
                    .map(|i| {
                        let dt = 1e-5 * 2f64.powi(i);
                        (
                            dt,
                            3e-4 * (k as f64 + 1.0) * (dt / 1e-5).powi(k as i32 % 3 + 1),
                        )
                    })
                    .collect(),
            })
            .collect(),
        ..LineChart::default()
    };
    log.to_png()
        .unwrap()
        .write_png(&dir.join("fem-render-log-chart.png"))
        .unwrap();

    many_series(40, 720, 420)
        .to_png()
        .unwrap()
        .write_png(&dir.join("fem-render-many-series.png"))
        .unwrap();

    let grid = stability_grid();
    grid.to_png()
        .unwrap()
        .write_png(&dir.join("fem-render-grid-chart.png"))
        .unwrap();
    std::fs::write(
        dir.join("fem-render-grid-chart.svg"),
        grid.to_svg().unwrap(),
    )
    .unwrap();
    assert!(dir.join("fem-render-grid-chart.png").exists());
}

#[test]
fn degenerate_ranges_still_draw() {
    for points in [
        vec![(1.0, 5.0)],
        vec![(0.0, 0.0), (1.0, 0.0)],
        vec![(2.0, -1.0), (2.0, 3.0)],
    ] {
        let chart = LineChart {
            series: vec![Series {
                label: "s".to_string(),
                points: points.clone(),
            }],
            markers: true,
            ..LineChart::default()
        };
        let svg = chart.to_svg().unwrap();
        assert!(!svg.contains("NaN") && !svg.contains("inf"), "{points:?}");
        let img = chart.to_png().unwrap();
        let n = count(&img, all(&img), |p| near(p, series_color(0), 40));
        assert!(n > 20, "{points:?}: {n} pixels of the series colour");
    }
}

/// `n` labelled straight lines in a `width` x `height` chart.
fn many_series(n: usize, width: u32, height: u32) -> LineChart {
    LineChart {
        title: "Many series".to_string(),
        x_label: "time [s]".to_string(),
        y_label: "u [m]".to_string(),
        series: (0..n)
            .map(|k| Series {
                label: format!("energy {k:02}, E = {} kPa", 10 * (k + 1)),
                points: vec![(0.0, k as f64), (1.0, 2.0 * k as f64)],
            })
            .collect(),
        width,
        height,
        ..LineChart::default()
    }
}

#[test]
fn a_long_legend_wraps_into_columns_inside_the_chart() {
    for n in [5, 17, 18, 40, 60] {
        let chart = many_series(n, 720, 420);
        let svg = chart.to_svg().unwrap();
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let [left, _, width, _] = chart.plot_rect().unwrap();
        let places: Vec<(f64, f64)> = doc
            .descendants()
            .filter(|e| e.has_tag_name("text") && e.attribute("class") == Some("legend"))
            .map(|e| {
                let at = |a: &str| e.attribute(a).unwrap().parse::<f64>().unwrap();
                (at("x"), at("y"))
            })
            .collect();
        assert_eq!(places.len(), n, "{n} series");
        for (k, &(x, y)) in places.iter().enumerate() {
            // Right of the plot, above the chart's bottom edge, and left of its right edge
            // with room for at least a few characters.
            assert!(x > left + width, "{n} series: entry {k} at x = {x}");
            assert!(x < 720.0 - 30.0, "{n} series: entry {k} at x = {x}");
            assert!(y < 420.0 - 4.0, "{n} series: entry {k} at y = {y}");
            // No two entries share a place: different columns or a full row apart.
            for &(x2, y2) in &places[..k] {
                assert!(
                    (x - x2).abs() > 20.0 || (y - y2).abs() >= 19.9,
                    "{n} series: entries overlap at ({x}, {y}) and ({x2}, {y2})"
                );
            }
        }
    }
    // Far too many entries for the chart: a clear error, not a clipped legend.
    let e = many_series(400, 400, 200).to_svg().unwrap_err().to_string();
    assert!(e.contains("400 legend entries"), "{e}");
}
