//! `fem_cases::compare` on both dimensions: the 2D writers' exact text (markdown, CSV, JSON,
//! curves) on a fixed table, so a change to the shared types cannot move 2D output by a byte;
//! and the matrix on a coarse `case-a-3d` ([`compare3`]), whose rows are the runs of the edited
//! scenes bit for bit, with a linear-implicit row that reports the missing 3D path.

use fem_cases::compare::{CompareSpec, Comparison, Curves, VariantAxis, compare3, rms_distance};
use fem_cases::solid::{RunOptions3, run_scene3};
use fem_core::energy::EnergyKind;
use fem_scene::solid::{LoadedScene3, RunResult3, load_case3};
use fem_solvers::SolverKind;

/// `case-a-3d` made cheap: 8 x 2 x 2 cells (192 tetrahedra), 40 steps, a frame every 10.
fn coarse_case_a_3d() -> LoadedScene3 {
    let sets: Vec<String> = [
        "solver.steps=40",
        "mesh.nx=8",
        "mesh.ny=2",
        "mesh.nz=2",
        "output.frame_every=10",
    ]
    .map(String::from)
    .to_vec();
    load_case3("case-a-3d", &sets).unwrap()
}

fn spec(
    energies: &[EnergyKind],
    solvers: &[SolverKind],
    variants: Vec<VariantAxis>,
) -> CompareSpec {
    CompareSpec {
        energies: energies.to_vec(),
        solvers: solvers.to_vec(),
        variants,
        threads: Some(1),
        snapshot_every: None,
    }
}

/// `base` with `energy` and `solver` set by hand (not through the comparison's code), run.
fn run_edited(base: &LoadedScene3, energy: EnergyKind, solver: SolverKind) -> RunResult3 {
    let mut scene = base.clone();
    scene.scene.energy = energy;
    scene.scene.solver.kind = solver;
    scene.validate().unwrap();
    run_scene3(
        &scene,
        &RunOptions3 {
            threads: Some(1),
            ..RunOptions3::default()
        },
        None,
    )
    .unwrap()
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The tip's curve of a 3D run, one `[ux, uy, uz]` per recorded frame.
fn tip_series(r: &RunResult3) -> Vec<[f64; 3]> {
    r.probe_rows.iter().map(|(_, _, row)| row[0]).collect()
}

/// Fields of one CSV line (quotes respected).
fn csv_fields(line: &str) -> usize {
    let mut quoted = false;
    1 + line
        .chars()
        .filter(|&c| {
            if c == '"' {
                quoted = !quoted;
            }
            c == ',' && !quoted
        })
        .count()
}

#[test]
fn compare3_rows_are_the_runs_of_the_edited_scenes_and_linear_implicit_is_an_error_row() {
    let base = coarse_case_a_3d();
    let energies = [EnergyKind::NeoHookean, EnergyKind::Stvk];
    let solvers = [
        SolverKind::Explicit,
        SolverKind::Implicit,
        SolverKind::LinearImplicit,
    ];
    let c = compare3(&base, &spec(&energies, &solvers, Vec::new())).unwrap();
    assert_eq!(c.dim, 3);
    assert_eq!(c.triangles, 8 * 2 * 2 * 6, "tetrahedra");
    assert_eq!((c.steps, c.dt), (40, 5e-4));
    assert_eq!(c.scene_solver, SolverKind::Explicit);
    assert_eq!(c.rows.len(), 6);
    assert_eq!(c.curves.len(), 6);
    assert!(c.runs.is_empty());
    for (e, &energy) in energies.iter().enumerate() {
        let rows = &c.rows[3 * e..3 * e + 3];
        let explicit = run_edited(&base, energy, SolverKind::Explicit);
        let implicit = run_edited(&base, energy, SolverKind::Implicit);
        assert_eq!(explicit.summary.tetrahedra, c.triangles);
        for (row, run) in rows.iter().zip([&explicit, &implicit]) {
            assert_eq!((row.energy, row.solver), (energy, run.summary.solver));
            assert!(row.stable, "{row:?}");
            assert_eq!(row.error, None);
            assert_eq!(row.steps_completed, 40);
            assert_eq!(row.probes.len(), 1);
            let tip = &row.probes[0];
            assert_eq!(tip.name, "tip");
            assert_eq!(tip.final_displacement.len(), 3);
            assert_eq!(
                bits(&tip.final_displacement),
                bits(&run.summary.probes[0].final_displacement),
                "{energy} / {}",
                row.solver
            );
            // The cantilever falls: the smallest uy over the frames is the run's.
            let min_uy = tip_series(run)
                .iter()
                .map(|u| u[1])
                .fold(f64::INFINITY, f64::min);
            assert_eq!(tip.min_uy.to_bits(), min_uy.to_bits());
            assert!(tip.min_uy < 0.0, "{}", tip.min_uy);
            assert_eq!(
                row.max_von_mises.to_bits(),
                run.summary.max_von_mises.to_bits()
            );
        }
        // RMS against explicit of the same energy: none on the explicit row, the distance of
        // the two tip curves on the implicit one.
        assert_eq!(rows[0].probes[0].rms_vs_explicit, None);
        let rms = rows[1].probes[0]
            .rms_vs_explicit
            .expect("implicit has an RMS");
        let want = rms_distance(&tip_series(&implicit), &tip_series(&explicit));
        assert_eq!(rms.to_bits(), want.to_bits());
        assert!(rms > 0.0 && rms < rows[0].probes[0].min_uy.abs(), "{rms}");
        // The curves: 5 frames (0, 10, ..., 40 steps) of three components.
        assert_eq!(c.curves[3 * e + 1].times.len(), 5);
        assert_eq!(c.curves[3 * e + 1].probes[0].1[4].len(), 3);
        // linear-implicit has no 3D path: an error row, nothing run.
        let li = &rows[2];
        assert_eq!(li.solver, SolverKind::LinearImplicit);
        assert!(!li.stable);
        assert_eq!(li.steps_completed, 0);
        assert!(li.probes.is_empty());
        let error = li.error.as_deref().unwrap();
        assert!(
            error.contains("linear-implicit") && error.contains("has no 3D path"),
            "{error}"
        );
        assert!(c.curves[3 * e + 2].probes.is_empty());
    }
    // The writers show uz after uy, and count tetrahedra.
    let md = c.to_markdown();
    assert!(
        md.starts_with("Scene `case-a-3d`: 192 tetrahedra, dt = 5e-4 s, 40 steps. Displacements in mm (final ux, uy, uz; lowest uy over the run).\n\n| energy | solver | variant | stable | tip ux | tip uy | tip uz | tip min uy | tip RMS vs explicit | max von Mises"),
        "{md}"
    );
    assert!(
        md.contains("| stvk | linear-implicit |  | **no** | - | - | - | - | - |"),
        "{md}"
    );
    let csv = c.to_csv();
    let mut lines = csv.lines();
    let header = lines.next().unwrap();
    assert!(
        header.starts_with(
            "energy,solver,variant,stable,steps_completed,tip.ux,tip.uy,tip.uz,tip.min_uy,tip.rms_vs_explicit,max_von_mises"
        ),
        "{header}"
    );
    for line in lines {
        assert_eq!(csv_fields(line), csv_fields(header), "{line}");
    }
    let json: serde_json::Value = serde_json::from_str(&c.to_json()).unwrap();
    assert_eq!(json["dim"], 3);
    assert_eq!(json["triangles"], 192);
    assert_eq!(
        json["rows"][1]["probes"][0]["final_displacement"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    let curves = c.to_curves_csv();
    let header: Vec<&str> = curves.lines().next().unwrap().split(',').collect();
    assert_eq!(header.len(), 2 + 4 * 3, "{header:?}");
    assert_eq!(
        header[2..5],
        [
            "neo-hookean/explicit:tip.ux",
            "neo-hookean/explicit:tip.uy",
            "neo-hookean/explicit:tip.uz"
        ]
    );
    assert_eq!(curves.lines().count(), 1 + 5);
    for line in curves.lines() {
        assert_eq!(line.split(',').count(), header.len(), "{line}");
    }
}

#[test]
fn compare3_takes_an_option_the_3d_path_refuses_as_an_error_row_and_refuses_snapshots() {
    let base = coarse_case_a_3d();
    let bdf2 = vec![VariantAxis {
        key: "integrator".into(),
        values: vec!["bdf2".into()],
    }];
    let c = compare3(
        &base,
        &spec(
            &[EnergyKind::Stvk],
            &[SolverKind::Explicit, SolverKind::Implicit],
            bdf2,
        ),
    )
    .unwrap();
    assert_eq!(c.rows.len(), 2);
    assert!(
        c.rows[0].stable && c.rows[0].error.is_none(),
        "{:?}",
        c.rows[0]
    );
    let r = &c.rows[1];
    assert_eq!(
        (r.solver, r.variant.as_str()),
        (SolverKind::Implicit, "bdf2")
    );
    assert!(!r.stable && r.probes.is_empty());
    let error = r.error.as_deref().unwrap();
    assert!(
        error.contains("integrator = bdf2") && error.contains("not available in 3d"),
        "{error}"
    );
    // No pictures of 3D comparisons: keeping the runs is refused before anything runs.
    let mut with_snapshots = spec(&[EnergyKind::Stvk], &[SolverKind::Explicit], Vec::new());
    with_snapshots.snapshot_every = Some(1);
    let e = compare3(&base, &with_snapshots).unwrap_err().to_string();
    assert!(e.contains("not available for 3D scenes"), "{e}");
}

/// `rms_distance` on `[ux, uy]` pairs is the 2D formula bit for bit; it takes three
/// components as well.
#[test]
fn compare_rms_distance_keeps_the_2d_sum_and_takes_three_components() {
    let a: Vec<[f64; 2]> = (0..50)
        .map(|k| [0.1 * (k as f64).sin(), -0.37 * (k as f64 * 0.7).cos()])
        .collect();
    let b: Vec<[f64; 2]> = (0..45)
        .map(|k| [0.11 * (k as f64).sin(), -0.3 * (k as f64 * 0.71).cos()])
        .collect();
    let sum: f64 = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
        .sum();
    let want = (sum / 45.0).sqrt();
    assert_eq!(rms_distance(&a, &b).to_bits(), want.to_bits());
    let a3 = [[0.0, 0.0, 0.0], [1.0, 2.0, 2.0]];
    let b3 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
    assert_eq!(rms_distance(&a3, &b3), (9.0f64 / 2.0).sqrt());
    assert!(rms_distance::<[f64; 3], [f64; 3]>(&[], &b3).is_nan());
}

/// A 2D comparison with two probes: a stable explicit row, an XPBD row with a variant and RMS
/// columns, and a row that could not run (no probes, NaN stress, an error with a quote).
fn table_2d() -> Comparison {
    let json = r#"{
  "scene": "case-x",
  "triangles": 160,
  "scene_solver": "explicit",
  "dt": 0.0005,
  "steps": 20,
  "rows": [
    {"energy": "stvk", "solver": "explicit", "variant": "", "stable": true,
     "steps_completed": 20,
     "probes": [
       {"name": "tip", "final_displacement": [0.0012345678901234567, -0.25],
        "min_uy": -0.2500001, "rms_vs_explicit": null},
       {"name": "mid", "final_displacement": [-1e-7, -0.0625], "min_uy": -0.07,
        "rms_vs_explicit": null}
     ],
     "max_von_mises": 123456.789, "min_det_f": 0.987654321, "inverted_elements": 0,
     "step_seconds": 0.0123, "element_steps_per_second": 260162.6, "real_time_factor": 0.8130081,
     "error": null},
    {"energy": "stvk", "solver": "xpbd", "variant": "consistent, 20 it", "stable": true,
     "steps_completed": 20,
     "probes": [
       {"name": "tip", "final_displacement": [0.001, -0.2], "min_uy": -0.21,
        "rms_vs_explicit": 0.0333333333333},
       {"name": "mid", "final_displacement": [0.0, -0.05], "min_uy": -0.06,
        "rms_vs_explicit": 0.004}
     ],
     "max_von_mises": 99.5, "min_det_f": 1.0, "inverted_elements": 3,
     "step_seconds": 0.5, "element_steps_per_second": 6400.0, "real_time_factor": 0.02,
     "error": null},
    {"energy": "neo-hookean", "solver": "pd", "variant": "", "stable": false,
     "steps_completed": 0, "probes": [],
     "max_von_mises": 0.0, "min_det_f": 0.0, "inverted_elements": 0,
     "step_seconds": 0.0, "element_steps_per_second": 0.0, "real_time_factor": 0.0,
     "error": "solver.kind = \"pd\": no contact"}
  ]
}"#;
    let mut c: Comparison = serde_json::from_str(json).unwrap();
    c.rows[2].max_von_mises = f64::NAN;
    c.rows[2].min_det_f = f64::NAN;
    c.curves = vec![
        Curves {
            times: vec![0.0, 0.005, 0.01],
            probes: vec![
                (
                    "tip".into(),
                    vec![
                        [0.0, 0.0].into(),
                        [1e-4, -0.125].into(),
                        [0.0012345678901234567, -0.25].into(),
                    ],
                ),
                (
                    "mid".into(),
                    vec![
                        [0.0, 0.0].into(),
                        [0.0, -0.03].into(),
                        [-1e-7, -0.0625].into(),
                    ],
                ),
            ],
        },
        Curves {
            times: vec![0.0, 0.005],
            probes: vec![
                ("tip".into(), vec![[0.0, 0.0].into(), [0.001, -0.2].into()]),
                ("mid".into(), vec![[0.0, 0.0].into(), [0.0, -0.05].into()]),
            ],
        },
        Curves::default(),
    ];
    c
}

/// The 2D writers' text, as the code printed it before 3D comparisons shared these types.
#[test]
fn compare_2d_writers_print_this_exact_text() {
    let c = table_2d();
    assert_eq!(c.dim, 2);
    assert_eq!(c.to_markdown(), MD_2D);
    assert_eq!(c.to_csv(), CSV_2D);
    assert_eq!(c.to_json(), JSON_2D);
    assert_eq!(c.to_curves_csv(), CURVES_2D);
}

const MD_2D: &str = r##"Scene `case-x`: 160 triangles, dt = 5e-4 s, 20 steps. Displacements in mm (final ux, uy; lowest uy over the run).

| energy | solver | variant | stable | tip ux | tip uy | tip min uy | tip RMS vs explicit | mid ux | mid uy | mid min uy | mid RMS vs explicit | max von Mises (Pa) | min det F | step time (s) | element-steps/s | real-time factor |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
| stvk | explicit |  | yes | 1.2 | -250.0 | -250.0 | - | -0.0 | -62.5 | -70.0 | - | 1.2346e5 | 0.9877 | 0.0123 | 2.602e5 | 0.8 |
| stvk | xpbd | consistent, 20 it | yes | 1.0 | -200.0 | -210.0 | 33.3 | 0.0 | -50.0 | -60.0 | 4.0 | 9.9500e1 | 1.0000 | 0.5000 | 6.400e3 | 0.0 |
| neo-hookean | pd |  | **no** | - | - | - | - | - | - | - | - | NaN | NaN | 0.0000 | 0.000e0 | 0.0 |

- neo-hookean / pd : solver.kind = "pd": no contact
"##;

const CSV_2D: &str = r##"energy,solver,variant,stable,steps_completed,tip.ux,tip.uy,tip.min_uy,tip.rms_vs_explicit,mid.ux,mid.uy,mid.min_uy,mid.rms_vs_explicit,max_von_mises,min_det_f,inverted_elements,step_seconds,element_steps_per_second,real_time_factor,error
stvk,explicit,"",true,20,0.0012345678901234567,-0.25,-0.2500001,,-0.0000001,-0.0625,-0.07,,123456.789,0.987654321,0,0.0123,260162.6,0.8130081,""
stvk,xpbd,"consistent, 20 it",true,20,0.001,-0.2,-0.21,0.0333333333333,0,-0.05,-0.06,0.004,99.5,1,3,0.5,6400,0.02,""
neo-hookean,pd,"",false,0,,,,,,,,,NaN,NaN,0,0,0,0,"solver.kind = 'pd': no contact"
"##;

const JSON_2D: &str = r##"{
  "scene": "case-x",
  "triangles": 160,
  "scene_solver": "explicit",
  "dt": 0.0005,
  "steps": 20,
  "rows": [
    {
      "energy": "stvk",
      "solver": "explicit",
      "variant": "",
      "stable": true,
      "steps_completed": 20,
      "probes": [
        {
          "name": "tip",
          "final_displacement": [
            0.0012345678901234567,
            -0.25
          ],
          "min_uy": -0.2500001,
          "rms_vs_explicit": null
        },
        {
          "name": "mid",
          "final_displacement": [
            -1e-7,
            -0.0625
          ],
          "min_uy": -0.07,
          "rms_vs_explicit": null
        }
      ],
      "max_von_mises": 123456.789,
      "min_det_f": 0.987654321,
      "inverted_elements": 0,
      "step_seconds": 0.0123,
      "element_steps_per_second": 260162.6,
      "real_time_factor": 0.8130081,
      "error": null
    },
    {
      "energy": "stvk",
      "solver": "xpbd",
      "variant": "consistent, 20 it",
      "stable": true,
      "steps_completed": 20,
      "probes": [
        {
          "name": "tip",
          "final_displacement": [
            0.001,
            -0.2
          ],
          "min_uy": -0.21,
          "rms_vs_explicit": 0.0333333333333
        },
        {
          "name": "mid",
          "final_displacement": [
            0.0,
            -0.05
          ],
          "min_uy": -0.06,
          "rms_vs_explicit": 0.004
        }
      ],
      "max_von_mises": 99.5,
      "min_det_f": 1.0,
      "inverted_elements": 3,
      "step_seconds": 0.5,
      "element_steps_per_second": 6400.0,
      "real_time_factor": 0.02,
      "error": null
    },
    {
      "energy": "neo-hookean",
      "solver": "pd",
      "variant": "",
      "stable": false,
      "steps_completed": 0,
      "probes": [],
      "max_von_mises": null,
      "min_det_f": null,
      "inverted_elements": 0,
      "step_seconds": 0.0,
      "element_steps_per_second": 0.0,
      "real_time_factor": 0.0,
      "error": "solver.kind = \"pd\": no contact"
    }
  ]
}"##;

const CURVES_2D: &str = r##"frame,time,stvk/explicit:tip.ux,stvk/explicit:tip.uy,stvk/explicit:mid.ux,stvk/explicit:mid.uy,stvk/xpbd/consistent-20-it:tip.ux,stvk/xpbd/consistent-20-it:tip.uy,stvk/xpbd/consistent-20-it:mid.ux,stvk/xpbd/consistent-20-it:mid.uy
0,0,0,0,0,0,0,0,0,0
1,0.005,0.0001,-0.125,0,-0.03,0.001,-0.2,0,-0.05
2,0.01,0.0012345678901234567,-0.25,-0.0000001,-0.0625,,,,
"##;
