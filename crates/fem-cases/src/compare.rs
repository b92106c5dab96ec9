//! The energy x solver matrix on one scene: every combination run from the same scene, one
//! row each, with the probes' displacements, the peak von Mises stress, the cost and whether
//! the run stayed stable; optionally several PBD/XPBD iteration counts and both XPBD forms, and
//! each probe's deviation from the explicit run of the same energy (case C).

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;
use serde::{Deserialize, Serialize};

use crate::error::CaseError;
use crate::run::{RunOptions, RunResult, run_scene};
use crate::scene::{LoadedScene, SolverKind, XpbdFormName};

/// What to compare.
#[derive(Clone, Debug)]
pub struct CompareSpec {
    /// Energies (rows are grouped by energy).
    pub energies: Vec<EnergyKind>,
    /// Solvers.
    pub solvers: Vec<SolverKind>,
    /// PBD/XPBD iteration counts (empty: the scene's).
    pub iterations: Vec<usize>,
    /// XPBD forms (empty: the scene's).
    pub xpbd_forms: Vec<XpbdFormName>,
    /// Worker threads per run.
    pub threads: Option<usize>,
    /// Keep each row's run, with every `n`-th frame as a snapshot, in [`Comparison::runs`]
    /// (for pictures). `None`: keep nothing.
    pub snapshot_every: Option<usize>,
}

/// One combination's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompareRow {
    /// Energy name.
    pub energy: String,
    /// Solver name.
    pub solver: String,
    /// Solver variant (`consistent, 20 it`), empty for explicit.
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

/// Run the matrix. `load` builds the scene with extra overrides (the energy, solver and
/// variant of each combination are passed as `--set`-style overrides).
pub fn compare(
    load: &dyn Fn(&[String]) -> Result<LoadedScene, CaseError>,
    spec: &CompareSpec,
) -> Result<Comparison, CaseError> {
    let base = load(&[])?;
    let mut rows = Vec::new();
    let mut header = None;
    let mut curves = Vec::new();
    let mut runs = Vec::new();
    for &energy in &spec.energies {
        let mut explicit: Option<RunResult> = None;
        for &solver in &spec.solvers {
            for (variant, extra) in variants(solver, spec) {
                let mut o = vec![
                    format!("energy=\"{}\"", energy.name()),
                    format!("solver.kind=\"{}\"", solver.name()),
                ];
                o.extend(extra);
                let outcome = load(&o).and_then(|scene| {
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
                                    .filter(|_| solver != SolverKind::Static)
                                    .and_then(|e| e.probe(&p.name))
                                    .map(|reference| rms_distance(series, reference)),
                            })
                            .collect();
                        let row = CompareRow {
                            energy: energy.name().into(),
                            solver: solver.name().into(),
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
                        if solver == SolverKind::Explicit && explicit.is_none() && !s.blew_up {
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
                            energy: energy.name().into(),
                            solver: solver.name().into(),
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
        triangles,
        dt,
        steps,
        rows,
        curves,
        runs,
    })
}

fn variants(solver: SolverKind, spec: &CompareSpec) -> Vec<(String, Vec<String>)> {
    let iterations: Vec<Option<usize>> = if spec.iterations.is_empty() {
        vec![None]
    } else {
        spec.iterations.iter().copied().map(Some).collect()
    };
    let forms: Vec<Option<XpbdFormName>> = if spec.xpbd_forms.is_empty() {
        vec![None]
    } else {
        spec.xpbd_forms.iter().copied().map(Some).collect()
    };
    let it = |n: Option<usize>| n.map(|n| format!("solver.iterations={n}"));
    match solver {
        SolverKind::Pbd => iterations
            .iter()
            .map(|&n| {
                (
                    n.map(|n| format!("{n} it")).unwrap_or_default(),
                    it(n).into_iter().collect(),
                )
            })
            .collect(),
        SolverKind::Xpbd => forms
            .iter()
            .flat_map(|&f| {
                iterations.iter().map(move |&n| {
                    let name = match f {
                        Some(XpbdFormName::Consistent) => "consistent",
                        Some(XpbdFormName::Literal) => "literal",
                        None => "",
                    };
                    let label = match (name, n) {
                        ("", None) => String::new(),
                        ("", Some(n)) => format!("{n} it"),
                        (f, None) => f.to_owned(),
                        (f, Some(n)) => format!("{f}, {n} it"),
                    };
                    let mut o: Vec<String> = it(n).into_iter().collect();
                    if !name.is_empty() {
                        o.push(format!("solver.xpbd_form=\"{name}\""));
                    }
                    (label, o)
                })
            })
            .collect(),
        _ => vec![(String::new(), Vec::new())],
    }
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
