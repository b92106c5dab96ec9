//! The budget's sentences, tables and charts.

use std::fmt::Write as _;

use fem_core::energy::EnergyKind;

use super::measure::{self, Phase, WindowErrors};
use super::{
    Budget, BudgetRun, BudgetSpec, Framework, RankBy, Reference, Trial, fmt_num, pct, sci,
};

/// A ranking value in its unit: metres for position, a percentage otherwise.
fn rank_text(rank: RankBy, v: Option<f64>) -> String {
    match (rank, v) {
        (_, None) => "-".into(),
        (RankBy::Position, Some(v)) => format!("{} m", sci(v)),
        (_, v) => pct(v),
    }
}

/// A short column name of the ranking quantity.
fn rank_column(rank: RankBy) -> &'static str {
    match rank {
        RankBy::Position => "position RMS",
        RankBy::Stress => "sustained stress (ranked)",
        RankBy::StressImpact => "impact stress (ranked)",
        RankBy::Pressure => "sustained pressure (ranked)",
        RankBy::PressureImpact => "impact pressure (ranked)",
    }
}

impl Trial {
    /// What became of it, in words (the CSV's `status`): `measured` (with a remark: `measured;
    /// its largest step residual is not finite`), `not measured: WHY`, `unstable: WHY` or `stopped:
    /// ...` (over the cost cap).
    pub fn status(&self) -> String {
        if self.over_cap {
            self.failure.clone().unwrap_or_else(|| "stopped".into())
        } else if !self.stable {
            format!(
                "unstable: {}",
                self.failure
                    .as_deref()
                    .unwrap_or("the run did not complete")
            )
        } else if !self.measured {
            format!(
                "not measured: {}",
                self.note.as_deref().unwrap_or("no reason recorded")
            )
        } else {
            match &self.note {
                Some(n) => format!("measured; {n}"),
                None => "measured".into(),
            }
        }
    }
}

impl Budget {
    /// The first stable setting of `framework` on `energy` within the budget whose errors
    /// were not measured (when the row has no measured one, the table says why).
    fn unmeasured_within(&self, energy: EnergyKind, framework: Framework) -> Option<&Trial> {
        self.trials.iter().find(|t| {
            t.energy == energy
                && t.framework == framework
                && t.stable
                && !t.measured
                && t.ms_per_frame <= self.budget_ms
        })
    }

    /// The reference of `energy`.
    pub fn reference_of(&self, energy: EnergyKind) -> Option<&Reference> {
        self.references.iter().find(|r| r.energy == energy)
    }

    /// The medical check of `energy`: the stable settings within the budget whose soft tissue
    /// stress (relative L2) and peak contact pressure, both in the sustained phase (the whole
    /// run without one), are within the criterion; and the closest one (smallest larger of
    /// the two). `None` when the scene has no soft tissue stress or no contact to check.
    pub fn medical_check(&self, energy: EnergyKind) -> Option<(Vec<&Trial>, Option<&Trial>)> {
        let r = self.reference_of(energy)?;
        let phase = RankBy::Stress.effective_phase(&r.windows);
        let pair = |t: &Trial| -> Option<(f64, f64)> {
            let w = t.errors.get(phase)?;
            Some((w.stress_l2?, w.pressure_peak?))
        };
        let candidates: Vec<&Trial> = self
            .trials
            .iter()
            .filter(|t| t.energy == energy && t.measured && t.ms_per_frame <= self.budget_ms)
            .filter(|t| pair(t).is_some())
            .collect();
        if candidates.is_empty() {
            return None;
        }
        let worst = |t: &Trial| pair(t).map_or(f64::INFINITY, |(a, b)| a.max(b));
        let pass = candidates
            .iter()
            .copied()
            .filter(|t| worst(t) <= self.criterion)
            .collect();
        let closest = candidates
            .iter()
            .copied()
            .min_by(|a, b| worst(a).total_cmp(&worst(b)));
        Some((pass, closest))
    }

    /// The ranked table (one section per energy), the sentences, the reference and its own
    /// error, and the residual-driven rungs.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "# Frame budget: {} at {} Hz, {} ms per frame (one thread)\n\n\
             {} frames; reference: {}. Ranked by {}. Windows, found on each energy's \
             reference: the impact from the first contact with an obstacle (or the ground, without one) until the body's kinetic energy has \
             fallen for good below {} of its peak, the sustained phase after it. Stress errors \
             are over the soft tissue (the deformable regions), relative L2 over the window's \
             frames; pressure errors are the largest relative error of a contact target's peak \
             pressure. A rung is stopped once it costs {} times the budget.\n\n",
            self.scene,
            fmt_num(self.fps),
            fmt_num(self.budget_ms),
            self.frames,
            self.reference,
            self.references.first().map_or_else(
                || self.rank_by.name().to_owned(),
                |r| self.rank_by.describe(&r.windows)
            ),
            pct(self.references.first().map(|r| r.windows.settle)),
            fmt_num(self.cost_cap),
        );
        for sentence in &self.sentences {
            let _ = writeln!(s, "- {sentence}");
        }
        let mut energies: Vec<EnergyKind> = Vec::new();
        for r in &self.rows {
            if !energies.contains(&r.energy) {
                energies.push(r.energy);
            }
        }
        for energy in energies {
            self.energy_section(&mut s, energy);
        }
        s
    }

    fn energy_section(&self, s: &mut String, energy: EnergyKind) {
        let _ = writeln!(s, "\n## {energy}\n");
        if let Some(r) = self.reference_of(energy) {
            let t = |f: usize| fmt_num(f as f64 / self.fps);
            let end = r.windows.whole[1].saturating_sub(1);
            match (r.windows.impact, r.windows.sustained) {
                (None, _) => {
                    let _ = writeln!(s, "No contact: one window, the whole run.");
                }
                (Some(i), None) => {
                    let _ = writeln!(
                        s,
                        "Impact window from {} s to the end ({} s): the reference does not settle \
                         within the run, so there is no sustained phase.",
                        t(i[0]),
                        t(end)
                    );
                }
                (Some(i), Some(su)) => {
                    let _ = writeln!(
                        s,
                        "Impact window {}-{} s, sustained phase {}-{} s (frames {}-{} and {}-{}).",
                        t(i[0]),
                        t(i[1]),
                        t(su[0]),
                        t(end),
                        i[0],
                        i[1] - 1,
                        su[0],
                        su[1] - 1
                    );
                }
            }
            let e = r.rank_phase_errors();
            match &r.note {
                Some(why) => {
                    let _ = writeln!(s, "\nThe reference's own error is not given: {why}.\n");
                }
                None => {
                    let _ = writeln!(
                        s,
                        "\nThe reference's own error, estimated against itself at twice its \
                         step: position RMS {} m, soft tissue stress {} (L2) and peak contact \
                         pressure {}, {}.\n",
                        sci(r.error.whole.position_rms),
                        pct(e.and_then(|w| w.stress_l2)),
                        pct(e.and_then(|w| w.pressure_peak)),
                        RankBy::Stress.effective_phase(&r.windows).name()
                    );
                }
            }
        }
        let rank = self.rank_by;
        let _ = writeln!(
            s,
            "| rank | framework | best within budget | ms/frame | iterations/frame | residual | {} | stress L2 sustained | stress peak sustained | pressure peak sustained | stress L2 impact | pressure peak impact | position RMS (m) | inverted | cheapest stable | its ms/frame | its {} |\n|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|",
            rank_column(rank),
            rank_column(rank)
        );
        let mine: Vec<_> = self.rows.iter().filter(|r| r.energy == energy).collect();
        for (k, r) in mine.iter().enumerate() {
            if let Some(why) = &r.cannot_run {
                let _ = writeln!(
                    s,
                    "| - | {} | cannot run: {why} | | | | | | | | | | | | | | |",
                    r.framework.name()
                );
                continue;
            }
            let best = match &r.best {
                Some(t) => {
                    let w = |p: Phase| t.errors.get(p);
                    let f = |p: Phase, g: fn(&WindowErrors) -> Option<f64>| pct(w(p).and_then(g));
                    format!(
                        "{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {}",
                        t.setting,
                        fmt_num(t.ms_per_frame),
                        iterations_text(t),
                        t.residual.map_or("-".into(), sci),
                        rank_text(rank, t.rank_value),
                        f(Phase::Sustained, |w| w.stress_l2),
                        f(Phase::Sustained, |w| w.stress_peak),
                        f(Phase::Sustained, |w| w.pressure_peak),
                        f(Phase::Impact, |w| w.stress_l2),
                        f(Phase::Impact, |w| w.pressure_peak),
                        sci(t.errors.whole.position_rms),
                        t.errors.whole.inverted
                    )
                }
                None => match self.unmeasured_within(r.energy, r.framework) {
                    Some(t) => format!(
                        "none measured within the budget ({}: {}) | | | | | | | | | | | ",
                        t.setting,
                        t.note.as_deref().unwrap_or("not measured")
                    ),
                    None => "none within the budget | | | | | | | | | | | ".into(),
                },
            };
            let cheapest = match &r.cheapest {
                Some(t) => format!(
                    "{} | {} | {}",
                    t.setting,
                    fmt_num(t.ms_per_frame),
                    if t.measured {
                        rank_text(rank, t.rank_value)
                    } else {
                        "not measured".into()
                    }
                ),
                None if self
                    .trials
                    .iter()
                    .any(|t| t.energy == r.energy && t.framework == r.framework && t.over_cap) =>
                {
                    format!(
                        "none stable within {} times the budget | | ",
                        fmt_num(self.cost_cap)
                    )
                }
                None => "none stable | | ".into(),
            };
            let place = if r.best.is_some() {
                (k + 1).to_string()
            } else {
                "-".into()
            };
            let _ = writeln!(
                s,
                "| {place} | {} | {best} | {cheapest} |",
                r.framework.name()
            );
        }
        self.detail_table(s, energy);
        self.tolerance_table(s, energy);
        if let Some((pass, closest)) = self.medical_check(energy) {
            let _ = writeln!(
                s,
                "\nWithin {} on both the sustained soft tissue stress and the peak contact \
                 pressure: {}.",
                pct(Some(self.criterion)),
                if pass.is_empty() {
                    match closest {
                        Some(c) => format!(
                            "no setting within the budget; closest {} ({})",
                            c.framework.name(),
                            c.setting
                        ),
                        None => "no setting within the budget".into(),
                    }
                } else {
                    pass.iter()
                        .map(|t| format!("{} ({})", t.framework.name(), t.setting))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            );
        }
    }

    /// Per region and contact target, for each row's best setting: `sustained / impact`.
    fn detail_table(&self, s: &mut String, energy: EnergyKind) {
        let rows: Vec<&Trial> = self
            .rows
            .iter()
            .filter(|r| r.energy == energy)
            .filter_map(|r| r.best.as_ref())
            .collect();
        let Some(first) = rows.first() else { return };
        let w = &first.errors.whole;
        if w.regions.len() < 2 && w.contact.is_empty() {
            return;
        }
        let mut head = vec!["framework".to_owned()];
        for r in &w.regions {
            if r.force.is_some() || r.torque.is_some() || r.stress_l2.is_none() {
                head.push(format!("{} force", r.region));
                head.push(format!("{} torque", r.region));
            } else {
                head.push(format!("{} stress L2", r.region));
                head.push(format!("{} stress peak", r.region));
            }
        }
        for c in &w.contact {
            head.push(format!("{} peak pressure", c.target));
            head.push(format!("{} impulse", c.target));
        }
        let _ = writeln!(
            s,
            "\nPer material region and contact target, each row's best setting: relative \
             error in the sustained phase / the impact window (rigid regions: the tissue's \
             force and torque on their bodies).\n"
        );
        let _ = writeln!(s, "| {} |", head.join(" | "));
        let _ = writeln!(s, "|---|{}", "---:|".repeat(head.len().saturating_sub(1)));
        for t in rows {
            let cell = |g: &dyn Fn(&WindowErrors) -> Option<f64>| {
                format!(
                    "{} / {}",
                    pct(t.errors.get(Phase::Sustained).and_then(g)),
                    pct(t.errors.get(Phase::Impact).and_then(g))
                )
            };
            let mut cells = vec![t.framework.name().to_owned()];
            for (k, r) in t.errors.whole.regions.iter().enumerate() {
                if r.force.is_some() || r.torque.is_some() || r.stress_l2.is_none() {
                    cells.push(cell(&|w| w.regions.get(k).and_then(|r| r.force)));
                    cells.push(cell(&|w| w.regions.get(k).and_then(|r| r.torque)));
                } else {
                    cells.push(cell(&|w| w.regions.get(k).and_then(|r| r.stress_l2)));
                    cells.push(cell(&|w| w.regions.get(k).and_then(|r| r.stress_peak)));
                }
            }
            for k in 0..t.errors.whole.contact.len() {
                cells.push(cell(&|w| w.contact.get(k).and_then(|c| c.peak_pressure)));
                cells.push(cell(&|w| w.contact.get(k).and_then(|c| c.impulse)));
            }
            let _ = writeln!(s, "| {} |", cells.join(" | "));
        }
    }

    /// Every rung with a residual tolerance: the iterations it used and the residual reached.
    fn tolerance_table(&self, s: &mut String, energy: EnergyKind) {
        let rungs: Vec<&Trial> = self
            .trials
            .iter()
            .filter(|t| t.energy == energy && t.tolerance.is_some())
            .collect();
        if rungs.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "\nResidual-driven rungs (VBD, PD and quasi-Newton: gradient norm of the incremental \
             potential below the tolerance times the force scale; XPBD: constraint residual \
             below the tolerance times the substep's first; implicit: Newton's tolerance), at \
             most {} iterations:\n",
            super::TOLERANCE_MAX_ITERATIONS
        );
        let _ = writeln!(
            s,
            "| framework | tolerance | stable | ms/frame | iterations/frame | largest residual | {} | position RMS (m) |\n|---|---:|---|---:|---:|---:|---:|---:|",
            rank_column(self.rank_by)
        );
        for t in rungs {
            let _ = writeln!(
                s,
                "| {} | {:e} | {} | {} | {} | {} | {} | {} |",
                t.framework.name(),
                t.tolerance.unwrap_or(f64::NAN),
                if t.measured {
                    "yes".to_owned()
                } else if t.stable {
                    "yes, not measured".to_owned()
                } else if t.over_cap {
                    "stopped (cost)".to_owned()
                } else {
                    "no".to_owned()
                },
                if t.ms_per_frame.is_finite() {
                    fmt_num(t.ms_per_frame)
                } else {
                    "-".into()
                },
                iterations_text(t),
                t.residual.map_or("-".into(), sci),
                rank_text(self.rank_by, t.rank_value),
                if t.measured {
                    sci(t.errors.whole.position_rms)
                } else {
                    "-".into()
                }
            );
        }
    }

    /// Every trial, one CSV row each (RFC 4180: a field with a comma, a quote or a line break
    /// is quoted, as the settings' labels `bdf2, 10 iterations` and `cg-jacobi, 25 iterations`
    /// are). Every number is finite: an unknown one (the cost of a stopped rung, the errors of
    /// a rung that was not measured) is an empty cell, and the last column, `status`, says why
    /// ([`Trial::status`]).
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "energy,framework,setting,tolerance,stable,over_cap,ms_per_frame,iterations_per_frame,residual,rank_value,position_rms,position_max,area,inverted",
        );
        for p in ["whole", "impact", "sustained"] {
            let _ = write!(
                s,
                ",{p}_position_rms,{p}_stress_l2,{p}_stress_peak,{p}_pressure_peak"
            );
        }
        s.push_str(",status\n");
        let num = |x: f64| {
            if x.is_finite() {
                x.to_string()
            } else {
                String::new()
            }
        };
        let opt = |x: Option<f64>| x.map_or(String::new(), num);
        for t in &self.trials {
            let _ = write!(
                s,
                "{},{},{},{},{},{},{},{},{},{}",
                t.energy,
                t.framework.name(),
                csv_field(&t.setting),
                opt(t.tolerance),
                t.stable,
                t.over_cap,
                num(t.ms_per_frame),
                num(t.iterations_per_frame),
                opt(t.residual),
                opt(t.rank_value),
            );
            if t.measured {
                let _ = write!(
                    s,
                    ",{},{},{},{}",
                    num(t.errors.whole.position_rms),
                    num(t.errors.whole.position_max),
                    num(t.errors.whole.area),
                    t.errors.whole.inverted
                );
            } else {
                s.push_str(",,,,");
            }
            for p in [Phase::Whole, Phase::Impact, Phase::Sustained] {
                match t.errors.get(p).filter(|_| t.measured) {
                    Some(w) => {
                        let _ = write!(
                            s,
                            ",{},{},{},{}",
                            num(w.position_rms),
                            opt(w.stress_l2),
                            opt(w.stress_peak),
                            opt(w.pressure_peak)
                        );
                    }
                    None => s.push_str(",,,,"),
                }
            }
            let _ = writeln!(s, ",{}", csv_field(&t.status()));
        }
        s
    }

    /// One chart per energy: the ranking quantity against ms per frame for every measured
    /// setting, a curve per framework (log-log), and the budget as a vertical line. An error
    /// of exactly 0 (a body at rest) cannot sit on a log axis: it is drawn at a floor, a
    /// decade below the smallest error that is not 0 (1e-12 when none is), and a dotted line
    /// at the floor says so in the legend (`error 0, drawn at 1e-12`). An energy with nothing
    /// to draw (no measured setting) has a chart without points, which is not written.
    pub fn charts(&self) -> Vec<(EnergyKind, fem_render::chart::LineChart)> {
        use fem_render::chart::{LineChart, Scale, Series};
        let mut energies: Vec<EnergyKind> = Vec::new();
        for t in &self.trials {
            if !energies.contains(&t.energy) {
                energies.push(t.energy);
            }
        }
        energies
            .into_iter()
            .map(|e| {
                let per_framework: Vec<(Framework, Vec<(f64, f64)>)> = Framework::ALL
                    .into_iter()
                    .map(|f| {
                        let points = self
                            .trials
                            .iter()
                            .filter(|t| t.energy == e && t.framework == f && t.measured)
                            .filter_map(|t| Some((t.ms_per_frame, t.rank_value?)))
                            .filter(|p| {
                                p.0 > 0.0 && p.0.is_finite() && p.1 >= 0.0 && p.1.is_finite()
                            })
                            .collect();
                        (f, points)
                    })
                    .collect();
                let values = || per_framework.iter().flat_map(|(_, p)| p.iter());
                let smallest = values()
                    .map(|p| p.1)
                    .filter(|&v| v > 0.0)
                    .fold(f64::INFINITY, f64::min);
                let floor = values().any(|p| p.1 == 0.0).then(|| {
                    if smallest.is_finite() {
                        10f64.powf(smallest.log10().floor() - 1.0)
                    } else {
                        1e-12
                    }
                });
                let mut series = Vec::new();
                let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
                let (mut left, mut right) = (f64::INFINITY, 0.0f64);
                for (f, points) in per_framework {
                    let points: Vec<(f64, f64)> = points
                        .into_iter()
                        .map(|(x, y)| (x, if y == 0.0 { floor.unwrap_or(y) } else { y }))
                        .collect();
                    for p in &points {
                        lo = lo.min(p.1);
                        hi = hi.max(p.1);
                        left = left.min(p.0);
                        right = right.max(p.0);
                    }
                    if !points.is_empty() {
                        series.push(Series {
                            label: f.name().into(),
                            points,
                        });
                    }
                }
                if let Some(floor) = floor {
                    series.push(Series {
                        label: format!("error 0, drawn at {floor:e}"),
                        points: vec![
                            (left.min(self.budget_ms), floor),
                            (right.max(self.budget_ms), floor),
                        ],
                    });
                }
                if lo.is_finite() {
                    // A decade either side when every error is the same (a body at rest).
                    let (lo, hi) = if hi > lo {
                        (lo, hi)
                    } else {
                        (lo / 10.0, hi * 10.0)
                    };
                    series.push(Series {
                        label: "budget".into(),
                        points: vec![(self.budget_ms, lo), (self.budget_ms, hi)],
                    });
                }
                let phase = self
                    .reference_of(e)
                    .map_or(Phase::Whole, |r| self.rank_by.effective_phase(&r.windows));
                let what = match self.rank_by {
                    RankBy::Position => "position RMS [m]".to_owned(),
                    RankBy::Stress | RankBy::StressImpact => {
                        format!("tissue stress error, {} (L2)", phase.name())
                    }
                    RankBy::Pressure | RankBy::PressureImpact => {
                        format!("peak pressure error, {}", phase.name())
                    }
                };
                (
                    e,
                    LineChart {
                        title: format!(
                            "{}: {e} at {} Hz, error against cost per frame",
                            self.scene,
                            fmt_num(self.fps)
                        ),
                        x_label: "ms per frame (one thread)".into(),
                        y_label: what,
                        x_scale: Scale::Log,
                        y_scale: Scale::Log,
                        series,
                        markers: true,
                        ..LineChart::default()
                    },
                )
            })
            .collect()
    }
}

/// Whether `chart` has a point it can draw (finite, and positive on a log axis): a chart
/// without one is not written.
pub fn drawable(chart: &fem_render::chart::LineChart) -> bool {
    use fem_render::chart::Scale;
    let ok = |v: f64, s: Scale| v.is_finite() && (s == Scale::Linear || v > 0.0);
    chart.series.iter().any(|s| {
        s.points
            .iter()
            .any(|&(x, y)| ok(x, chart.x_scale) && ok(y, chart.y_scale))
    })
}

fn iterations_text(t: &Trial) -> String {
    if t.iterations_per_frame.is_finite() && t.iterations_per_frame > 0.0 {
        fmt_num(t.iterations_per_frame)
    } else {
        "-".into()
    }
}

impl Reference {
    /// The reference's own error in the phase the medical answer reads (sustained, or the
    /// whole run without one).
    pub fn rank_phase_errors(&self) -> Option<&WindowErrors> {
        self.error
            .get(RankBy::Stress.effective_phase(&self.windows))
    }
}

impl<C: measure::Cell> BudgetRun<C> {
    /// One chart per energy: the reference's kinetic energy, the soft tissue's peak von Mises
    /// stress and the total contact force against time, each over its largest value (log
    /// scale), with the settle threshold and the windows' starts as lines.
    pub fn phase_charts(&self) -> Vec<(EnergyKind, fem_render::chart::LineChart)> {
        use fem_render::chart::{LineChart, Scale, Series};
        let lay = &self.layout;
        self.budget
            .references
            .iter()
            .filter_map(|r| {
                let name = format!("{}-reference", r.energy.name());
                let traj = &self.trajectories.iter().find(|(n, _)| *n == name)?.1;
                let dt = lay.frame_dt;
                let soft: Vec<bool> = lay
                    .region_tags
                    .iter()
                    .map(|&t| !lay.regions[t as usize].rigid)
                    .collect();
                let peak: Vec<f64> = traj
                    .von_mises
                    .iter()
                    .map(|f| {
                        f.iter()
                            .zip(&soft)
                            .filter(|(v, s)| **s && v.is_finite())
                            .map(|(v, _)| *v)
                            .fold(0.0, f64::max)
                    })
                    .collect();
                let force: Vec<f64> = traj
                    .contact
                    .iter()
                    .map(|row| row.iter().map(|c| c[1]).sum())
                    .collect();
                // Values below a hundredth of the settle threshold (the body at rest before
                // the first contact) are left out: they would stretch the log axis.
                let floor = 1e-2 * r.windows.settle;
                let normalised = |label: &str, v: &[f64]| {
                    let m = v.iter().copied().fold(0.0, f64::max);
                    let points: Vec<(f64, f64)> = v
                        .iter()
                        .enumerate()
                        .filter(|(_, x)| m > 0.0 && **x >= floor * m)
                        .map(|(k, x)| (k as f64 * dt, x / m))
                        .collect();
                    (!points.is_empty()).then(|| Series {
                        label: label.into(),
                        points,
                    })
                };
                let mut series: Vec<Series> = [
                    normalised("kinetic energy", &traj.kinetic_energy),
                    normalised("soft tissue peak von Mises", &peak),
                    normalised("total contact force", &force),
                ]
                .into_iter()
                .flatten()
                .collect();
                // A body at rest has none of the three: the chart says so.
                let at_rest = if series.is_empty() {
                    " (at rest: no kinetic energy, stress or contact force to draw)"
                } else {
                    ""
                };
                let lo = floor;
                let end = (traj.frames.len().saturating_sub(1)) as f64 * dt;
                series.push(Series {
                    label: format!("settle threshold ({})", pct(Some(r.windows.settle))),
                    points: vec![(0.0, r.windows.settle), (end, r.windows.settle)],
                });
                for (label, span) in [
                    ("impact starts", r.windows.impact),
                    ("sustained starts", r.windows.sustained),
                ] {
                    if let Some(span) = span {
                        let t = span[0] as f64 * dt;
                        series.push(Series {
                            label: label.into(),
                            points: vec![(t, lo.min(r.windows.settle)), (t, 1.0)],
                        });
                    }
                }
                Some((
                    r.energy,
                    LineChart {
                        title: format!(
                            "{}: {} reference, the windows the errors are taken over{at_rest}",
                            self.budget.scene, r.energy
                        ),
                        x_label: "time [s]".into(),
                        y_label: "over its largest value".into(),
                        x_scale: Scale::Linear,
                        y_scale: Scale::Log,
                        series,
                        ..LineChart::default()
                    },
                ))
            })
            .collect()
    }
}

/// One sentence naming the best framework of `energy` within the budget, the quantity ranked
/// by, and (with contact and soft tissue) the medical check.
pub(super) fn sentence(budget: &Budget, energy: EnergyKind, spec: &BudgetSpec) -> String {
    let rank = budget.rank_by;
    let what = budget
        .reference_of(energy)
        .map_or_else(|| rank.name().to_owned(), |r| rank.describe(&r.windows));
    let mine: Vec<_> = budget.rows.iter().filter(|r| r.energy == energy).collect();
    let within: Vec<_> = mine.iter().copied().filter(|r| r.best.is_some()).collect();
    let head = format!(
        "{energy} at {} Hz within {} ms per frame, ranked by {what}",
        fmt_num(spec.fps),
        fmt_num(spec.budget_ms)
    );
    let unmeasured = mine
        .iter()
        .find_map(|r| budget.unmeasured_within(energy, r.framework));
    let mut reasons: Vec<&str> = Vec::new();
    for why in mine.iter().filter_map(|r| r.cannot_run.as_deref()) {
        if !reasons.contains(&why) {
            reasons.push(why);
        }
    }
    let mut out = match within.first() {
        None if !mine.is_empty() && mine.iter().all(|r| r.cannot_run.is_some()) => {
            format!("{head}: no framework can run it: {}.", reasons.join("; "))
        }
        None => match unmeasured {
            Some(t) => format!(
                "{head}: no framework has a measured stable setting within the budget ({} {}: \
                 not measured: {}).",
                t.framework.name(),
                t.setting,
                t.note.as_deref().unwrap_or("no reason recorded")
            ),
            None => format!("{head}: no framework has a stable setting within the budget."),
        },
        Some(r) => {
            let b = r.best.as_ref().expect("filtered");
            let position = if rank == RankBy::Position {
                String::new()
            } else {
                format!(", position RMS {} m", sci(b.errors.whole.position_rms))
            };
            let mut out = format!(
                "{head}: {} ({}) is the most accurate, {}{position}, {} ms per frame",
                r.framework.name(),
                b.setting,
                rank_text(rank, b.rank_value),
                fmt_num(b.ms_per_frame)
            );
            if let Some(next) = within.get(1) {
                let n = next.best.as_ref().expect("filtered");
                let _ = write!(
                    out,
                    "; next {} ({}), {}",
                    next.framework.name(),
                    n.setting,
                    rank_text(rank, n.rank_value)
                );
            }
            out.push('.');
            out
        }
    };
    if let Some((pass, closest)) = budget.medical_check(energy) {
        let phase = budget
            .reference_of(energy)
            .map_or(Phase::Whole, |r| RankBy::Stress.effective_phase(&r.windows));
        let both = format!(
            "the soft tissue's stress (L2) and the peak contact pressure {} within {}",
            match phase {
                Phase::Sustained => "in the sustained phase",
                _ => "over the whole run",
            },
            pct(Some(budget.criterion))
        );
        let errs = |t: &Trial| {
            let w = t.errors.get(phase);
            format!(
                "stress {}, pressure {}",
                pct(w.and_then(|w| w.stress_l2)),
                pct(w.and_then(|w| w.pressure_peak))
            )
        };
        if let Some(t) = pass
            .iter()
            .min_by(|a, b| a.ms_per_frame.total_cmp(&b.ms_per_frame))
        {
            let _ = write!(
                out,
                " Gets {both}: {} (the cheapest of them: {} ({}), {} ms per frame, {}).",
                pass.iter()
                    .map(|t| t.framework.name())
                    .fold(Vec::<&str>::new(), |mut v, n| {
                        if !v.contains(&n) {
                            v.push(n);
                        }
                        v
                    })
                    .join(", "),
                t.framework.name(),
                t.setting,
                fmt_num(t.ms_per_frame),
                errs(t)
            );
        } else if let Some(c) = closest {
            let _ = write!(
                out,
                " No setting within the budget gets {both}; the closest is {} ({}), {}.",
                c.framework.name(),
                c.setting,
                errs(c)
            );
        }
        // The reference's own error bounds what the check can decide.
        if let Some(w) = budget
            .reference_of(energy)
            .and_then(|r| r.rank_phase_errors())
        {
            let (rs, rp) = (w.stress_l2, w.pressure_peak);
            let _ = write!(
                out,
                " The reference's own error there (against itself at twice its step): stress {}, pressure {}",
                pct(rs),
                pct(rp)
            );
            let undecided: Vec<&str> = [("stress", rs), ("pressure", rp)]
                .into_iter()
                .filter(|(_, e)| e.is_some_and(|e| e > budget.criterion))
                .map(|(n, _)| n)
                .collect();
            if undecided.is_empty() {
                out.push('.');
            } else {
                let _ = write!(
                    out,
                    ": above {} on {}, which this reference cannot decide to that accuracy.",
                    pct(Some(budget.criterion)),
                    undecided.join(" and ")
                );
            }
        }
    }
    out
}

/// One CSV field (RFC 4180): quoted, with its quotes doubled, when it holds a comma, a quote or
/// a line break; as it is otherwise.
fn csv_field(s: &str) -> std::borrow::Cow<'_, str> {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\"")).into()
    } else {
        s.into()
    }
}

/// One sentence setting the budget of a 2D scene beside that of its 3D counterpart for
/// `energy`: each dimension's ranking of the frameworks with a setting within the budget (best
/// first, with its setting and ranking value), whether the order of the frameworks both rank
/// is the same, and implicit Euler's cheapest stable cost per frame in each.
pub fn dimensions_sentence(two: &Budget, three: &Budget, energy: EnergyKind) -> String {
    let ranked = |b: &Budget| -> Vec<(Framework, String)> {
        b.rows
            .iter()
            .filter(|r| r.energy == energy)
            .filter_map(|r| {
                let t = r.best.as_ref()?;
                Some((
                    r.framework,
                    format!(
                        "{} ({}, {})",
                        r.framework.name(),
                        t.setting,
                        rank_text(b.rank_by, t.rank_value)
                    ),
                ))
            })
            .collect()
    };
    let (r2, r3) = (ranked(two), ranked(three));
    let list = |r: &[(Framework, String)]| {
        if r.is_empty() {
            "none".to_owned()
        } else {
            r.iter()
                .map(|(_, s)| s.as_str())
                .collect::<Vec<_>>()
                .join(" > ")
        }
    };
    let common = |a: &[(Framework, String)], b: &[(Framework, String)]| -> Vec<Framework> {
        a.iter()
            .map(|(f, _)| *f)
            .filter(|f| b.iter().any(|(g, _)| g == f))
            .collect()
    };
    let (c2, c3) = (common(&r2, &r3), common(&r3, &r2));
    let verdict = if r2.first().map(|x| x.0) == r3.first().map(|x| x.0) && c2 == c3 {
        "the 2D ranking holds in 3D".to_owned()
    } else if r2.first().map(|x| x.0) == r3.first().map(|x| x.0) {
        "the winner holds in 3D, the order behind it does not".to_owned()
    } else {
        "the 2D ranking does not hold in 3D".to_owned()
    };
    let implicit = |b: &Budget| {
        b.rows
            .iter()
            .find(|r| r.energy == energy && r.framework == Framework::Implicit)
            .and_then(|r| r.cheapest.as_ref())
            .map_or("-".to_owned(), |t| {
                format!("{} ms", fmt_num(t.ms_per_frame))
            })
    };
    format!(
        "{energy}, {} in 2D against {} in 3D at {} Hz within {} ms per frame, ranked by {}: \
         {verdict}. 2D: {}. 3D: {}. Implicit Euler's cheapest stable setting costs {} per \
         frame in 2D and {} in 3D.",
        two.scene,
        three.scene,
        fmt_num(two.fps),
        fmt_num(two.budget_ms),
        two.rank_by.name(),
        list(&r2),
        list(&r3),
        implicit(two),
        implicit(three)
    )
}
