//! Vertex Block Descent in 3D ([`fem_solvers::nd::NdVbd`]) against its oracle, implicit Euler
//! in 3D: each step reaches Newton's step as the sweeps grow, for every energy, with whole
//! vertices pinned and with single components held; every initial guess, the line search and
//! Chebyshev acceleration reach the same step; the residual tolerance stops the sweeps where it
//! says; substeps are steps of `dt / substeps`; steps that would invert a Neo-Hookean
//! tetrahedron are halved; the vertex colouring of a box of tetrahedra is valid; BDF2 is
//! refused in one line. (The generic nd tests, `nd.rs`, run it against the 2D solver in 2D and
//! through the 3D battery.)

use crate::common::case_a_lame;
use fem_core::dim::{D2, D3, Vec3};
use fem_core::energy::{AnyEnergy, EnergyKind, Hyperelastic, NeoHookean};
use fem_core::math::Real;
use fem_core::math::Vec2;
use fem_core::simplex::SimplexMesh;
use fem_core::structured::{BoxParams, box_mesh};
use fem_solvers::nd::{self, NdModel, NdRegion, NdState, NdStepper, NdVbd};
use fem_solvers::testing::beam_mesh;
use fem_solvers::{ImplicitParams, Integrator, NewtonParams, SolverParams, VbdInit, VbdParams};

const G: Real = fem_solvers::model::STANDARD_GRAVITY;

/// A `l x 1 x 0.5` m beam of `nx x 2 x 2` cells under `energy`, case A's density through the
/// depth, left face pinned, gravity along -y; `plane_strain` also holds `u_z = 0` on both
/// side faces (single components held).
fn beam<E: Hyperelastic<D3>>(nx: usize, l: Real, energy: E, plane_strain: bool) -> NdModel<D3, E> {
    let depth = 0.5;
    let mesh = box_mesh(&BoxParams::new(l, 1.0, depth, nx, 2, 2)).unwrap();
    let mut model = NdModel::with_density(mesh, energy, 0.2).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, depth),
        ))
        .unwrap();
    if plane_strain {
        for z in [0.0, depth] {
            model
                .fix(
                    &NdRegion::in_box(Vec3::new(0.0, 0.0, z), Vec3::new(l, 1.0, z)),
                    &[false, false, true],
                    "side",
                )
                .unwrap();
        }
    }
    model
}

/// Implicit Euler with Newton to `1e-13` of its force scale.
fn tight_implicit(dt: Real) -> SolverParams {
    SolverParams::Implicit(ImplicitParams {
        dt,
        velocity_tolerance: 0.0,
        newton: NewtonParams {
            tolerance: 1e-13,
            ..NewtonParams::default()
        },
        ..ImplicitParams::default()
    })
}

/// A swinging state: `steps` implicit steps of 10 ms from rest (velocity and strain).
fn swinging<E: Hyperelastic<D3> + 'static>(model: &NdModel<D3, E>, steps: usize) -> NdState<D3> {
    let mut state = NdState::at_rest(model);
    let mut s = nd::build(model, &tight_implicit(1e-2), "solver").unwrap();
    for _ in 0..steps {
        s.step(model, &mut state).unwrap();
    }
    state
}

fn implicit_step<E: Hyperelastic<D3> + 'static>(
    model: &NdModel<D3, E>,
    start: &NdState<D3>,
    dt: Real,
) -> NdState<D3> {
    let mut s = start.clone();
    nd::build(model, &tight_implicit(dt), "solver")
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

fn vbd_step<E: Hyperelastic<D3> + 'static>(
    model: &NdModel<D3, E>,
    start: &NdState<D3>,
    params: VbdParams,
) -> (NdState<D3>, fem_solvers::StepReport, fem_solvers::VbdStats) {
    let mut s = start.clone();
    let mut vbd = NdVbd::new(model, params, "vbd").unwrap();
    let report = vbd.step(model, &mut s).unwrap_or_else(|e| panic!("{e}"));
    (s, report, vbd.last_stats())
}

/// Largest vertex distance between `a` and `b` over the largest distance `reference` moved
/// from `start`.
fn gap(a: &NdState<D3>, b: &NdState<D3>, start: &NdState<D3>, reference: &NdState<D3>) -> Real {
    let dist = |p: &[Vec3], q: &[Vec3]| {
        p.iter()
            .zip(q)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, Real::max)
    };
    dist(&a.x, &b.x) / dist(&reference.x, &start.x)
}

/// As the sweeps grow, one 3D VBD step reaches the implicit Euler step, for every energy and
/// with single components held (the plane-strain side faces): the gap shrinks with the sweeps
/// and ends at round-off. Measured (10 ms step of the swinging 4 x 2 x 2 beam, 2 x 1 x 0.5 m):
/// Neo-Hookean 2.5e-1, 9.8e-2, 1.2e-2, 3.9e-12 after 3, 10, 30, 500 sweeps (every energy
/// within a few percent of it; the linear one ends at 1e-13; with the side faces held,
/// 2.7e-1, 9.4e-2, 4.8e-3, 6.7e-12). Gauss-Seidel's linear rate: about 0.96 per sweep.
#[test]
fn each_step_converges_to_the_implicit_euler_step_in_3d() {
    let cases =
        (EnergyKind::ALL.into_iter().map(|k| (k, false))).chain([(EnergyKind::NeoHookean, true)]);
    for (kind, plane_strain) in cases {
        let energy: AnyEnergy = kind.build(case_a_lame()).unwrap();
        let model = beam(4, 2.0, energy, plane_strain);
        let start = swinging(&model, 10);
        let reference = implicit_step(&model, &start, 1e-2);
        let mut gaps = Vec::new();
        for iterations in [3, 10, 30, 500] {
            let params = VbdParams {
                dt: 1e-2,
                iterations,
                ..VbdParams::default()
            };
            let (s, report, _) = vbd_step(&model, &start, params);
            assert_eq!(report.iterations, iterations);
            // Held components stay where they were.
            for (v, p) in s.x.iter().enumerate() {
                for i in 0..3 {
                    if model.fixed()[3 * v + i] {
                        assert_eq!(p[i].to_bits(), start.x[v][i].to_bits(), "{v} {i}");
                        assert_eq!(s.v[v][i], 0.0);
                    }
                }
            }
            gaps.push(gap(&s, &reference, &start, &reference));
        }
        eprintln!(
            "{kind} (plane strain {plane_strain}): gap to implicit Euler after 3, 10, 30, 500 sweeps: {:.2e} {:.2e} {:.2e} {:.2e}",
            gaps[0], gaps[1], gaps[2], gaps[3]
        );
        for w in gaps.windows(2) {
            assert!(
                w[1] < w[0] || w[1] < 1e-10,
                "{kind}: not shrinking {gaps:?}"
            );
        }
        assert!(gaps[0] > 1e-4, "{kind}: the step is too easy {gaps:?}");
        assert!(gaps[3] < 1e-9, "{kind}: {gaps:?}");
    }
}

/// Every initial guess, with and without the line search, and with Chebyshev acceleration at
/// a moderate `rho`, reaches the same step.
#[test]
fn every_option_reaches_the_same_step_in_3d() {
    let model = beam(4, 2.0, NeoHookean::new(case_a_lame()).unwrap(), false);
    let start = swinging(&model, 10);
    let reference = implicit_step(&model, &start, 1e-2);
    for init in [VbdInit::Previous, VbdInit::Inertia, VbdInit::Adaptive] {
        for line_search in [false, true] {
            for chebyshev_rho in [0.0, 0.5] {
                let params = VbdParams {
                    dt: 1e-2,
                    iterations: 500,
                    init,
                    line_search,
                    chebyshev_rho,
                    ..VbdParams::default()
                };
                let (s, _, _) = vbd_step(&model, &start, params);
                let g = gap(&s, &reference, &start, &reference);
                assert!(
                    g < 1e-9,
                    "{init:?}, line search {line_search}, rho {chebyshev_rho}: {g:e}"
                );
            }
        }
    }
}

/// With a residual tolerance the sweeps stop once the gradient is at most `tolerance` times
/// the force scale (well before `iterations`), and the step is as close to implicit Euler's as
/// that residual allows. Measured (6 x 2 x 2 beam): 87, 143, 200 sweeps for 1e-4, 1e-6, 1e-8,
/// gaps 1.2e-5, 1.1e-7, 1.1e-9. (With tolerance 0 every sweep runs: the convergence test.)
#[test]
fn the_residual_tolerance_stops_the_sweeps() {
    let model = beam(6, 3.0, NeoHookean::new(case_a_lame()).unwrap(), false);
    let start = swinging(&model, 10);
    let reference = implicit_step(&model, &start, 1e-2);
    let mut last = Real::INFINITY;
    for tolerance in [1e-4, 1e-6, 1e-8] {
        let params = VbdParams {
            dt: 1e-2,
            iterations: 5000,
            tolerance,
            ..VbdParams::default()
        };
        let (s, report, stats) = vbd_step(&model, &start, params);
        let g = gap(&s, &reference, &start, &reference);
        eprintln!(
            "tolerance {tolerance:e}: {} sweeps, residual {:.2e} N of scale {:.2e} N, gap {g:.2e}",
            report.iterations, report.residual, stats.force_scale
        );
        assert!(report.iterations > 1 && report.iterations < 5000);
        assert!(report.residual <= tolerance * stats.force_scale);
        assert!(g < last, "{g:e} vs {last:e}");
        last = g;
    }
    assert!(last < 1e-6, "{last:e}");
}

/// Substeps are steps of `dt / substeps`: two substeps of one step and two steps of half the
/// step give the same bits (the adaptive guess carries over either way).
#[test]
fn substeps_are_steps_of_dt_over_substeps() {
    let model = beam(6, 3.0, NeoHookean::new(case_a_lame()).unwrap(), false);
    let start = swinging(&model, 10);
    let mut a = start.clone();
    let mut one = NdVbd::new(
        &model,
        VbdParams {
            dt: 2e-2,
            substeps: 2,
            damping: 3.0,
            ..VbdParams::default()
        },
        "vbd",
    )
    .unwrap();
    let mut b = start.clone();
    let mut two = NdVbd::new(
        &model,
        VbdParams {
            dt: 1e-2,
            damping: 3.0,
            ..VbdParams::default()
        },
        "vbd",
    )
    .unwrap();
    for _ in 0..3 {
        let r = one.step(&model, &mut a).unwrap();
        assert_eq!(r.iterations, 20);
        two.step(&model, &mut b).unwrap();
        two.step(&model, &mut b).unwrap();
    }
    assert_eq!(a.x, b.x);
    assert_eq!(a.v, b.v);
    assert!((a.t - b.t).abs() < 1e-15);
}

/// A Neo-Hookean beam hurled against its pinned face at 3000 m/s with 10 ms steps: full Newton
/// steps would invert tetrahedra, so vertex steps are halved (the orientation test is the exact
/// rank-one update `det(F + s g^T) = det F + s . cof(F) g`, in 3D too), and no tetrahedron
/// ever inverts. (At 300 m/s, the 2D test's speed, the stiffening Neo-Hookean blocks keep every
/// full step valid in 3D: measured 0 halvings; at 3000 m/s 282.)
#[test]
fn steps_that_would_invert_a_neo_hookean_tetrahedron_are_halved() {
    let model = beam(6, 3.0, NeoHookean::new(case_a_lame()).unwrap(), false);
    let mut vbd = NdVbd::new(
        &model,
        VbdParams {
            dt: 1e-2,
            ..VbdParams::default()
        },
        "vbd",
    )
    .unwrap();
    let mut state = NdState::at_rest(&model);
    for (v, vel) in state.v.iter_mut().enumerate() {
        if !model.fixed()[3 * v] {
            *vel = Vec3::new(-3000.0, 0.0, 0.0);
        }
    }
    let mut halved = 0;
    for _ in 0..5 {
        let report = vbd.step(&model, &mut state).unwrap();
        halved += vbd.last_stats().halved;
        assert_eq!(report.inverted, 0);
        assert!(report.min_det_f > 0.0);
    }
    eprintln!("halved vertex steps: {halved}");
    assert!(
        halved > 0,
        "no step was halved: the test does not reach the orientation test"
    );
}

/// The greedy vertex colouring of a box of tetrahedra: every free vertex has one colour, the
/// pinned ones none, and no two vertices of a colour share a tetrahedron. A 3D vertex has more
/// than twice the neighbours of a 2D one (up to 14 against 6 in the structured meshes), and the
/// greedy colouring takes twice the colours: measured 8 on this box, 4 on the 2D 20 x 4
/// cantilever (the same code in 2D).
#[test]
fn the_vertex_colouring_of_a_box_of_tetrahedra_is_valid() {
    let mesh = box_mesh(&BoxParams::new(2.0, 1.0, 1.0, 8, 4, 4)).unwrap();
    let mut model =
        NdModel::with_density(mesh, NeoHookean::new(case_a_lame()).unwrap(), 1.0).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 1.0),
        ))
        .unwrap();
    let vbd = NdVbd::new(&model, VbdParams::default(), "vbd").unwrap();
    let c = vbd.colouring();
    let n = model.mesh().n_vertices();
    let mut colour = vec![usize::MAX; n];
    for k in 0..c.n_colours() {
        for &v in c.class(k) {
            assert_eq!(colour[v as usize], usize::MAX, "vertex {v} twice");
            colour[v as usize] = k;
        }
    }
    for (v, &k) in colour.iter().enumerate() {
        let pinned = model.fixed()[3 * v];
        assert_eq!(pinned, k == usize::MAX, "vertex {v}");
    }
    for cell in model.mesh().cells() {
        for a in 0..4 {
            for b in a + 1..4 {
                let (ca, cb) = (colour[cell[a] as usize], colour[cell[b] as usize]);
                assert!(ca == usize::MAX || ca != cb, "cell {cell:?}");
            }
        }
    }
    // The largest vertex degree of the cells' graph, for the record.
    let degree = (0..n)
        .map(|v| {
            let mut nb: Vec<u32> = (model.mesh().cells_of(v).iter())
                .flat_map(|&(t, _)| model.mesh().cells()[t as usize])
                .filter(|&u| u as usize != v)
                .collect();
            nb.sort_unstable();
            nb.dedup();
            nb.len()
        })
        .max()
        .unwrap();
    // The 2D cantilever's colouring by the same code, for comparison.
    let tri = beam_mesh(20, 4).unwrap();
    let mesh2 = SimplexMesh::<D2>::new(tri.vertices().to_vec(), tri.triangles().to_vec()).unwrap();
    let mut model2 =
        NdModel::with_density(mesh2, NeoHookean::new(case_a_lame()).unwrap(), 1.0).unwrap();
    model2
        .pin(&NdRegion::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    let two = NdVbd::new(&model2, VbdParams::default(), "vbd")
        .unwrap()
        .n_colours();
    eprintln!(
        "3D box 8 x 4 x 4: {} colours, largest vertex degree {degree}; 2D cantilever 20 x 4: {two} colours",
        vbd.n_colours()
    );
    assert!(
        (two + 1..=degree + 1).contains(&vbd.n_colours()),
        "{} colours (2D: {two})",
        vbd.n_colours()
    );
}

/// BDF2 has no 3D path: refused in one line naming the field.
#[test]
fn bdf2_is_refused_in_one_line() {
    let model = beam(2, 1.0, NeoHookean::new(case_a_lame()).unwrap(), false);
    let params = SolverParams::Vbd(VbdParams {
        integrator: Integrator::Bdf2,
        ..VbdParams::default()
    });
    let e = nd::build(&model, &params, "solver")
        .err()
        .unwrap()
        .to_string();
    assert!(e.starts_with("solver.integrator = bdf2: "), "{e}");
    assert!(!e.contains('\n'));
}

/// Within a colour the vertex updates run in parallel in fixed chunks of 512 vertices: on a box
/// with more than one chunk per colour, 1, 2 and 3 threads give the same bits (with Chebyshev
/// acceleration and the residual test on, so every parallel pass is in).
#[test]
fn bit_identical_across_thread_counts_with_several_chunks_per_colour() {
    let mesh = box_mesh(&BoxParams::new(4.0, 1.0, 1.0, 40, 10, 10)).unwrap();
    let mut model =
        NdModel::with_density(mesh, NeoHookean::new(case_a_lame()).unwrap(), 0.2).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 1.0),
        ))
        .unwrap();
    let params = VbdParams {
        dt: 1e-2,
        iterations: 3,
        chebyshev_rho: 0.5,
        tolerance: 1e-12,
        ..VbdParams::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut vbd = NdVbd::new(&model, params, "vbd").unwrap();
            let c = vbd.colouring();
            let largest = (0..c.n_colours()).map(|k| c.class(k).len()).max().unwrap();
            assert!(largest > 512, "{largest} vertices: one chunk per colour");
            let mut st = NdState::at_rest(&model);
            let mut residual = Vec::new();
            for _ in 0..2 {
                residual.push(vbd.step(&model, &mut st).unwrap().residual.to_bits());
            }
            let bits: Vec<u64> = (st.x.iter().chain(&st.v))
                .flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                .collect();
            (bits, residual)
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}
