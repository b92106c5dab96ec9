//! `fem_cases::budget`: the ranking does not change between two runs (case A, and case D with
//! its regions and contact), every error the tables report is recomputed from the written
//! trajectories, case D's windows are found, a deliberately poor setting ranks last on the
//! soft tissue's stress, and the iterative solvers' tolerance rungs approach implicit Euler's
//! step.

use std::sync::OnceLock;

use fem_cases::budget::{
    BudgetRun, BudgetSpec, Cell, Framework, Layout, Phase, RankBy, Trajectory, Windows, budget,
    errors,
};
use fem_cases::files::load_case_or_file;
use fem_core::energy::EnergyKind;

fn spec() -> BudgetSpec {
    BudgetSpec {
        duration: Some(0.5),
        energies: vec![EnergyKind::NeoHookean, EnergyKind::Corotational],
        ..BudgetSpec::default()
    }
}

/// Case D, 0.7 s (the reference settles about 0.46 s in), with a budget of one second a
/// frame: the ladders are not cut by cost and every setting is within the budget, so the
/// ranking depends on the errors alone (deterministic), not on this machine's timing. PBD (its
/// 1-iteration rung is the deliberately poor setting), XPBD small steps and implicit Euler.
/// Stable Neo-Hookean: under Neo-Hookean PBD below 200 iterations crushes the tissue until
/// triangles invert, where `log J` is undefined, and the run stops (so its poorest setting
/// would not rank at all); the inversion-safe energy keeps every rung running.
fn case_d_spec() -> BudgetSpec {
    BudgetSpec {
        duration: Some(0.7),
        budget_ms: 1000.0,
        energies: vec![EnergyKind::StableNeoHookean],
        frameworks: vec![
            Framework::Pbd,
            Framework::XpbdSmallSteps,
            Framework::Implicit,
        ],
        ..BudgetSpec::default()
    }
}

fn case_d() -> &'static BudgetRun {
    static RUN: OnceLock<BudgetRun> = OnceLock::new();
    RUN.get_or_init(|| {
        let base = load_case_or_file("case-d", &[]).unwrap();
        budget(&base, &case_d_spec(), |_| {}).unwrap()
    })
}

type Ranking = Vec<(EnergyKind, Framework, Option<String>)>;

fn ranking(b: &fem_cases::budget::Budget) -> Ranking {
    b.rows
        .iter()
        .map(|r| {
            (
                r.energy,
                r.framework,
                r.best.as_ref().map(|t| t.setting.clone()),
            )
        })
        .collect()
}

/// Case A at 90 Hz: every framework runs (no contact), ranked by position error (the default
/// without regions or contact); the ranking is the same in a second run (the errors are
/// deterministic, and with a budget every rung meets, timing noise cannot move a setting
/// across it).
#[test]
fn case_a_ranking_is_the_same_in_two_runs() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    // A budget of one second a frame: the ladders' dearer rungs (VBD at 200 sweeps, its
    // tolerance 1e-4, about 5 ms here) would otherwise sit on the 5 ms line, where a loaded
    // machine's timing decides the side.
    let spec = BudgetSpec {
        budget_ms: 1000.0,
        ..spec()
    };
    let first = budget(&base, &spec, |_| {}).unwrap().budget;
    let second = budget(&base, &spec, |_| {}).unwrap().budget;
    assert_eq!(first.rank_by, RankBy::Position);
    assert_eq!(ranking(&first), ranking(&second));
    for s in &first.sentences {
        eprintln!("{s}");
        assert!(
            s.contains("ranked by position RMS over the whole run"),
            "{s}"
        );
    }
    // No contact: no phases.
    for r in &first.references {
        assert_eq!(r.windows.impact, None);
        assert_eq!(r.windows.sustained, None);
    }
    // Projective Dynamics cannot run Neo-Hookean and says so; every other row has a stable
    // setting within the budget.
    for r in &first.rows {
        if r.framework == Framework::Pd && r.energy == EnergyKind::NeoHookean {
            assert!(r.cannot_run.is_some());
        } else {
            assert!(r.best.is_some(), "{:?} {:?}", r.energy, r.framework);
        }
    }
    // The implicit family converges to the reference, explicit and PBD do not reach it.
    let err = |e: EnergyKind, f: Framework| {
        first
            .rows
            .iter()
            .find(|r| r.energy == e && r.framework == f)
            .and_then(|r| r.best.as_ref())
            .map(|t| t.errors.whole.position_rms)
            .unwrap()
    };
    assert!(
        err(EnergyKind::NeoHookean, Framework::QuasiNewton)
            < err(EnergyKind::NeoHookean, Framework::Xpbd)
    );
    assert!(
        err(EnergyKind::Corotational, Framework::Pd)
            < err(EnergyKind::Corotational, Framework::Pbd)
    );
}

/// With a residual tolerance the iterative solvers approach implicit Euler's step at the same
/// frame step: on case A, the position error (against the converged reference) of VBD's,
/// quasi-Newton's and (co-rotational) Projective Dynamics' tightest tolerance rung is within
/// 2 % of implicit Euler's at Newton's tolerance 1e-8 (both then carry implicit Euler's own
/// numerical damping, 6.1e-3 m RMS over these 0.5 s; the 2 % is the part of the iterative solvers' residual
/// still left at their tolerance 1e-6 and 200 iterations at most), and each rung reports the
/// iterations it used, fewer than the fixed ladder's top where the tolerance was met. The
/// BDF2 rungs of the same frameworks beat backward Euler's, and linearly implicit Euler's CG
/// rungs reach its direct rung, which is near implicit Euler's.
#[test]
fn tolerance_rungs_approach_implicit_euler_on_case_a() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let spec = BudgetSpec {
        duration: Some(0.5),
        budget_ms: 1000.0,
        energies: vec![EnergyKind::Corotational],
        frameworks: vec![
            Framework::Vbd,
            Framework::Pd,
            Framework::QuasiNewton,
            Framework::LinearImplicit,
            Framework::Implicit,
        ],
        ..BudgetSpec::default()
    };
    let b = budget(&base, &spec, |_| {}).unwrap().budget;
    let rung = |f: Framework, label: &str| {
        let t = b
            .trials
            .iter()
            .find(|t| t.framework == f && t.setting == label)
            .unwrap_or_else(|| panic!("{f:?} {label}"));
        assert!(t.stable, "{f:?} {label}");
        t.errors.whole.position_rms
    };
    // BDF2's rungs: second order at the same cost a step, so on this smooth motion, where
    // backward Euler's numerical damping is the error, each is closer to the converged motion
    // than backward Euler's rung of the same setting: at most 0.75 of its error (measured 0.65:
    // 4.0e-3 m against 6.1e-3 m RMS over 0.5 s, where the swing's phase error dominates).
    for (f, label) in [
        (Framework::Implicit, "velocity 1e-3 m/s"),
        (Framework::Vbd, "100 iterations"),
        (Framework::Pd, "100 iterations"),
        (Framework::QuasiNewton, "100 iterations"),
    ] {
        let (be, bdf2) = (rung(f, label), rung(f, &format!("bdf2, {label}")));
        eprintln!("{f:?} {label}: backward Euler {be:.4e} m, BDF2 {bdf2:.4e} m");
        assert!(bdf2 < 0.75 * be, "{f:?} {label}: BDF2 {bdf2} against {be}");
    }
    // Linearly implicit Euler: CG reaches the direct solve's motion as its iterations grow
    // (measured: 200 Jacobi iterations equal it to 5 digits), and the direct solve's motion
    // (one Newton iteration a step) is near implicit Euler's (measured 1.7 % apart; the bound
    // 5 %).
    let direct = rung(Framework::LinearImplicit, "direct");
    let implicit_be = rung(Framework::Implicit, "tolerance 1e-8");
    for n in [10, 25, 50, 100, 200] {
        let e = rung(
            Framework::LinearImplicit,
            &format!("cg-jacobi, {n} iterations"),
        );
        eprintln!(
            "linear-implicit cg-jacobi {n}: {e:.4e} m (direct {direct:.4e} m, implicit {implicit_be:.4e} m)"
        );
    }
    let cg = rung(Framework::LinearImplicit, "cg-jacobi, 200 iterations");
    assert!(
        (cg - direct).abs() <= 1e-3 * direct,
        "{cg} against {direct}"
    );
    assert!(
        (direct - implicit_be).abs() <= 0.05 * implicit_be,
        "{direct} against implicit Euler's {implicit_be}"
    );
    let trial = |f: Framework, tol: f64| {
        b.trials
            .iter()
            .find(|t| t.framework == f && t.tolerance == Some(tol))
            .unwrap_or_else(|| panic!("{f:?} {tol}"))
    };
    let implicit = trial(Framework::Implicit, 1e-8).errors.whole.position_rms;
    for f in [Framework::Vbd, Framework::Pd, Framework::QuasiNewton] {
        let loose = trial(f, 1e-2);
        let tight = trial(f, 1e-6);
        assert!(loose.stable && tight.stable, "{f:?}");
        let (el, et) = (
            loose.errors.whole.position_rms,
            tight.errors.whole.position_rms,
        );
        eprintln!(
            "{f:?}: tolerance 1e-2 {el:.4e} m ({:.1} it/frame), 1e-6 {et:.4e} m ({:.1} it/frame), implicit {implicit:.4e} m",
            loose.iterations_per_frame, tight.iterations_per_frame
        );
        assert!(
            (et - implicit).abs() <= 0.02 * implicit,
            "{f:?}: {et} against implicit Euler's {implicit}"
        );
        assert!(
            (el - implicit).abs() >= (et - implicit).abs(),
            "{f:?}: the looser tolerance is not further from implicit Euler's step"
        );
        assert!(loose.iterations_per_frame <= tight.iterations_per_frame);
        assert!(loose.iterations_per_frame > 0.0 && loose.iterations_per_frame < 200.0);
    }
}

/// The table's errors are those of the written trajectories: recomputed from
/// `trajectories.json` (the layout, the windows found again on each reference, the
/// trajectories), every row's best setting and each reference's own error give the same
/// numbers, bit for bit.
pub(crate) fn recompute_from_written<C: Cell>(run: &BudgetRun<C>, tag: &str) -> usize {
    let dir = std::env::temp_dir().join(format!("fem2d-budget-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    run.write(&dir, true).unwrap();
    let text = std::fs::read_to_string(dir.join("trajectories.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let layout: Layout<C> = serde_json::from_value(v["layout"].clone()).unwrap();
    let trajectory = |name: &str| -> Trajectory<C::Point> {
        serde_json::from_value(v["trajectories"][name].clone())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let written: fem_cases::budget::Budget =
        serde_json::from_str(&std::fs::read_to_string(dir.join("budget.json")).unwrap()).unwrap();
    // Compared as JSON: a rung stopped over the cost cap has a NaN cost (`null` in the file),
    // and NaN is never equal to itself.
    let (a, b) = (
        serde_json::to_value(&written).unwrap(),
        serde_json::to_value(&run.budget).unwrap(),
    );
    if a != b {
        panic!(
            "budget.json does not read back: first difference at {}",
            first_difference(&a, &b, String::new()).unwrap_or_else(|| "(none in JSON)".into())
        );
    }
    let mut checked = 0;
    for r in &written.references {
        let e = r.energy.name();
        let reference = trajectory(&format!("{e}-reference"));
        let windows = Windows::find(&layout, &reference, r.windows.settle);
        assert_eq!(windows, r.windows);
        let stored: Windows = serde_json::from_value(v["windows"][e].clone()).unwrap();
        assert_eq!(stored, windows);
        let coarse = trajectory(&format!("{e}-reference-coarse"));
        assert_eq!(errors(&layout, &windows, &coarse, &reference), r.error);
        for row in written.rows.iter().filter(|row| row.energy == r.energy) {
            let Some(best) = &row.best else { continue };
            let mine = trajectory(&format!("{e}-{}", row.framework.name()));
            let again = errors(&layout, &windows, &mine, &reference);
            assert_eq!(again, best.errors, "{e} {:?}", row.framework);
            assert_eq!(
                written.rank_by.value(&again, &windows),
                best.rank_value,
                "{e} {:?}",
                row.framework
            );
            checked += 1;
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    checked
}

#[test]
fn every_reported_error_is_recomputed_from_the_written_trajectories() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let run = budget(&base, &spec(), |_| {}).unwrap();
    let checked = recompute_from_written(&run, "a");
    assert!(checked >= 10, "{checked}");
}

/// The same on case D: stress per region (soft tissue and the rigid bones' wrench), contact
/// pressure per target (ground and debris), per window.
#[test]
fn case_d_errors_per_region_phase_and_contact_are_recomputed_from_the_trajectories() {
    let run = case_d();
    let checked = recompute_from_written(run, "d");
    assert_eq!(checked, 3);
    let best = run.budget.rows[0].best.as_ref().unwrap();
    let s = best.errors.sustained.as_ref().unwrap();
    // The soft tissue, the bones (rigid: wrench, not stress), the ground and the debris.
    let names: Vec<&str> = s.regions.iter().map(|r| r.region.as_str()).collect();
    assert_eq!(names, ["soft-tissue", "bone"]);
    assert!(s.regions[0].stress_l2.is_some() && s.regions[0].force.is_none());
    assert!(s.regions[1].stress_l2.is_none() && s.regions[1].force.is_some());
    let targets: Vec<&str> = s.contact.iter().map(|c| c.target.as_str()).collect();
    assert_eq!(targets, ["ground", "debris"]);
    for c in &s.contact {
        assert!(
            c.reference_peak_pressure > 0.0 && c.reference_impulse > 0.0,
            "{c:?}"
        );
    }
    // With only the soft tissue deformable, its stress is the tissue's.
    assert_eq!(s.stress_l2, s.regions[0].stress_l2);
}

/// Case D's windows: the impact starts at the first contact (the body settles on the ground
/// in the first frames, the debris lands on the shin 2 mm below it) and ends once the
/// reference's kinetic energy stays below 1 % of its peak; the sustained phase starts after
/// the soft tissue's peak stress, and both windows are non-empty.
#[test]
fn case_d_windows_are_found_and_the_sustained_phase_follows_the_peak() {
    let run = case_d();
    let r = &run.budget.references[0];
    let impact = r.windows.impact.expect("an impact window");
    let sustained = r.windows.sustained.expect("a sustained window");
    assert!(impact[0] < impact[1] && impact[1] == sustained[0]);
    assert!(sustained[0] < sustained[1] && sustained[1] == r.windows.whole[1]);
    let reference = &run
        .trajectories
        .iter()
        .find(|(n, _)| n == "stable-neo-hookean-reference")
        .unwrap()
        .1;
    let lay = &run.layout;
    let soft_peak = |f: &Vec<f64>| {
        f.iter()
            .enumerate()
            .filter(|(t, v)| !lay.regions[lay.region_tags[*t] as usize].rigid && v.is_finite())
            .map(|(_, v)| *v)
            .fold(0.0, f64::max)
    };
    let peaks: Vec<f64> = reference.von_mises.iter().map(soft_peak).collect();
    let peak_frame = (0..peaks.len())
        .max_by(|&a, &b| peaks[a].total_cmp(&peaks[b]))
        .unwrap();
    eprintln!(
        "impact {impact:?}, sustained {sustained:?}, tissue peak {:.0} Pa at frame {peak_frame}",
        peaks[peak_frame]
    );
    assert!(impact[0] <= peak_frame && peak_frame < sustained[0]);
    let ke = &reference.kinetic_energy;
    let ke_peak = ke[impact[0]..].iter().copied().fold(0.0, f64::max);
    assert!(ke[sustained[0]..].iter().all(|&k| k < 0.01 * ke_peak));
    assert!(ke[impact[1] - 1] >= 0.01 * ke_peak);
}

/// The default ranking on a scene with regions and contact is the soft tissue's sustained
/// stress; PBD with one iteration (the deliberately poor setting) has a larger error in it
/// than every framework's best setting; two runs rank the same.
#[test]
fn case_d_poor_setting_ranks_last_and_the_ranking_repeats() {
    let run = case_d();
    let b = &run.budget;
    assert_eq!(b.rank_by, RankBy::Stress);
    let poor = b
        .trials
        .iter()
        .find(|t| t.framework == Framework::Pbd && t.setting == "1 iterations")
        .unwrap();
    assert!(poor.stable, "{:?}", poor.failure);
    let poor_value = poor.rank_value.unwrap();
    for t in b.rows.iter().filter_map(|r| r.best.as_ref()) {
        assert!(
            t.rank_value.unwrap() < poor_value,
            "{:?} {}: {:?} above PBD x 1's {poor_value}",
            t.framework,
            t.setting,
            t.rank_value
        );
    }
    assert!(b.sentences[0].contains("the soft tissue's von Mises stress in the sustained phase"));
    assert!(b.sentences[0].contains("peak contact pressure"));
    let base = load_case_or_file("case-d", &[]).unwrap();
    let again = budget(&base, &case_d_spec(), |_| {}).unwrap().budget;
    assert_eq!(ranking(b), ranking(&again));
    for (x, y) in b.trials.iter().zip(&again.trials) {
        assert_eq!(x.errors, y.errors, "{:?} {}", x.framework, x.setting);
    }
    let phase = b.rank_by.effective_phase(&b.references[0].windows);
    assert_eq!(phase, Phase::Sustained);
}

/// A budget no rung can meet: every rung is stopped once its stepping passes four times the
/// budget over the run, so no row has a setting, the table says "none stable within 4 times
/// the budget", and `budget.json` (with the stopped rungs' unknown cost, NaN, as `null`) reads
/// back.
#[test]
fn rungs_over_the_cost_cap_are_stopped_and_reported() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let spec = BudgetSpec {
        duration: Some(0.2),
        budget_ms: 1e-4,
        energies: vec![EnergyKind::Corotational],
        frameworks: vec![Framework::Pbd, Framework::Pd],
        ..BudgetSpec::default()
    };
    let run = budget(&base, &spec, |_| {}).unwrap();
    let b = &run.budget;
    assert!(!b.trials.is_empty());
    // Each ladder stops at its first stopped rung: one fixed rung each, PD's first tolerance
    // rung and PD's first BDF2 rung.
    assert!(
        b.trials.iter().all(|t| t.over_cap && !t.stable),
        "{:?}",
        b.trials
    );
    assert_eq!(b.trials.len(), 4);
    assert!(
        b.rows
            .iter()
            .all(|r| r.best.is_none() && r.cheapest.is_none())
    );
    let md = b.to_markdown();
    assert!(md.contains("none stable within 4 times the budget"), "{md}");
    // budget.csv: a label with a comma (PD's `bdf2, 2 iterations`) is one quoted field, so
    // every row has the header's fields.
    let csv = b.to_csv();
    assert!(csv.contains("\"bdf2, 2 iterations\""), "{csv}");
    let fields = |line: &str| {
        let (mut n, mut quoted) = (1, false);
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => n += 1,
                _ => {}
            }
        }
        n
    };
    let mut lines = csv.lines();
    let header = fields(lines.next().unwrap());
    for line in lines {
        assert_eq!(fields(line), header, "{line}");
    }
    assert!(b.sentences[0].contains("no framework has a stable setting within the budget"));
    let dir = std::env::temp_dir().join(format!("fem2d-budget-cap-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let written = run.write(&dir, false).unwrap();
    assert!(!dir.join("trajectories.json").exists());
    // Nothing stable: no Pareto chart to draw (the windows' chart of the reference stays).
    assert!(
        !written.iter().any(|f| f.starts_with("pareto-")),
        "{written:?}"
    );
    let text = std::fs::read_to_string(dir.join("budget.json")).unwrap();
    let back: fem_cases::budget::Budget = serde_json::from_str(&text).unwrap();
    assert!(back.trials.iter().all(|t| t.ms_per_frame.is_nan()));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes `run` into a fresh directory and returns it with the files written; `budget.json`
/// reads back equal (compared as JSON: NaN costs are `null`), and no written table carries a
/// NaN or an infinity.
fn write_and_read_back(run: &BudgetRun, tag: &str) -> (std::path::PathBuf, Vec<String>) {
    let dir = std::env::temp_dir().join(format!("fem2d-budget-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let written = run.write(&dir, false).unwrap();
    let text = std::fs::read_to_string(dir.join("budget.json")).unwrap();
    let back: fem_cases::budget::Budget = serde_json::from_str(&text).unwrap();
    assert_eq!(
        serde_json::to_value(&back).unwrap(),
        serde_json::to_value(&run.budget).unwrap()
    );
    for file in ["budget.csv", "budget.md", "budget.json"] {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        for bad in ["NaN", "nan", "inf"] {
            // `inf` inside a word (`information`) is not a number.
            let hit = text.match_indices(bad).find(|(i, _)| {
                let before = text[..*i].chars().last().unwrap_or(' ');
                let after = text[i + bad.len()..].chars().next().unwrap_or(' ');
                !before.is_alphabetic() && !after.is_alphabetic()
            });
            assert!(hit.is_none(), "{file} holds {bad}:\n{text}");
        }
    }
    (dir, written)
}

/// A body at rest (case A without gravity): every error is exactly 0. The budget finishes and
/// writes every output: the table states the errors as 0, and the Pareto chart draws them at
/// a floor it names in its legend (a log axis has no 0).
#[test]
fn a_body_at_rest_writes_its_outputs_with_errors_of_zero() {
    let base = load_case_or_file("case-a", &["gravity=[0,0]".to_owned()]).unwrap();
    let spec = BudgetSpec {
        duration: Some(0.2),
        energies: vec![EnergyKind::NeoHookean],
        frameworks: vec![Framework::Explicit, Framework::Implicit],
        ..BudgetSpec::default()
    };
    let run = budget(&base, &spec, |_| {}).unwrap();
    let b = &run.budget;
    assert!(b.trials.iter().all(|t| t.measured), "{:?}", b.trials);
    assert!(
        b.trials
            .iter()
            .all(|t| t.rank_value == Some(0.0) && t.errors.whole.position_rms == 0.0),
        "{:?}",
        b.trials
    );
    let md = b.to_markdown();
    assert!(md.contains("is the most accurate, 0 m,"), "{md}");
    let charts = b.charts();
    let zero = charts[0]
        .1
        .series
        .iter()
        .find(|s| s.label.starts_with("error 0, drawn at "))
        .expect("the floor's legend entry");
    assert_eq!(zero.label, "error 0, drawn at 1e-12");
    let (dir, written) = write_and_read_back(&run, "rest");
    for f in [
        "pareto-neo-hookean.svg",
        "pareto-neo-hookean.png",
        "phases-neo-hookean.svg",
    ] {
        assert!(written.iter().any(|w| w == f), "{f} not in {written:?}");
    }
    let svg = std::fs::read_to_string(dir.join("pareto-neo-hookean.svg")).unwrap();
    assert!(svg.contains("error 0, drawn at 1e-12"));
    let csv = std::fs::read_to_string(dir.join("budget.csv")).unwrap();
    assert!(
        csv.lines().skip(1).all(|l| l.ends_with(",measured")),
        "{csv}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A modulus beyond double precision's reach is refused before any rung runs, naming the
/// field: case A with a Young's modulus of 1e300 Pa once gave VBD a stress of infinity and
/// implicit Euler a beam held exactly at rest (a load far below the round-off of its
/// stiffness), which the budget ranked "most accurate". Rungs whose stress is still not finite
/// are marked unmeasured (`measure::non_finite`, tested in the library).
#[test]
fn a_modulus_beyond_double_precision_is_refused_before_any_rung() {
    let e = load_case_or_file("case-a", &["material.youngs_modulus=1e300".to_owned()])
        .map(|_| ())
        .expect_err("refused");
    let e = e.to_string();
    assert!(e.contains("material.youngs_modulus = 1e300"), "{e}");
    assert_eq!(e.lines().count(), 1);
}

/// A reference that does not complete (case D at the smallest Young's modulus a scene
/// allows: its Newton cannot solve the body's step) leaves nothing to measure against: the
/// budget still finishes and writes, every row saying why, and no framework is run.
#[test]
fn a_reference_that_does_not_complete_is_reported_in_the_rows() {
    let base = load_case_or_file("case-d", &["material.youngs_modulus=1e-290".to_owned()]).unwrap();
    let spec = BudgetSpec {
        duration: Some(0.1),
        frameworks: vec![Framework::Explicit, Framework::Implicit],
        ..BudgetSpec::default()
    };
    let run = budget(&base, &spec, |_| {}).unwrap();
    let b = &run.budget;
    assert!(b.trials.is_empty());
    assert_eq!(b.rows.len(), 2);
    for r in &b.rows {
        let why = r.cannot_run.as_deref().unwrap();
        assert!(
            why.starts_with("no reference to measure against: the reference run (implicit Euler"),
            "{why}"
        );
    }
    assert!(
        b.sentences[0].contains("no framework can run it: no reference"),
        "{}",
        b.sentences[0]
    );
    let (dir, written) = write_and_read_back(&run, "noref");
    assert_eq!(written, ["budget.md", "budget.csv", "budget.json"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A framework or an energy listed twice would repeat its rows (both ranked first): refused,
/// naming the list and the name.
#[test]
fn a_framework_or_energy_listed_twice_is_refused() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let spec = BudgetSpec {
        frameworks: vec![Framework::Implicit, Framework::Implicit],
        ..BudgetSpec::default()
    };
    let Err(e) = budget(&base, &spec, |_| panic!("nothing runs")) else {
        panic!("accepted")
    };
    assert_eq!(e.to_string(), "--frameworks: implicit is listed twice");
    let spec = BudgetSpec {
        energies: vec![EnergyKind::Stvk, EnergyKind::Linear, EnergyKind::Stvk],
        ..BudgetSpec::default()
    };
    let Err(e) = budget(&base, &spec, |_| panic!("nothing runs")) else {
        panic!("accepted")
    };
    assert_eq!(e.to_string(), "--energies: stvk is listed twice");
}

/// The time bound before anything runs: the estimate from the step counts alone (no clock),
/// so the refusal is the same on every machine. Case A's co-rotational energy over 0.5 s (45
/// frames, a reference of 4500 steps on 160 triangles, 19 ladders) is estimated at about
/// 0.6 s, more than 0.001 minutes; a run of hours (`--haptics` over 100 s: 100000 frames) is refused at the
/// default ten minutes. Nothing runs (the progress is never told anything).
#[test]
fn the_time_bound_refuses_before_anything_runs() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let spec = BudgetSpec {
        duration: Some(0.5),
        energies: vec![EnergyKind::Corotational],
        max_minutes: 0.001,
        ..BudgetSpec::default()
    };
    let Err(e) = budget(&base, &spec, |w| panic!("{w} ran")) else {
        panic!("accepted")
    };
    let e = e.to_string();
    assert!(
        e.starts_with("--max-minutes 0.001: the budget would take about 0.0")
            && e.contains(" minutes (0.")
            && e.contains(
                "estimated before running, from the step counts: 1 energy x (a reference of \
                 4500 steps on 160 triangles + up to 19 ladders of settings over 45 frames)"
            )
            && e.contains("shorten --duration, choose fewer --frameworks or --energies, or raise --max-minutes"),
        "{e}"
    );
    let spec = BudgetSpec {
        duration: Some(100.0),
        ..BudgetSpec::haptics()
    };
    assert_eq!(spec.max_minutes, fem_cases::budget::DEFAULT_MAX_MINUTES);
    let Err(e) = budget(&base, &spec, |w| panic!("{w} ran")) else {
        panic!("accepted")
    };
    assert!(
        e.to_string()
            .starts_with("--max-minutes 10: the budget would take about "),
        "{e}"
    );
}

/// The path of the first difference between two JSON values (`None`: equal).
fn first_difference(a: &serde_json::Value, b: &serde_json::Value, path: String) -> Option<String> {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => x.iter().find_map(|(k, v)| match y.get(k) {
            Some(w) => first_difference(v, w, format!("{path}.{k}")),
            None => Some(format!("{path}.{k} (missing)")),
        }),
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => (x.iter().zip(y))
            .enumerate()
            .find_map(|(i, (v, w))| first_difference(v, w, format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some(format!("{path}: {a} read back, {b} in memory")),
    }
}
