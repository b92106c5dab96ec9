//! The claims of the paper's Section 4, one test each, on the built-in cases (and, for case D,
//! on the real MakeHuman body in `../shared/fixtures/human/`). Each test fails if the claim
//! stops holding; the margins are stated beside each assertion.

use std::io::Write;

use fem_cases::run::{RunOptions, RunResult, run_scene};
use fem_cases::table1::{ENERGIES, FRAMES, PAPER_MM, ordering_holds, table1, tip_mm};
use fem_scene::cases::load_case;

fn run(case: &str, overrides: &[&str]) -> RunResult {
    run_with(case, overrides, None)
}

/// `case` with `overrides` on one thread, keeping every `snapshot_every`-th frame in memory.
fn run_with(case: &str, overrides: &[&str], snapshot_every: Option<usize>) -> RunResult {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let scene = load_case(case, &o).unwrap_or_else(|e| panic!("{e}"));
    run_scene(
        &scene,
        &RunOptions {
            threads: Some(1),
            snapshot_every,
            ..RunOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

fn last(result: &RunResult, probe: &str) -> [f64; 2] {
    *result.probe(probe).unwrap().last().unwrap()
}

/// Case A: "no significant differences ... across the different models". The three energies'
/// tip displacements agree within 0.5% at frames 10 and 50, within 6% of their mean at frame
/// 120 (the paper's own spread is 4.4%), and within 50 mm at frame 200, which sits near a zero
/// crossing (the paper's spread is 33 mm).
#[test]
fn case_a_energies_agree_within_stated_margins() {
    let mm: Vec<[f64; 4]> = ENERGIES
        .iter()
        .map(|e| {
            let r = run("case-a", &[&format!("energy=\"{}\"", e.name())]);
            tip_mm(&r).unwrap()
        })
        .collect();
    for (k, frame) in FRAMES.iter().enumerate() {
        let values: Vec<f64> = mm.iter().map(|row| row[k]).collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mean = values.iter().sum::<f64>() / 3.0;
        match frame {
            10 | 50 => assert!((hi - lo) / mean < 0.005, "frame {frame}: {values:?}"),
            120 => assert!((hi - lo) / mean < 0.06, "frame {frame}: {values:?}"),
            _ => assert!(hi - lo < 50.0, "frame {frame}: {values:?}"),
        }
    }
    // Frame 10 is free fall: 1/2 g t^2 = 49 mm at t = 0.1 s, within 1 mm.
    assert!(mm.iter().all(|row| (row[0] - 49.0).abs() < 1.0), "{mm:?}");
}

/// Case A, Table 1 as calibrated: the paper's ordering of the energies at every frame, and
/// frames 10, 50 and 120 within 10% of the paper for every energy (the aim).
#[test]
fn case_a_table1_reproduces_the_ordering_and_stays_within_ten_percent() {
    let t = table1(&[], 1, Some(1)).unwrap();
    assert_eq!(t.ordering_matches, [true; 4], "{}", t.to_markdown());
    assert!(
        t.max_relative_difference_frames_10_to_120 <= 0.10,
        "{}",
        t.to_markdown()
    );
    let mm: [[f64; 4]; 3] = [0, 1, 2].map(|r| t.rows[r].ours_mm);
    assert!((0..4).all(|f| ordering_holds(&mm, f, 1.0)));
    assert_eq!(t.rows.len(), PAPER_MM.len());
}

/// Lateral contraction of case B at mid-span, m: bottom minus top vertical displacement.
fn contraction(r: &RunResult) -> f64 {
    last(r, "mid_bottom")[1] - last(r, "mid_top")[1]
}

/// Case B: "the StVK model exhibits more pronounced contraction compared to the corotational
/// and Neo-Hookean models". At the scene's 40% stretch StVK contracts at least 20% more than
/// either.
#[test]
fn case_b_stvk_contracts_more_than_corotational_and_neo_hookean() {
    let c = |e: &str| contraction(&run("case-b", &[&format!("energy=\"{e}\"")]));
    let (s, r, n) = (c("stvk"), c("corotational"), c("neo-hookean"));
    assert!(
        s > 1.2 * r && s > 1.2 * n,
        "stvk {s}, corotational {r}, neo-hookean {n}"
    );
}

/// Case B at small strain (0.2% stretch): every energy's lateral-to-axial strain ratio at
/// mid-span equals the plane-strain Poisson value nu / (1 - nu) = 0.4286 within 1% (observed:
/// 0.14% or better; the margin leaves room for the 20 x 4 mesh's discretisation error; the axial strain is measured between
/// probes 1 m apart around mid-span, so the pinned ends' restraint does not bias it).
#[test]
fn case_b_small_stretch_matches_the_poisson_ratio() {
    let nu: f64 = 0.3;
    let expected = nu / (1.0 - nu);
    for e in ENERGIES.iter().map(|e| e.name()).chain(["linear"]) {
        let r = run(
            "case-b",
            &[
                &format!("energy=\"{e}\""),
                "prescribed.0.velocity=[0.01, 0.0]",
            ],
        );
        let axial = last(&r, "axial_right")[0] - last(&r, "axial_left")[0];
        let lateral = contraction(&r);
        let ratio = lateral / axial;
        assert!(
            (ratio - expected).abs() / expected < 0.01,
            "{e}: lateral {lateral:e} m / axial {axial:e} = {ratio}, expected {expected}"
        );
    }
}

/// Case B: "the StVK model required a smaller time step than the corotational and
/// Neo-Hookean models to achieve stable simulations" at high Young's modulus. At E = 1 MPa
/// and dt = 64 us StVK blows up during the stretch while co-rotational and Neo-Hookean stay
/// stable; at dt = 45 us all three are stable (the bracket of `fixtures/sweeps/case-b-stability.toml`).
#[test]
fn case_b_stvk_needs_the_smaller_time_step_at_high_modulus() {
    let stable = |energy: &str, dt: f64| {
        let steps = (1.5 / dt).ceil() as u64;
        let r = run(
            "case-b",
            &[
                &format!("energy=\"{energy}\""),
                "material.youngs_modulus=1e6",
                &format!("solver.dt={dt:e}"),
                &format!("solver.steps={steps}"),
                "output.frame_every=100",
            ],
        );
        !r.summary.blew_up
    };
    assert!(!stable("stvk", 6.4e-5), "stvk should blow up at 64 us");
    assert!(stable("corotational", 6.4e-5));
    assert!(stable("neo-hookean", 6.4e-5));
    for e in ["stvk", "corotational", "neo-hookean"] {
        assert!(stable(e, 4.5e-5), "{e} should be stable at 45 us");
    }
}

/// Case C: "the deformation under the PBD framework is not significant": PBD's deepest tip
/// deflection is under 10% of explicit's (10 iterations), while XPBD in the consistent form
/// follows explicit (RMS deviation of the tip curve under 2% of explicit's deepest
/// deflection) and the paper's literal XPBD form does not (over 10 times the consistent
/// form's deviation).
#[test]
fn case_c_pbd_deflects_far_less_than_explicit_and_xpbd_forms_differ() {
    let explicit = run("case-c", &[]);
    let pbd = run("case-c", &["solver.kind=\"pbd\""]);
    let xpbd = run("case-c", &["solver.kind=\"xpbd\""]);
    let literal = run(
        "case-c",
        &["solver.kind=\"xpbd\"", "solver.xpbd_form=\"literal\""],
    );
    let deepest = |r: &RunResult| {
        r.probe("tip")
            .unwrap()
            .iter()
            .map(|u| u[1])
            .fold(0.0, f64::min)
    };
    let e = deepest(&explicit);
    assert!(e < -2.0, "explicit tip should fall over 2 m, got {e}");
    assert!(
        deepest(&pbd) > 0.1 * e,
        "pbd {} vs explicit {e}",
        deepest(&pbd)
    );
    let rms = |r: &RunResult| {
        fem_cases::compare::rms_distance(r.probe("tip").unwrap(), explicit.probe("tip").unwrap())
    };
    assert!(rms(&xpbd) < 0.02 * e.abs(), "xpbd rms {}", rms(&xpbd));
    assert!(
        rms(&literal) > 10.0 * rms(&xpbd),
        "literal {} vs consistent {}",
        rms(&literal),
        rms(&xpbd)
    );
}

fn span_x(poly: &[[f64; 2]]) -> (f64, f64) {
    poly.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[0]), hi.max(p[0]))
        })
}

/// Checks of a settled case D run: stable, no inverted element, the debris resting on the leg
/// (above the ground by more than a centimetre), and the stress peaks at the debris: the
/// body's peak over the run and each elastic region's within the debris' x-span widened by
/// 5 cm (on the built-in body the soft tissue's lies 2 cm beyond the slab's corner, at the
/// distal end of the tibia; with elastic bone the body's peak was the bone's, under the slab).
fn assert_peak_under_debris(r: &RunResult) {
    let s = &r.summary;
    assert!(!s.blew_up, "{:?}", s.blow_up_message);
    assert_eq!(s.inverted_elements, 0);
    let (lo, hi) = span_x(&r.final_obstacles[0]);
    assert!(
        s.max_von_mises_at[0] >= lo - 0.05 && s.max_von_mises_at[0] <= hi + 0.05,
        "peak over the run at {:?}, debris spans [{lo}, {hi}]",
        s.max_von_mises_at
    );
    for region in s.regions.iter().filter(|r| !r.rigid) {
        let x = region.peak_von_mises_at[0];
        assert!(
            x >= lo - 0.05 && x <= hi + 0.05,
            "{}: peak {} Pa at {:?}, debris spans [{lo}, {hi}]",
            region.name,
            region.peak_von_mises,
            region.peak_von_mises_at
        );
    }
    // The debris rests on the leg: it has sunk but not through it (it stays above the
    // ground by more than a centimetre).
    let bottom = r.final_obstacles[0]
        .iter()
        .map(|p| p[1])
        .fold(f64::INFINITY, f64::min);
    assert!(bottom > 0.01, "debris bottom at {bottom} m");
}

/// Case D on the built-in body with its skeleton: "the stress distribution on the leg when
/// compressed by the debris": the peaks lie at the debris (see `assert_peak_under_debris`).
/// The bones are rigid (the scene's default): ten bodies, which carry no stress.
#[test]
fn case_d_peak_von_mises_lies_under_the_debris() {
    let r = run("case-d", &[]);
    assert_eq!(r.summary.regions.len(), 2);
    assert!(r.summary.regions[1].rigid);
    assert_eq!(r.summary.regions[1].peak_von_mises, 0.0);
    assert_eq!(r.summary.rigid_bodies.len(), 10);
    assert_peak_under_debris(&r);
}

/// Case D with rigid bones under explicit FEM: the summary reports the critical time step of
/// the deformable elements (35 us: the soft tissue's; elastic bone made it 0.36 us), and
/// explicit runs case D at that step, without a stability warning and without blowing up
/// (0.1 s: the slab lands on the shin).
#[test]
fn explicit_runs_case_d_at_the_soft_tissues_critical_step() {
    let probe = run("case-d", &["solver.steps=1"]);
    let dt = probe.summary.critical_time_step;
    assert!(dt > 2e-5 && dt < 5e-5, "critical step {dt} s");
    let steps = (0.1 / dt).ceil() as u64;
    let r = run(
        "case-d",
        &[
            "solver.kind=\"explicit\"",
            &format!("solver.dt={dt}"),
            &format!("solver.steps={steps}"),
            "output.frame_every=100",
        ],
    );
    let s = &r.summary;
    eprintln!(
        "case-d explicit at dt = {dt:.4e} s ({steps} steps): blew up {}, warning {:?}, soft tissue peak {:.4e} Pa",
        s.blew_up, s.time_step_warning, s.max_von_mises
    );
    assert!(!s.blew_up, "{:?}", s.blow_up_message);
    assert_eq!(s.critical_time_step, dt);
    assert!(s.time_step_warning.is_none(), "{:?}", s.time_step_warning);
    assert_eq!(s.inverted_elements, 0);
    assert!(s.contact_peak_force > 0.0, "the slab lands");
    // The same step with elastic bones is far above their limit: the summary warns.
    let elastic = run(
        "case-d",
        &[
            "regions.0.rigid=false",
            "solver.kind=\"explicit\"",
            &format!("solver.dt={dt}"),
            "solver.steps=1",
        ],
    );
    assert!(elastic.summary.critical_time_step < 1e-6);
    assert!(elastic.summary.time_step_warning.is_some());
}

/// The soft tissue's largest von Mises stress over the frames whose time lies in
/// `[from, to]`, Pa.
fn tissue_peak(r: &RunResult, from: f64, to: f64) -> f64 {
    let soft: Vec<bool> = r.region_tags.iter().map(|&t| t == 0).collect();
    (r.snapshots.iter())
        .filter(|s| s.time >= from - 1e-12 && s.time <= to + 1e-12)
        .flat_map(|s| s.von_mises.iter().zip(&soft).filter(|p| *p.1).map(|p| *p.0))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
}

fn run_kept(case: &str, overrides: &[&str]) -> RunResult {
    run_with(case, overrides, Some(1))
}

/// Rigid against elastic bone, every other setting equal (implicit Euler at 1/90 s, the
/// scenes' own). At a contrast of 9,200 the bone's own compliance barely changes the tissue:
/// - case D: the soft tissue's peak von Mises stress over the run and at rest agree within
///   2 % (measured 0.25 % and 0.13 %), and the tissue's positions within 1e-4 m RMS at every
///   frame (measured 1.1e-5 m): the bones are stocky and the debris presses the tissue, not a
///   span of bone;
/// - the lower-leg close-up: the tibia, held at its two end faces, spans 0.33 m under the slab
///   and bends as a beam (about `P L^3 / (192 E I)` = 0.17 mm under the measured 134 kN/m with
///   a 47 mm section, against a 3 mm squeeze: 6 %), which the rigid tibia cannot. So at full
///   squeeze the rigid tibia's tissue peaks higher, by 5.5 % (measured); the test allows 8 %
///   and requires the rigid peak to be the higher one. At rest after the lift they agree
///   within 2 % (measured 0.48 %).
#[test]
fn rigid_bones_change_the_soft_tissues_stress_little() {
    let rigid = run_kept("case-d", &[]);
    let elastic = run_kept("case-d", &["regions.0.rigid=false"]);
    let end = rigid.summary.simulated_seconds;
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    let (pr, pe) = (
        tissue_peak(&rigid, 0.0, end),
        tissue_peak(&elastic, 0.0, end),
    );
    let (rr, re) = (
        tissue_peak(&rigid, end, end),
        tissue_peak(&elastic, end, end),
    );
    let soft: Vec<usize> = {
        let mut used = vec![false; rigid.rest.len()];
        for (t, &tag) in rigid.triangles.iter().zip(&rigid.region_tags) {
            if tag == 0 {
                t.iter().for_each(|&v| used[v as usize] = true);
            }
        }
        (0..used.len()).filter(|&v| used[v]).collect()
    };
    let mut rms: f64 = 0.0;
    for (a, b) in rigid.snapshots.iter().zip(&elastic.snapshots) {
        let sq: f64 = (soft.iter())
            .map(|&v| {
                let (p, q) = (a.positions[v], b.positions[v]);
                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
            })
            .sum();
        rms = rms.max((sq / soft.len() as f64).sqrt());
    }
    eprintln!(
        "case-d: tissue peak {pr:.5e} / {pe:.5e} Pa over the run ({:.2e}), {rr:.5e} / {re:.5e} Pa at rest ({:.2e}), position RMS {rms:.2e} m",
        rel(pr, pe),
        rel(rr, re)
    );
    assert!(rel(pr, pe) < 0.02 && rel(rr, re) < 0.02);
    assert!(rms < 1e-4, "{rms}");

    let rigid = run_kept("lower-leg", &[]);
    let elastic = run_kept("lower-leg", &["regions.0.rigid=false"]);
    let end = rigid.summary.simulated_seconds;
    let (sr, se) = (
        tissue_peak(&rigid, 0.2, 0.8),
        tissue_peak(&elastic, 0.2, 0.8),
    );
    let (rr, re) = (
        tissue_peak(&rigid, end, end),
        tissue_peak(&elastic, end, end),
    );
    eprintln!(
        "lower-leg: tissue peak at full squeeze {sr:.5e} / {se:.5e} Pa ({:.2e}), at rest {rr:.5e} / {re:.5e} Pa ({:.2e})",
        rel(sr, se),
        rel(rr, re)
    );
    assert!(sr > se && rel(sr, se) < 0.08);
    assert!(rel(rr, re) < 0.02);
}

/// Case D on the real MakeHuman body (`../shared/fixtures/human/makehuman_base.obj`,
/// decimetres, so scale 0.1): the same claim, with the debris placed over that body's shin.
/// Where the shared fixtures are not beside the repository (a clone on its own) the test prints
/// one line and skips, unless `FEM2D_REQUIRE_SHARED_FIXTURES=1` (set by CI) makes that a failure.
#[test]
fn case_d_on_the_real_body() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/fixtures/human/makehuman_base.obj");
    if !path.is_file() {
        assert!(
            std::env::var_os("FEM2D_REQUIRE_SHARED_FIXTURES").is_none_or(|v| v != "1"),
            "shared fixture {} is missing and FEM2D_REQUIRE_SHARED_FIXTURES=1: put the shared/ \
             folder beside the repository",
            path.display()
        );
        // Straight to the terminal, past the test harness's capture, so the skip shows.
        let _ = writeln!(
            std::io::stderr(),
            "skipped: shared fixture {} not found (FEM2D_REQUIRE_SHARED_FIXTURES=1 makes this a failure)",
            path.display()
        );
        return;
    }
    let r = run(
        "case-d",
        &[
            "mesh.kind=\"model\"",
            &format!("mesh.path={:?}", path.display().to_string()),
            "mesh.groups=[\"body\"]",
            "mesh.scale=0.1",
            "mesh.alpha=0.025",
            "mesh.max_area=1e-3",
            "mesh.rotate_deg=86.64",
            // The model file carries no bones: one material.
            "regions=[]",
            "obstacles.0.polygon=[[1.3089, 0.1358], [1.5289, 0.1358], [1.5289, 0.3158], [1.3089, 0.3158]]",
            "probes.0.point=[1.42, 0.13]",
        ],
    );
    assert!(r.summary.triangles > 300, "{}", r.summary.triangles);
    assert_peak_under_debris(&r);
}
