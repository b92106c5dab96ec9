//! `fem_cases::budget::budget3`: the frame budget on a 3D scene. Its errors are recomputed
//! from the written trajectories (tetrahedra), a framework without a 3D path is a row that
//! cannot run, no BDF2 rung is tried, the reference converges at first order in its step, and
//! the tetrahedron's measure is its signed volume.

use fem_cases::budget::{BudgetSpec, Cell, Framework, budget3};
use fem_core::energy::EnergyKind;
use fem_scene::solid::load_case3;

use crate::budget::recompute_from_written;

/// Case A in 3D on a coarse box (8 x 2 x 2 cubes, 192 tetrahedra), 0.2 s at 90 Hz (18
/// frames), a reference of 20 steps per frame, and a budget of one second a frame so that
/// no ladder is cut by this machine's timing.
fn coarse() -> fem_scene::solid::LoadedScene3 {
    load_case3(
        "case-a-3d",
        &["mesh.nx=8".into(), "mesh.ny=2".into(), "mesh.nz=2".into()],
    )
    .unwrap()
}

fn spec() -> BudgetSpec {
    BudgetSpec {
        duration: Some(0.2),
        budget_ms: 1000.0,
        energies: vec![EnergyKind::NeoHookean],
        frameworks: vec![
            Framework::Explicit,
            Framework::Xpbd,
            Framework::Vbd,
            Framework::Pd,
            Framework::LinearImplicit,
            Framework::Implicit,
        ],
        reference_steps: Some(20),
        ..BudgetSpec::default()
    }
}

#[test]
fn a_3d_budget_reports_its_rows_and_its_errors_are_recomputed_from_the_trajectories() {
    let run = budget3(&coarse(), &spec(), |_| {}).unwrap();
    let b = &run.budget;
    assert_eq!(b.frames, 18);
    assert_eq!(run.layout.cells.len(), 192);
    // Position ranks a scene without contact or regions.
    assert_eq!(b.rank_by.name(), "position");
    let row = |f: Framework| b.rows.iter().find(|r| r.framework == f).unwrap();
    let why = row(Framework::LinearImplicit).cannot_run.clone().unwrap();
    assert!(why.contains("no 3D path"), "{why}");
    let why = row(Framework::Pd).cannot_run.clone().unwrap();
    assert!(why.contains("co-rotational"), "{why}");
    // Backward Euler only: no BDF2 rung in 3D.
    assert!(b.trials.iter().all(|t| !t.setting.starts_with("bdf2")));
    for f in [
        Framework::Explicit,
        Framework::Xpbd,
        Framework::Vbd,
        Framework::Implicit,
    ] {
        let best = row(f)
            .best
            .as_ref()
            .unwrap_or_else(|| panic!("{f:?} has no best"));
        assert!(best.measured, "{f:?}");
        // The soft tissue's stress (the whole body) is measured in 3D too.
        let l2 = best.errors.whole.stress_l2.unwrap();
        assert!(l2.is_finite() && l2 >= 0.0, "{f:?} {l2}");
    }
    // Implicit Euler's residual rungs converge to one step: at Newton tolerances 1e-6 and
    // 1e-8 its distance to the reference (its time-discretisation error) agrees to 1e-3.
    let rms = |label: &str| {
        b.trials
            .iter()
            .find(|t| t.framework == Framework::Implicit && t.setting == label)
            .unwrap()
            .errors
            .whole
            .position_rms
    };
    let (a, c) = (rms("tolerance 1e-6"), rms("tolerance 1e-8"));
    assert!((a - c).abs() <= 1e-3 * c, "{a} against {c}");
    let checked = recompute_from_written(&run, "3d");
    assert!(checked >= 4, "{checked}");
}

/// The reference is implicit Euler at a twentieth of the frame step; its estimated own error
/// (against itself at a tenth) and the error of implicit Euler at the frame step, converged
/// (Newton tolerance 1e-8), both measured against it, shrink at first order: the frame step
/// is 10 times the coarse reference's, so its error is about 10 times the reference's own
/// (first order, with the reference's own error a tenth of the coarse one's: the band 5 to 20
/// allows for the next order's terms).
#[test]
fn the_3d_reference_and_implicit_euler_converge_at_first_order() {
    let spec = BudgetSpec {
        frameworks: vec![Framework::Implicit],
        ..spec()
    };
    let run = budget3(&coarse(), &spec, |_| {}).unwrap();
    let reference = run.budget.references[0].error.whole.position_rms;
    let frame_step = run
        .budget
        .trials
        .iter()
        .find(|t| t.setting == "tolerance 1e-8")
        .unwrap()
        .errors
        .whole
        .position_rms;
    let ratio = frame_step / reference;
    assert!(
        (5.0..=20.0).contains(&ratio),
        "frame step {frame_step} m, reference's own {reference} m: ratio {ratio}"
    );
}

/// The tetrahedron's measure is its signed volume: 1/6 for the unit corner, negative when two
/// vertices swap; a triangle's is its signed area.
#[test]
fn cell_measures_are_signed_volumes_and_areas() {
    let x = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    assert!(([0u32, 1, 2, 3].measure(&x) - 1.0 / 6.0).abs() < 1e-15);
    assert!(([1u32, 0, 2, 3].measure(&x) + 1.0 / 6.0).abs() < 1e-15);
    let y = [[0.0, 0.0], [2.0, 0.0], [0.0, 3.0]];
    assert!(([0u32, 1, 2].measure(&y) - 3.0).abs() < 1e-15);
    assert!(([0u32, 2, 1].measure(&y) + 3.0).abs() < 1e-15);
}

/// A tool that takes 2D scenes only (the Python package, sweeps) refuses a built-in 3D case in
/// one line naming the commands that take it.
#[test]
fn a_2d_only_tool_names_the_commands_that_take_3d_scenes() {
    let e = fem_cases::files::load_case_or_file("case-a-3d", &[])
        .err()
        .unwrap()
        .to_string();
    assert_eq!(
        e,
        "`case-a-3d` is a 3D scene (dim = 3): only `fem2d run`, `compare` and `budget` take 3D scenes yet"
    );
}
