//! The energy x solver matrix on one scene: every combination run from the same scene, one
//! row each, with the probes' displacements, the peak von Mises stress, the cost and whether
//! the run stayed stable; optionally variants of solver parameters (several iteration counts,
//! both XPBD constraint forms: any parameter key), and each probe's deviation from the run of
//! the default solver (explicit) with the same energy (case C).
//!
//! Each row is the scene changed as a typed value (energy, solver, parameters), never through
//! its text.
//!
//! [`compare`] runs a 2D scene, [`compare3`] a 3D one (`dim = 3`): the same matrix and the
//! same [`Comparison`], with three-component probes and the tetrahedron count in
//! [`Comparison::triangles`]. A combination that cannot run in 3D (a solver without a 3D path,
//! an option the 3D path refuses) is a row with its error, as in 2D.

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use fem_solvers::{Clock, SolverKind};
use serde::{Deserialize, Serialize};

use crate::run::{RunOptions, RunResult, run_scene};
use crate::solid::{RunOptions3, run_scene3};
use fem_scene::SceneError;
use fem_scene::SolverSpec;
use fem_scene::scene::LoadedScene;
use fem_scene::solid::{LoadedScene3, RunResult3};

/// Values of one solver parameter to compare: rows are made for each value, for the solvers
/// that have the parameter (`iterations` for PBD and XPBD, `xpbd_form` for XPBD).
#[derive(Clone, Debug, PartialEq)]
pub struct VariantAxis {
    /// The parameter's key in the scene's `[solver]` table.
    pub key: String,
    /// Its values.
    pub values: Vec<toml::Value>,
}

impl VariantAxis {
    /// The label of one value in a row's variant: `20 it` for an iteration count, the value
    /// itself otherwise.
    fn label(&self, value: &toml::Value) -> String {
        match (self.key.as_str(), value) {
            ("iterations", toml::Value::Integer(n)) => format!("{n} it"),
            (_, toml::Value::String(s)) => s.clone(),
            (_, v) => v.to_string(),
        }
    }
}

/// What to compare.
#[derive(Clone, Debug)]
pub struct CompareSpec {
    /// Energies (rows are grouped by energy).
    pub energies: Vec<EnergyKind>,
    /// Solvers.
    pub solvers: Vec<SolverKind>,
    /// Parameter variants, in label order (empty: the scene's parameters). A solver without
    /// an axis's key gets one row for that axis.
    pub variants: Vec<VariantAxis>,
    /// Worker threads per run.
    pub threads: Option<usize>,
    /// Keep each row's run, with every `n`-th frame as a snapshot, in [`Comparison::runs`]
    /// (for pictures). `None`: keep nothing. 2D only: [`compare3`] refuses it.
    pub snapshot_every: Option<usize>,
}

/// One combination's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompareRow {
    /// The energy (its name in files).
    pub energy: EnergyKind,
    /// The solver (its name in files).
    pub solver: SolverKind,
    /// Solver variant (`consistent, 20 it`), empty for a solver without variants.
    pub variant: String,
    /// Whether the run finished without blowing up.
    pub stable: bool,
    /// Steps completed.
    pub steps_completed: u64,
    /// Per probe: name, final displacement `[ux, uy]` (`[ux, uy, uz]` in 3D; m), smallest uy
    /// (m).
    pub probes: Vec<ProbeCell>,
    /// Peak per-element von Mises over the recorded frames, Pa.
    pub max_von_mises: f64,
    /// Smallest det F over the run.
    pub min_det_f: f64,
    /// Most inverted elements in a step.
    pub inverted_elements: usize,
    /// Wall time of the steps, s.
    pub step_seconds: f64,
    /// Element-steps per second.
    pub element_steps_per_second: f64,
    /// Simulated seconds per wall second.
    pub real_time_factor: f64,
    /// The error, when the combination could not run (e.g. an energy's parameter domain).
    pub error: Option<String>,
}

/// A probe in a comparison row.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeCell {
    /// Probe name.
    pub name: String,
    /// Final displacement, m: `[ux, uy]` in 2D, `[ux, uy, uz]` in 3D.
    pub final_displacement: Vec<f64>,
    /// Smallest vertical displacement over the run, m.
    pub min_uy: f64,
    /// Root-mean-square distance of the displacement curve from the explicit run of the same
    /// energy over the common frames, m (`None` without an explicit row).
    pub rms_vs_explicit: Option<f64>,
}

/// The comparison of one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Comparison {
    /// Scene name.
    pub scene: String,
    /// Cells of the mesh: triangles in 2D, tetrahedra in 3D (see [`Comparison::dim`]).
    pub triangles: usize,
    /// The scene's dimension, 2 or 3 (the probes' component count). Written to JSON in 3D
    /// only, so a 2D comparison's JSON has no `dim` key; read as 2 when absent.
    #[serde(default = "two", skip_serializing_if = "is_two")]
    pub dim: u8,
    /// The solver the scene itself names (the one a case's targets are stated for).
    pub scene_solver: SolverKind,
    /// Time step, s.
    pub dt: f64,
    /// Steps per run.
    pub steps: u64,
    /// The rows.
    pub rows: Vec<CompareRow>,
    /// Each row's probe curves: frame times (s; load factors for static rows) and, per probe,
    /// the displacement at each frame (m). Empty for rows that could not run.
    #[serde(skip)]
    pub curves: Vec<Curves>,
    /// Each row's run when [`CompareSpec::snapshot_every`] is set (`None` for rows that could
    /// not run); empty otherwise (always empty in 3D).
    #[serde(skip)]
    pub runs: Vec<Option<RunResult>>,
}

/// The probe curves of one comparison row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curves {
    /// Frame times, s.
    pub times: Vec<f64>,
    /// `(probe name, displacement per frame)`: `[ux, uy]` in 2D, `[ux, uy, uz]` in 3D.
    pub probes: Vec<(String, Vec<Vec<f64>>)>,
}

fn two() -> u8 {
    2
}

fn is_two(dim: &u8) -> bool {
    *dim == 2
}

/// What the matrix takes from one run of either dimension.
struct RowRun {
    /// Cells of the mesh.
    cells: usize,
    /// Frame times and probe curves.
    curves: Curves,
    /// Per probe (in the order of `curves.probes`): final displacement and smallest uy.
    finals: Vec<(Vec<f64>, f64)>,
    blew_up: bool,
    blow_up_message: Option<String>,
    steps_completed: u64,
    max_von_mises: f64,
    min_det_f: f64,
    inverted_elements: usize,
    step_seconds: f64,
    element_steps_per_second: f64,
    real_time_factor: f64,
}

impl RowRun {
    fn from_2d(result: &RunResult) -> Self {
        let s = &result.summary;
        RowRun {
            cells: s.triangles,
            curves: Curves {
                times: result.frame_times.iter().map(|f| f.1).collect(),
                probes: result
                    .probes
                    .iter()
                    .zip(&result.probe_series)
                    .map(|(p, series)| {
                        (p.name.clone(), series.iter().map(|u| u.to_vec()).collect())
                    })
                    .collect(),
            },
            finals: s
                .probes
                .iter()
                .map(|ps| (ps.final_displacement.to_vec(), ps.uy_range[0]))
                .collect(),
            blew_up: s.blew_up,
            blow_up_message: s.blow_up_message.clone(),
            steps_completed: s.steps_completed,
            max_von_mises: s.max_von_mises,
            min_det_f: s.min_det_f,
            inverted_elements: s.inverted_elements,
            step_seconds: s.step_seconds,
            element_steps_per_second: s.element_steps_per_second,
            real_time_factor: s.real_time_factor,
        }
    }

    fn from_3d(result: &RunResult3) -> Self {
        let s = &result.summary;
        let series = |k: usize| -> Vec<Vec<f64>> {
            result
                .probe_rows
                .iter()
                .map(|(_, _, row)| row[k].to_vec())
                .collect()
        };
        RowRun {
            cells: s.tetrahedra,
            curves: Curves {
                times: result.probe_rows.iter().map(|r| r.1).collect(),
                probes: s
                    .probes
                    .iter()
                    .enumerate()
                    .map(|(k, p)| (p.name.clone(), series(k)))
                    .collect(),
            },
            // The smallest uy over the recorded frames, as 2D's `uy_range`.
            finals: s
                .probes
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    let min_uy = result
                        .probe_rows
                        .iter()
                        .fold(f64::INFINITY, |m, (_, _, row)| m.min(row[k][1]));
                    (p.final_displacement.to_vec(), min_uy)
                })
                .collect(),
            blew_up: s.blew_up,
            blow_up_message: s.blow_up_message.clone(),
            steps_completed: s.steps_completed,
            max_von_mises: s.max_von_mises,
            min_det_f: s.min_det_f,
            inverted_elements: s.inverted_elements,
            step_seconds: s.step_seconds,
            element_steps_per_second: s.element_steps_per_second,
            real_time_factor: s.real_time_factor,
        }
    }
}

/// Run the matrix on `base`: each row is `base` with the row's energy, solver and variant set
/// (typed), validated again.
pub fn compare(base: &LoadedScene, spec: &CompareSpec) -> Result<Comparison, SceneError> {
    let options = RunOptions {
        threads: spec.threads,
        snapshot_every: spec.snapshot_every,
        ..RunOptions::default()
    };
    let mut runs = Vec::new();
    let (rows, curves, cells) = matrix(spec, |energy, solver, settings| {
        let outcome = variant_scene(base, energy, solver, settings)
            .and_then(|scene| run_scene(&scene, &options));
        if spec.snapshot_every.is_some() {
            runs.push(outcome.as_ref().ok().cloned());
        }
        outcome.map(|result| RowRun::from_2d(&result))
    });
    Ok(Comparison {
        scene: base.scene.name.clone(),
        scene_solver: base.scene.solver.kind,
        triangles: cells.unwrap_or(0),
        dim: 2,
        // dt and steps as the scene gives them (a static row reports load increments as its
        // steps).
        dt: base.scene.solver.dt,
        steps: base.scene.solver.steps,
        rows,
        curves,
        runs,
    })
}

/// Run the matrix on a 3D scene: each row is `base` with the row's energy, solver and variant
/// set (typed), validated again, and run by [`run_scene3`] on `spec.threads`. A combination
/// that cannot run (a solver without a 3D path, such as linear-implicit; an option the 3D path
/// refuses, such as `integrator = "bdf2"`; an energy's parameter domain) is a row with its
/// `error`, not stable, as in 2D. The probes have three components; [`Comparison::triangles`]
/// counts tetrahedra and [`Comparison::dim`] is 3. Errors: `spec.snapshot_every` (no pictures
/// of 3D comparisons yet).
pub fn compare3(base: &LoadedScene3, spec: &CompareSpec) -> Result<Comparison, SceneError> {
    if spec.snapshot_every.is_some() {
        return Err(SceneError::Usage(format!(
            "{}: snapshots of a comparison are not available for 3D scenes yet",
            base.origin
        )));
    }
    let options = RunOptions3 {
        threads: spec.threads,
        ..RunOptions3::default()
    };
    let (rows, curves, cells) = matrix(spec, |energy, solver, settings| {
        variant_scene3(base, energy, solver, settings)
            .and_then(|scene| run_scene3(&scene, &options, None))
            .map(|result| RowRun::from_3d(&result))
    });
    Ok(Comparison {
        scene: base.scene.name.clone(),
        scene_solver: base.scene.solver.kind,
        triangles: cells.unwrap_or(0),
        dim: 3,
        dt: base.scene.solver.dt,
        steps: base.scene.solver.steps,
        rows,
        curves,
        runs: Vec::new(),
    })
}

/// The rows of the matrix, each run by `run` (the scene of one energy, solver and settings),
/// their curves, and the cell count of the first run that ran.
fn matrix(
    spec: &CompareSpec,
    mut run: impl FnMut(EnergyKind, SolverKind, &Settings) -> Result<RowRun, SceneError>,
) -> (Vec<CompareRow>, Vec<Curves>, Option<usize>) {
    // The reference of the RMS columns: the default solver (explicit) of the same energy.
    let reference = SolverKind::default();
    let mut rows = Vec::new();
    let mut cells = None;
    let mut curves = Vec::new();
    for &energy in &spec.energies {
        let mut explicit: Option<Curves> = None;
        for &solver in &spec.solvers {
            for (variant, settings) in variants(solver, spec) {
                let row = match run(energy, solver, &settings) {
                    Ok(r) => {
                        cells.get_or_insert(r.cells);
                        let probes = r
                            .curves
                            .probes
                            .iter()
                            .zip(&r.finals)
                            .map(|((name, series), (last, min_uy))| ProbeCell {
                                name: name.clone(),
                                final_displacement: last.clone(),
                                min_uy: *min_uy,
                                // A static run's frames are load increments, not times:
                                // no curve to compare with explicit's.
                                rms_vs_explicit: explicit
                                    .as_ref()
                                    .filter(|_| solver.capabilities().clock == Clock::Time)
                                    .and_then(|e| e.probes.iter().find(|(n, _)| n == name))
                                    .map(|(_, reference)| rms_distance(series, reference)),
                            })
                            .collect();
                        let row = CompareRow {
                            energy,
                            solver,
                            variant: variant.clone(),
                            stable: !r.blew_up,
                            steps_completed: r.steps_completed,
                            probes,
                            max_von_mises: r.max_von_mises,
                            min_det_f: r.min_det_f,
                            inverted_elements: r.inverted_elements,
                            step_seconds: r.step_seconds,
                            element_steps_per_second: r.element_steps_per_second,
                            real_time_factor: r.real_time_factor,
                            error: r.blow_up_message,
                        };
                        if solver == reference && explicit.is_none() && !r.blew_up {
                            explicit = Some(r.curves.clone());
                        }
                        curves.push(r.curves);
                        row
                    }
                    Err(e) => {
                        curves.push(Curves::default());
                        CompareRow {
                            energy,
                            solver,
                            variant,
                            stable: false,
                            steps_completed: 0,
                            probes: Vec::new(),
                            max_von_mises: f64::NAN,
                            min_det_f: f64::NAN,
                            inverted_elements: 0,
                            step_seconds: 0.0,
                            element_steps_per_second: 0.0,
                            real_time_factor: 0.0,
                            error: Some(e.to_string()),
                        }
                    }
                };
                rows.push(row);
            }
        }
    }
    (rows, curves, cells)
}

/// `base` with the energy, the solver and the parameter settings of one row, validated.
pub(crate) fn variant_scene(
    base: &LoadedScene,
    energy: EnergyKind,
    solver: SolverKind,
    settings: &Settings,
) -> Result<LoadedScene, SceneError> {
    let mut scene = base.clone();
    scene.scene.energy = energy;
    set_solver(&mut scene.scene.solver, solver, settings, &scene.origin)?;
    scene.validate()?;
    Ok(scene)
}

/// [`variant_scene`] of a 3D scene: `base` with the energy, the solver and the parameter
/// settings of one row, validated (a solver without a 3D path is refused here).
pub(crate) fn variant_scene3(
    base: &LoadedScene3,
    energy: EnergyKind,
    solver: SolverKind,
    settings: &Settings,
) -> Result<LoadedScene3, SceneError> {
    let mut scene = base.clone();
    scene.scene.energy = energy;
    set_solver(&mut scene.scene.solver, solver, settings, &scene.origin)?;
    scene.validate()?;
    Ok(scene)
}

/// Set `spec`'s solver to `solver` with `settings` (of the scene at `origin`, for messages): the
/// typed edit both dimensions' rows make.
fn set_solver(
    spec: &mut SolverSpec,
    solver: SolverKind,
    settings: &Settings,
    origin: &str,
) -> Result<(), SceneError> {
    spec.kind = solver;
    for (key, value) in settings {
        spec.set(key, value.clone())
            .map_err(|e| SceneError::Scene(format!("{origin}: {e}")))?;
    }
    Ok(())
}

/// Parameter settings of one row: `(key, value)` pairs.
pub(crate) type Settings = Vec<(String, toml::Value)>;

/// The rows of one solver: `(label, settings)` for each combination of the axes whose key the
/// solver has (one row with no settings when it has none).
fn variants(solver: SolverKind, spec: &CompareSpec) -> Vec<(String, Settings)> {
    let mut rows: Vec<(Vec<String>, Settings)> = vec![(Vec::new(), Vec::new())];
    for axis in &spec.variants {
        if axis.values.is_empty() || !SolverSpec::accepts(solver, &axis.key) {
            continue;
        }
        rows = rows
            .into_iter()
            .flat_map(|(labels, settings)| {
                axis.values.iter().map(move |v| {
                    let mut labels = labels.clone();
                    labels.push(axis.label(v));
                    let mut settings = settings.clone();
                    settings.push((axis.key.clone(), v.clone()));
                    (labels, settings)
                })
            })
            .collect();
    }
    rows.into_iter()
        .map(|(labels, settings)| (labels.join(", "), settings))
        .collect()
}

/// RMS of `|a_k - b_k|` over the common prefix of two displacement series, m. The samples
/// have any number of components (`[ux, uy]`, `[ux, uy, uz]`; the common ones count): per
/// sample `dx^2 + dy^2 (+ dz^2)` in component order, summed over the samples in order.
pub fn rms_distance<P: AsRef<[f64]>, Q: AsRef<[f64]>>(a: &[P], b: &[Q]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return f64::NAN;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .take(n)
        .map(|(p, q)| {
            let (p, q) = (p.as_ref(), q.as_ref());
            // The first square alone, then the others added in order: in 2D exactly
            // `(p[0] - q[0])^2 + (p[1] - q[1])^2`.
            p.iter()
                .zip(q)
                .map(|(x, y)| (x - y).powi(2))
                .reduce(|s, d| s + d)
                .unwrap_or(0.0)
        })
        .sum();
    (sum / n as f64).sqrt()
}

impl Comparison {
    fn probe_names(&self) -> Vec<String> {
        self.rows
            .iter()
            .find(|r| !r.probes.is_empty())
            .map(|r| r.probes.iter().map(|p| p.name.clone()).collect())
            .unwrap_or_default()
    }

    /// The displacement components' names: `ux, uy` in 2D, `ux, uy, uz` in 3D.
    fn components(&self) -> &'static [&'static str] {
        if self.dim == 3 {
            &["ux", "uy", "uz"]
        } else {
            &["ux", "uy"]
        }
    }

    /// A markdown table (displacements in mm, stress in Pa). In 3D each probe has a `uz`
    /// column after `uy`, and the header counts tetrahedra.
    pub fn to_markdown(&self) -> String {
        let names = self.probe_names();
        let comps = self.components();
        let with_rms = self
            .rows
            .iter()
            .any(|r| r.probes.iter().any(|p| p.rms_vs_explicit.is_some()));
        let mut out = format!(
            "Scene `{}`: {} {}, dt = {:e} s, {} steps. Displacements in mm (final {}; lowest uy over the run).\n\n",
            self.scene,
            self.triangles,
            if self.dim == 3 {
                "tetrahedra"
            } else {
                "triangles"
            },
            self.dt,
            self.steps,
            comps.join(", ")
        );
        out.push_str("| energy | solver | variant | stable |");
        for n in &names {
            for c in comps {
                let _ = write!(out, " {n} {c} |");
            }
            let _ = write!(out, " {n} min uy |");
            if with_rms {
                let _ = write!(out, " {n} RMS vs explicit |");
            }
        }
        out.push_str(" max von Mises (Pa) | min det F | step time (s) | element-steps/s | real-time factor |\n|");
        let per_probe = comps.len() + 1 + usize::from(with_rms);
        let cols = 4 + names.len() * per_probe + 5;
        out.push_str(&"---|".repeat(cols));
        out.push('\n');
        for r in &self.rows {
            let _ = write!(
                out,
                "| {} | {} | {} | {} |",
                r.energy,
                r.solver,
                r.variant,
                if r.stable { "yes" } else { "**no**" }
            );
            for n in &names {
                match r.probes.iter().find(|p| &p.name == n) {
                    Some(p) => {
                        for k in 0..comps.len() {
                            match p.final_displacement.get(k) {
                                Some(u) => {
                                    let _ = write!(out, " {:.1} |", 1e3 * u);
                                }
                                None => out.push_str(" - |"),
                            }
                        }
                        let _ = write!(out, " {:.1} |", 1e3 * p.min_uy);
                        if with_rms {
                            match p.rms_vs_explicit {
                                Some(v) => {
                                    let _ = write!(out, " {:.1} |", 1e3 * v);
                                }
                                None => out.push_str(" - |"),
                            }
                        }
                    }
                    None => out.push_str(&" - |".repeat(per_probe)),
                }
            }
            let _ = writeln!(
                out,
                " {:.4e} | {:.4} | {:.4} | {:.3e} | {:.1} |",
                r.max_von_mises,
                r.min_det_f,
                r.step_seconds,
                r.element_steps_per_second,
                r.real_time_factor
            );
        }
        let errors: Vec<&CompareRow> = self.rows.iter().filter(|r| r.error.is_some()).collect();
        if !errors.is_empty() {
            out.push('\n');
            for r in errors {
                let _ = writeln!(
                    out,
                    "- {} / {} {}: {}",
                    r.energy,
                    r.solver,
                    r.variant,
                    r.error.as_deref().unwrap_or_default()
                );
            }
        }
        out
    }

    /// CSV, one row per combination, SI units. In 3D each probe has a `NAME.uz` column after
    /// `NAME.uy`.
    pub fn to_csv(&self) -> String {
        let names = self.probe_names();
        let comps = self.components();
        let mut out = String::from("energy,solver,variant,stable,steps_completed");
        for n in &names {
            for c in comps {
                let _ = write!(out, ",{n}.{c}");
            }
            let _ = write!(out, ",{n}.min_uy,{n}.rms_vs_explicit");
        }
        out.push_str(",max_von_mises,min_det_f,inverted_elements,step_seconds,element_steps_per_second,real_time_factor,error\n");
        for r in &self.rows {
            let _ = write!(
                out,
                "{},{},\"{}\",{},{}",
                r.energy, r.solver, r.variant, r.stable, r.steps_completed
            );
            for n in &names {
                match r.probes.iter().find(|p| &p.name == n) {
                    Some(p) => {
                        for k in 0..comps.len() {
                            match p.final_displacement.get(k) {
                                Some(u) => {
                                    let _ = write!(out, ",{u}");
                                }
                                None => out.push(','),
                            }
                        }
                        let _ = write!(
                            out,
                            ",{},{}",
                            p.min_uy,
                            p.rms_vs_explicit.map(|v| v.to_string()).unwrap_or_default()
                        );
                    }
                    None => out.push_str(&",".repeat(comps.len() + 2)),
                }
            }
            let _ = writeln!(
                out,
                ",{},{},{},{},{},{},\"{}\"",
                r.max_von_mises,
                r.min_det_f,
                r.inverted_elements,
                r.step_seconds,
                r.element_steps_per_second,
                r.real_time_factor,
                r.error.as_deref().unwrap_or_default().replace('"', "'")
            );
        }
        out
    }

    /// The probe curves of every row side by side, one line per frame of the longest run:
    /// `step`, then for each row and probe `ENERGY/SOLVER[/VARIANT]:PROBE.ux` and `.uy` (and
    /// `.uz` in 3D; m);
    /// with `time` (s) taken from the row of that length. Rows that stopped early leave their
    /// later cells empty. For plotting tip curves of several solvers or energies on one chart.
    pub fn to_curves_csv(&self) -> String {
        let longest = self
            .curves
            .iter()
            .max_by_key(|c| c.times.len())
            .cloned()
            .unwrap_or_default();
        let comps = self.components();
        let mut out = String::from("frame,time");
        for (r, c) in self.rows.iter().zip(&self.curves) {
            let label = if r.variant.is_empty() {
                format!("{}/{}", r.energy, r.solver)
            } else {
                format!(
                    "{}/{}/{}",
                    r.energy,
                    r.solver,
                    r.variant.replace(", ", "-").replace(' ', "-")
                )
            };
            for (name, _) in &c.probes {
                for comp in comps {
                    let _ = write!(out, ",{label}:{name}.{comp}");
                }
            }
        }
        out.push('\n');
        for (k, t) in longest.times.iter().enumerate() {
            let _ = write!(out, "{k},{t}");
            for c in &self.curves {
                for (_, series) in &c.probes {
                    let u = series.get(k);
                    for j in 0..comps.len() {
                        match u.and_then(|u| u.get(j)) {
                            Some(x) => {
                                let _ = write!(out, ",{x}");
                            }
                            None => out.push(','),
                        }
                    }
                }
            }
            out.push('\n');
        }
        out
    }

    /// Pretty JSON (non-finite numbers become `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}
