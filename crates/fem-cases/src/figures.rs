//! The paper's figures, regenerated from runs of the built-in cases, and the plots that go with
//! them (probe curves, the case B stability map), as written by `fem2d figures` (and
//! `cargo xtask figures`, into `docs/figures/`) and embedded by `fem2d report`.
//!
//! - Figure 1: the mesh pipeline's stages on the built-in body (case D's settings);
//! - Figure 2: case A, the cantilever under StVK, co-rotational and Neo-Hookean side by side,
//!   at Table 1's frames 50, 120 and 200;
//! - Figure 3: case B, the stretched bar under the three energies (lateral contraction);
//! - Figure 4: case C, explicit FEM, PBD and XPBD side by side at explicit's deepest deflection;
//! - Figure 5: case D, the scene (body, skeleton, ground, debris), the soft tissue's von Mises
//!   map at its peak and at rest (bone drawn flat and outlined, so its stress, a thousand times
//!   the soft tissue's, does not swamp the scale), and the contact pressure against x on the
//!   debris and on the ground at both frames.

use std::path::Path;
use std::time::Instant;

use fem_core::energy::EnergyKind;
use fem_render::Image;
use fem_render::chart::{GridCell, GridChart, LineChart, Series};
use fem_render::frame::{region_edges, render};

use crate::compare::{CompareSpec, Comparison, compare};
use crate::pictures::{
    FieldKind, FramePicture, GifOptions, overlay_pressure, pressure_range, probe_chart,
    render_side_by_side, snapshot_at, style, write_chart, write_gif,
};
use crate::run::{RunResult, Snapshot};
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

    // Figure 2 in 3D: the same beam as a box of tetrahedra (case-a-3d, StVK).
    let (fig2_3d, tips, _) = crate::solid::case_a_3d_figure()?;
    write_png(&fig2_3d, dir, "figure-2-case-a-3d.png")?;
    figures.push(Figure {
        file: "figure-2-case-a-3d.png".into(),
        title: "Figure 2 in 3D: case A as a box of tetrahedra".into(),
        caption: format!(
            "The same cantilever extruded by 1 m (20 x 4 x 4 cubes, 1920 tetrahedra, the built-in case-a-3d: StVK, explicit, dt = 0.5 ms, side faces free) at t = 0.5, 1.2 and 2.0 s, its surface coloured by von Mises stress on one scale and seen from azimuth 30 deg, elevation 25 deg (painter's algorithm). Tip deflection: {} m.",
            tips.iter().map(|t| format!("{t:.3}")).collect::<Vec<_>>().join(", ")
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

    // Figure 5: case D's scene, the soft tissue's von Mises map at its peak and at rest, and
    // the contact pressure along the body.
    let d = runs(&runs_.d);
    let (_, drun) = d
        .first()
        .ok_or_else(|| SceneError::Io("case D did not run".into()))?;
    figures.push(figure_5(drun, dir)?);

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

/// The flat colour of bone in the stress maps: a light ivory, apart from every colour of
/// viridis.
pub const BONE_COLOR: [u8; 3] = [236, 228, 204];

/// The elements a stress map draws flat (material region other than the base, 0) and the
/// outlines of those regions: the edges between elements of different mesh regions (the
/// mesh's own tissues when it carries them, else the material regions) and the flat
/// elements' edges on the body's boundary.
pub fn flat_regions(run: &RunResult) -> (Vec<bool>, Vec<[usize; 2]>) {
    let flat: Vec<bool> = run.region_tags.iter().map(|&t| t != 0).collect();
    let triangles: Vec<[usize; 3]> = run
        .triangles
        .iter()
        .map(|t| t.map(|i| i as usize))
        .collect();
    let tags = if run.mesh_regions.0.len() == triangles.len() {
        &run.mesh_regions.0
    } else {
        &run.region_tags
    };
    // A tag is outlined on the boundary when its elements are drawn flat.
    let mut outlined = vec![false; tags.iter().max().map_or(0, |&t| t as usize + 1)];
    for (&t, &f) in tags.iter().zip(&flat) {
        outlined[t as usize] |= f;
    }
    let edges = region_edges(&triangles, tags, |t| outlined[t as usize]);
    (flat, edges)
}

/// The largest von Mises stress of the elements not drawn flat in `snapshot`, Pa, with its
/// element; `None` when no such element has a finite stress.
pub fn unmasked_peak(snapshot: &Snapshot, flat: &[bool]) -> Option<(f64, usize)> {
    snapshot
        .von_mises
        .iter()
        .zip(flat)
        .enumerate()
        .filter(|(_, (v, f))| !**f && v.is_finite())
        .map(|(e, (&v, _))| (v, e))
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// What a run of loaded boundary edges touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Touching {
    /// The horizontal ground.
    Ground,
    /// Obstacle `k` of the frame.
    Obstacle(usize),
}

/// One contact patch of a frame: consecutive boundary edges with a positive pressure at
/// either end, walked along the boundary (its two end vertices are the first unloaded ones,
/// so a line through its points is the piecewise-linear pressure of
/// `fem_solvers::pressure`).
#[derive(Clone, Debug, PartialEq)]
pub struct PressurePatch {
    /// Closest to the loaded vertices on average: the ground or an obstacle.
    pub touching: Touching,
    /// The patch's vertices in boundary order: `(vertex, position (m), pressure (Pa))`.
    pub points: Vec<(usize, [f64; 2], f64)>,
}

/// The contact patches of `snapshot` of `run`, in the order of the boundary, each with what it
/// touches: the ground at height `ground` (when given) or the nearest obstacle of the
/// snapshot. A non-finite pressure counts as unloaded.
pub fn contact_patches(
    run: &RunResult,
    snapshot: &Snapshot,
    ground: Option<f64>,
) -> Vec<PressurePatch> {
    let p = &snapshot.contact_pressure;
    let x = &snapshot.positions;
    if p.len() != x.len() {
        return Vec::new();
    }
    let loaded = |v: usize| p[v].is_finite() && p[v] > 0.0;
    // Boundary edges (used by one triangle), oriented as in it; next[a] = b.
    let mut next = vec![u32::MAX; x.len()];
    for [a, b] in fem_solvers::model::boundary_edges(&run.triangles) {
        next[a as usize] = b;
    }
    // Walk each boundary loop from an unloaded edge, cutting it into runs of loaded edges.
    let mut seen = vec![false; x.len()];
    let mut patches = Vec::new();
    for start in 0..x.len() {
        if next[start] == u32::MAX || seen[start] {
            continue;
        }
        let mut cycle = vec![start];
        seen[start] = true;
        let mut v = next[start] as usize;
        while v != start && next[v] != u32::MAX && !seen[v] {
            seen[v] = true;
            cycle.push(v);
            v = next[v] as usize;
        }
        let n = cycle.len();
        let edge_loaded = |k: usize| loaded(cycle[k % n]) || loaded(cycle[(k + 1) % n]);
        let Some(first) = (0..n).find(|&k| !edge_loaded(k)) else {
            // The whole loop is loaded: one closed patch.
            patches.push(cycle.clone());
            continue;
        };
        let mut current: Vec<usize> = Vec::new();
        for k in first + 1..=first + n {
            if edge_loaded(k) {
                if current.is_empty() {
                    current.push(cycle[k % n]);
                }
                current.push(cycle[(k + 1) % n]);
            } else if !current.is_empty() {
                patches.push(std::mem::take(&mut current));
            }
        }
    }
    patches
        .into_iter()
        .map(|vs| {
            let touching = nearest_contact(
                vs.iter().filter(|&&v| loaded(v)).map(|&v| x[v]),
                ground,
                &snapshot.obstacles,
            );
            PressurePatch {
                touching,
                points: vs.iter().map(|&v| (v, x[v], p[v])).collect(),
            }
        })
        .collect()
}

/// The ground or the obstacle closest on average to `points`.
fn nearest_contact(
    points: impl Iterator<Item = [f64; 2]>,
    ground: Option<f64>,
    obstacles: &[Vec<[f64; 2]>],
) -> Touching {
    let mut sums = vec![0.0; obstacles.len() + 1];
    for q in points {
        sums[0] += ground.map_or(f64::INFINITY, |g| (q[1] - g).abs());
        for (k, poly) in obstacles.iter().enumerate() {
            let d = (0..poly.len())
                .map(|i| {
                    let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                    fem_mesh::quality::segment_distance(q, a, b)
                })
                .fold(f64::INFINITY, f64::min);
            sums[k + 1] += d;
        }
    }
    let best = (0..sums.len())
        .min_by(|&a, &b| sums[a].total_cmp(&sums[b]))
        .unwrap_or(0);
    if best == 0 && ground.is_some() {
        Touching::Ground
    } else {
        Touching::Obstacle(best.saturating_sub(1))
    }
}

/// The series of one kind of contact of a frame: pressure (kPa) against x (m), the patches
/// one after another, a NaN point between two so the line breaks there.
fn pressure_series(patches: &[PressurePatch], on_ground: bool, label: String) -> Series {
    let mut points = Vec::new();
    for patch in patches
        .iter()
        .filter(|p| (p.touching == Touching::Ground) == on_ground)
    {
        if !points.is_empty() {
            points.push((f64::NAN, f64::NAN));
        }
        points.extend(patch.points.iter().map(|(_, q, pa)| (q[0], pa * 1e-3)));
    }
    Series { label, points }
}

/// The largest pressure of the patches touching the ground (`on_ground`) or an obstacle, Pa,
/// and its x, m.
fn patch_peak(patches: &[PressurePatch], on_ground: bool) -> Option<(f64, f64)> {
    patches
        .iter()
        .filter(|p| (p.touching == Touching::Ground) == on_ground)
        .flat_map(|p| p.points.iter())
        .filter(|(_, _, pa)| pa.is_finite())
        .map(|(_, q, pa)| (*pa, q[0]))
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// The chart of the contact pressure against x on the obstacles and on the ground, at each
/// `(name, snapshot)` (e.g. peak and rest); `width` pixels wide.
pub fn contact_pressure_chart(
    run: &RunResult,
    frames: &[(&str, &Snapshot)],
    ground: Option<f64>,
    title: &str,
    width: u32,
) -> LineChart {
    let mut series = Vec::new();
    for on_ground in [false, true] {
        for (name, snap) in frames {
            let patches = contact_patches(run, snap, ground);
            let what = if on_ground { "ground" } else { "debris" };
            let s = pressure_series(
                &patches,
                on_ground,
                format!("{what}, {name} (t = {:.2} s)", snap.time),
            );
            if !s.points.is_empty() {
                series.push(s);
            }
        }
    }
    LineChart {
        title: title.to_owned(),
        x_label: "x along the body, head at 0 [m]".into(),
        y_label: "contact pressure [kPa]".into(),
        series,
        markers: true,
        width,
        height: 380,
        ..LineChart::default()
    }
}

/// Figure 5 from case D's run into `dir`.
fn figure_5(run: &RunResult, dir: &Path) -> Result<Figure, SceneError> {
    let scene = load_case("case-d", &[])?;
    let ground = ground_height("case-d")?;
    let s = &run.summary;
    let first = run.snapshots.first().expect("a run keeps its first frame");
    let rest = run.snapshots.last().expect("a run keeps its last frame");
    let (flat, edges) = flat_regions(run);
    // The soft tissue's peak frame (the whole body's peak is in the bone).
    let peak = run
        .snapshots
        .iter()
        .filter_map(|x| unmasked_peak(x, &flat).map(|p| (p, x)))
        .max_by(|a, b| a.0.0.total_cmp(&b.0.0))
        .map_or(rest, |(_, x)| x);
    let (soft_peak, soft_element) = unmasked_peak(peak, &flat).unwrap_or((0.0, 0));
    let soft_rest = unmasked_peak(rest, &flat).map_or(0.0, |p| p.0);
    let range = (0.0, (soft_peak.max(soft_rest) * 1e-3).max(1e-9));
    let flat_label = s
        .regions
        .iter()
        .skip(1)
        .map(|r| r.name.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    fn with_bones<'a>(
        p: FramePicture<'a>,
        ground: Option<f64>,
        (flat, edges, label): (&[bool], &[[usize; 2]], &str),
    ) -> FramePicture<'a> {
        p.with_ground(ground)
            .with_flat_elements(flat.to_vec(), BONE_COLOR, label)
            .with_outline_edges(edges.to_vec())
    }
    let bones = (flat.as_slice(), edges.as_slice(), flat_label.as_str());
    let decorate = |p| with_bones(p, ground, bones);
    let panel = (900, 250);
    let scene_pic = decorate(FramePicture::new(
        run,
        first,
        FieldKind::VonMises,
        "(a) the scene at t = 0: soft tissue (blue), bones (ivory, outlined), debris, ground",
    ))
    .plain();
    let maps = [
        (peak, "(b) at the soft tissue's peak"),
        (rest, "(c) at rest"),
    ];
    let pictures: Vec<FramePicture<'_>> = maps
        .iter()
        .map(|(snap, what)| {
            decorate(FramePicture::new(
                run,
                snap,
                FieldKind::VonMises,
                &format!(
                    "{what}, t = {:.2} s: von Mises stress of the soft tissue, contact pressure",
                    snap.time
                ),
            ))
            .with_contact_pressure()
        })
        .collect();
    let refs: Vec<&FramePicture<'_>> = pictures.iter().chain([&scene_pic]).collect();
    let bounds = refs.iter().map(|p| p.bounds()).reduce(|a, b| {
        (
            [a.0[0].min(b.0[0]), a.0[1].min(b.0[1])],
            [a.1[0].max(b.1[0]), a.1[1].max(b.1[1])],
        )
    });
    let pressure = pressure_range(&refs);
    let draw = |p: &FramePicture<'_>, title: &str| -> Result<Image, SceneError> {
        let mut st = style(FieldKind::VonMises, title, panel.0, panel.1);
        st.range = Some(range);
        st.bounds = bounds;
        let mut r = render(&[p.view()], &st)
            .map_err(|e| SceneError::Io(format!("rendering figure 5: {e}")))?;
        if pressure.is_some() {
            overlay_pressure(&mut r, &[p], pressure)?;
        }
        Ok(r.image)
    };
    let mut rows = vec![draw(
        &scene_pic,
        "Figure 5. Case D: debris falling on the shin of a body lying on the ground",
    )?];
    for p in &pictures {
        rows.push(draw(p, "")?);
    }
    let width = rows.iter().map(Image::width).max().unwrap_or(900);
    let chart = contact_pressure_chart(
        run,
        &[("peak", peak), ("rest", rest)],
        ground,
        "(d) contact pressure along the body on the debris and on the ground",
        width,
    );
    rows.push(chart.to_png().map_err(render_err)?);
    let fig5 = Image::vstack(&rows, 6, [255, 255, 255, 255]);
    write_png(&fig5, dir, "figure-5-case-d.png")?;

    // The caption's numbers.
    let peak_tri = run.triangles[soft_element].map(|i| peak.positions[i as usize]);
    let at = [
        peak_tri.iter().map(|q| q[0]).sum::<f64>() / 3.0,
        peak_tri.iter().map(|q| q[1]).sum::<f64>() / 3.0,
    ];
    let near = nearest_flat_region(run, peak, &flat, at)
        .map_or_else(String::new, |name| format!(", next to the {name}"));
    let contacts = |snap: &Snapshot| {
        let patches = contact_patches(run, snap, ground);
        let say = |on_ground: bool, what: &str| {
            patch_peak(&patches, on_ground).map_or_else(
                || format!("no contact with the {what}"),
                |(pa, x)| format!("{:.0} kPa on the {what} at x = {x:.2} m", pa * 1e-3),
            )
        };
        format!("{}, {}", say(false, "debris"), say(true, "ground"))
    };
    Ok(Figure {
        file: "figure-5-case-d.png".into(),
        title: "Figure 5: case D, the body under debris".into(),
        caption: format!(
            "A {} kg slab falls on the shin of the body lying on the ground ({} triangles, {} of them {flat_label}). The von Mises colour scale spans the soft tissue only, 0 to {:.1} kPa over the two frames shown; {flat_label} is drawn flat and outlined (its own peak, {:.0} kPa, would swamp the scale). The soft tissue's peak, {:.1} kPa at t = {:.2} s, is at x = {:.3} m, y = {:.3} m{near}; at rest (t = {:.2} s) its largest stress is {:.1} kPa. Peak contact pressure at t = {:.2} s: {}; at rest: {}.",
            fmt_mass(&scene),
            s.triangles,
            flat.iter().filter(|&&f| f).count(),
            range.1,
            s.max_von_mises * 1e-3,
            soft_peak * 1e-3,
            peak.time,
            at[0],
            at[1],
            rest.time,
            soft_rest * 1e-3,
            peak.time,
            contacts(peak),
            contacts(rest),
        ),
    })
}

/// The mesh region name of the flat element whose centroid in `snapshot` is closest to `at`.
fn nearest_flat_region(
    run: &RunResult,
    snapshot: &Snapshot,
    flat: &[bool],
    at: [f64; 2],
) -> Option<String> {
    let (tags, names) = &run.mesh_regions;
    let centroid = |t: &[u32; 3]| {
        let q = t.map(|i| snapshot.positions[i as usize]);
        [
            (q[0][0] + q[1][0] + q[2][0]) / 3.0,
            (q[0][1] + q[1][1] + q[2][1]) / 3.0,
        ]
    };
    let (e, _) = run
        .triangles
        .iter()
        .enumerate()
        .filter(|(e, _)| flat[*e])
        .map(|(e, t)| {
            let c = centroid(t);
            (e, (c[0] - at[0]).hypot(c[1] - at[1]))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    names.get(*tags.get(e)? as usize).cloned()
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
