//! Volumetric locking and the averaged nodal pressure triangle (`material.formulation`)
//! against oracles:
//! - Lamé's thick-walled cylinder: a quarter ring under internal pressure in plane strain, on
//!   an unstructured constrained-Delaunay mesh (the mesher of the 3D pipeline), for nu = 0.3,
//!   0.49 and 0.4999. Lamé's radial displacement holds for any nu below 1/2; the averaged
//!   nodal pressure triangle meets it within 2 % at every nu, plain triangles miss it at 0.4999.
//! - Cook's membrane (a classic locking benchmark): tip displacement against an independent
//!   reference (a mixed finite element code, `fixtures/reference/cook/`) under refinement.
//! - Case A at nu = 0.3 (nothing locks): the tip within 1 % of plain triangles.

use std::collections::BTreeSet;

use fem_core::assembly::{Stiffness, Tangent, populate_stiffness_serial};
use fem_core::energy::{AnyEnergy, ElementEnergies, EnergyKind};
use fem_core::material::{Material, PlaneModel};
use fem_core::math::{Real, Vec2};
use fem_core::mesh::Mesh;
use fem_core::na::{DMatrix, DVector};
use fem_mesh::triangulate::{TriangulateParams, triangulate};
use fem_mesh::types::PolygonWithHoles;

const E: Real = 1.0e4;
const PRESSURE: Real = 10.0;
const A_IN: Real = 1.0;
const B_OUT: Real = 2.0;

/// A quarter ring `1 <= r <= 2`, `0 <= angle <= 90 degrees`, arcs of 32 segments, refined to
/// triangles of at most `max_area` with angles of at least 25 degrees.
fn quarter_ring(max_area: Real) -> Mesh {
    let arc = |r: Real, reverse: bool| -> Vec<[Real; 2]> {
        let mut pts: Vec<[Real; 2]> = (0..=32)
            .map(|k| {
                let a = std::f64::consts::FRAC_PI_2 * k as Real / 32.0;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        if reverse {
            pts.reverse();
        }
        pts
    };
    let mut outer = arc(B_OUT, false);
    outer.extend(arc(A_IN, true));
    let polygon = PolygonWithHoles {
        outer,
        holes: vec![],
    };
    let (m, report) = triangulate(
        &[polygon],
        &TriangulateParams {
            max_area: Some(max_area),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(report.quality_met());
    Mesh::from_arrays(&m.vertices, &m.triangles).unwrap()
}

/// Lamé's radial displacement at the inner radius, plane strain.
fn lame_inner(nu: Real) -> Real {
    let (a, b) = (A_IN, B_OUT);
    (1.0 + nu) * PRESSURE * a * a / (E * (b * b - a * a)) * ((1.0 - 2.0 * nu) * a + b * b / a)
}

/// The mean radial displacement of the inner arc's vertices: a linear solve of the stiffness at
/// rest (small strain) with the pressure's consistent nodal forces on the inner arc and
/// symmetry rollers (`u_y = 0` on `y = 0`, `u_x = 0` on `x = 0`).
fn inner_displacement(mesh: &Mesh, kind: EnergyKind, nu: Real, averaged: bool) -> Real {
    let lame = Material::new(E, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let mut energies: ElementEnergies<AnyEnergy> =
        ElementEnergies::uniform(kind.build(lame).unwrap());
    if averaged {
        energies = energies.with_nodal_pressure(mesh).unwrap();
    }
    let x = mesh.vertices().to_vec();
    let mut k = Stiffness::for_energy(mesh, &energies);
    populate_stiffness_serial(mesh, &energies, &x, Tangent::Exact, &mut k);
    let n = 2 * mesh.n_vertices();
    let on_arc = |p: &Vec2, r: Real| (p.norm() - r).abs() < 1e-9;
    // Consistent forces of the pressure on the inner boundary edges.
    let mut f = DVector::zeros(n);
    let boundary = fem_solvers::model::boundary_edges(mesh.triangles());
    for [a, b] in boundary {
        let (pa, pb) = (x[a as usize], x[b as usize]);
        if on_arc(&pa, A_IN) && on_arc(&pb, A_IN) {
            let mid = (pa + pb) * 0.5;
            let len = (pb - pa).norm();
            let normal = mid / mid.norm();
            for v in [a, b] {
                f[2 * v as usize] += 0.5 * PRESSURE * len * normal.x;
                f[2 * v as usize + 1] += 0.5 * PRESSURE * len * normal.y;
            }
        }
    }
    let mut fixed = BTreeSet::new();
    for (v, p) in x.iter().enumerate() {
        if p.y.abs() < 1e-9 {
            fixed.insert(2 * v + 1);
        }
        if p.x.abs() < 1e-9 {
            fixed.insert(2 * v);
        }
    }
    let free: Vec<usize> = (0..n).filter(|d| !fixed.contains(d)).collect();
    let index: Vec<Option<usize>> = {
        let mut idx = vec![None; n];
        for (i, &d) in free.iter().enumerate() {
            idx[d] = Some(i);
        }
        idx
    };
    let mut kf = DMatrix::zeros(free.len(), free.len());
    for (r, c, v) in k.matrix.triplets() {
        if let (Some(i), Some(j)) = (index[r], index[c]) {
            kf[(i, j)] += v;
        }
    }
    let ff = DVector::from_iterator(free.len(), free.iter().map(|&d| f[d]));
    let u = kf
        .cholesky()
        .expect("anchored and positive definite")
        .solve(&ff);
    let mut sum = 0.0;
    let mut count = 0;
    for (v, p) in x.iter().enumerate() {
        if on_arc(p, A_IN) {
            let ux = index[2 * v].map_or(0.0, |i| u[i]);
            let uy = index[2 * v + 1].map_or(0.0, |i| u[i]);
            sum += (ux * p.x + uy * p.y) / p.norm();
            count += 1;
        }
    }
    sum / count as Real
}

/// Lamé's cylinder on an unstructured mesh of 416 triangles: the averaged nodal pressure
/// triangle within 2 % for nu = 0.3, 0.49 and 0.4999 (linear and Neo-Hookean, which linearise
/// alike); plain triangles miss by more than 5 % at 0.4999 (they lock).
#[test]
fn lame_cylinder_within_two_percent_at_every_nu_and_plain_triangles_lock() {
    let mesh = quarter_ring(0.01);
    eprintln!("quarter ring: {} triangles", mesh.n_triangles());
    for nu in [0.3, 0.49, 0.4999] {
        let exact = lame_inner(nu);
        for kind in [EnergyKind::Linear, EnergyKind::NeoHookean] {
            let averaged = inner_displacement(&mesh, kind, nu, true);
            let plain = inner_displacement(&mesh, kind, nu, false);
            let (ea, ep) = (averaged / exact - 1.0, plain / exact - 1.0);
            eprintln!(
                "nu = {nu}, {kind:?}: exact {exact:.6e} m; averaged pressure {:+.2} %, plain {:+.2} %",
                100.0 * ea,
                100.0 * ep
            );
            assert!(
                ea.abs() < 0.02,
                "nu = {nu}, {kind:?}: averaged pressure off by {ea:e}"
            );
            if nu == 0.4999 {
                assert!(
                    ep < -0.05,
                    "nu = {nu}, {kind:?}: plain triangles off by only {ep:e}"
                );
            }
        }
    }
}

/// Case A's tip under the static solver (Neo-Hookean, nu = 0.3): where nothing locks, the
/// averaged nodal pressure triangle and plain triangles converge to the same tip. Both approach
/// it from the stiff side; the averaged pressure tip is the closer at every level (it is the
/// softer), and the two differ by less than 1 % from 80 x 16 cells on. Measured (m): 20 x 4
/// -1.2983 / -1.3891, 40 x 8 -1.4864 / -1.5161, 80 x 16 -1.5450 / -1.5533 (0.54 %),
/// 320 x 64 -1.5658 / -1.5664.
#[test]
fn case_a_tip_matches_plain_triangles_where_nothing_locks() {
    let tip = |nx: usize, ny: usize, formulation: &str| -> f64 {
        let overrides: Vec<String> = [
            "solver.kind=static".to_string(),
            "energy=neo-hookean".to_string(),
            format!("mesh.nx={nx}"),
            format!("mesh.ny={ny}"),
            format!("material.formulation={formulation}"),
        ]
        .into();
        let scene = fem_scene::cases::load_case("case-a", &overrides).unwrap();
        let r = fem_scene::run::run(&scene, &mut fem_scene::run::RunEnv::default()).unwrap();
        assert_eq!(r.summary.formulation.name(), formulation);
        r.probe("tip").unwrap().last().unwrap()[1]
    };
    let mut gap_before = f64::INFINITY;
    for (nx, ny) in [(20, 4), (40, 8), (80, 16)] {
        let (plain, averaged) = (tip(nx, ny, "standard"), tip(nx, ny, "averaged-pressure"));
        let gap = (averaged - plain).abs() / plain.abs();
        eprintln!(
            "{nx} x {ny}: plain {plain:.5} m, averaged pressure {averaged:.5} m, gap {:.2} %",
            100.0 * gap
        );
        assert!(
            averaged < plain,
            "{nx} x {ny}: the averaged pressure tip is the softer"
        );
        assert!(
            gap < gap_before / 2.5,
            "{nx} x {ny}: the gap shrinks under refinement"
        );
        gap_before = gap;
    }
    assert!(gap_before < 0.01, "80 x 16: gap {gap_before}");
}

/// Cook's membrane (plane strain, linear elasticity, E = 250 Pa, 1 N of shear on the right
/// edge, left edge clamped) on `n x n` quads of 2 triangles (`/`), by the static solver: the
/// top-right corner's vertical displacement.
fn cook_tip(n: usize, nu: Real, averaged: bool) -> Real {
    use fem_solvers::{Model, Region, State, StaticParams, StaticStepper, Stepper};
    let unit = fem_core::structured::rectangle(&fem_core::structured::RectangleParams::new(
        1.0, 1.0, n, n,
    ))
    .unwrap();
    let vertices: Vec<Vec2> = (unit.vertices().iter())
        .map(|p| Vec2::new(48.0 * p.x, 44.0 * p.x + 44.0 * p.y - 28.0 * p.x * p.y))
        .collect();
    let mesh = Mesh::new(vertices, unit.triangles().to_vec()).unwrap();
    let tip = (mesh.vertices().iter())
        .position(|p| (p - Vec2::new(48.0, 60.0)).norm() < 1e-9)
        .unwrap();
    let lame = Material::new(250.0, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let energy = EnergyKind::Linear.build(lame).unwrap();
    let mut model = Model::with_density(mesh, energy, 1.0).unwrap();
    model.set_averaged_pressure(averaged).unwrap();
    let eps = 1e-9;
    model
        .pin(&Region::in_box(
            Vec2::new(-eps, -eps),
            Vec2::new(eps, 44.0 + eps),
        ))
        .unwrap();
    model
        .add_traction(
            &Region::in_box(
                Vec2::new(48.0 - eps, 44.0 - eps),
                Vec2::new(48.0 + eps, 60.0 + eps),
            ),
            Vec2::new(0.0, 1.0 / 16.0),
        )
        .unwrap();
    let mut stepper = StaticStepper::new(&model, StaticParams::default()).unwrap();
    let mut state = State::at_rest(&model);
    stepper.step(&model, &mut state).unwrap();
    state.x[tip].y - 60.0
}

/// The reference: a mixed (Taylor-Hood P3/P2) solution by an independent finite element code,
/// converged to 5e-6 (`fixtures/reference/cook/`).
fn cook_reference(nu: Real) -> Real {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/reference/cook/cook_reference.json"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    json["results"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["nu"].as_f64() == Some(nu))
        .and_then(|r| r["tip_uy"].as_f64())
        .unwrap()
}

/// Cook's membrane under refinement against the independent reference: the averaged nodal
/// pressure triangle's error falls at least 2.4x per halving of the cell size from 16 x 16 on
/// (measured 2.5-2.8x) and stays within twice its nu = 0.3 error at every nu up to 0.4999
/// (measured at most 1.80x: 64 x 64, -1.27 % at 0.3, -1.46 % at 0.45, -1.76 % at 0.49, -2.28 %
/// at 0.4999), where plain triangles lock (more than 60 % short at nu = 0.4999 on every mesh;
/// their errors reproduce the locking table of docs/energies.md to 0.01 %).
#[test]
fn cook_membrane_converges_without_locking() {
    let levels = [8, 16, 32, 64];
    let mut at_03 = Vec::new();
    for nu in [0.3, 0.45, 0.49, 0.4999] {
        let reference = cook_reference(nu);
        let mut errors = Vec::new();
        for (k, &n) in levels.iter().enumerate() {
            let (averaged, plain) = (cook_tip(n, nu, true), cook_tip(n, nu, false));
            let (ea, ep) = (averaged / reference - 1.0, plain / reference - 1.0);
            eprintln!(
                "nu = {nu}, {n} x {n}: averaged pressure {:+.2} %, plain {:+.2} %",
                100.0 * ea,
                100.0 * ep
            );
            if nu == 0.3 {
                at_03.push(ea.abs());
            } else {
                assert!(
                    ea.abs() <= 2.0 * at_03[k],
                    "nu = {nu}, {n} x {n}: {ea:e} against {:e} at 0.3",
                    at_03[k]
                );
            }
            if nu == 0.4999 {
                assert!(ep < -0.6, "nu = {nu}, {n} x {n}: plain {ep:e}");
            }
            errors.push(ea.abs());
        }
        for k in 2..levels.len() {
            assert!(
                errors[k] * 2.4 <= errors[k - 1],
                "nu = {nu}: error {:e} at {} after {:e} at {}",
                errors[k],
                levels[k],
                errors[k - 1],
                levels[k - 1]
            );
        }
    }
}
