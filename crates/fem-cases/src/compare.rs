//! The energy x solver matrix on one scene: every combination run from the same scene, one
//! row each, with the probes' displacements, the peak von Mises stress, the cost and whether
//! the run stayed stable; optionally variants of solver parameters (several iteration counts,
//! both XPBD constraint forms: any parameter key), and each probe's deviation from the run of
//! the default solver (explicit) with the same energy (case C).
//!
//! Each row is the scene changed as a typed value (energy, solver, parameters), never through
//! its text.

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use fem_solvers::{Clock, SolverKind};
use serde::{Deserialize, Serialize};

use crate::run::{RunOptions, RunResult, run_scene};
use fem_scene::SceneError;
use fem_scene::SolverSpec;
use fem_scene::scene::LoadedScene;

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
    /// (for pictures). `None`: keep nothing.
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
    /// Per probe: name, final displacement `[ux, uy]` (m), smallest uy (m).
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
    /// Final displacement, m.
    pub final_displacement: [f64; 2],
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
    /// Triangles of the mesh.
    pub triangles: usize,
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
    /// not run); empty otherwise.
    #[serde(skip)]
    pub runs: Vec<Option<RunResult>>,
}

/// The probe curves of one comparison row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curves {
    /// Frame times, s.
    pub times: Vec<f64>,
    /// `(probe name, displacement per frame)`.
    pub probes: Vec<(String, Vec<[f64; 2]>)>,
}

/// Run the matrix on `base`: each row is `base` with the row's energy, solver and variant set
/// (typed), validated again.
pub fn compare(base: &LoadedScene, spec: &CompareSpec) -> Result<Comparison, SceneError> {
    // The reference of the RMS columns: the default solver (explicit) of the same energy.
    let reference = SolverKind::default();
    let mut rows = Vec::new();
    let mut header = None;
    let mut curves = Vec::new();
    let mut runs = Vec::new();
    for &energy in &spec.energies {
        let mut explicit: Option<RunResult> = None;
        for &solver in &spec.solvers {
            for (variant, settings) in variants(solver, spec) {
                let outcome = variant_scene(base, energy, solver, &settings).and_then(|scene| {
                    run_scene(
                        &scene,
                        &RunOptions {
                            threads: spec.threads,
                            snapshot_every: spec.snapshot_every,
                            ..RunOptions::default()
                        },
                    )
                });
                let row = match outcome {
                    Ok(result) => {
                        curves.push(Curves {
                            times: result.frame_times.iter().map(|f| f.1).collect(),
                            probes: result
                                .probes
                                .iter()
                                .zip(&result.probe_series)
                                .map(|(p, series)| (p.name.clone(), series.clone()))
                                .collect(),
                        });
                        let s = &result.summary;
                        // dt and steps as the scene gives them (a static row reports load
                        // increments as its steps).
                        header.get_or_insert((
                            s.triangles,
                            base.scene.solver.dt,
                            base.scene.solver.steps,
                        ));
                        let probes = result
                            .probes
                            .iter()
                            .zip(&result.probe_series)
                            .zip(&s.probes)
                            .map(|((p, series), ps)| ProbeCell {
                                name: p.name.clone(),
                                final_displacement: ps.final_displacement,
                                min_uy: ps.uy_range[0],
                                // A static run's frames are load increments, not times:
                                // no curve to compare with explicit's.
                                rms_vs_explicit: explicit
                                    .as_ref()
                                    .filter(|_| solver.capabilities().clock == Clock::Time)
                                    .and_then(|e| e.probe(&p.name))
                                    .map(|reference| rms_distance(series, reference)),
                            })
                            .collect();
                        let row = CompareRow {
                            energy,
                            solver,
                            variant: variant.clone(),
                            stable: !s.blew_up,
                            steps_completed: s.steps_completed,
                            probes,
                            max_von_mises: s.max_von_mises,
                            min_det_f: s.min_det_f,
                            inverted_elements: s.inverted_elements,
                            step_seconds: s.step_seconds,
                            element_steps_per_second: s.element_steps_per_second,
                            real_time_factor: s.real_time_factor,
                            error: s.blow_up_message.clone(),
                        };
                        if spec.snapshot_every.is_some() {
                            runs.push(Some(result.clone()));
                        }
                        if solver == reference && explicit.is_none() && !s.blew_up {
                            explicit = Some(result);
                        }
                        row
                    }
                    Err(e) => {
                        curves.push(Curves::default());
                        if spec.snapshot_every.is_some() {
                            runs.push(None);
                        }
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
    let (triangles, dt, steps) =
        header.unwrap_or((0, base.scene.solver.dt, base.scene.solver.steps));
    Ok(Comparison {
        scene: base.scene.name.clone(),
        scene_solver: base.scene.solver.kind,
        triangles,
        dt,
        steps,
        rows,
        curves,
        runs,
    })
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
    scene.scene.solver.kind = solver;
    for (key, value) in settings {
        scene
            .scene
            .solver
            .set(key, value.clone())
            .map_err(|e| SceneError::Scene(format!("{}: {e}", scene.origin)))?;
    }
    scene.validate()?;
    Ok(scene)
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

/// RMS of `|a_k - b_k|` over the common prefix of two displacement series, m.
pub fn rms_distance(a: &[[f64; 2]], b: &[[f64; 2]]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return f64::NAN;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .take(n)
        .map(|(p, q)| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
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

    /// A markdown table (displacements in mm, stress in Pa).
    pub fn to_markdown(&self) -> String {
        let names = self.probe_names();
        let with_rms = self
            .rows
            .iter()
            .any(|r| r.probes.iter().any(|p| p.rms_vs_explicit.is_some()));
        let mut out = format!(
            "Scene `{}`: {} triangles, dt = {:e} s, {} steps. Displacements in mm (final ux, uy; lowest uy over the run).\n\n",
            self.scene, self.triangles, self.dt, self.steps
        );
        out.push_str("| energy | solver | variant | stable |");
        for n in &names {
            let _ = write!(out, " {n} ux | {n} uy | {n} min uy |");
            if with_rms {
                let _ = write!(out, " {n} RMS vs explicit |");
            }
        }
        out.push_str(" max von Mises (Pa) | min det F | step time (s) | element-steps/s | real-time factor |\n|");
        let cols = 4 + names.len() * (3 + usize::from(with_rms)) + 5;
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
                        let _ = write!(
                            out,
                            " {:.1} | {:.1} | {:.1} |",
                            1e3 * p.final_displacement[0],
                            1e3 * p.final_displacement[1],
                            1e3 * p.min_uy
                        );
                        if with_rms {
                            match p.rms_vs_explicit {
                                Some(v) => {
                                    let _ = write!(out, " {:.1} |", 1e3 * v);
                                }
                                None => out.push_str(" - |"),
                            }
                        }
                    }
                    None => out.push_str(&" - |".repeat(3 + usize::from(with_rms))),
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

    /// CSV, one row per combination, SI units.
    pub fn to_csv(&self) -> String {
        let names = self.probe_names();
        let mut out = String::from("energy,solver,variant,stable,steps_completed");
        for n in &names {
            let _ = write!(out, ",{n}.ux,{n}.uy,{n}.min_uy,{n}.rms_vs_explicit");
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
                        let _ = write!(
                            out,
                            ",{},{},{},{}",
                            p.final_displacement[0],
                            p.final_displacement[1],
                            p.min_uy,
                            p.rms_vs_explicit.map(|v| v.to_string()).unwrap_or_default()
                        );
                    }
                    None => out.push_str(",,,,"),
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
    /// `step`, then for each row and probe `ENERGY/SOLVER[/VARIANT]:PROBE.ux` and `.uy` (m);
    /// with `time` (s) taken from the row of that length. Rows that stopped early leave their
    /// later cells empty. For plotting tip curves of several solvers or energies on one chart.
    pub fn to_curves_csv(&self) -> String {
        let longest = self
            .curves
            .iter()
            .max_by_key(|c| c.times.len())
            .cloned()
            .unwrap_or_default();
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
                let _ = write!(out, ",{label}:{name}.ux,{label}:{name}.uy");
            }
        }
        out.push('\n');
        for (k, t) in longest.times.iter().enumerate() {
            let _ = write!(out, "{k},{t}");
            for c in &self.curves {
                for (_, series) in &c.probes {
                    match series.get(k) {
                        Some(u) => {
                            let _ = write!(out, ",{},{}", u[0], u[1]);
                        }
                        None => out.push_str(",,"),
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
