//! How the cost of a real-time frame grows with the mesh, in 2D and in 3D: case A's cantilever
//! refined in the plane (2D: `nx x ny` cells of 2 triangles; 3D: `nx x ny x nz` cubes of 6
//! tetrahedra), stepped at one frame per step (`dt = 1 / fps`) by implicit Euler, XPBD and VBD
//! at fixed settings on one thread, Neo-Hookean. The settings are the frame budget's
//! ([`crate::budget`]) common ones: implicit Euler's cheapest rung (velocity tolerance 1e-2
//! m/s), XPBD's and VBD's 10 iterations, so the cost per frame of a fixed amount of solver work
//! is what grows. Iterative solvers at a fixed iteration count cost about linearly in the mesh;
//! implicit Euler's sparse factorisation grows faster, and faster in 3D (fill).
//!
//! [`scaling`] runs the matrix and [`Scaling`] gives the markdown table and the log-log
//! chart (ms per frame against unknowns).

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use fem_render::chart::{LineChart, Scale, Series};
use fem_scene::SceneError;
use fem_solvers::SolverKind;
use serde::{Deserialize, Serialize};

use crate::budget::Framework;
use crate::run::{RunOptions, run_scene};
use crate::solid::{RunOptions3, run_scene3};

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalingSpec {
    /// Frames per second: one step of `1 / fps` a frame.
    pub fps: f64,
    /// Frames stepped per measurement.
    pub frames: u64,
    /// Measurements per point; the fastest counts (the others are the machine's noise).
    pub repeats: usize,
    /// 2D meshes, `[nx, ny]` cells of case A's 5 m x 1 m.
    pub sizes_2d: Vec<[usize; 2]>,
    /// 3D meshes, `[nx, ny, nz]` cubes of case A's 5 m x 1 m x 1 m.
    pub sizes_3d: Vec<[usize; 3]>,
}

impl ScalingSpec {
    /// The full measurement: 2D from 20 x 4 to 160 x 32 cells (160 to 10240 triangles), 3D
    /// from 10 x 2 x 2 to 40 x 8 x 8 (240 to 15360 tetrahedra); 9 frames, best of 3.
    pub fn full() -> Self {
        ScalingSpec {
            fps: 90.0,
            frames: 9,
            repeats: 3,
            sizes_2d: vec![[20, 4], [40, 8], [80, 16], [160, 32]],
            sizes_3d: vec![[10, 2, 2], [20, 4, 4], [40, 8, 8]],
        }
    }

    /// A quick one for the report: the two smallest sizes of each dimension and the third of
    /// 2D, 3 frames, one repeat (a few seconds).
    pub fn quick() -> Self {
        ScalingSpec {
            fps: 90.0,
            frames: 3,
            repeats: 1,
            sizes_2d: vec![[20, 4], [40, 8], [80, 16]],
            sizes_3d: vec![[10, 2, 2], [20, 4, 4]],
        }
    }
}

/// A solver measured: its solver, its setting in words and its `[solver]` keys.
pub type Measured = (SolverKind, String, Vec<(String, toml::Value)>);

/// The three solvers measured and their settings: the frame budget's rungs of the same names
/// ([`Framework::ladder`]).
pub fn settings() -> Vec<Measured> {
    [
        (Framework::Implicit, "velocity 1e-2 m/s"),
        (Framework::Xpbd, "10 iterations"),
        (Framework::Vbd, "10 iterations"),
    ]
    .into_iter()
    .filter_map(|(f, label)| {
        let rung = f.ladder().into_iter().find(|s| s.label == label)?;
        Some((f.solver(), format!("{}, {label}", f.name()), rung.values))
    })
    .collect()
}

/// One measurement.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// 2 or 3.
    pub dim: u8,
    /// The solver.
    pub solver: SolverKind,
    /// Its setting, in words.
    pub setting: String,
    /// `[nx, ny]` or `[nx, ny, nz]`.
    pub cells: Vec<usize>,
    /// Triangles or tetrahedra.
    pub elements: usize,
    /// Degrees of freedom: vertices x dimension.
    pub unknowns: usize,
    /// Stepping time per frame on one thread, ms (the fastest repeat).
    pub ms_per_frame: f64,
    /// Solver iterations per frame (Newton iterations for implicit Euler).
    pub iterations_per_frame: f64,
    /// Why the run did not complete, if it did not (then `ms_per_frame` is the completed
    /// steps').
    pub failure: Option<String>,
}

/// The measurements.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scaling {
    /// Frames per second.
    pub fps: f64,
    /// Frames per measurement.
    pub frames: u64,
    /// Repeats per point (the fastest counts).
    pub repeats: usize,
    /// Every point, 2D first, by solver then size.
    pub points: Vec<Point>,
}

/// Scene overrides setting the solver, its settings, Neo-Hookean and `frames` steps of
/// `1 / fps`, recording only the first and last frame.
fn overrides(
    solver: SolverKind,
    values: &[(String, toml::Value)],
    spec: &ScalingSpec,
    mesh: &[(&str, usize)],
) -> Vec<String> {
    let mut o = vec![
        format!("energy=\"{}\"", EnergyKind::NeoHookean.name()),
        format!("solver.kind=\"{}\"", solver.name()),
        format!("solver.dt={:e}", 1.0 / spec.fps),
        format!("solver.steps={}", spec.frames),
        format!("output.frame_every={}", spec.frames),
    ];
    o.extend(values.iter().map(|(k, v)| format!("solver.{k}={v}")));
    o.extend(mesh.iter().map(|(k, n)| format!("mesh.{k}={n}")));
    o
}

/// The fastest of `repeats` measurements (`None` for none).
fn fastest(
    repeats: usize,
    mut measure: impl FnMut() -> Result<Point, SceneError>,
) -> Result<Option<Point>, SceneError> {
    let mut best: Option<Point> = None;
    for _ in 0..repeats {
        let p = measure()?;
        if best
            .as_ref()
            .is_none_or(|b| p.ms_per_frame < b.ms_per_frame)
        {
            best = Some(p);
        }
    }
    Ok(best)
}

/// Run the matrix of `spec` (see the module docs); `progress` is told each point.
pub fn scaling(spec: &ScalingSpec, mut progress: impl FnMut(&str)) -> Result<Scaling, SceneError> {
    if !(spec.fps.is_finite() && spec.fps > 0.0) || spec.frames == 0 || spec.repeats == 0 {
        return Err(SceneError::Usage(format!(
            "scaling: fps {} must be a finite number > 0, frames {} and repeats {} at least 1",
            spec.fps, spec.frames, spec.repeats
        )));
    }
    let mut points = Vec::new();
    for (solver, setting, values) in settings() {
        for &[nx, ny] in &spec.sizes_2d {
            progress(&format!("2D {nx} x {ny}: {setting}"));
            let scene = fem_scene::cases::load_case(
                "case-a",
                &overrides(solver, &values, spec, &[("nx", nx), ("ny", ny)]),
            )?;
            points.extend(fastest(spec.repeats, || {
                let r = run_scene(
                    &scene,
                    &RunOptions {
                        threads: Some(1),
                        ..RunOptions::default()
                    },
                )?;
                let s = r.summary;
                Ok(Point {
                    dim: 2,
                    solver,
                    setting: setting.clone(),
                    cells: vec![nx, ny],
                    elements: s.triangles,
                    unknowns: 2 * s.vertices,
                    ms_per_frame: 1e3 * s.step_seconds / spec.frames as f64,
                    iterations_per_frame: s.solver_iterations as f64 / spec.frames as f64,
                    failure: s.blow_up_message,
                })
            })?);
        }
    }
    for (solver, setting, values) in settings() {
        for &[nx, ny, nz] in &spec.sizes_3d {
            progress(&format!("3D {nx} x {ny} x {nz}: {setting}"));
            let scene = fem_scene::solid::load_case3(
                "case-a-3d",
                &overrides(solver, &values, spec, &[("nx", nx), ("ny", ny), ("nz", nz)]),
            )?;
            points.extend(fastest(spec.repeats, || {
                let r = run_scene3(
                    &scene,
                    &RunOptions3 {
                        threads: Some(1),
                        ..RunOptions3::default()
                    },
                    None,
                )?;
                let s = r.summary;
                Ok(Point {
                    dim: 3,
                    solver,
                    setting: setting.clone(),
                    cells: vec![nx, ny, nz],
                    elements: s.tetrahedra,
                    unknowns: 3 * s.vertices,
                    ms_per_frame: 1e3 * s.step_seconds / spec.frames as f64,
                    iterations_per_frame: s.iterations as f64 / spec.frames as f64,
                    failure: s.blow_up_message,
                })
            })?);
        }
    }
    Ok(Scaling {
        fps: spec.fps,
        frames: spec.frames,
        repeats: spec.repeats,
        points,
    })
}

impl Scaling {
    /// The growth exponent of each dimension x solver: the slope of log(ms per frame) against
    /// log(unknowns) between its two largest meshes (`None` with fewer than two).
    pub fn slopes(&self) -> Vec<(u8, SolverKind, Option<f64>)> {
        let mut out = Vec::new();
        for dim in [2u8, 3] {
            for (solver, _, _) in settings() {
                let mine: Vec<&Point> = self
                    .points
                    .iter()
                    .filter(|p| p.dim == dim && p.solver == solver)
                    .collect();
                let slope = match mine.as_slice() {
                    [.., a, b] if a.ms_per_frame > 0.0 && b.ms_per_frame > 0.0 => Some(
                        (b.ms_per_frame / a.ms_per_frame).ln()
                            / (b.unknowns as f64 / a.unknowns as f64).ln(),
                    ),
                    _ => None,
                };
                out.push((dim, solver, slope));
            }
        }
        out
    }

    /// The table: one row per point, then the growth exponents.
    pub fn to_markdown(&self) -> String {
        let mut md = String::new();
        let _ = writeln!(
            md,
            "Case A, Neo-Hookean, one step of 1/{} s a frame, {} frames, one thread, the fastest of {} runs.\n",
            crate::budget::fmt_num(self.fps),
            self.frames,
            self.repeats
        );
        md.push_str("| dim | solver | mesh | elements | unknowns | ms/frame | iterations/frame |\n|---:|---|---|---:|---:|---:|---:|\n");
        for p in &self.points {
            let mesh: Vec<String> = p.cells.iter().map(|n| n.to_string()).collect();
            let _ = writeln!(
                md,
                "| {}D | {} | {} | {} | {} | {:.3} | {:.1}{} |",
                p.dim,
                p.setting,
                mesh.join(" x "),
                p.elements,
                p.unknowns,
                p.ms_per_frame,
                p.iterations_per_frame,
                p.failure
                    .as_ref()
                    .map_or(String::new(), |f| format!(" (failed: {f})"))
            );
        }
        md.push_str("\nGrowth exponent of the cost per frame in the unknowns, between the two largest meshes:\n\n| solver | 2D | 3D |\n|---|---:|---:|\n");
        let slopes = self.slopes();
        for (solver, setting, _) in settings() {
            let of = |dim: u8| {
                slopes
                    .iter()
                    .find(|(d, s, _)| *d == dim && *s == solver)
                    .and_then(|x| x.2)
                    .map_or("-".to_owned(), |x| format!("{x:.2}"))
            };
            let _ = writeln!(md, "| {setting} | {} | {} |", of(2), of(3));
        }
        md
    }

    /// Milliseconds per frame against unknowns, log-log: one curve per solver and dimension,
    /// and the frame budget `budget_ms` as a horizontal line.
    pub fn chart(&self, budget_ms: f64) -> LineChart {
        let mut series = Vec::new();
        for dim in [2u8, 3] {
            for (solver, setting, _) in settings() {
                let points: Vec<(f64, f64)> = self
                    .points
                    .iter()
                    .filter(|p| p.dim == dim && p.solver == solver && p.failure.is_none())
                    .map(|p| (p.unknowns as f64, p.ms_per_frame))
                    .collect();
                if !points.is_empty() {
                    series.push(Series {
                        label: format!("{dim}D {setting}"),
                        points,
                    });
                }
            }
        }
        let (lo, hi) = self
            .points
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
                (lo.min(p.unknowns as f64), hi.max(p.unknowns as f64))
            });
        if lo < hi {
            series.push(Series {
                label: format!("{} ms budget", crate::budget::fmt_num(budget_ms)),
                points: vec![(lo, budget_ms), (hi, budget_ms)],
            });
        }
        LineChart {
            title: format!(
                "Case A: cost of a frame (1/{} s, one step) against mesh size, one thread",
                crate::budget::fmt_num(self.fps)
            ),
            x_label: "unknowns (vertices x dimension)".into(),
            y_label: "ms per frame".into(),
            x_scale: Scale::Log,
            y_scale: Scale::Log,
            series,
            markers: true,
            ..LineChart::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three settings are found among the budget's rungs.
    #[test]
    fn the_settings_are_the_budgets_rungs() {
        let names: Vec<String> = settings().into_iter().map(|m| m.1).collect();
        assert_eq!(
            names,
            [
                "implicit, velocity 1e-2 m/s",
                "xpbd, 10 iterations",
                "vbd, 10 iterations"
            ]
        );
    }
}
