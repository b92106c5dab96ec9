//! Vertex Block Descent against its oracle, implicit Euler: both minimise the same incremental
//! potential, so VBD's step must reach Newton's as its sweeps grow, for every energy; the
//! definiteness fix must hold under compression (StVK indefinite); Chebyshev acceleration
//! must not change the converged answer. With the averaged nodal pressure triangle the same
//! holds for the formulation's potential (rigid bodies and contact included), the colouring
//! keeps node patches apart, and the bits do not depend on the threads.

use fem_core::PlaneModel;
use fem_core::energy::{AnyEnergy, ElementEnergies, Energy, EnergyKind, EnergyOf};
use fem_core::material::{Lame, Material};
use fem_core::math::{Real, Vec2};
use fem_solvers::colour::VertexColouring;
use fem_solvers::testing::{RectangleParams, assert_apart, rectangle};
use fem_solvers::{
    ImplicitParams, ImplicitStepper, Model, NewtonParams, Region, State, Stepper, VbdInit,
    VbdParams, VbdStepper,
};

use crate::common::{bits, cantilever, case_a_lame};

/// The case A cantilever (10 x 2 cells) under `kind`, swinging: a state after 20 implicit
/// steps of 10 ms from rest, so each step starts with velocity and strain.
pub fn swinging(kind: EnergyKind) -> (Model<AnyEnergy>, State) {
    let model = cantilever(kind.build(case_a_lame()).unwrap(), 10, 2);
    let mut state = State::at_rest(&model);
    let mut implicit = ImplicitStepper::new(&model, ImplicitParams::default()).unwrap();
    for _ in 0..20 {
        implicit.step(&model, &mut state).unwrap();
    }
    (model, state)
}

/// One implicit Euler step of `dt` from `state`, Newton to 1e-13 ([`tight_implicit`]).
pub fn implicit_step(model: &Model<AnyEnergy>, state: &State, dt: Real) -> State {
    let mut s = state.clone();
    tight_implicit(model, dt).step(model, &mut s).unwrap();
    s
}

/// One VBD step of `dt` from `state` with `params` (dt overridden).
fn vbd_step(model: &Model<AnyEnergy>, state: &State, dt: Real, params: VbdParams) -> State {
    let mut s = state.clone();
    VbdStepper::new(model, VbdParams { dt, ..params })
        .unwrap()
        .step(model, &mut s)
        .unwrap();
    s
}

/// Implicit Euler's incremental potential of the step of `dt` from `start`, at `x` (gravity
/// only, as in these scenes), J per unit thickness.
pub fn potential(model: &Model<AnyEnergy>, start: &State, dt: Real, x: &[Vec2]) -> Real {
    let mesh = model.mesh();
    let mut e = 0.0;
    for (i, m) in model.masses().iter().enumerate() {
        let target = start.x[i] + start.v[i] * dt;
        e += 0.5 * m / (dt * dt) * (x[i] - target).norm_squared();
        e -= (model.gravity() * *m).dot(&(x[i] - mesh.vertices()[i]));
    }
    for (t, el) in mesh.elements().iter().enumerate() {
        let f = el.deformation_gradient(mesh.gather(t, x));
        e += el.area * model.energies().energy_of(t).psi(&f);
    }
    e
}

/// Largest vertex distance between `a` and `b` over the largest distance `reference` moved
/// from `start`.
pub fn gap(a: &State, b: &State, start: &State, reference: &State) -> Real {
    let d =
        a.x.iter()
            .zip(&b.x)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, Real::max);
    let moved = reference
        .x
        .iter()
        .zip(&start.x)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    d / moved
}

/// As the sweeps grow, one VBD step reaches the implicit Euler step for every energy: the gap
/// (largest vertex distance over the step's largest displacement) shrinks with the sweeps and
/// ends at round-off. Measured (10 ms step, 10 x 2 cells, Neo-Hookean): 8e-3 after 10 sweeps,
/// round-off (4e-12) from about 100.
#[test]
fn one_step_converges_to_the_implicit_euler_step_for_every_energy() {
    for kind in EnergyKind::ALL {
        let (model, start) = swinging(kind);
        let reference = implicit_step(&model, &start, 1e-2);
        let mut gaps = Vec::new();
        for iterations in [3, 10, 30, 1000] {
            let params = VbdParams {
                iterations,
                ..VbdParams::default()
            };
            let s = vbd_step(&model, &start, 1e-2, params);
            gaps.push(gap(&s, &reference, &start, &reference));
        }
        eprintln!(
            "{kind}: gap to implicit Euler after 3, 10, 30, 1000 sweeps: {:.2e} {:.2e} {:.2e} {:.2e}",
            gaps[0], gaps[1], gaps[2], gaps[3]
        );
        // Shrinking until round-off (the reference's own Newton tolerance is 1e-13).
        for w in gaps.windows(2) {
            assert!(
                w[1] < w[0] || w[1] < 1e-10,
                "{kind}: not shrinking {gaps:?}"
            );
        }
        assert!(gaps[3] < 1e-9, "{kind}: {gaps:?}");
    }
}

/// Every initial guess, with and without the line search, converges to the same step (they
/// change where and how the sweeps go, not where they end).
#[test]
fn every_initial_guess_with_or_without_line_search_converges_to_the_same_step() {
    let (model, start) = swinging(EnergyKind::NeoHookean);
    let reference = implicit_step(&model, &start, 1e-2);
    for init in [VbdInit::Previous, VbdInit::Inertia, VbdInit::Adaptive] {
        for line_search in [false, true] {
            let params = VbdParams {
                iterations: 1000,
                init,
                line_search,
                ..VbdParams::default()
            };
            let s = vbd_step(&model, &start, 1e-2, params);
            let g = gap(&s, &reference, &start, &reference);
            assert!(g < 1e-9, "{init:?}, line search {line_search}: {g:e}");
        }
    }
}

/// A bar squashed to 30 % of its length and released: StVK's Hessian is indefinite there, and
/// the projected blocks keep every update a descent step. With every energy but StVK the step
/// ends where implicit Euler's does, uninverted; with StVK it ends in another, inverted,
/// stationary point of the same (non-convex) potential.
#[test]
fn a_squashed_bar_recovers_under_every_energy() {
    for kind in EnergyKind::ALL {
        let energy = kind.build(case_a_lame()).unwrap();
        let mut model =
            Model::with_total_mass(fem_solvers::testing::beam_mesh(10, 2).unwrap(), energy, 1.0)
                .unwrap();
        model
            .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
            .unwrap();
        let x = model
            .mesh()
            .vertices()
            .iter()
            .map(|p| Vec2::new(0.3 * p.x, p.y))
            .collect();
        let start = State::new(&model, x, vec![Vec2::zeros(); model.mesh().n_vertices()]).unwrap();
        let reference = implicit_step(&model, &start, 1e-2);
        let params = VbdParams {
            iterations: 2000,
            ..VbdParams::default()
        };
        let mut s = start.clone();
        let mut vbd = VbdStepper::new(&model, VbdParams { dt: 1e-2, ..params }).unwrap();
        let report = vbd.step(&model, &mut s).unwrap();
        let g = gap(&s, &reference, &start, &reference);
        eprintln!(
            "{kind}: squashed bar, gap {g:.2e}, min det F {:.3}, {:?}",
            report.min_det_f,
            vbd.last_stats()
        );
        let (mine, newton) = (
            potential(&model, &start, 1e-2, &s.x),
            potential(&model, &start, 1e-2, &reference.x),
        );
        let initial = potential(&model, &start, 1e-2, &start.x);
        eprintln!("  potential: VBD {mine:.6e}, Newton {newton:.6e}, start {initial:.6e}");
        if kind == EnergyKind::Stvk {
            // StVK's potential is not convex here: VBD, a local descent, settles in an
            // inverted local minimum above Newton's (measured 403.9 against 359.5 J, min det F
            // -0.91): StVK's known collapse under compression. It still descended.
            assert!(mine < initial, "{mine} vs {initial}");
        } else {
            assert!(g < 1e-9, "{kind}: {g:e}");
            assert!(report.min_det_f > 0.0, "{kind}: {}", report.min_det_f);
        }
    }
}

/// Chebyshev acceleration does not change the converged step, and at a good `rho` it gets
/// there in fewer sweeps (measured after 50 sweeps: 2.1e-7 without, 1.7e-8 at rho = 0.5,
/// 8.3e-8 at 0.9); at a `rho` far above the sweeps' spectral radius it diverges (0.99: 96
/// after 3000 sweeps).
#[test]
fn chebyshev_keeps_the_converged_step_and_a_good_rho_speeds_it_up() {
    let (model, start) = swinging(EnergyKind::NeoHookean);
    let reference = implicit_step(&model, &start, 1e-2);
    let run = |rho: Real, iterations: usize| {
        let params = VbdParams {
            iterations,
            chebyshev_rho: rho,
            ..VbdParams::default()
        };
        gap(
            &vbd_step(&model, &start, 1e-2, params),
            &reference,
            &start,
            &reference,
        )
    };
    let mut rows = Vec::new();
    for rho in [0.0, 0.5, 0.9, 0.95, 0.99, 0.999] {
        rows.push((rho, run(rho, 50), run(rho, 3000)));
    }
    for (rho, at50, converged) in &rows {
        eprintln!("rho {rho}: gap {at50:.2e} after 50 sweeps, {converged:.2e} after 3000");
    }
    // Up to 0.95 the converged step is the same; at 0.99 and above (far beyond the sweeps'
    // spectral radius on this step) the extrapolation overshoots and never settles.
    for (rho, _, converged) in &rows {
        if *rho <= 0.95 {
            assert!(*converged < 1e-10, "rho {rho}: {converged:e}");
        } else {
            assert!(
                *converged > 1e-3,
                "rho {rho}: expected to diverge, {converged:e}"
            );
        }
    }
    let plain = rows[0].1;
    let best = rows.iter().map(|r| r.1).fold(Real::INFINITY, Real::min);
    assert!(best < 0.5 * plain, "no rho helped: {rows:?}");
}

/// A Neo-Hookean beam hurled against its pinned edge at 300 m/s with 10 ms steps: full Newton
/// steps would invert triangles, so vertex steps are halved (the orientation test is the exact
/// rank-one update `det(F + s g^T) = det F + s . cof(F) g`), and no triangle ever inverts.
#[test]
fn steps_that_would_invert_a_neo_hookean_triangle_are_halved() {
    let model = cantilever(
        fem_core::energy::NeoHookean::new(case_a_lame()).unwrap(),
        10,
        2,
    );
    let mut stepper = VbdStepper::new(
        &model,
        VbdParams {
            dt: 0.01,
            ..VbdParams::default()
        },
    )
    .unwrap();
    let mut state = State::at_rest(&model);
    for v in state.v.iter_mut() {
        *v = Vec2::new(-300.0, 0.0);
    }
    let mut halved = 0;
    for _ in 0..5 {
        let report = stepper.step(&model, &mut state).unwrap();
        halved += stepper.last_stats().halved;
        assert_eq!(report.inverted, 0);
        assert!(report.min_det_f > 0.0);
    }
    eprintln!("halved vertex steps: {halved}");
    assert!(
        halved > 0,
        "no step was halved: the test does not reach the orientation test"
    );
}

/// Lamé parameters of a nearly incompressible material: E = 1000 Pa, nu = 0.49, plane strain.
fn incompressible_lame() -> Lame {
    Material::new(1000.0, 0.49, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain)
}

/// The case A cantilever (`nx` x `ny` cells) of the nearly incompressible material under
/// `kind`, of averaged nodal pressure triangles when `averaged`.
fn incompressible_cantilever(
    kind: EnergyKind,
    nx: usize,
    ny: usize,
    averaged: bool,
) -> Model<AnyEnergy> {
    let mut model = cantilever(kind.build(incompressible_lame()).unwrap(), nx, ny);
    model.set_averaged_pressure(averaged).unwrap();
    model
}

/// `steps` steps of `stepper` from `start`.
fn run<S: Stepper>(model: &Model<AnyEnergy>, start: &State, mut stepper: S, steps: usize) -> State {
    let mut s = start.clone();
    for _ in 0..steps {
        stepper.step(model, &mut s).unwrap();
    }
    s
}

/// Implicit Euler with steps of `dt`, Newton to 1e-13 (no velocity tolerance).
fn tight_implicit(model: &Model<AnyEnergy>, dt: Real) -> ImplicitStepper {
    let params = ImplicitParams {
        dt,
        newton: NewtonParams {
            tolerance: 1e-13,
            max_iterations: 200,
            ..NewtonParams::default()
        },
        velocity_tolerance: 0.0,
        ..ImplicitParams::default()
    };
    ImplicitStepper::new(model, params).unwrap()
}

/// `steps` VBD steps of `dt` with `params` (dt overridden).
fn run_vbd(
    model: &Model<AnyEnergy>,
    start: &State,
    dt: Real,
    params: VbdParams,
    steps: usize,
) -> State {
    let stepper = VbdStepper::new(model, VbdParams { dt, ..params }).unwrap();
    run(model, start, stepper, steps)
}

/// With the averaged nodal pressure triangle (nu = 0.49, plane strain) VBD minimises the
/// formulation's incremental potential: three 10 ms steps of the 10 x 2 cantilever from rest
/// reach implicit Euler's with the formulation as the sweeps grow. The same VBD on plain
/// triangles (which lock) ends far from it, so the test fails if the sweeps ignore the
/// formulation. Measured (gap: largest vertex distance over the largest displacement):
/// Neo-Hookean 6.1e-5 after 100 sweeps, 2.9e-10 from 1000 (Newton's own round-off floor at
/// nu = 0.49; VBD's residual is below Newton's there), plain VBD 5.7e-2; stable Neo-Hookean
/// 5.1e-5, 2.9e-10 and 6.0e-2.
#[test]
fn vbd_converges_to_implicit_euler_with_the_averaged_nodal_pressure_triangle() {
    for kind in [EnergyKind::NeoHookean, EnergyKind::StableNeoHookean] {
        let averaged = incompressible_cantilever(kind, 10, 2, true);
        let plain = incompressible_cantilever(kind, 10, 2, false);
        let start = State::at_rest(&averaged);
        let reference = run(&averaged, &start, tight_implicit(&averaged, 1e-2), 3);
        let gap_of = |model: &Model<AnyEnergy>, iterations: usize| {
            let params = VbdParams {
                iterations,
                ..VbdParams::default()
            };
            let s = run_vbd(model, &start, 1e-2, params, 3);
            gap(&s, &reference, &start, &reference)
        };
        let (g100, g2000, plain2000) = (
            gap_of(&averaged, 100),
            gap_of(&averaged, 2000),
            gap_of(&plain, 2000),
        );
        eprintln!(
            "{kind}: gap to implicit Euler with the formulation: {g100:.2e} after 100 sweeps, \
             {g2000:.2e} after 2000; plain VBD {plain2000:.2e}"
        );
        assert!(g2000 < 1e-8 && g2000 < g100, "{kind}: {g100:e} {g2000:e}");
        assert!(
            plain2000 > 1e-2 && plain2000 > 1e5 * g2000,
            "{kind}: plain {plain2000:e}"
        );
    }
}

/// Every initial guess, the line search, Chebyshev acceleration and the residual tolerance
/// reach the same step with the formulation (one 10 ms step of a swinging nearly
/// incompressible cantilever).
#[test]
fn every_option_reaches_the_same_step_with_the_averaged_nodal_pressure_triangle() {
    let model = incompressible_cantilever(EnergyKind::NeoHookean, 10, 2, true);
    let mut start = State::at_rest(&model);
    let mut implicit = tight_implicit(&model, 1e-2);
    for _ in 0..5 {
        implicit.step(&model, &mut start).unwrap();
    }
    let reference = run(&model, &start, tight_implicit(&model, 1e-2), 1);
    let mut cases = Vec::new();
    for init in [VbdInit::Previous, VbdInit::Inertia, VbdInit::Adaptive] {
        for line_search in [false, true] {
            cases.push(VbdParams {
                init,
                line_search,
                ..VbdParams::default()
            });
        }
    }
    cases.push(VbdParams {
        chebyshev_rho: 0.5,
        ..VbdParams::default()
    });
    cases.push(VbdParams {
        tolerance: 1e-10,
        ..VbdParams::default()
    });
    for params in cases {
        let params = VbdParams {
            iterations: 3000,
            ..params
        };
        let s = run_vbd(&model, &start, 1e-2, params, 1);
        let g = gap(&s, &reference, &start, &reference);
        eprintln!(
            "{:?}, line search {}, rho {}, tolerance {:e}: gap {g:.2e}",
            params.init, params.line_search, params.chebyshev_rho, params.tolerance
        );
        assert!(g < 1e-7, "{params:?}: {g:e}");
    }
}

/// Two materials (a soft and a five times stiffer half, both nu = 0.49, light: the sweeps
/// converge slowly): the nodes on the interface are one per side, and VBD still reaches
/// implicit Euler's two steps. Measured: gap 5.8e-7 after 2000 sweeps, 4.4e-11 after 5000
/// (plain triangles, against their own implicit Euler: 2.7e-4 and 2.8e-6).
#[test]
fn two_materials_with_the_averaged_nodal_pressure_triangle_reach_implicit_euler() {
    let model = two_material_cantilever(true);
    let start = State::at_rest(&model);
    let reference = run(&model, &start, tight_implicit(&model, 1e-2), 2);
    let params = VbdParams {
        iterations: 5000,
        ..VbdParams::default()
    };
    let s = run_vbd(&model, &start, 1e-2, params, 2);
    let g = gap(&s, &reference, &start, &reference);
    eprintln!("two materials: gap {g:.2e}");
    assert!(g < 1e-8, "{g:e}");
}

/// The 20 x 4 cantilever with its right half five times stiffer (two regions, nu = 0.49).
fn two_material_cantilever(averaged: bool) -> Model<AnyEnergy> {
    let mesh = fem_solvers::testing::beam_mesh(20, 4).unwrap();
    let soft = EnergyKind::NeoHookean.build(incompressible_lame()).unwrap();
    let stiff = soft
        .with_lame(
            Material::new(5000.0, 0.49, 1.0)
                .unwrap()
                .lame(PlaneModel::PlaneStrain),
        )
        .unwrap();
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
            u32::from(c.x > 2.5)
        })
        .collect();
    let energies = ElementEnergies::new(vec![soft, stiff], tags).unwrap();
    let masses = mesh.lumped_masses_from_density(0.2).unwrap();
    let mut model = Model::with_regions(mesh, energies, masses).unwrap();
    model.set_standard_gravity();
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    model.set_averaged_pressure(averaged).unwrap();
    model
}

/// With the formulation the vertices are coloured so that no two of one colour lie in one
/// node's patch (a vertex's local energy reads the nodal volumes of every node whose patch
/// holds it); every free vertex has one colour and the pinned ones none. Without it the
/// colouring is the plain one (no two of a colour share a triangle), unchanged. Measured on
/// the two-material 20 x 4 cantilever: 9 colours with the formulation, 4 without.
#[test]
fn with_the_averaged_nodal_pressure_triangle_no_two_vertices_of_a_colour_share_a_node_patch() {
    let model = two_material_cantilever(true);
    let stepper = VbdStepper::new(&model, VbdParams::default()).unwrap();
    let c = stepper.colouring();
    let mesh = model.elastic_mesh();
    let mut colour = vec![usize::MAX; mesh.n_vertices()];
    for k in 0..c.n_colours() {
        for &v in c.class(k) {
            assert_eq!(colour[v as usize], usize::MAX, "vertex {v} coloured twice");
            colour[v as usize] = k;
        }
    }
    for (v, p) in mesh.vertices().iter().enumerate() {
        assert_eq!(colour[v] == usize::MAX, p.x == 0.0, "vertex {v} at {p:?}");
    }
    let np = model.elastic_energies().nodal_pressure().unwrap();
    let mut patch = Vec::new();
    let mut seen = vec![usize::MAX; c.n_colours()];
    for n in 0..np.n_nodes() {
        np.patch(mesh, n, &mut patch);
        for &v in &patch {
            let k = colour[v as usize];
            if k != usize::MAX {
                assert_ne!(seen[k], n, "two vertices of colour {k} in node {n}'s patch");
                seen[k] = n;
            }
        }
    }
    let plain = two_material_cantilever(false);
    let plain_stepper = VbdStepper::new(&plain, VbdParams::default()).unwrap();
    let free: Vec<bool> = colour.iter().map(|&k| k != usize::MAX).collect();
    assert_eq!(
        plain_stepper.colouring(),
        &VertexColouring::greedy(plain.elastic_mesh(), &free)
    );
    eprintln!(
        "colours: {} with the formulation, {} without",
        c.n_colours(),
        plain_stepper.n_colours()
    );
}

/// With the formulation the sweeps stay bit-identical on 1, 2 and 4 threads: a 160 x 32
/// cantilever (10240 triangles, several chunks per colour and per measure pass) from a
/// sheared state, with a ground under its tip and the line search, and without it under
/// Chebyshev acceleration and the residual tolerance.
#[test]
fn averaged_nodal_pressure_vbd_is_bit_identical_across_thread_counts() {
    let mut model = incompressible_cantilever(EnergyKind::NeoHookean, 160, 32, true);
    let x: Vec<Vec2> = (model.mesh().vertices().iter())
        .map(|p| Vec2::new(p.x + 0.02 * p.y * p.x / 5.0, p.y - 0.015 * p.x * p.x / 25.0))
        .collect();
    let n = x.len();
    let start = State::new(&model, x.clone(), vec![Vec2::zeros(); n]).unwrap();
    let chebyshev = VbdParams {
        dt: 1e-2,
        iterations: 5,
        chebyshev_rho: 0.5,
        tolerance: 1e-6,
        ..VbdParams::default()
    };
    let runs = |model: &Model<AnyEnergy>, start: &State, params: VbdParams| {
        [1, 2, 4].map(|threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let stepper = VbdStepper::new(model, params).unwrap();
                let s = run(model, start, stepper, 3);
                (bits(&s.x), bits(&s.v))
            })
        })
    };
    let [one, two, four] = runs(&model, &start, chebyshev);
    assert_ne!(one.0, bits(&start.x), "nothing moved");
    assert!(
        one == two && one == four,
        "Chebyshev: the bits depend on the threads"
    );
    model
        .set_ground(Some(fem_solvers::Ground::horizontal(-0.02)))
        .unwrap();
    let start = State::new(&model, x, vec![Vec2::zeros(); n]).unwrap();
    let contact = VbdParams {
        dt: 1e-2,
        iterations: 5,
        line_search: true,
        ..VbdParams::default()
    };
    let [one, two, four] = runs(&model, &start, contact);
    assert!(
        one == two && one == four,
        "contact: the bits depend on the threads"
    );
}

/// A pinned beam (2 m x 0.2 m, nu = 0.49) with a free rigid block in its middle, of averaged
/// nodal pressure triangles when `averaged`.
fn beam_with_block(kind: EnergyKind, averaged: bool) -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams::new(2.0, 0.2, 20, 2)).unwrap();
    let energy = kind.build(incompressible_lame()).unwrap();
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
            u32::from((c.x - 1.2).abs() < 0.3)
        })
        .collect();
    let energies = ElementEnergies::new(vec![energy.clone(), energy], tags).unwrap();
    let masses = mesh.lumped_masses_from_density(10.0).unwrap();
    let mut model = Model::with_regions(mesh, energies, masses).unwrap();
    model.make_rigid(1, 10.0).unwrap();
    model.set_averaged_pressure(averaged).unwrap();
    model.set_standard_gravity();
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.2)))
        .unwrap();
    model
}

/// A free rigid body with the formulation: its block's gradient, 3x3 matrix and potential
/// include the nodes of the triangles it touches, so VBD (with and without the line search)
/// reaches implicit Euler's steps with the formulation, body pose included; on plain
/// triangles it ends far from them.
#[test]
fn a_free_rigid_body_with_the_averaged_nodal_pressure_triangle_reaches_implicit_euler() {
    for kind in [EnergyKind::NeoHookean, EnergyKind::StableNeoHookean] {
        let model = beam_with_block(kind, true);
        let plain = beam_with_block(kind, false);
        assert!(model.rigid_bodies()[0].is_free());
        let start = State::at_rest(&model);
        let reference = run(&model, &start, tight_implicit(&model, 1e-2), 5);
        for line_search in [false, true] {
            let params = VbdParams {
                iterations: 2000,
                line_search,
                ..VbdParams::default()
            };
            let s = run_vbd(&model, &start, 1e-2, params, 5);
            let p = run_vbd(&plain, &start, 1e-2, params, 5);
            let (g, pg) = (
                gap(&s, &reference, &start, &reference),
                gap(&p, &reference, &start, &reference),
            );
            let pose = (s.rigid[0].position - reference.rigid[0].position).norm()
                + (s.rigid[0].angle - reference.rigid[0].angle).abs();
            let moved = (reference.rigid[0].position - start.rigid[0].position).norm();
            eprintln!(
                "{kind}, line search {line_search}: gap {g:.2e}, pose {pose:.2e} (moved {moved:.2e} m), plain gap {pg:.2e}"
            );
            assert!(
                g < 1e-8 && pose < 1e-8 * moved.max(1e-3),
                "{kind}: {g:e} {pose:e}"
            );
            assert!(pg > 1e-3, "{kind}: plain {pg:e}");
        }
    }
}

/// A nearly incompressible block (1 kg, E = 10 kPa, nu = 0.49, 8 x 8 cells) with the
/// formulation dropped 2 cm onto the ground at 90 Hz (VBD, 20 sweeps, damping 2/s): no vertex
/// ever crosses the ground, and after 3 s it rests with the ground carrying its weight.
/// Measured: 9.8004 N, largest speed 1e-6 m/s.
#[test]
fn a_nearly_incompressible_block_with_averaged_pressure_rests_on_the_ground_under_vbd() {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 0.02],
        ..RectangleParams::new(1.0, 1.0, 8, 8)
    })
    .unwrap();
    let lame = Material::new(1e4, 0.49, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    let energy = EnergyKind::NeoHookean.build(lame).unwrap();
    let mut model = Model::with_total_mass(mesh, energy, 1.0).unwrap();
    model.set_standard_gravity();
    model
        .set_ground(Some(fem_solvers::Ground::horizontal(0.0)))
        .unwrap();
    model.set_averaged_pressure(true).unwrap();
    let params = VbdParams {
        dt: 1.0 / 90.0,
        iterations: 20,
        damping: 2.0,
        ..VbdParams::default()
    };
    let mut stepper = VbdStepper::new(&model, params).unwrap();
    let mut state = State::at_rest(&model);
    for _ in 0..270 {
        stepper.step(&model, &mut state).unwrap();
        assert_apart(&model, &state);
    }
    let speed = state.v.iter().map(|v| v.norm()).fold(0.0, Real::max);
    let total: Vec2 = (stepper.contacts().iter())
        .map(|c| c.normal * c.force)
        .sum();
    eprintln!(
        "block at rest: ground force {:.4} N, speed {speed:.1e} m/s",
        total.y
    );
    assert!(speed < 1e-2, "still moving at {speed} m/s");
    assert!(
        (total.y - 9.8).abs() < 0.01 * 9.8,
        "ground force {total:?} N, weight 9.8 N"
    );
}
