//! The paper's Table 1 (case A): the tip's downward displacement in mm at frames 10, 50, 120
//! and 200 for StVK, co-rotational and Neo-Hookean, beside the paper's values, plus the time of
//! 2000 steps per energy; and the calibration scan over the settings the paper does not state
//! (mesh, diagonal pattern, damping, tracked tip node).
//!
//! A frame is 10 steps of 1 ms (frame 10 = 0.1 s, where the tip has fallen 1/2 g t^2 = 49 mm).

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use serde::{Deserialize, Serialize};

use crate::run::{RunOptions, RunResult, run_scene};
use fem_core::structured::Diagonal;
use fem_scene::SceneError;
use fem_scene::cases::load_case;

/// The frames of Table 1.
pub const FRAMES: [u64; 4] = [10, 50, 120, 200];
/// Steps per frame.
pub const STEPS_PER_FRAME: u64 = 10;
/// The energies of Table 1, in its row order.
pub const ENERGIES: [EnergyKind; 3] = [
    EnergyKind::Stvk,
    EnergyKind::Corotational,
    EnergyKind::NeoHookean,
];
/// The paper's Table 1, mm (downward), rows in [`ENERGIES`] order.
pub const PAPER_MM: [[f64; 4]; 3] = [
    [49.0, 1269.0, 1948.0, 246.0],
    [49.0, 1270.0, 1880.0, 272.0],
    [49.0, 1271.0, 1865.0, 279.0],
];
/// The paper's time for 2000 steps, s (Section 4: "approximately 14 seconds" for StVK and
/// Neo-Hookean, "nearly 20 seconds" for co-rotational).
pub const PAPER_SECONDS: [f64; 3] = [14.0, 20.0, 14.0];

/// One energy's row.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table1Row {
    /// Energy name.
    pub energy: String,
    /// Our tip displacement, mm downward, at [`FRAMES`].
    pub ours_mm: [f64; 4],
    /// The paper's, mm.
    pub paper_mm: [f64; 4],
    /// `(ours - paper) / paper`.
    pub relative_difference: [f64; 4],
    /// Best wall time of the 2000 steps over the repeats, s.
    pub seconds: f64,
    /// The paper's time, s.
    pub paper_seconds: f64,
}

/// Table 1 as regenerated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table1 {
    /// The setting (mesh, diagonal, damping, tip), as text.
    pub setting: String,
    /// Rows in [`ENERGIES`] order.
    pub rows: Vec<Table1Row>,
    /// Whether the paper's ordering of the energies holds at each frame (values rounded to mm
    /// as the paper prints them).
    pub ordering_matches: [bool; 4],
    /// Largest |relative difference| over frames 10, 50 and 120 and every energy.
    pub max_relative_difference_frames_10_to_120: f64,
    /// Threads used for the timings.
    pub threads: usize,
}

/// The sign pattern of the paper's ordering at each frame, from its table: at frame 50 and
/// 200 StVK < co-rotational < Neo-Hookean, at frame 120 the reverse; frame 10 is a tie.
fn paper_order(frame: usize) -> Option<[usize; 3]> {
    match frame {
        1 | 3 => Some([0, 1, 2]), // ascending: S < C < N
        2 => Some([2, 1, 0]),     // ascending: N < C < S
        _ => None,
    }
}

/// Whether the rounded values of `mm` (rows in [`ENERGIES`] order) follow the paper's
/// ordering at `frame` (index into [`FRAMES`]), with gaps of at least `min_gap` mm.
pub fn ordering_holds(mm: &[[f64; 4]; 3], frame: usize, min_gap: f64) -> bool {
    match paper_order(frame) {
        None => {
            let r: Vec<f64> = mm.iter().map(|row| row[frame].round()).collect();
            r[0] == r[1] && r[1] == r[2]
        }
        Some(order) => order.windows(2).all(|w| {
            let (a, b) = (mm[w[0]][frame].round(), mm[w[1]][frame].round());
            b - a >= min_gap.max(1.0)
        }),
    }
}

/// The tip's downward displacement (mm) at [`FRAMES`] from a case A run.
pub fn tip_mm(result: &RunResult) -> Result<[f64; 4], SceneError> {
    let series = result
        .probe("tip")
        .ok_or_else(|| SceneError::Scene("case-a: the scene has no probe named `tip`".into()))?;
    let mut out = [f64::NAN; 4];
    for (k, frame) in FRAMES.iter().enumerate() {
        let step = frame * STEPS_PER_FRAME;
        let i = result
            .frame_times
            .iter()
            .position(|(s, _)| *s == step)
            .ok_or_else(|| {
                SceneError::Scene(format!(
                    "case-a: no frame recorded at step {step} (output.frame_every must divide {step} and the run must reach it)"
                ))
            })?;
        out[k] = -1e3 * series[i][1];
    }
    Ok(out)
}

/// Run case A (with `overrides`) for the three energies; time each over `repeats` runs (best).
pub fn table1(
    overrides: &[String],
    repeats: usize,
    threads: Option<usize>,
) -> Result<Table1, SceneError> {
    let mut rows = Vec::new();
    let mut mm = [[0.0; 4]; 3];
    let mut setting = String::new();
    let mut used_threads = 0;
    let base = load_case("case-a", overrides)?;
    for (r, energy) in ENERGIES.iter().enumerate() {
        let mut scene = base.clone();
        scene.scene.energy = *energy;
        if setting.is_empty() {
            setting = describe_setting(&scene);
        }
        let options = RunOptions {
            threads,
            ..RunOptions::default()
        };
        let mut best = f64::INFINITY;
        let mut first = None;
        for _ in 0..repeats.max(1) {
            let result = run_scene(&scene, &options)?;
            if let Some(m) = &result.summary.blow_up_message {
                return Err(SceneError::BlowUp(m.clone()));
            }
            best = best.min(result.summary.step_seconds);
            used_threads = result.summary.threads;
            first.get_or_insert(result);
        }
        let result = first.expect("at least one repeat");
        let ours = tip_mm(&result)?;
        mm[r] = ours;
        let paper = PAPER_MM[r];
        rows.push(Table1Row {
            energy: energy.name().into(),
            ours_mm: ours,
            paper_mm: paper,
            relative_difference: [0, 1, 2, 3].map(|k| (ours[k] - paper[k]) / paper[k]),
            seconds: best,
            paper_seconds: PAPER_SECONDS[r],
        });
    }
    let max_rel = rows
        .iter()
        .flat_map(|r| r.relative_difference[..3].iter().map(|d| d.abs()))
        .fold(0.0, f64::max);
    Ok(Table1 {
        setting,
        rows,
        ordering_matches: [0, 1, 2, 3].map(|f| ordering_holds(&mm, f, 1.0)),
        max_relative_difference_frames_10_to_120: max_rel,
        threads: used_threads,
    })
}

fn describe_setting(scene: &fem_scene::scene::LoadedScene) -> String {
    let s = &scene.scene;
    let m = &s.mesh;
    let diag = m.diagonal.unwrap_or_default().name();
    let tip = s
        .probes
        .iter()
        .find(|p| p.name == "tip")
        .map(|p| format!("[{}, {}]", p.point[0], p.point[1]))
        .unwrap_or_default();
    format!(
        "mesh {}x{} cells, {diag} diagonals; damping c = {} 1/s; tip node nearest {tip} m; dt = {:e} s; gravity {} m/s^2; {}",
        m.nx.unwrap_or(0),
        m.ny.unwrap_or(0),
        damping_of(scene),
        s.solver.dt,
        -s.gravity[1],
        match s.material.plane {
            fem_core::PlaneModel::PlaneStrain => "plane strain",
            fem_core::PlaneModel::PlaneStress => "plane stress",
        }
    )
}

impl Table1 {
    /// Markdown: the table beside the paper's, relative differences, timings.
    pub fn to_markdown(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "Tip vertical displacement (mm, downward) at frames 10, 50, 120, 200 (one frame = 10 steps of 1 ms); ours / paper (relative difference).\n\nSetting: {}.\n",
            self.setting
        );
        out.push_str(
            "| energy | frame 10 | frame 50 | frame 120 | frame 200 |\n|---|---|---|---|---|\n",
        );
        for r in &self.rows {
            let _ = write!(out, "| {} |", r.energy);
            for k in 0..4 {
                let _ = write!(
                    out,
                    " {:.0} / {:.0} ({:+.1}%) |",
                    r.ours_mm[k],
                    r.paper_mm[k],
                    100.0 * r.relative_difference[k]
                );
            }
            out.push('\n');
        }
        let _ = writeln!(
            out,
            "\nPaper's ordering of the energies holds at frames 10/50/120/200: {}. Largest |relative difference| over frames 10-120: {:.1}%.\n",
            self.ordering_matches
                .iter()
                .map(|b| if *b { "yes" } else { "no" })
                .collect::<Vec<_>>()
                .join("/"),
            100.0 * self.max_relative_difference_frames_10_to_120
        );
        let _ = writeln!(
            out,
            "| energy | 2000 steps, ours (ms, best, {} thread(s)) | paper (s) | speed-up |\n|---|---|---|---|",
            self.threads
        );
        for r in &self.rows {
            let _ = writeln!(
                out,
                "| {} | {:.2} | {:.0} | {:.0}x |",
                r.energy,
                1e3 * r.seconds,
                r.paper_seconds,
                r.paper_seconds / r.seconds
            );
        }
        out
    }

    /// The largest difference, mm, between this table's displacements and `baseline`'s (rows
    /// matched by energy), and a description of where it is.
    pub fn max_difference_mm(&self, baseline: &Table1) -> (f64, String) {
        let mut worst = (0.0, String::from("no difference"));
        for r in &self.rows {
            match baseline.rows.iter().find(|b| b.energy == r.energy) {
                None => {
                    return (
                        f64::INFINITY,
                        format!("{} is missing from the baseline", r.energy),
                    );
                }
                Some(b) => {
                    for ((frame, now), then) in FRAMES.iter().zip(r.ours_mm).zip(b.ours_mm) {
                        let d = (now - then).abs();
                        if d > worst.0 || d.is_nan() {
                            worst = (
                                d,
                                format!(
                                    "{} frame {frame}: {now:.3} mm now, {then:.3} mm in the baseline",
                                    r.energy
                                ),
                            );
                        }
                    }
                }
            }
        }
        worst
    }
}

/// One setting of the calibration scan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationRow {
    /// Cells along x and y.
    pub cells: [usize; 2],
    /// Diagonal pattern (its name in scene files).
    pub diagonal: String,
    /// Damping, 1/s.
    pub damping: f64,
    /// Tracked tip point, m.
    pub tip: [f64; 2],
    /// Tip displacement, mm, rows in [`ENERGIES`] order (NaN when the run blew up).
    pub mm: [[f64; 4]; 3],
    /// Paper's ordering holds at every frame with gaps of at least 3 mm at frames 120, 200.
    pub ordering: bool,
    /// Largest |relative difference| over frames 10-120.
    pub max_relative_10_to_120: f64,
    /// RMS relative difference over all 12 entries.
    pub rms_relative: f64,
}

/// The axes of the calibration scan.
#[derive(Clone, Debug)]
pub struct CalibrationGrid {
    /// Cells `(nx, ny)`.
    pub cells: Vec<[usize; 2]>,
    /// Diagonal patterns.
    pub diagonals: Vec<Diagonal>,
    /// Damping values, 1/s.
    pub damping: Vec<f64>,
    /// Tip points, m.
    pub tips: Vec<[f64; 2]>,
}

impl Default for CalibrationGrid {
    fn default() -> Self {
        CalibrationGrid {
            cells: vec![[10, 2], [15, 3], [20, 4], [25, 5], [10, 4], [15, 4]],
            diagonals: Diagonal::ALL.to_vec(),
            damping: vec![0.0, 0.05, 0.1, 0.15, 0.175, 0.2, 0.3, 0.5],
            tips: vec![[5.0, 0.0], [5.0, 0.5], [5.0, 1.0]],
        }
    }
}

/// One setting of the calibration scan: mesh cells, diagonal, damping (1/s), tip point (m).
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// Cells `(nx, ny)`.
    pub cells: [usize; 2],
    /// Diagonal pattern.
    pub diagonal: Diagonal,
    /// Damping, 1/s.
    pub damping: f64,
    /// Tip point, m.
    pub tip: [f64; 2],
}

/// Evaluate one setting: the three energies' tip displacements and the scores.
pub fn evaluate(setting: &Setting) -> Result<CalibrationRow, SceneError> {
    let Setting {
        cells: [nx, ny],
        diagonal,
        damping,
        tip,
    } = setting.clone();
    let mut mm = [[f64::NAN; 4]; 3];
    let base = load_case("case-a", &[])?;
    for (r, energy) in ENERGIES.iter().enumerate() {
        let mut scene = base.clone();
        let s = &mut scene.scene;
        s.mesh.nx = Some(nx);
        s.mesh.ny = Some(ny);
        s.mesh.diagonal = Some(diagonal);
        s.solver
            .set("damping", damping)
            .map_err(|e| SceneError::Scene(format!("{}: {e}", scene.origin)))?;
        if let Some(p) = scene.scene.probes.first_mut() {
            p.point = tip;
        }
        scene.scene.energy = *energy;
        scene.scene.output.frames = false;
        scene.validate()?;
        let result = run_scene(&scene, &RunOptions::default())?;
        if !result.summary.blew_up {
            mm[r] = tip_mm(&result)?;
        }
    }
    let finite = mm.iter().flatten().all(|v| v.is_finite());
    let ordering = finite && (0..4).all(|f| ordering_holds(&mm, f, if f >= 2 { 3.0 } else { 1.0 }));
    let rel: Vec<f64> = (0..3)
        .flat_map(|r| (0..4).map(move |k| (r, k)))
        .map(|(r, k)| (mm[r][k] - PAPER_MM[r][k]) / PAPER_MM[r][k])
        .collect();
    let max_rel = (0..3)
        .flat_map(|r| (0..3).map(move |k| (r, k)))
        .map(|(r, k)| rel[4 * r + k].abs())
        .fold(0.0, f64::max);
    let rms = (rel.iter().map(|d| d * d).sum::<f64>() / rel.len() as f64).sqrt();
    Ok(CalibrationRow {
        cells: [nx, ny],
        diagonal: diagonal.name().into(),
        damping,
        tip,
        mm,
        ordering,
        max_relative_10_to_120: if finite { max_rel } else { f64::NAN },
        rms_relative: if finite { rms } else { f64::NAN },
    })
}

/// Run the scan (every combination of the grid, three energies each), best first: settings
/// whose ordering holds (gaps of at least 3 mm at frames 120 and 200, where the paper's are
/// 7-68 mm, so a sub-millimetre tie does not count), then by RMS relative difference.
pub fn calibrate(grid: &CalibrationGrid) -> Result<Vec<CalibrationRow>, SceneError> {
    let mut rows = Vec::new();
    for &cells in &grid.cells {
        for diagonal in &grid.diagonals {
            for &damping in &grid.damping {
                for &tip in &grid.tips {
                    rows.push(evaluate(&Setting {
                        cells,
                        diagonal: *diagonal,
                        damping,
                        tip,
                    })?);
                }
            }
        }
    }
    rows.sort_by(|a, b| {
        b.ordering
            .cmp(&a.ordering)
            .then(a.rms_relative.total_cmp(&b.rms_relative))
    });
    Ok(rows)
}

/// The scene's own setting (`case-a` with `overrides`).
pub fn scene_setting(overrides: &[String]) -> Result<Setting, SceneError> {
    let scene = load_case("case-a", overrides)?;
    let s = &scene.scene;
    Ok(Setting {
        cells: [s.mesh.nx.unwrap_or(1), s.mesh.ny.unwrap_or(1)],
        diagonal: s.mesh.diagonal.unwrap_or_default(),
        damping: damping_of(&scene),
        tip: s
            .probes
            .iter()
            .find(|p| p.name == "tip")
            .map_or([5.0, 0.0], |p| p.point),
    })
}

/// One-factor-at-a-time sensitivity around `base`: for each factor of `grid`, the table of
/// every value with the other factors held at `base`. Markdown.
pub fn sensitivity(base: &Setting, grid: &CalibrationGrid) -> Result<String, SceneError> {
    let mut out = String::new();
    let mut section = |title: &str, settings: Vec<Setting>| -> Result<(), SceneError> {
        let rows = settings
            .iter()
            .map(evaluate)
            .collect::<Result<Vec<_>, _>>()?;
        let _ = writeln!(out, "\n#### {title}\n");
        out.push_str(&calibration_markdown(&rows, rows.len()));
        Ok(())
    };
    section(
        "Mesh (cells)",
        grid.cells
            .iter()
            .map(|&cells| Setting {
                cells,
                ..base.clone()
            })
            .collect(),
    )?;
    section(
        "Diagonal pattern",
        grid.diagonals
            .iter()
            .map(|d| Setting {
                diagonal: *d,
                ..base.clone()
            })
            .collect(),
    )?;
    section(
        "Damping",
        grid.damping
            .iter()
            .map(|&damping| Setting {
                damping,
                ..base.clone()
            })
            .collect(),
    )?;
    section(
        "Tracked tip node",
        grid.tips
            .iter()
            .map(|&tip| Setting {
                tip,
                ..base.clone()
            })
            .collect(),
    )?;
    Ok(out)
}

/// Markdown of the `top` best calibration rows.
pub fn calibration_markdown(rows: &[CalibrationRow], top: usize) -> String {
    let mut out = String::from(
        "| # | cells | diagonal | damping (1/s) | tip (m) | ordering | max rel. diff. frames 10-120 | RMS rel. diff. | StVK (mm) | co-rotational (mm) | Neo-Hookean (mm) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (i, r) in rows.iter().take(top).enumerate() {
        let fmt = |row: &[f64; 4]| {
            row.iter()
                .map(|v| format!("{v:.0}"))
                .collect::<Vec<_>>()
                .join("/")
        };
        let _ = writeln!(
            out,
            "| {} | {}x{} | {} | {} | [{}, {}] | {} | {:.1}% | {:.1}% | {} | {} | {} |",
            i + 1,
            r.cells[0],
            r.cells[1],
            r.diagonal,
            r.damping,
            r.tip[0],
            r.tip[1],
            if r.ordering { "yes" } else { "no" },
            100.0 * r.max_relative_10_to_120,
            100.0 * r.rms_relative,
            fmt(&r.mm[0]),
            fmt(&r.mm[1]),
            fmt(&r.mm[2])
        );
    }
    out
}

/// The damping rate of the scene's solver (its `damping` parameter), 1/s; 0 when it has none.
fn damping_of(scene: &fem_scene::scene::LoadedScene) -> f64 {
    scene
        .scene
        .solver
        .get("damping")
        .and_then(|v| v.as_float())
        .unwrap_or(0.0)
}
