//! `fem_cases::budget` on case A: the ranking does not change between two runs, and every
//! error the table reports is recomputed from the written trajectories.

use fem_cases::budget::{BudgetSpec, Framework, Trajectory, budget, errors};
use fem_cases::files::load_case_or_file;
use fem_core::energy::EnergyKind;

fn spec() -> BudgetSpec {
    BudgetSpec {
        duration: Some(0.5),
        energies: vec![EnergyKind::NeoHookean, EnergyKind::Corotational],
        ..BudgetSpec::default()
    }
}

/// Case A at 90 Hz: every framework runs (no contact), ranked by position error within the
/// 5 ms budget; the ranking is the same in a second run (the errors are deterministic and
/// case A's 160 triangles cost far below the budget, so timing noise cannot move a setting
/// across it).
#[test]
fn case_a_ranking_is_the_same_in_two_runs() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let first = budget(&base, &spec(), |_| {}).unwrap().budget;
    let second = budget(&base, &spec(), |_| {}).unwrap().budget;
    let ranking = |b: &fem_cases::budget::Budget| -> Vec<(EnergyKind, Framework, Option<String>)> {
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
    };
    assert_eq!(ranking(&first), ranking(&second));
    for s in &first.sentences {
        eprintln!("{s}");
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
            .map(|t| t.errors.position_rms)
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

/// The table's errors are those of the written trajectories: recomputed from
/// `trajectories.json`, every row's best setting gives the same numbers, bit for bit.
#[test]
fn every_reported_error_is_recomputed_from_the_written_trajectories() {
    let base = load_case_or_file("case-a", &[]).unwrap();
    let run = budget(&base, &spec(), |_| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("fem2d-budget-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    run.write(&dir).unwrap();
    let text = std::fs::read_to_string(dir.join("trajectories.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let rest: Vec<[f64; 2]> = serde_json::from_value(v["rest"].clone()).unwrap();
    let triangles: Vec<[u32; 3]> = serde_json::from_value(v["triangles"].clone()).unwrap();
    let trajectory = |name: &str| -> Trajectory {
        serde_json::from_value(v["trajectories"][name].clone())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let written: fem_cases::budget::Budget =
        serde_json::from_str(&std::fs::read_to_string(dir.join("budget.json")).unwrap()).unwrap();
    let mut checked = 0;
    for r in &written.rows {
        let Some(best) = &r.best else { continue };
        let reference = trajectory(&format!("{}-reference", r.energy.name()));
        let mine = trajectory(&format!("{}-{}", r.energy.name(), r.framework.name()));
        let again = errors(&rest, &triangles, &mine, &reference);
        assert_eq!(again, best.errors, "{:?} {:?}", r.energy, r.framework);
        checked += 1;
    }
    assert!(checked >= 10, "{checked}");
    let _ = std::fs::remove_dir_all(&dir);
}
