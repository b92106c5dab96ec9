//! The dimension-generic PBD and XPBD ([`fem_solvers::nd::NdPbd`], [`NdXpbd`]):
//! - in 2D every option (orderings, forms, schedules, substeps, damping, relaxation, multiplier
//!   reset, residual tolerance) is the 2D solver, colouring included;
//! - XPBD's sweeps converge, in 3D as in 2D, to a fixed point of their own per ordering, a few
//!   per cent of the step away from implicit Euler's step (the 2D docs' claim);
//! - PBD's stiffness grows with the sweeps and as `dt` shrinks (the paper's case C) in 3D;
//! - the 3D colouring is a valid greedy colouring;
//! - free fall, thread independence for every ordering, fixed components, the failing step
//!   and the refusals.

use crate::common::case_a_lame;
use fem_core::dim::{D2, D3, Vec3};
use fem_core::energy::{Hyperelastic, NeoHookean};
use fem_core::math::{Real, Vec2};
use fem_core::simplex::SimplexMesh;
use fem_core::structured::{BoxParams, box_mesh};
use fem_solvers::nd::{self, NdModel, NdPbd, NdRegion, NdState, NdStepper, NdXpbd};
use fem_solvers::steppers::colour::Colouring;
use fem_solvers::testing::{beam_mesh, cantilever};
use fem_solvers::{
    ImplicitParams, LambdaReset, NewtonParams, Ordering, PbdParams, SolverParams, State, Stepper,
    XpbdForm, XpbdParams, XpbdSchedule,
};

const G: Real = fem_solvers::model::STANDARD_GRAVITY;

/// The case A beam extruded by `depth` (`nz` cells through it), left face pinned, gravity -y.
fn beam<E: Hyperelastic<D3>>(
    nx: usize,
    ny: usize,
    nz: usize,
    depth: Real,
    energy: E,
) -> NdModel<D3, E> {
    let mesh = box_mesh(&BoxParams::new(5.0, 1.0, depth, nx, ny, nz)).unwrap();
    let mut model = NdModel::with_density(mesh, energy, 0.2).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    model
        .pin(&NdRegion::in_box(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, depth),
        ))
        .unwrap();
    model
}

fn nh() -> NeoHookean {
    NeoHookean::new(case_a_lame()).unwrap()
}

fn dist<V: std::ops::Sub<Output = V> + Copy>(a: &[V], b: &[V], norm: impl Fn(V) -> Real) -> Real {
    a.iter()
        .zip(b)
        .map(|(p, q)| norm(*p - *q))
        .fold(0.0, Real::max)
}

fn dist3(a: &[Vec3], b: &[Vec3]) -> Real {
    dist(a, b, |d| d.norm())
}

/// The option sets the 2D agreement and thread tests run.
fn option_sets(dt: Real) -> Vec<(&'static str, SolverParams)> {
    let pbd = PbdParams {
        dt,
        ..PbdParams::default()
    };
    let xpbd = XpbdParams {
        dt,
        ..XpbdParams::default()
    };
    vec![
        (
            "pbd gauss-seidel, 2 substeps, k = 0.5, damping",
            SolverParams::Pbd(PbdParams {
                ordering: Ordering::GaussSeidel,
                substeps: 2,
                stiffness: 0.5,
                damping: 1.0,
                ..pbd
            }),
        ),
        (
            "pbd jacobi, relaxation 1.5",
            SolverParams::Pbd(PbdParams {
                ordering: Ordering::Jacobi,
                relaxation: 1.5,
                ..pbd
            }),
        ),
        (
            "xpbd gauss-seidel, 3 substeps, damping",
            SolverParams::Xpbd(XpbdParams {
                ordering: Ordering::GaussSeidel,
                substeps: 3,
                damping: 2.0,
                ..xpbd
            }),
        ),
        (
            "xpbd jacobi, 30 sweeps, relaxation 1.2",
            SolverParams::Xpbd(XpbdParams {
                ordering: Ordering::Jacobi,
                iterations: 30,
                relaxation: 1.2,
                ..xpbd
            }),
        ),
        (
            "xpbd literal, compliance 1e-4",
            SolverParams::Xpbd(XpbdParams {
                form: XpbdForm::Literal,
                compliance: 1e-4,
                ..xpbd
            }),
        ),
        (
            "xpbd small steps, soft, rest threshold 1e-10",
            SolverParams::Xpbd(XpbdParams {
                schedule: XpbdSchedule::SmallSteps,
                compliance: 2.0,
                rest_threshold: 1e-10,
                ..xpbd
            }),
        ),
        (
            "xpbd multipliers reset every sweep",
            SolverParams::Xpbd(XpbdParams {
                lambda_reset: LambdaReset::Iteration,
                iterations: 4,
                ..xpbd
            }),
        ),
        (
            "xpbd residual tolerance 1e-2, 50 sweeps at most",
            SolverParams::Xpbd(XpbdParams {
                tolerance: 1e-2,
                iterations: 50,
                ..xpbd
            }),
        ),
    ]
}

/// In 2D every option is the 2D solver: 20 steps of 10 ms of case A's cantilever
/// (Neo-Hookean, 20 x 4), the largest vertex gap within `1e-8` of the largest displacement
/// (the two evaluate `psi` and `P` with different kernels, equal to round-off). Measured: gaps
/// of 1.6e-14 to 8e-11 m on deflections of 0.21 to 0.26 m; the sweep counts agree (those of the
/// residual tolerance included).
#[test]
fn in_2d_every_option_is_the_2d_solver() {
    let energy = nh();
    let model2 = cantilever(beam_mesh(20, 4).unwrap(), energy).unwrap();
    let tri = beam_mesh(20, 4).unwrap();
    let mesh = SimplexMesh::<D2>::new(tri.vertices().to_vec(), tri.triangles().to_vec()).unwrap();
    let mut model = NdModel::with_total_mass(mesh, energy, 1.0).unwrap();
    model.set_gravity(Vec2::new(0.0, -G)).unwrap();
    model
        .pin(&NdRegion::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    for (what, params) in option_sets(1e-2) {
        let mut s2 = params.build(&model2).unwrap();
        let mut st2 = State::at_rest(&model2);
        let mut s = nd::build(&model, &params, "solver").unwrap();
        let mut st = NdState::at_rest(&model);
        let (mut sweeps2, mut sweeps) = (0, 0);
        for _ in 0..20 {
            sweeps2 += s2.step(&model2, &mut st2).unwrap().iterations;
            sweeps += s.step(&model, &mut st).unwrap().iterations;
        }
        let scale = dist(&st2.x, model2.mesh().vertices(), |d| d.norm());
        let gap = dist(&st2.x, &st.x, |d| d.norm());
        eprintln!("{what}: {gap:.3e} m of {scale:.3e} m, sweeps {sweeps} ({sweeps2} in 2D)");
        assert!(scale > 1e-3, "{what}: the beam moved {scale}");
        assert!(gap <= 1e-8 * scale, "{what}: {gap:e} of {scale:e}");
        assert_eq!(sweeps, sweeps2, "{what}");
        assert_eq!(st.t.to_bits(), st2.t.to_bits(), "{what}: clock");
    }
}

/// The colouring in 2D is the 2D solver's, and in 3D it is a greedy colouring: every cell in
/// one class, no two cells of a class sharing a vertex, each cell of class `c` touching a cell
/// of every lower class (otherwise greedy would have taken that class), classes in increasing
/// cell order. Measured: 7 colours on the 20 x 4 triangle beam (2D), 26 on the 10 x 2 x 2
/// tetrahedral box (240 tetrahedra) and 28 on 20 x 4 x 2 (960).
#[test]
fn colouring_is_greedy_and_valid_in_3d() {
    let tri = beam_mesh(20, 4).unwrap();
    let mesh = SimplexMesh::<D2>::new(tri.vertices().to_vec(), tri.triangles().to_vec()).unwrap();
    let model2 = NdModel::with_total_mass(mesh, nh(), 1.0).unwrap();
    let s = NdXpbd::new(&model2, XpbdParams::default(), "xpbd").unwrap();
    let c = Colouring::greedy(&tri);
    let want: Vec<Vec<usize>> = (c.offsets.windows(2))
        .map(|w| c.order[w[0]..w[1]].iter().map(|&t| t as usize).collect())
        .collect();
    assert_eq!(s.colours(), want, "2D");
    eprintln!("2D: {} colours", s.n_colours());

    for (nx, ny, nz) in [(10, 2, 2), (20, 4, 2)] {
        let model = beam(nx, ny, nz, 0.5, nh());
        let mesh = model.mesh();
        let s = NdPbd::new(&model, PbdParams::default(), "pbd").unwrap();
        let colours = s.colours();
        assert_eq!(colours.len(), s.n_colours());
        let mut class = vec![usize::MAX; mesh.n_cells()];
        for (k, cells) in colours.iter().enumerate() {
            assert!(cells.windows(2).all(|w| w[0] < w[1]), "class {k} order");
            let mut seen = vec![false; mesh.n_vertices()];
            for &c in cells {
                assert_eq!(class[c], usize::MAX, "cell {c} twice");
                class[c] = k;
                for &v in mesh.cells()[c].as_ref() {
                    assert!(!seen[v as usize], "class {k} shares vertex {v}");
                    seen[v as usize] = true;
                }
            }
        }
        assert!(
            class.iter().all(|&k| k != usize::MAX),
            "a cell without a class"
        );
        for (c, &k) in class.iter().enumerate() {
            let mut lower = vec![false; k];
            for &v in mesh.cells()[c].as_ref() {
                for &(e, _) in mesh.cells_of(v as usize) {
                    let ke = class[e as usize];
                    if ke < k && (e as usize) < c {
                        lower[ke] = true;
                    }
                }
            }
            assert!(
                lower.iter().all(|&b| b),
                "cell {c} of class {k} is not greedy"
            );
        }
        eprintln!(
            "{nx} x {ny} x {nz}: {} tetrahedra in {} colours",
            mesh.n_cells(),
            colours.len()
        );
        let one = NdXpbd::new(
            &model,
            XpbdParams {
                ordering: Ordering::Jacobi,
                ..XpbdParams::default()
            },
            "xpbd",
        )
        .unwrap();
        assert_eq!(one.n_colours(), 1);
        assert_eq!(one.colours(), vec![(0..mesh.n_cells()).collect::<Vec<_>>()]);
    }
}

/// XPBD's step as the sweeps grow, in 3D: from a sagging, moving beam (15 implicit steps of
/// 10 ms), one step of 10 ms. Each ordering converges (the change from 160 to 640 sweeps, 2560
/// to 10240 for Jacobi, below `1e-9` of the step; the residual falls by `1e9`) to a limit of
/// its own that is not implicit Euler's step: the primal residual is neglected, as the 2D
/// docs say. Measured, as fractions of the step's largest displacement (22 mm): Gauss-Seidel
/// 5.3 %, coloured 8.0 %, Jacobi 3.0 % from implicit Euler; changes of 5e-12, 3e-12, 4e-12.
#[test]
fn xpbd_sweeps_converge_to_their_own_limit_not_implicit_euler() {
    let model = beam(10, 2, 2, 0.5, nh());
    let dt = 1e-2;
    let ip = SolverParams::Implicit(ImplicitParams {
        dt,
        velocity_tolerance: 0.0,
        newton: NewtonParams {
            tolerance: 1e-11,
            ..NewtonParams::default()
        },
        ..ImplicitParams::default()
    });
    let mut s = nd::build(&model, &ip, "solver").unwrap();
    let mut start = NdState::at_rest(&model);
    for _ in 0..15 {
        s.step(&model, &mut start).unwrap();
    }
    let mut implicit = start.clone();
    s.step(&model, &mut implicit).unwrap();
    let scale = dist3(&implicit.x, &start.x);
    let mut limits = Vec::new();
    for (ordering, sweeps) in [
        (Ordering::GaussSeidel, [10, 160, 640]),
        (Ordering::Coloured, [10, 160, 640]),
        (Ordering::Jacobi, [10, 2560, 10240]),
    ] {
        let run = |iterations: usize| {
            let mut x = NdXpbd::new(
                &model,
                XpbdParams {
                    dt,
                    iterations,
                    ordering,
                    ..XpbdParams::default()
                },
                "xpbd",
            )
            .unwrap();
            let mut st = start.clone();
            let r = x.step(&model, &mut st).unwrap();
            (st.x, r.residual)
        };
        let (_, r0) = run(sweeps[0]);
        let (a, _) = run(sweeps[1]);
        let (b, r) = run(sweeps[2]);
        let change = dist3(&a, &b) / scale;
        let gap = dist3(&b, &implicit.x) / scale;
        eprintln!(
            "{ordering:?}: change {change:.2e}, residual {r0:.2e} -> {r:.2e}, {:.2} % from implicit Euler",
            100.0 * gap
        );
        assert!(change < 1e-9, "{ordering:?}: not converged ({change:e})");
        assert!(r < 1e-9 * r0, "{ordering:?}: residual {r0:e} -> {r:e}");
        assert!(gap > 0.01 && gap < 0.15, "{ordering:?}: {gap}");
        limits.push(b);
    }
    // Three different limits.
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let d = dist3(&limits[i], &limits[j]) / scale;
        assert!(d > 0.01, "limits {i} and {j}: {d:e}");
    }
}

/// The tip deflection (mean `u_y` of the free end's bottom edge).
fn tip<E: Hyperelastic<D3>>(model: &NdModel<D3, E>, st: &NdState<D3>) -> Real {
    let tips: Vec<usize> = (0..model.mesh().n_vertices())
        .filter(|&v| {
            let p = model.mesh().vertices()[v];
            (p.x - 5.0).abs() < 1e-9 && p.y.abs() < 1e-9
        })
        .collect();
    tips.iter()
        .map(|&v| st.displacement(model, v).y)
        .sum::<Real>()
        / tips.len() as Real
}

fn tip_after<S: NdStepper<D3, NeoHookean>>(
    model: &NdModel<D3, NeoHookean>,
    mut s: S,
    steps: usize,
) -> Real {
    let mut st = NdState::at_rest(model);
    for _ in 0..steps {
        s.step(model, &mut st).unwrap();
    }
    tip(model, &st)
}

/// The paper's case C in 3D: PBD's response stiffens with the sweeps and as `dt` shrinks,
/// far from the material's; XPBD's hardly depends on the sweeps. Tip after 0.2 s (measured):
/// XPBD with 5 and 40 sweeps at 1 ms: -0.2519 m both (to 1e-6 m); PBD (1 ms, 5 sweeps)
/// -12.4 mm, (1 ms, 20 sweeps) -2.9 mm, (0.25 ms, 5 sweeps) -0.63 mm.
#[test]
fn pbd_stiffens_with_sweeps_and_smaller_steps_in_3d() {
    let model = beam(10, 2, 2, 0.5, nh());
    let pbd = |dt: Real, iterations| {
        let s = NdPbd::new(
            &model,
            PbdParams {
                dt,
                iterations,
                ..PbdParams::default()
            },
            "pbd",
        )
        .unwrap();
        tip_after(&model, s, (0.2 / dt).round() as usize)
    };
    let xpbd = |iterations| {
        let s = NdXpbd::new(
            &model,
            XpbdParams {
                dt: 1e-3,
                iterations,
                ..XpbdParams::default()
            },
            "xpbd",
        )
        .unwrap();
        tip_after(&model, s, 200)
    };
    let (x5, x40) = (xpbd(5), xpbd(40));
    let (base, more, finer) = (pbd(1e-3, 5), pbd(1e-3, 20), pbd(2.5e-4, 5));
    eprintln!("xpbd {x5:.6} / {x40:.6} m; pbd {base:.3e}, {more:.3e}, {finer:.3e} m");
    assert!(x5 < -0.1, "xpbd {x5}");
    assert!((x5 - x40).abs() < 1e-3 * x5.abs(), "xpbd {x5} vs {x40}");
    for d in [base, more, finer] {
        assert!(d < 0.0 && d.abs() < 0.2 * x5.abs(), "pbd {d} vs xpbd {x5}");
    }
    assert!(more.abs() < base.abs() / 2.0, "{base} vs {more}");
    assert!(finer.abs() < base.abs() / 2.0, "{base} vs {finer}");
}

/// Free fall in 3D is symplectic Euler for every ordering, form and substep count (rigid
/// motion leaves every constraint at rest, below the rest threshold): `y_n = -g h^2 n (n + 1)
/// / 2` over the substeps, to `1e-9` m over 100 steps of 1 ms.
#[test]
fn free_fall_in_3d_for_every_ordering_form_and_substeps() {
    let mesh = box_mesh(&BoxParams::new(1.0, 0.5, 0.5, 4, 2, 2)).unwrap();
    let mut model = NdModel::with_density(mesh, nh(), 1.0).unwrap();
    model.set_gravity(Vec3::new(0.0, -G, 0.0)).unwrap();
    for ordering in [Ordering::GaussSeidel, Ordering::Coloured, Ordering::Jacobi] {
        for substeps in [1, 2] {
            let mut runs: Vec<(String, SolverParams)> = vec![(
                "pbd".into(),
                SolverParams::Pbd(PbdParams {
                    ordering,
                    substeps,
                    ..PbdParams::default()
                }),
            )];
            for form in [XpbdForm::Consistent, XpbdForm::Literal] {
                runs.push((
                    format!("xpbd {form:?}"),
                    SolverParams::Xpbd(XpbdParams {
                        ordering,
                        substeps,
                        form,
                        ..XpbdParams::default()
                    }),
                ));
            }
            for (what, p) in runs {
                let mut s = nd::build(&model, &p, "solver").unwrap();
                let mut st = NdState::at_rest(&model);
                for _ in 0..100 {
                    s.step(&model, &mut st).unwrap();
                }
                let n = (100 * substeps) as Real;
                let h = 1e-3 / substeps as Real;
                let want = -G * h * h * n * (n + 1.0) / 2.0;
                for v in 0..st.x.len() {
                    let u = st.displacement(&model, v);
                    assert!(
                        (u.y - want).abs() < 1e-9 && u.x.abs() < 1e-12 && u.z.abs() < 1e-12,
                        "{what} {ordering:?} x{substeps}, vertex {v}: {u:?} vs {want}"
                    );
                }
            }
        }
    }
}

/// One and two threads give the same bits in 3D for every option set (the battery runs the
/// defaults only).
#[test]
fn every_option_is_thread_independent_in_3d() {
    for (what, params) in option_sets(1e-2) {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let model = beam(20, 4, 2, 0.5, nh());
                let mut s = nd::build(&model, &params, "solver").unwrap();
                let mut st = NdState::at_rest(&model);
                let mut sweeps = 0;
                for _ in 0..3 {
                    sweeps += s.step(&model, &mut st).unwrap().iterations;
                }
                let bits: Vec<u64> =
                    st.x.iter()
                        .chain(&st.v)
                        .flat_map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                        .collect();
                (bits, sweeps)
            })
        };
        assert_eq!(run(1), run(2), "{what}");
    }
}

/// Fixed components, not vertices: the beam with `u_z = 0` on both side faces (two cells
/// through the depth) sags under XPBD, Jacobi and PBD with every fixed `z` exactly at rest and
/// its velocity exactly zero, while the same vertices move in `x` and `y`.
#[test]
fn fixed_components_keep_position_and_zero_velocity() {
    let depth = 0.5;
    let mut model = beam(10, 2, 2, depth, nh());
    for z in [0.0, depth] {
        model
            .fix(
                &NdRegion::in_box(Vec3::new(0.0, 0.0, z), Vec3::new(5.0, 1.0, z)),
                &[false, false, true],
                "side",
            )
            .unwrap();
    }
    let rest = model.mesh().vertices().to_vec();
    let sides: Vec<usize> = (0..rest.len())
        .filter(|&v| rest[v].z.abs() < 1e-9 || (rest[v].z - depth).abs() < 1e-9)
        .filter(|&v| rest[v].x > 1e-9)
        .collect();
    for params in [
        SolverParams::Xpbd(XpbdParams {
            dt: 1e-2,
            ..XpbdParams::default()
        }),
        SolverParams::Xpbd(XpbdParams {
            dt: 1e-2,
            ordering: Ordering::Jacobi,
            substeps: 2,
            ..XpbdParams::default()
        }),
        SolverParams::Pbd(PbdParams {
            dt: 1e-2,
            ordering: Ordering::GaussSeidel,
            ..PbdParams::default()
        }),
    ] {
        let mut s = nd::build(&model, &params, "solver").unwrap();
        let mut st = NdState::at_rest(&model);
        for _ in 0..20 {
            s.step(&model, &mut st).unwrap();
        }
        let kind = params.kind();
        for &v in &sides {
            assert_eq!(st.x[v].z.to_bits(), rest[v].z.to_bits(), "{kind}: z of {v}");
            assert_eq!(st.v[v].z, 0.0, "{kind}: v_z of {v}");
        }
        let moved = sides
            .iter()
            .map(|&v| (st.x[v] - rest[v]).norm())
            .fold(0.0, Real::max);
        assert!(moved > 1e-4, "{kind}: the side faces moved {moved} m");
    }
}

/// A step that fails in a later substep leaves the state as it was before the step (the 2D
/// solver commits each substep; the nd contract is per step), with a one-line error naming
/// the step. The beam under 300 g in steps of 50 ms (4 substeps): the first step fails
/// (inverted Neo-Hookean cells give `psi = +inf` and a NaN projection, which surfaces), while
/// its first substep alone succeeds (measured, PBD and XPBD alike).
#[test]
fn a_failing_step_leaves_the_state_as_it_was() {
    let mut model = beam(10, 2, 2, 0.5, nh());
    model.set_gravity(Vec3::new(0.0, -300.0 * G, 0.0)).unwrap();
    for pbd in [false, true] {
        let params = |dt: Real, substeps| {
            if pbd {
                SolverParams::Pbd(PbdParams {
                    dt,
                    substeps,
                    ..PbdParams::default()
                })
            } else {
                SolverParams::Xpbd(XpbdParams {
                    dt,
                    substeps,
                    ..XpbdParams::default()
                })
            }
        };
        let mut s = nd::build(&model, &params(5e-2, 4), "solver").unwrap();
        let mut st = NdState::at_rest(&model);
        let e = s.step(&model, &mut st).err().unwrap().to_string();
        eprintln!("pbd {pbd}: {e}");
        assert_eq!(st, NdState::at_rest(&model), "pbd {pbd}: the state changed");
        assert!(!e.contains('\n') && e.starts_with("step 1 "), "{e}");
        // The first substep on its own succeeds: the step failed in a later one.
        let mut first = nd::build(&model, &params(5e-2 / 4.0, 1), "solver").unwrap();
        let mut one = NdState::at_rest(&model);
        first.step(&model, &mut one).unwrap();
    }
}

/// Invalid values are refused in one line naming `<prefix>.<field>` and the value, and a
/// stepper refuses a model other than the one it was built for.
#[test]
fn refusals_are_one_line() {
    let model = beam(4, 1, 1, 0.5, nh());
    let bad = [
        SolverParams::Xpbd(XpbdParams {
            relaxation: 2.5,
            ..XpbdParams::default()
        }),
        SolverParams::Pbd(PbdParams {
            stiffness: 1.5,
            ..PbdParams::default()
        }),
    ];
    for (p, want) in bad
        .iter()
        .zip(["scene.relaxation = 2.5", "scene.stiffness = 1.5"])
    {
        let e = nd::build(&model, p, "scene").err().unwrap().to_string();
        assert!(e.starts_with(want) && !e.contains('\n'), "{e}");
    }
    let other = beam(5, 1, 1, 0.5, nh());
    let mut s = NdXpbd::new(&model, XpbdParams::default(), "xpbd").unwrap();
    let mut st = NdState::at_rest(&other);
    let e = s.step(&other, &mut st).err().unwrap().to_string();
    assert!(e.starts_with("model = ") && !e.contains('\n'), "{e}");
    assert_eq!(st, NdState::at_rest(&other));
}
