//! Figure 5's pieces on a short case D run (the slab lands on the shin within a few steps; the
//! buttocks and the heel rest on the ground from the start): bone is drawn flat and stays out of
//! the colour scale, its outlines are where the tissues change, and the contact pressure plot
//! shows the snapshot's pressure, split between the debris and the ground.

use fem_cases::figures::{
    PressurePatch, Touching, contact_patches, contact_pressure_chart, flat_regions, unmasked_peak,
};
use fem_cases::pictures::{FieldKind, FramePicture};
use fem_cases::run::{RunOptions, RunResult, run_scene};
use fem_scene::cases::load_case;

/// Case D for `steps` steps with elastic bone (stressed, so the picture must mask it; the
/// scene's rigid bone carries no stress at all).
fn case_d(steps: u32) -> RunResult {
    let scene = load_case(
        "case-d",
        &[
            format!("solver.steps={steps}"),
            "regions.0.rigid=false".to_string(),
        ],
    )
    .unwrap();
    run_scene(
        &scene,
        &RunOptions {
            threads: Some(1),
            snapshot_every: Some(1),
            ..RunOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn bone_is_flat_outlined_and_out_of_the_stress_scale() {
    let run = case_d(6);
    let (flat, edges) = flat_regions(&run);
    assert_eq!(flat.len(), run.triangles.len());
    for (e, (&f, &tag)) in flat.iter().zip(&run.region_tags).enumerate() {
        assert_eq!(f, tag != 0, "element {e}");
    }
    // Bone is far stiffer and, loaded, several times more stressed than the soft tissue
    // around it (373 kPa against 68 kPa after six steps): the scale must not see it.
    let last = run.snapshots.last().unwrap();
    let (soft, element) = unmasked_peak(last, &flat).unwrap();
    assert!(!flat[element]);
    let bone = last
        .von_mises
        .iter()
        .zip(&flat)
        .filter(|(_, f)| **f)
        .map(|(v, _)| *v)
        .fold(0.0, f64::max);
    assert!(bone > 2.0 * soft, "bone {bone} Pa, soft tissue {soft} Pa");
    let picture = FramePicture::new(&run, last, FieldKind::VonMises, "").with_flat_elements(
        flat.clone(),
        [236, 228, 204],
        "bone",
    );
    assert_eq!(picture.range().unwrap().1, soft);
    // Every outline edge separates two tissues or bounds a bone on the body's boundary.
    let (tags, names) = &run.mesh_regions;
    assert!(names.len() > 2, "{names:?}");
    assert!(!edges.is_empty());
    for e in &edges {
        let users: Vec<usize> = (0..run.triangles.len())
            .filter(|&t| {
                let tri = run.triangles[t].map(|v| v as usize);
                tri.contains(&e[0]) && tri.contains(&e[1])
            })
            .collect();
        match users.as_slice() {
            [a, b] => assert_ne!(tags[*a], tags[*b], "edge {e:?}"),
            [a] => assert!(flat[*a], "boundary edge {e:?} of soft tissue"),
            other => panic!("edge {e:?} used by {other:?}"),
        }
    }
}

#[test]
fn pressure_plot_shows_the_snapshot_pressure_on_the_debris_and_the_ground() {
    let run = case_d(12);
    let snap = run.snapshots.last().unwrap();
    let patches = contact_patches(&run, snap, Some(0.0));
    let debris: Vec<&PressurePatch> = patches
        .iter()
        .filter(|p| p.touching == Touching::Obstacle(0))
        .collect();
    let ground: Vec<&PressurePatch> = patches
        .iter()
        .filter(|p| p.touching == Touching::Ground)
        .collect();
    assert!(!debris.is_empty() && !ground.is_empty(), "{patches:?}");
    // Every loaded vertex is in exactly one patch, with the snapshot's pressure and position;
    // each open patch ends at unloaded vertices.
    let loaded: Vec<usize> = (0..snap.positions.len())
        .filter(|&v| snap.contact_pressure[v] > 0.0)
        .collect();
    for &v in &loaded {
        let n = patches
            .iter()
            .flat_map(|p| &p.points)
            .filter(|q| q.0 == v)
            .count();
        assert_eq!(n, 1, "vertex {v}");
    }
    for p in &patches {
        for &(v, x, pa) in &p.points {
            assert_eq!((x, pa), (snap.positions[v], snap.contact_pressure[v]));
        }
        let (a, b) = (p.points[0], p.points[p.points.len() - 1]);
        assert!(a.2 == 0.0 && b.2 == 0.0, "patch ends {a:?} {b:?}");
    }
    // The debris presses on top of the shin, the ground under the body.
    let top = |ps: &[&PressurePatch]| {
        ps.iter()
            .flat_map(|p| &p.points)
            .filter(|q| q.2 > 0.0)
            .map(|q| q.1[1])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |m, y| {
                (m.0.min(y), m.1.max(y))
            })
    };
    assert!(
        top(&debris).0 > 0.08,
        "debris contact heights {:?}",
        top(&debris)
    );
    assert!(
        top(&ground).1 < 0.01,
        "ground contact heights {:?}",
        top(&ground)
    );

    // The chart: one series per contact and frame, its points the patches' (x, kPa), a NaN
    // between two patches.
    let chart = contact_pressure_chart(&run, &[("last", snap)], Some(0.0), "", 800);
    assert_eq!(chart.series.len(), 2);
    for (series, patches) in chart.series.iter().zip([&debris, &ground]) {
        let want: Vec<(f64, f64)> = patches
            .iter()
            .enumerate()
            .flat_map(|(k, p)| {
                let gap = (k > 0).then_some((f64::NAN, f64::NAN));
                gap.into_iter()
                    .chain(p.points.iter().map(|q| (q.1[0], q.2 * 1e-3)))
            })
            .collect();
        assert_eq!(series.points.len(), want.len(), "{}", series.label);
        for (got, want) in series.points.iter().zip(&want) {
            assert!(
                got == want || (got.0.is_nan() && want.0.is_nan()),
                "{}: {got:?} != {want:?}",
                series.label
            );
        }
    }
    assert!(chart.series[0].label.starts_with("debris"));
    assert!(chart.series[1].label.starts_with("ground"));
    chart.to_png().unwrap();
}
