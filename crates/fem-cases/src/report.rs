//! `fem2d report`: runs cases A-D, Table 1 and the case B stability sweep, and writes one
//! self-contained `index.html` (every picture embedded as a data URI, no script or style
//! fetched from anywhere) beside the pictures themselves:
//!
//! - Table 1 regenerated beside the paper's, with the timing of the 2000 steps;
//! - the comparison tables of every case (probes, peak stress, det F, cost per step);
//! - Figures 1-5, the probe curves and the stability map ([`crate::figures`]);
//! - an animation of each case;
//! - the run's metadata: version, parameters, machine, wall time of each part.
//!
//! The page checks itself when it loads: a small inline script counts the images that decoded
//! and writes the count into `<body data-images-loaded="N/M">`, which the browser test reads.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use base64::Engine as _;

use crate::figures::{CaseRuns, Figure, run_cases, write_animations, write_figures};
use crate::run::write_atomic;
use crate::table1::table1;
use fem_core::energy::EnergyKind;
use fem_scene::SceneError;

/// How to build the report.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Worker threads per run (`None`: rayon's default).
    pub threads: Option<usize>,
    /// Run the case B stability sweep (156 short runs, a few seconds).
    pub stability: bool,
    /// Write the animations.
    pub animations: bool,
    /// Run the frame budget on cases A and D (about 40 s on one core).
    pub budget: bool,
    /// The command line, shown in the metadata.
    pub command: String,
    /// When the report was made, shown in the metadata (the caller formats it, e.g. RFC 3339
    /// UTC `2026-11-22T10:50:55Z`).
    pub date: String,
}

impl Default for ReportOptions {
    fn default() -> Self {
        Self {
            threads: None,
            stability: true,
            animations: true,
            budget: true,
            command: "fem2d report".into(),
            date: String::new(),
        }
    }
}

/// What [`write_report`] wrote.
#[derive(Clone, Debug)]
pub struct ReportSummary {
    /// The page.
    pub index: std::path::PathBuf,
    /// The pictures, in page order.
    pub figures: Vec<Figure>,
    /// Total wall time, s.
    pub wall_seconds: f64,
    /// Size of `index.html`, bytes.
    pub bytes: usize,
}

/// Runs everything and writes `dir/index.html` plus every picture under `dir/figures/`.
pub fn write_report(
    dir: &Path,
    options: &ReportOptions,
    mut progress: impl FnMut(&str),
) -> Result<ReportSummary, SceneError> {
    let start = Instant::now();
    let figures_dir = dir.join("figures");
    std::fs::create_dir_all(&figures_dir).map_err(|e| {
        SceneError::Io(format!(
            "{}: cannot create the output directory: {e}",
            figures_dir.display()
        ))
    })?;
    progress("Table 1");
    let t = Instant::now();
    let table = table1(&[], 3, Some(1))?;
    let table_seconds = t.elapsed().as_secs_f64();
    let runs = run_cases(options.threads, options.stability, &mut progress)?;
    progress("figures");
    let t = Instant::now();
    let mut figures = write_figures(&runs, &figures_dir)?;
    let figure_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let animations = if options.animations {
        progress("animations");
        write_animations(&runs, &figures_dir)?
    } else {
        Vec::new()
    };
    let animation_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let budgets = if options.budget {
        frame_budgets(&figures_dir, &mut progress)?
    } else {
        Vec::new()
    };
    let budget_seconds = t.elapsed().as_secs_f64();
    let mut timings = vec![("Table 1 (3 energies x 3 repeats)".to_owned(), table_seconds)];
    timings.extend(runs.timings.iter().cloned());
    timings.push(("figures and plots".into(), figure_seconds));
    timings.push(("animations".into(), animation_seconds));
    if options.budget {
        timings.push((
            "frame budget (cases A, D and A in 3D; cost against mesh size)".into(),
            budget_seconds,
        ));
    }
    let html = page(
        &table,
        &runs,
        &figures,
        &budgets,
        &animations,
        &figures_dir,
        options,
        &timings,
        start,
    )?;
    let index = dir.join("index.html");
    write_atomic(&index, html.as_bytes())?;
    for b in budgets {
        figures.extend(b.charts);
    }
    figures.extend(animations);
    Ok(ReportSummary {
        index,
        figures,
        wall_seconds: start.elapsed().as_secs_f64(),
        bytes: html.len(),
    })
}

const STYLE: &str = r#"
body { font-family: "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; margin: 0 auto; max-width: 1320px; padding: 1.5em 2em 4em; color: #1c2430; line-height: 1.45; }
h1 { font-size: 1.8em; margin-bottom: 0.2em; }
h2 { border-bottom: 2px solid #d8dee8; padding-bottom: 0.2em; margin-top: 2.2em; }
h3 { margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.88em; }
th, td { border: 1px solid #d0d6e0; padding: 0.3em 0.6em; text-align: right; }
th { background: #eef2f7; }
td:first-child, th:first-child { text-align: left; }
figure { margin: 1.2em 0 2em; }
figure img { max-width: 100%; border: 1px solid #e4e8ee; }
figcaption { font-size: 0.92em; color: #3d4a5c; margin-top: 0.4em; max-width: 1100px; }
.gallery { display: flex; flex-wrap: wrap; gap: 1.5em; }
.gallery figure { margin: 0.5em 0; }
.meta td { text-align: left; }
.note { color: #3d4a5c; font-size: 0.92em; }
code { background: #f2f4f8; padding: 0 0.25em; }
"#;

const SELF_CHECK: &str = r#"
window.addEventListener("load", function () {
  var imgs = document.images, ok = 0;
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { ok++; }
  }
  document.body.setAttribute("data-images-loaded", ok + "/" + imgs.length);
  var s = document.getElementById("self-check");
  if (s) { s.textContent = ok + " of " + imgs.length + " images loaded."; }
});
"#;

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Markdown to HTML for what the crate's own markdown writers produce: pipe tables, and
/// paragraphs of plain text.
pub fn markdown_tables_to_html(md: &str) -> String {
    let mut out = String::new();
    let mut in_table = false;
    let mut header_done = false;
    for line in md.lines() {
        let l = line.trim();
        if l.starts_with('|') {
            let cells: Vec<&str> = l.trim_matches('|').split('|').map(str::trim).collect();
            if cells
                .iter()
                .all(|c| !c.is_empty() && c.chars().all(|ch| ch == '-' || ch == ':'))
            {
                continue;
            }
            if !in_table {
                out.push_str("<table>\n");
                in_table = true;
                header_done = false;
            }
            let tag = if header_done { "td" } else { "th" };
            out.push_str("<tr>");
            for c in cells {
                let _ = write!(out, "<{tag}>{}</{tag}>", escape(c));
            }
            out.push_str("</tr>\n");
            header_done = true;
        } else {
            if in_table {
                out.push_str("</table>\n");
                in_table = false;
            }
            if !l.is_empty() {
                let _ = writeln!(out, "<p>{}</p>", escape(l).replace('`', ""));
            }
        }
    }
    if in_table {
        out.push_str("</table>\n");
    }
    out
}

fn data_uri(path: &Path) -> Result<String, SceneError> {
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::Io(format!("{}: cannot read: {e}", path.display())))?;
    let mime = match path.extension().and_then(|e| e.to_str()) {
        Some("gif") => "image/gif",
        Some("svg") => "image/svg+xml",
        _ => "image/png",
    };
    Ok(format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    ))
}

fn figure_html(out: &mut String, f: &Figure, dir: &Path) -> Result<(), SceneError> {
    let _ = writeln!(
        out,
        "<figure><img src=\"{}\" alt=\"{}\"><figcaption><b>{}.</b> {} <span class=\"note\">(<code>figures/{}</code>)</span></figcaption></figure>",
        data_uri(&dir.join(&f.file))?,
        escape(&f.title),
        escape(&f.title),
        escape(&f.caption),
        escape(&f.file)
    );
    Ok(())
}

fn machine() -> Vec<(String, String)> {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let rustc = std::process::Command::new("rustc")
        .arg("--version")
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_else(|| "not found".into());
    vec![
        (
            "operating system".into(),
            format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
        ),
        ("CPU".into(), cpu),
        ("cores available".into(), cores.to_string()),
        ("rustc on this machine".into(), rustc),
        (
            "build".into(),
            if cfg!(debug_assertions) {
                "debug (timings are not representative)".into()
            } else {
                "release".into()
            },
        ),
    ]
}

/// One case's frame budget in the report: its markdown and its charts.
struct CaseBudget {
    name: &'static str,
    markdown: String,
    charts: Vec<Figure>,
}

/// The frame budget (90 Hz, 5 ms per frame, one thread) of case A (the paper's three energies,
/// 0.5 s), case D (its `[budget]` table: Neo-Hookean, 1 s) and case A in 3D (Neo-Hookean,
/// 0.5 s, the 2D mesh extruded: 20 x 4 x 4 cubes), with one Pareto chart per energy and case
/// D's window chart in `dir`; then the sentence setting case A's two dimensions side by side
/// and the cost of a frame against mesh size in both ([`crate::scaling`], quick).
fn frame_budgets(
    dir: &Path,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<CaseBudget>, SceneError> {
    use crate::budget::{BudgetSpec, budget, budget3};
    let mut out = Vec::new();
    let mut case_a = None;
    // Case D's own `[budget]` table: Neo-Hookean over one second (the impact and half a
    // second of sustained crush).
    for (name, energies, duration) in [
        ("case-a", crate::figures::PAPER_ENERGIES.to_vec(), Some(0.5)),
        ("case-d", Vec::new(), None),
    ] {
        progress(&format!("frame budget: {name}"));
        let base = fem_scene::cases::load_case(name, &[])?;
        let spec = BudgetSpec {
            duration,
            energies,
            ..BudgetSpec::default()
        };
        let run = budget(&base, &spec, |_| {})?;
        out.push(case_budget(name, &run, dir)?);
        if name == "case-a" {
            case_a = Some(run.budget);
        }
    }
    progress("frame budget: case-a-3d");
    let base = fem_scene::solid::load_case3("case-a-3d", &[])?;
    let spec = BudgetSpec {
        duration: Some(0.5),
        energies: vec![EnergyKind::NeoHookean],
        ..BudgetSpec::default()
    };
    let run = budget3(&base, &spec, |_| {})?;
    let mut three = case_budget("case-a-3d", &run, dir)?;
    if let Some(two) = &case_a {
        three.markdown = format!(
            "- {}\n\n{}",
            crate::budget::dimensions_sentence(two, &run.budget, EnergyKind::NeoHookean),
            three.markdown
        );
    }
    out.push(three);
    progress("cost against mesh size, 2D and 3D");
    let scaling = crate::scaling::scaling(&crate::scaling::ScalingSpec::quick(), |_| {})?;
    let file = "budget-scaling.png".to_owned();
    let png = scaling
        .chart(5.0)
        .to_png()
        .and_then(|i| i.to_png())
        .map_err(|e| SceneError::Io(e.to_string()))?;
    write_atomic(&dir.join(&file), &png)?;
    out.push(CaseBudget {
        name: "case A in 2D and 3D: the cost of a frame against mesh size",
        markdown: scaling.to_markdown(),
        charts: vec![Figure {
            file,
            title: "Cost of a frame against mesh size, 2D and 3D".into(),
            caption: "Case A refined in the plane (2D: nx x ny cells of 2 triangles; 3D: nx x ny x nz cubes of 6 tetrahedra), Neo-Hookean, one step of 1/90 s a frame on one thread: implicit Euler (velocity tolerance 1e-2 m/s), XPBD and VBD at 10 iterations; milliseconds per frame against unknowns, log-log, with the 5 ms budget (`fem2d scaling`; a quick run of small meshes here, the full one in docs/budget.md).".into(),
        }],
    });
    Ok(out)
}

/// One budget's section of the report: its markdown, its Pareto charts and (with an impact
/// window) its window charts, written to `dir`.
fn case_budget<C: crate::budget::Cell>(
    name: &'static str,
    run: &crate::budget::BudgetRun<C>,
    dir: &Path,
) -> Result<CaseBudget, SceneError> {
    let mut charts = Vec::new();
    let png_of = |chart: &fem_render::chart::LineChart| {
        chart
            .to_png()
            .and_then(|i| i.to_png())
            .map_err(|e| SceneError::Io(e.to_string()))
    };
    let phases = run.phase_charts();
    for (energy, chart) in run
        .budget
        .charts()
        .into_iter()
        .filter(|(_, c)| crate::budget::drawable(c))
    {
        let file = format!("budget-{name}-{}.png", energy.name());
        write_atomic(&dir.join(&file), &png_of(&chart)?)?;
        let sentence = run
            .budget
            .sentences
            .iter()
            .find(|s| s.starts_with(energy.name()))
            .cloned()
            .unwrap_or_default();
        charts.push(Figure {
            file,
            title: format!("Frame budget, {name}, {energy}"),
            caption: format!(
                "The error the frameworks are ranked by ({}) against stepping time per frame on one thread, every stable setting of every framework ({} frames); the vertical line is the 5 ms budget. {sentence}",
                run.budget.reference_of(energy).map_or_else(
                    || run.budget.rank_by.name().to_owned(),
                    |r| run.budget.rank_by.describe(&r.windows)
                ),
                run.budget.frames
            ),
        });
        if let Some((_, phase)) = phases.iter().find(|(e, _)| *e == energy)
            && run
                .budget
                .reference_of(energy)
                .is_some_and(|r| r.windows.impact.is_some())
        {
            let file = format!("budget-{name}-{}-phases.png", energy.name());
            write_atomic(&dir.join(&file), &png_of(phase)?)?;
            charts.push(Figure {
                file,
                title: format!("Frame budget windows, {name}, {energy}"),
                caption: "The reference's kinetic energy, the soft tissue's peak von Mises stress and the total contact force, each over its largest value; the impact window runs from the first contact with an obstacle until the kinetic energy has fallen for good below the settle threshold, the sustained phase after it.".into(),
            });
        }
    }
    Ok(CaseBudget {
        name,
        markdown: run.budget.to_markdown(),
        charts,
    })
}

#[allow(clippy::too_many_arguments)]
fn page(
    table: &crate::table1::Table1,
    runs: &CaseRuns,
    figures: &[Figure],
    budgets: &[CaseBudget],
    animations: &[Figure],
    dir: &Path,
    options: &ReportOptions,
    timings: &[(String, f64)],
    start: Instant,
) -> Result<String, SceneError> {
    let mut h = String::new();
    h.push_str("<h2 id=\"table1\">Table 1: case A, tip displacement</h2>\n");
    h.push_str(&markdown_tables_to_html(&table.to_markdown()));

    let (main, plots): (Vec<&Figure>, Vec<&Figure>) =
        figures.iter().partition(|f| f.file.starts_with("figure-"));
    h.push_str("<h2 id=\"figures\">Figures 1-5</h2>\n");
    for f in main {
        figure_html(&mut h, f, dir)?;
    }
    h.push_str("<h2 id=\"curves\">Probe curves and the stability map</h2>\n");
    for f in plots {
        figure_html(&mut h, f, dir)?;
    }

    h.push_str("<h2 id=\"comparisons\">Comparisons and timing</h2>\n<p class=\"note\">Step times are wall-clock seconds for the whole run on this machine; element-steps per second = triangles x steps / step time; real-time factor = simulated time / step time.</p>\n");
    for (name, c) in [
        ("Case A", &runs.a),
        ("Case B", &runs.b),
        ("Case C", &runs.c),
        ("Case D", &runs.d),
    ] {
        let _ = writeln!(h, "<h3>{name}</h3>");
        h.push_str(&markdown_tables_to_html(&c.to_markdown()));
    }
    if let Some(m) = &runs.stability {
        h.push_str("<h3>Case B stability sweep</h3>\n");
        let md = m.to_markdown();
        // The per-job table is long; the page keeps the stability summary after it.
        let summary = md
            .find("Largest stable time step")
            .map_or(md.as_str(), |k| &md[k..]);
        h.push_str(&markdown_tables_to_html(summary));
    }

    if !budgets.is_empty() {
        h.push_str("<h2 id=\"budget\">Frame budget: 90 Hz, 5 ms per frame</h2>\n<p class=\"note\">Every energy x framework at every setting of its ladders (fixed counts and residual tolerances), each advancing 1/90 s per frame on one thread, compared frame by frame with a converged reference whose own error is stated: case A by its motion, case D by what a medic reads, the soft tissue's von Mises stress and the contact pressure, in the impact window and the sustained crush after it, with the bones' load (<code>fem2d budget</code>, docs/budget.md). Case C's scene is case A's with StVK, so its budget is case A's StVK table. Case A in 3D is case A's mesh extruded (20 x 4 x 4 cubes of 6 tetrahedra) under the same frameworks, Neo-Hookean; a framework without a 3D path says so.</p>\n");
        for b in budgets {
            let _ = writeln!(h, "<h3>{}</h3>", b.name);
            let mut items = String::new();
            for line in b.markdown.lines().filter(|l| l.starts_with("- ")) {
                let _ = writeln!(items, "<li>{}</li>", escape(&line[2..]));
            }
            let _ = writeln!(h, "<ul>\n{items}</ul>");
            h.push_str(&markdown_tables_to_html(&b.markdown));
            for f in &b.charts {
                figure_html(&mut h, f, dir)?;
            }
        }
    }

    h.push_str("<h2 id=\"animations\">Animations</h2>\n<div class=\"gallery\">\n");
    for f in animations {
        figure_html(&mut h, f, dir)?;
    }
    h.push_str("</div>\n");

    h.push_str("<h2 id=\"metadata\">Run metadata</h2>\n<table class=\"meta\">\n");
    let mut meta = vec![
        ("fem2d".to_owned(), env!("CARGO_PKG_VERSION").to_owned()),
        ("command".into(), options.command.clone()),
        (
            "threads per run".into(),
            options
                .threads
                .map_or_else(|| "all cores (rayon default)".into(), |n| n.to_string()),
        ),
        ("Table 1 setting".into(), table.setting.clone()),
    ];
    meta.extend(machine());
    for (k, v) in &meta {
        let _ = writeln!(h, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(v));
    }
    h.push_str("</table>\n<h3>Scenes as run</h3>\n");
    for (name, c) in [
        ("case-a", &runs.a),
        ("case-b", &runs.b),
        ("case-c", &runs.c),
        ("case-d", &runs.d),
    ] {
        let _ = writeln!(
            h,
            "<p><b>{name}</b>: {} triangles, dt = {:e} s, {} steps; rows: {}.</p>",
            c.triangles,
            c.dt,
            c.steps,
            c.rows
                .iter()
                .map(|r| format!(
                    "{} / {}{}",
                    r.energy,
                    r.solver,
                    if r.variant.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", r.variant)
                    }
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    h.push_str("<h3>Wall time</h3>\n<table>\n<tr><th>part</th><th>seconds</th></tr>\n");
    for (k, v) in timings {
        let _ = writeln!(h, "<tr><td>{}</td><td>{v:.2}</td></tr>", escape(k));
    }
    let _ = writeln!(
        h,
        "<tr><th>total</th><th>{:.2}</th></tr>\n</table>",
        start.elapsed().as_secs_f64()
    );
    h.push_str(
        "<p id=\"self-check\" class=\"note\">Images not checked yet.</p>\n</body>\n</html>\n",
    );
    // The header last, so that it can state the wall time of everything above.
    let mut head = String::new();
    let _ = write!(
        head,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>fem2d report</title>\n<style>{STYLE}</style>\n<script>{SELF_CHECK}</script>\n</head>\n<body>\n"
    );
    let _ = writeln!(
        head,
        "<h1>fem2d report</h1>\n<p>2D energy-based FEM elastodynamics: the paper's cases A-D regenerated with fem2d {} on {}. Every number and picture on this page was computed by the command <code>{}</code> in {:.1} s.</p>",
        env!("CARGO_PKG_VERSION"),
        escape(&options.date),
        escape(&options.command),
        start.elapsed().as_secs_f64()
    );
    head.push_str("<p>Contents: <a href=\"#table1\">Table 1</a> · <a href=\"#figures\">Figures 1-5</a> · <a href=\"#curves\">curves and stability</a> · <a href=\"#comparisons\">comparisons and timing</a> · <a href=\"#animations\">animations</a> · <a href=\"#metadata\">metadata</a></p>\n");

    Ok(head + &h)
}
