//! Projective Dynamics in 3D ([`fem_solvers::nd::NdPd`]) against implicit Euler of the
//! co-rotational energy: the energy is exactly two projective terms in either dimension (the
//! volume term's weight `D lambda / 2`), so the fixed point of the local-global iterations is
//! Newton's step at every Poisson ratio, with a plane-strain constraint (two coordinate blocks)
//! too; Chebyshev keeps the fixed point; the residual tolerance stops the iterations where it
//! says; other energies and BDF2 are refused in one line.

use fem_core::dim::{D2, D3, Dense, Dim, Mat3, Vec3};
use fem_core::energy::{Corotational, Hyperelastic, NeoHookean, Stvk};
use fem_core::material::Material;
use fem_core::math::{Mat2, Real};
use fem_core::structured::{BoxParams, box_mesh};
use fem_core::{Lame, PlaneModel};
use fem_solvers::nd::{self, NdModel, NdPd, NdRegion, NdState, NdStepper};
use fem_solvers::{ImplicitParams, Integrator, NewtonParams, PdParams, SolverParams};

const G: Real = fem_solvers::model::STANDARD_GRAVITY;

fn lame(nu: Real) -> Lame {
    Material::new(1000.0, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

/// The identity in `D` dimensions for each sample `F`: the energy at the projections is the
/// co-rotational density, their weighted differences its `P`, and `p2`'s stretch has trace `D`.
fn check_projective_terms<D: Dim>(samples: &[D::Matrix]) {
    let l = lame(0.3);
    let energy = Corotational::new(l).unwrap();
    let d = D::D as Real;
    let (w1, w2) = (2.0 * l.mu(), d * l.lambda());
    for f in samples {
        let (p1, p2) = nd::corotational_projections::<D>(f);
        let psi = 0.5 * w1 * (*f - p1).norm2() + 0.5 * w2 * (*f - p2).norm2();
        let want = Hyperelastic::<D>::density(&energy, f);
        let scale = (l.mu() + l.lambda()) * f.norm2();
        assert!(
            (psi - want).abs() <= 1e-13 * scale,
            "{}: psi {psi} vs {want} at {f:?}",
            D::NAME
        );
        let p = (*f - p1) * w1 + (*f - p2) * w2;
        let want = Hyperelastic::<D>::piola(&energy, f);
        assert!(
            (p - want).norm2().sqrt() <= 1e-13 * scale.sqrt() * (l.mu() + l.lambda()).sqrt(),
            "{}: P {p:?} vs {want:?}",
            D::NAME
        );
        let r2 = D::polar_rotation(&p2);
        let trace = D::trace(&(D::transpose(&r2) * p2));
        assert!((trace - d).abs() < 1e-12, "{}: tr {trace}", D::NAME);
    }
}

/// The co-rotational energy is `mu |F - R|^2 + (D lambda / 2) |F - p2|^2` with the solver's
/// projections, in 2D and in 3D, stretched, sheared, rotated and compressed (the shifted
/// stretch positive; at the rest `F = I` both distances vanish).
#[test]
fn the_corotational_energy_is_two_projective_terms_in_either_dimension() {
    let rot3 = |a: Real| {
        let (c, s) = (a.cos(), a.sin());
        Mat3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    };
    let samples3 = [
        Mat3::identity(),
        Mat3::new(1.3, 0.2, -0.1, 0.05, 0.8, 0.3, -0.2, 0.1, 1.1),
        rot3(0.7) * Mat3::new(1.5, 0.4, 0.0, 0.0, 0.9, 0.2, 0.1, 0.0, 0.7),
        Mat3::from_diagonal(&Vec3::new(0.6, 0.7, 0.8)),
        Mat3::from_diagonal(&Vec3::new(2.0, 1.5, 1.2)),
    ];
    check_projective_terms::<D3>(&samples3);
    let samples2 = [
        Mat2::identity(),
        Mat2::new(1.3, 0.2, 0.05, 0.8),
        Mat2::new(0.3, -0.9, 1.1, 0.2),
        Mat2::new(0.6, 0.0, 0.0, 0.7),
    ];
    check_projective_terms::<D2>(&samples2);
    let _ = D2::NAME;
}

/// A 5 x 1 x 0.5 m beam of 10 x 2 x 2 cubes (240 tetrahedra), co-rotational with Poisson ratio
/// `nu`, left face pinned, under gravity; `plane_strain` adds `u_z = 0` on both side faces.
fn beam(nu: Real, plane_strain: bool) -> NdModel<D3, Corotational> {
    let mesh = box_mesh(&BoxParams::new(5.0, 1.0, 0.5, 10, 2, 2)).unwrap();
    let mut model = NdModel::with_density(mesh, Corotational::new(lame(nu)).unwrap(), 0.2).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.5),
        ))
        .unwrap();
    if plane_strain {
        for z in [0.0, 0.5] {
            model
                .fix(
                    &NdRegion::in_box(Vec3::new(0.0, 0.0, z), Vec3::new(5.0, 1.0, z)),
                    &[false, false, true],
                    "side",
                )
                .unwrap();
        }
    }
    model
}

fn implicit(dt: Real) -> SolverParams {
    SolverParams::Implicit(ImplicitParams {
        dt,
        velocity_tolerance: 0.0,
        newton: NewtonParams {
            tolerance: 1e-12,
            ..NewtonParams::default()
        },
        ..ImplicitParams::default()
    })
}

/// The beam after 20 implicit steps of 10 ms from rest (swinging down).
fn swinging(model: &NdModel<D3, Corotational>) -> NdState<D3> {
    let mut state = NdState::at_rest(model);
    let mut s = nd::build(model, &implicit(1e-2), "solver").unwrap();
    for _ in 0..20 {
        s.step(model, &mut state).unwrap();
    }
    state
}

fn step_of(
    model: &NdModel<D3, Corotational>,
    start: &NdState<D3>,
    params: &SolverParams,
) -> NdState<D3> {
    let mut s = start.clone();
    nd::build(model, params, "solver")
        .unwrap()
        .step(model, &mut s)
        .unwrap_or_else(|e| panic!("{e}"));
    s
}

/// The largest vertex distance between `a` and `reference` over the reference step's largest
/// displacement from `start`.
fn gap(a: &NdState<D3>, reference: &NdState<D3>, start: &NdState<D3>) -> Real {
    let d = (a.x.iter().zip(&reference.x))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    let moved = (reference.x.iter().zip(&start.x))
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    d / moved
}

fn pd(iterations: usize) -> PdParams {
    PdParams {
        dt: 1e-2,
        iterations,
        ..PdParams::default()
    }
}

/// At nu = 0 (ARAP), 0.3 and 0.45, and at 0.3 with the plane-strain side faces (the z
/// coordinate its own block), the iterations reach Newton's step: the gap shrinks with the
/// iterations to round-off.
#[test]
fn iterations_converge_to_the_implicit_euler_step_in_3d() {
    for (nu, plane_strain) in [(0.0, false), (0.3, false), (0.45, false), (0.3, true)] {
        let model = beam(nu, plane_strain);
        let start = swinging(&model);
        let reference = step_of(&model, &start, &implicit(1e-2));
        let gaps: Vec<Real> = [3, 10, 30, 1000]
            .iter()
            .map(|&k| {
                gap(
                    &step_of(&model, &start, &SolverParams::Pd(pd(k))),
                    &reference,
                    &start,
                )
            })
            .collect();
        eprintln!(
            "nu {nu}, plane strain {plane_strain}: gap after 3, 10, 30, 1000 iterations: \
             {:.2e} {:.2e} {:.2e} {:.2e}",
            gaps[0], gaps[1], gaps[2], gaps[3]
        );
        for w in gaps.windows(2) {
            assert!(w[1] < w[0] || w[1] < 1e-10, "nu {nu}: {gaps:?}");
        }
        assert!(gaps[3] < 1e-9, "nu {nu}: {gaps:?}");
    }
}

/// One factorisation when whole vertices are pinned, two when the z components have their own
/// fixed set (x and y share one); never another during a run; the fixed components held.
#[test]
fn one_factorisation_per_distinct_coordinate_block() {
    for (plane_strain, want) in [(false, 1), (true, 2)] {
        let model = beam(0.3, plane_strain);
        let mut s = NdPd::new(&model, pd(10), "solver").unwrap();
        assert_eq!(s.factorisations(), want);
        let mut state = NdState::at_rest(&model);
        for _ in 0..20 {
            s.step(&model, &mut state).unwrap();
        }
        assert_eq!(s.factorisations(), want);
        // Fixed components stay where they are, with zero velocity.
        let rest = model.mesh().vertices();
        for (dof, &fixed) in model.fixed().iter().enumerate() {
            let (v, i) = (dof / 3, dof % 3);
            if fixed {
                assert_eq!(state.x[v][i], rest[v][i]);
                assert_eq!(state.v[v][i], 0.0);
            }
        }
        let sag = (0..rest.len())
            .map(|v| rest[v].y - state.x[v].y)
            .fold(0.0, Real::max);
        assert!(sag > 0.05, "{sag}");
    }
}

/// Chebyshev keeps the fixed point and, at a good rho, gets closer in the same iterations.
#[test]
fn chebyshev_keeps_the_fixed_point_in_3d() {
    let model = beam(0.3, false);
    let start = swinging(&model);
    let reference = step_of(&model, &start, &implicit(1e-2));
    let run = |rho: Real, iterations: usize| {
        let p = PdParams {
            chebyshev_rho: rho,
            ..pd(iterations)
        };
        gap(
            &step_of(&model, &start, &SolverParams::Pd(p)),
            &reference,
            &start,
        )
    };
    let rows: Vec<(Real, Real, Real)> = [0.0, 0.5, 0.8, 0.9]
        .into_iter()
        .map(|rho| (rho, run(rho, 20), run(rho, 2000)))
        .collect();
    for (rho, at20, converged) in &rows {
        eprintln!("rho {rho}: gap {at20:.2e} after 20 iterations, {converged:.2e} after 2000");
        assert!(*converged < 1e-9, "rho {rho}: {converged:e}");
    }
    let best = rows.iter().map(|r| r.1).fold(Real::INFINITY, Real::min);
    assert!(best < 0.5 * rows[0].1, "no rho helped: {rows:?}");
}

/// With a residual tolerance the step stops once the gradient is below it (well before the
/// most iterations), close to Newton's step; the report gives the gradient's norm.
#[test]
fn the_residual_tolerance_stops_the_iterations_in_3d() {
    let model = beam(0.3, false);
    let start = swinging(&model);
    let reference = step_of(&model, &start, &implicit(1e-2));
    let mut s = NdPd::new(
        &model,
        PdParams {
            tolerance: 1e-9,
            ..pd(100_000)
        },
        "solver",
    )
    .unwrap();
    let mut state = start.clone();
    let report = s.step(&model, &mut state).unwrap();
    let g = gap(&state, &reference, &start);
    eprintln!(
        "tolerance 1e-9: {} iterations, residual {:.3e} N of scale {:.3e} N, gap {g:.2e}",
        report.iterations,
        report.residual,
        s.force_scale()
    );
    assert!(report.iterations > 10 && report.iterations < 100_000);
    assert!(report.residual <= 1e-9 * s.force_scale());
    assert!(g < 1e-6, "{g:e}");
}

/// Driven beyond double precision (1e300 g: the first iteration's deformation gradients
/// overflow, so they have no polar rotation), the step fails in one line naming the vertex and
/// leaves the state as it was.
#[test]
fn a_load_beyond_double_precision_fails_and_leaves_the_state() {
    let mut model = beam(0.3, false);
    model.set_gravity(Vec3::new(0.0, -1e300 * G, 0.0)).unwrap();
    let mut s = NdPd::new(&model, pd(10), "solver").unwrap();
    let mut state = NdState::at_rest(&model);
    let before = state.clone();
    let e = s.step(&model, &mut state).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(e.contains("became non-finite") && !e.contains('\n'), "{e}");
    assert_eq!(state, before);
}

/// Other energies are refused by name (pointing at quasi-Newton), BDF2 in one line.
#[test]
fn other_energies_and_bdf2_are_refused() {
    let mesh = || box_mesh(&BoxParams::new(1.0, 1.0, 1.0, 1, 1, 1)).unwrap();
    let params = SolverParams::Pd(PdParams::default());
    let neo = NdModel::with_density(mesh(), NeoHookean::new(lame(0.3)).unwrap(), 1.0).unwrap();
    let e = nd::build(&neo, &params, "solver")
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with("solver.energy = neo-hookean: Projective Dynamics runs the corotational")
            && e.contains("quasi-newton"),
        "{e}"
    );
    let stvk = NdModel::with_density(mesh(), Stvk::new(lame(0.3)).unwrap(), 1.0).unwrap();
    let e = nd::build(&stvk, &params, "solver")
        .err()
        .unwrap()
        .to_string();
    assert!(e.starts_with("solver.energy = stvk: "), "{e}");
    let corot = NdModel::with_density(mesh(), Corotational::new(lame(0.3)).unwrap(), 1.0).unwrap();
    let bdf2 = SolverParams::Pd(PdParams {
        integrator: Integrator::Bdf2,
        ..PdParams::default()
    });
    let e = nd::build(&corot, &bdf2, "solver")
        .err()
        .unwrap()
        .to_string();
    assert_eq!(
        e,
        "solver.integrator = bdf2: is not available in 3d yet (use backward-euler)"
    );
}
