//! The paper's figures, regenerated from runs of the built-in cases, and the plots that go with
//! them (probe curves, the case B stability map), as written by `fem2d figures` (and
//! `cargo xtask figures`, into `docs/figures/`) and embedded by `fem2d report`.
//!
//! - Figure 1: the mesh pipeline's stages on the built-in body (case D's settings);
//! - Figure 2: case A, the cantilever under StVK, co-rotational and Neo-Hookean side by side,
//!   at Table 1's frames 50, 120 and 200;
//! - Figure 3: case B, the stretched bar under the three energies (lateral contraction);
//! - Figure 4: case C, explicit FEM, PBD and XPBD side by side at explicit's deepest deflection;
//! - Figure 5: case D, the scene (body, ground, debris) and the von Mises map at peak stress.

use std::path::Path;
use std::time::Instant;

use fem_core::energy::EnergyKind;
use fem_render::Image;
use fem_render::chart::{GridCell, GridChart};

use crate::compare::{CompareSpec, Comparison, compare};
use crate::pictures::{
    FieldKind, FramePicture, GifOptions, probe_chart, render_side_by_side, snapshot_at,
    write_chart, write_gif,
};
use crate::run::RunResult;
use crate::sweep::{Merged, parse_sweep};
use fem_scene::SceneError;
use fem_scene::cases::load_case;
use fem_solvers::SolverKind;

/// The runs every figure is drawn from.
pub struct CaseRuns {
    /// Case A under StVK, co-rotational and Neo-Hookean (explicit).
    pub a: Comparison,
    /// Case B under the same three energies (explicit).
    pub b: Comparison,
    /// Case C under explicit, PBD and XPBD (StVK).
    pub c: Comparison,
    /// Case D (its scene's energy and solver).
    pub d: Comparison,
    /// The case B stability sweep (`fixtures/sweeps/case-b-stability.toml`, a link to the
    /// crate's `sweeps/case-b-stability.toml`), when run.
    pub stability: Option<Merged>,
    /// Wall time of each part, s: `(name, seconds)`.
    pub timings: Vec<(String, f64)>,
}

/// The three energies of the paper's comparisons.
pub const PAPER_ENERGIES: [EnergyKind; 3] = [
    EnergyKind::Stvk,
    EnergyKind::Corotational,
    EnergyKind::NeoHookean,
];

const STABILITY_SWEEP: &str = include_str!("../sweeps/case-b-stability.toml");

/// Runs cases A-D (and the case B stability sweep when `stability`), keeping every frame of
/// every run for the pictures. `progress` is told what starts.
pub fn run_cases(
    threads: Option<usize>,
    stability: bool,
    mut progress: impl FnMut(&str),
) -> Result<CaseRuns, SceneError> {
    let mut timings = Vec::new();
    let mut one = |name: &str, energies: &[EnergyKind], solvers: &[SolverKind]| {
        progress(name);
        let t = Instant::now();
        let spec = CompareSpec {
            energies: energies.to_vec(),
            solvers: solvers.to_vec(),
            variants: Vec::new(),
            threads,
            snapshot_every: Some(1),
        };
        let out = load_case(name, &[]).and_then(|base| compare(&base, &spec));
        timings.push((name.to_owned(), t.elapsed().as_secs_f64()));
        out
    };
    // Cases A and B under the default solver (explicit, the paper's), case C under each of the
    // paper's frameworks, case D as its scene says.
    let default = [SolverKind::default()];
    let paper: Vec<SolverKind> = SolverKind::ALL
        .into_iter()
        .filter(|k| k.capabilities().paper)
        .collect();
    let a = one("case-a", &PAPER_ENERGIES, &default)?;
    let b = one("case-b", &PAPER_ENERGIES, &default)?;
    let c = one("case-c", &[EnergyKind::Stvk], &paper)?;
    let d_scene = load_case("case-d", &[])?;
    let d = one(
        "case-d",
        &[d_scene.scene.energy],
        &[d_scene.scene.solver.kind],
    )?;
    let stability = if stability {
        progress("case-b stability sweep");
        let t = Instant::now();
        let merged = stability_sweep(threads)?;
        timings.push(("case-b stability sweep".into(), t.elapsed().as_secs_f64()));
        Some(merged)
    } else {
        None
    };
    Ok(CaseRuns {
        a,
        b,
        c,
        d,
        stability,
        timings,
    })
}

/// Runs the case B stability sweep on two shards at once (one thread each).
pub fn stability_sweep(threads: Option<usize>) -> Result<Merged, SceneError> {
    let sweep = parse_sweep(
        STABILITY_SWEEP,
        "built-in fixtures/sweeps/case-b-stability.toml",
        Path::new("."),
    )?;
    let shards = threads.unwrap_or(2).clamp(1, 2);
    let parts: Vec<Result<_, SceneError>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..shards)
            .map(|i| {
                let sweep = &sweep;
                s.spawn(move || sweep.run_shard(i, shards, Some(1), |_| {}))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(SceneError::Io("a sweep shard panicked".into())))
            })
            .collect()
    });
    let mut results = Vec::new();
    for p in parts {
        results.extend(p?.results);
    }
    results.sort_by_key(|r| r.job.index);
    Ok(Merged {
        digest: sweep.digest.clone(),
        spec: sweep.spec.clone(),
        results,
    })
}

/// One written picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// File name in the output directory (the PNG; charts also have an `.svg` of the same stem).
    pub file: String,
    /// Short title.
    pub title: String,
    /// What the picture shows, with numbers.
    pub caption: String,
}

/// The run of row `k` of a comparison with its label.
fn runs(c: &Comparison) -> Vec<(String, &RunResult)> {
    c.rows
        .iter()
        .zip(&c.runs)
        .filter_map(|(row, run)| {
            let label = match (row.solver, row.variant.as_str()) {
                _ if c.rows.iter().all(|r| r.solver == row.solver) => {
                    energy_label(row.energy.name())
                }
                (s, "") => solver_label(s),
                (s, v) => format!("{} ({v})", solver_label(s)),
            };
            Some((label, run.as_ref()?))
        })
        .collect()
}

/// Display name of an energy.
pub fn energy_label(name: &str) -> String {
    match name {
        "stvk" => "StVK".into(),
        "corotational" => "Co-rotational".into(),
        "neo-hookean" => "Neo-Hookean".into(),
        "stable-neo-hookean" => "Stable Neo-Hookean".into(),
        "linear" => "Linear".into(),
        other => other.into(),
    }
}

/// Display name of a solver (its capability record's title).
pub fn solver_label(kind: SolverKind) -> String {
    kind.capabilities().title.into()
}

fn write_png(image: &Image, dir: &Path, file: &str) -> Result<(), SceneError> {
    image
        .write_png(&dir.join(file))
        .map_err(|e| SceneError::Io(format!("{}: {e}", dir.join(file).display())))
}

fn render_err(e: fem_render::RenderError) -> SceneError {
    SceneError::Io(format!("rendering: {e}"))
}

/// Side-by-side von Mises pictures of every run at time `t` (one row), sharing `range`.
fn row_at(
    labelled: &[(String, &RunResult)],
    t: f64,
    title: &str,
    panel: (u32, u32),
    range: Option<(f64, f64)>,
) -> Result<Image, SceneError> {
    let pictures: Vec<FramePicture<'_>> = labelled
        .iter()
        .filter_map(|(label, run)| {
            snapshot_at(run, t).map(|s| FramePicture::new(run, s, FieldKind::VonMises, label))
        })
        .collect();
    let refs: Vec<&FramePicture<'_>> = pictures.iter().collect();
    Ok(render_side_by_side(&refs, FieldKind::VonMises, title, panel, range)?.image)
}

/// The von Mises range (kPa, from 0) over every kept frame of `labelled` between `t0` and `t1`.
fn range_over(labelled: &[(String, &RunResult)], t0: f64, t1: f64) -> Option<(f64, f64)> {
    let hi = labelled
        .iter()
        .flat_map(|(_, r)| r.snapshots.iter())
        .filter(|s| s.time >= t0 - 1e-9 && s.time <= t1 + 1e-9)
        .flat_map(|s| s.von_mises.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0_f64, f64::max);
    (hi > 0.0).then_some((0.0, hi * 1e-3))
}

/// Figure 1: the mesh pipeline's four stages on case D's body.
pub fn figure_1(dir: &Path) -> Result<Figure, SceneError> {
    let scene = load_case("case-d", &[])?;
    let out =
        fem_scene::build::mesh_pipeline(&scene, &crate::files::FileSource::for_scene(&scene))?
            .ok_or_else(|| {
                SceneError::Mesh("case-d: its mesh does not come from a model".into())
            })?;
    let params = fem_mesh::preview::PreviewParams {
        height_px: 520,
        margin: 0.05,
    };
    let canvases = fem_mesh::preview::render_stages(&out.stages(), &params);
    let captions = [
        "(a) projected surface points",
        "(b) alpha shape",
        "(c) simplified polygon",
        "(d) quality triangle mesh",
    ];
    let mut panels = Vec::new();
    for (canvas, caption) in canvases.iter().zip(captions) {
        let (w, h) = canvas.size();
        let rgba = canvas
            .pixels()
            .iter()
            .flat_map(|&[r, g, b]| [r, g, b, 255])
            .collect();
        let img = Image::from_rgba(w as u32, h as u32, rgba).map_err(render_err)?;
        panels.push(fem_render::frame::with_caption(&img, caption));
    }
    let figure = Image::hstack(&panels, 12, [255, 255, 255, 255]);
    let figure = fem_render::frame::with_caption(
        &figure,
        "Figure 1. From a 3D model to a 2D FEM mesh (built-in body, side view)",
    );
    write_png(&figure, dir, "figure-1-mesh-pipeline.png")?;
    let q = &out.quality;
    Ok(Figure {
        file: "figure-1-mesh-pipeline.png".into(),
        title: "Figure 1: the mesh pipeline".into(),
        caption: format!(
            "The built-in body's surface points projected to the side view, the alpha shape, the simplified polygon and the final mesh: {} vertices, {} triangles, smallest angle {:.1} degrees.",
            out.mesh.vertices.len(),
            out.mesh.triangles.len(),
            q.min_angle_deg
        ),
    })
}

/// Figures 2-5 and the plots, from `runs`, into `dir` (created if missing).
pub fn write_figures(runs_: &CaseRuns, dir: &Path) -> Result<Vec<Figure>, SceneError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| SceneError::Io(format!("{}: cannot create: {e}", dir.display())))?;
    let mut figures = vec![figure_1(dir)?];

    // Figure 2: case A at Table 1's frames 50, 120, 200 (t = 0.5, 1.2, 2.0 s).
    let a = runs(&runs_.a);
    let range = range_over(&a, 0.0, f64::INFINITY);
    let mut rows = Vec::new();
    for (k, t) in [0.5, 1.2, 2.0].into_iter().enumerate() {
        let title = format!(
            "{}Case A at t = {t:.1} s (frame {})",
            if k == 0 { "Figure 2. " } else { "" },
            (t * 100.0_f64).round()
        );
        rows.push(row_at(&a, t, &title, (420, 220), range)?);
    }
    let fig2 = Image::vstack(&rows, 8, [255, 255, 255, 255]);
    write_png(&fig2, dir, "figure-2-case-a.png")?;
    figures.push(Figure {
        file: "figure-2-case-a.png".into(),
        title: "Figure 2: case A, three energies".into(),
        caption: format!(
            "The 5 m x 1 m cantilever falling under gravity (explicit, dt = 1 ms), coloured by von Mises stress on one scale; the grey outline is the rest shape. Deepest tip deflection: {}.",
            deepest_tips(&runs_.a, |r| energy_label(r.energy.name()))
        ),
    });

    // Figure 3: case B at the end of the stretch.
    let b = runs(&runs_.b);
    let t_end = b
        .iter()
        .filter_map(|(_, r)| r.snapshots.last().map(|s| s.time))
        .fold(0.0, f64::max);
    let fig3 = row_at(
        &b,
        t_end,
        &format!("Figure 3. Case B: the bar stretched by 40 % (t = {t_end:.1} s)"),
        (420, 200),
        None,
    )?;
    write_png(&fig3, dir, "figure-3-case-b.png")?;
    figures.push(Figure {
        file: "figure-3-case-b.png".into(),
        title: "Figure 3: case B, three energies".into(),
        caption: "The bar pinned on the left and pulled to 140 % of its length on the right, coloured by von Mises stress; the grey outline is the rest shape, so the lateral contraction of each energy shows as the gap at mid-span.".into(),
    });

    // Figure 4: case C at explicit's deepest tip.
    let c = runs(&runs_.c);
    let t_deep = c
        .first()
        .and_then(|(_, r)| {
            let series = r.probe("tip")?;
            let k = series
                .iter()
                .enumerate()
                .min_by(|x, y| x.1[1].total_cmp(&y.1[1]))?
                .0;
            Some(r.frame_times[k].1)
        })
        .unwrap_or(1.0);
    let fig4 = row_at(
        &c,
        t_deep,
        &format!("Figure 4. Case C: explicit FEM, PBD and XPBD at t = {t_deep:.2} s"),
        (420, 240),
        None,
    )?;
    write_png(&fig4, dir, "figure-4-case-c.png")?;
    figures.push(Figure {
        file: "figure-4-case-c.png".into(),
        title: "Figure 4: case C, three solvers".into(),
        caption: format!(
            "The soft cantilever under explicit FEM, PBD and XPBD at the time of explicit's deepest deflection. Deepest tip deflection: {}. PBD's stiffness depends on its iteration count, XPBD's does not.",
            deepest_tips(&runs_.c, |r| solver_label(r.solver))
        ),
    });

    // Figure 5: case D's scene and the von Mises map at peak stress.
    let d = runs(&runs_.d);
    let (_, drun) = d
        .first()
        .ok_or_else(|| SceneError::Io("case D did not run".into()))?;
    let s = &drun.summary;
    let first = drun.snapshots.first().expect("a run keeps its first frame");
    let peak = drun
        .snapshots
        .iter()
        .find(|x| x.step == s.max_von_mises_step)
        .unwrap_or_else(|| drun.snapshots.last().expect("a run keeps its last frame"));
    let ground = ground_height("case-d")?;
    let scene_pic = FramePicture::new(drun, first, FieldKind::VonMises, "(a) the scene at t = 0")
        .plain()
        .with_ground(ground);
    let peak_pic = FramePicture::new(
        drun,
        peak,
        FieldKind::VonMises,
        &format!(
            "(b) von Mises stress and contact pressure at peak, t = {:.2} s",
            peak.time
        ),
    )
    .with_ground(ground)
    .with_contact_pressure();
    let top = render_side_by_side(
        &[&scene_pic],
        FieldKind::VonMises,
        "Figure 5. Case D: debris falling on a lying body",
        (900, 260),
        None,
    )?
    .image;
    let bottom = render_side_by_side(&[&peak_pic], FieldKind::VonMises, "", (900, 260), None)?;
    let fig5 = Image::vstack(&[top, bottom.image], 6, [255, 255, 255, 255]);
    write_png(&fig5, dir, "figure-5-case-d.png")?;
    figures.push(Figure {
        file: "figure-5-case-d.png".into(),
        title: "Figure 5: case D, the body under debris".into(),
        caption: format!(
            "A {} kg slab falls on the shin of the body lying on the ground ({} triangles). Peak von Mises stress {:.0} kPa at x = {:.3} m, at t = {:.2} s.",
            fmt_mass(&load_case("case-d", &[])?),
            s.triangles,
            s.max_von_mises * 1e-3,
            s.max_von_mises_at[0],
            peak.time
        ),
    });

    // Probe curves.
    for (comparison, stem, title, what) in [
        (
            &runs_.a,
            "curves-case-a",
            "Case A: tip deflection, three energies",
            "energy",
        ),
        (
            &runs_.c,
            "curves-case-c",
            "Case C: tip deflection, three solvers",
            "solver",
        ),
    ] {
        let labelled = runs(comparison);
        let refs: Vec<(&str, &RunResult)> =
            labelled.iter().map(|(l, r)| (l.as_str(), *r)).collect();
        let chart = probe_chart(&refs, "tip", title);
        write_chart(dir, stem, chart.to_svg(), chart.to_png())?;
        figures.push(Figure {
            file: format!("{stem}.png"),
            title: title.into(),
            caption: format!(
                "The tip's vertical displacement against time for every {what} (also as {stem}.svg)."
            ),
        });
    }

    if let Some(merged) = &runs_.stability {
        let chart = stability_chart(merged)?;
        write_chart(dir, "stability-case-b", chart.to_svg(), chart.to_png())?;
        figures.push(Figure {
            file: "stability-case-b.png".into(),
            title: "Case B: stability map".into(),
            caption: "Explicit FEM on the stretched bar: which time steps stay stable for 1.5 s, per energy and Young's modulus (also as stability-case-b.svg).".into(),
        });
    }
    Ok(figures)
}

/// "label N mm, ..." of each row's deepest deflection of its first probe.
fn deepest_tips(c: &Comparison, label: impl Fn(&crate::compare::CompareRow) -> String) -> String {
    c.rows
        .iter()
        .map(|r| {
            format!(
                "{} {:.0} mm",
                label(r),
                r.probes.first().map_or(f64::NAN, |p| -p.min_uy * 1e3)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The height of a built-in case's horizontal ground, if it has one.
fn ground_height(case: &str) -> Result<Option<f64>, SceneError> {
    Ok(load_case(case, &[])?
        .scene
        .ground
        .as_ref()
        .and_then(|g| g.height))
}

fn fmt_mass(scene: &fem_scene::scene::LoadedScene) -> String {
    scene
        .scene
        .obstacles
        .first()
        .and_then(|o| o.mass)
        .map_or_else(|| "-".into(), |m| format!("{m:.0}"))
}

/// The stability grid: one row per energy and Young's modulus, one column per time step.
pub fn stability_chart(merged: &Merged) -> Result<GridChart, SceneError> {
    let keys: Vec<String> = merged
        .spec
        .axes
        .iter()
        .filter_map(|a| a.key.clone())
        .collect();
    let pos = |k: &str| keys.iter().position(|x| x == k);
    let (Some(ei), Some(yi), Some(di)) = (
        pos("energy"),
        pos("material.youngs_modulus"),
        pos("solver.dt"),
    ) else {
        return Err(SceneError::Usage(
            "the stability map needs the axes energy, material.youngs_modulus and solver.dt".into(),
        ));
    };
    let mut rows: Vec<(String, String)> = Vec::new();
    let mut cols: Vec<String> = Vec::new();
    for r in &merged.results {
        let p = &r.job.params;
        let row = (p[ei].1.clone(), p[yi].1.clone());
        if !rows.contains(&row) {
            rows.push(row);
        }
        if !cols.contains(&p[di].1) {
            cols.push(p[di].1.clone());
        }
    }
    const STABLE: [u8; 3] = [68, 119, 170];
    const BLEW_UP: [u8; 3] = [238, 102, 119];
    const FAILED: [u8; 3] = [187, 187, 187];
    let mut cells = vec![
        vec![
            GridCell {
                color: FAILED,
                text: String::new()
            };
            cols.len()
        ];
        rows.len()
    ];
    for r in &merged.results {
        let p = &r.job.params;
        let (Some(i), Some(j)) = (
            rows.iter().position(|x| x.0 == p[ei].1 && x.1 == p[yi].1),
            cols.iter().position(|x| *x == p[di].1),
        ) else {
            continue;
        };
        cells[i][j].color = match &r.summary {
            Some(s) if !s.blew_up => STABLE,
            Some(_) => BLEW_UP,
            None => FAILED,
        };
    }
    let unquote = |s: &str| s.trim_matches('"').to_owned();
    Ok(GridChart {
        title: "Case B stability: explicit FEM, 1.5 s of stretching".into(),
        x_label: "time step dt [s]".into(),
        y_label: "energy, Young's modulus E [Pa]".into(),
        columns: cols
            .iter()
            .map(|c| c.parse::<f64>().map_or(c.clone(), |v| format!("{v:.1e}")))
            .collect(),
        rows: rows
            .iter()
            .map(|(e, y)| {
                format!(
                    "{}, E = {}",
                    energy_label(&unquote(e)),
                    y.parse::<f64>().map_or(y.clone(), |v| format!("{v:.0e}"))
                )
            })
            .collect(),
        cells,
        legend: vec![
            ("stable".into(), STABLE),
            ("blew up".into(), BLEW_UP),
            ("could not run".into(), FAILED),
        ],
        ..GridChart::default()
    })
}

/// Animated GIFs of cases A and B (Neo-Hookean), C (XPBD) and D into `dir`, at most ~100
/// frames each.
pub fn write_animations(runs_: &CaseRuns, dir: &Path) -> Result<Vec<Figure>, SceneError> {
    let mut out = Vec::new();
    for (c, k, case, what, panel) in [
        (&runs_.a, 2, "case-a", "Case A", (420, 220)),
        (&runs_.b, 2, "case-b", "Case B", (420, 220)),
        (&runs_.c, 2, "case-c", "Case C", (420, 220)),
        (&runs_.d, 0, "case-d", "Case D", (640, 200)),
    ] {
        let labelled = runs(c);
        let Some((label, run)) = labelled.get(k.min(labelled.len().saturating_sub(1))) else {
            continue;
        };
        let title = format!("{what}: {label}");
        let file = format!("animation-{case}.gif");
        let frames = write_gif(
            run,
            &dir.join(&file),
            &GifOptions {
                title: title.clone(),
                panel,
                ground: ground_height(case)?,
                // At most about 100 frames.
                every: run.snapshots.len().div_ceil(100).max(1),
                ..GifOptions::default()
            },
        )?;
        out.push(Figure {
            file,
            title,
            caption: format!("{frames} frames, von Mises stress on one scale for the whole run."),
        });
    }
    Ok(out)
}
