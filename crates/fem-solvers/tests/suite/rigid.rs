//! Rigid regions (bones) under every solver that moves them, against analytic answers.
//!
//! - **Series bar**: a bar (3 m x 0.2 m, left end pinned, a traction `t` on the right end, no
//!   gravity) whose middle third is rigid, co-rotational with `nu = 0`. As in the bimaterial
//!   test (`regions.rs`), `F = diag(1 + t / E, 1)` in each soft third is an exact equilibrium of
//!   the continuum and of the discrete model, and the rigid third translates by the left
//!   third's stretch without deforming: each soft third's strain is `t / E`. Tolerance 0.5 %
//!   of that strain, and the rigid third's vertices keep their rest distances to 1e-12 m (they
//!   are placed on one pose). PBD's stiffness is not the material's (it depends on `dt` and
//!   the iterations, paper case C): it is checked for rigidity only.
//! - **Spinning body**: a square with a rigid core and a soft shell, thrown and spinning, no
//!   gravity, damping or contact. Explicit conserves linear and angular momentum to round-off
//!   (the forces of every element sum to zero and so do their torques, and the body takes the
//!   sum); the tolerances of the others are in [`momentum_tolerance`].
//! - Solvers that do not move rigid regions refuse a free body in one line, and run a pinned
//!   one (its vertices are kinematic, as pinned vertices are to every solver).
//! - Free fall, thread independence and the explicit stability limit with a rigid region.

use fem_core::PlaneModel;
use fem_core::energy::{AnyEnergy, ElementEnergies, Energy, EnergyKind};
use fem_core::material::Material;
use fem_core::math::{Real, Vec2};
use fem_core::structured::{RectangleParams, rectangle};
use fem_solvers::{Model, Region, SolverKind, SolverParams, State, Stepper};

use crate::common::bits;

const LENGTH: Real = 3.0;
const SOFT: Real = 1.0e4;
const TRACTION: Real = 300.0;
const DENSITY: Real = 100.0;

fn corotational(e: Real, nu: Real) -> AnyEnergy {
    let lame = Material::new(e, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    EnergyKind::Corotational.build(lame).unwrap()
}

pub(crate) fn neo_hookean(e: Real, nu: Real) -> AnyEnergy {
    let lame = Material::new(e, nu, 1.0)
        .unwrap()
        .lame(PlaneModel::PlaneStrain);
    EnergyKind::NeoHookean.build(lame).unwrap()
}

/// A model of `mesh` whose triangles with `inside(centroid)` form region 1, both regions of
/// `energy` and density [`DENSITY`]; region 1 rigid when `rigid`.
pub(crate) fn with_region(
    mesh: fem_core::mesh::Mesh,
    energy: AnyEnergy,
    inside: impl Fn(Vec2) -> bool,
    rigid: bool,
) -> Model<AnyEnergy> {
    let tags: Vec<u32> = (0..mesh.n_triangles())
        .map(|t| {
            let c = mesh.gather(t, mesh.vertices()).iter().sum::<Vec2>() / 3.0;
            u32::from(inside(c))
        })
        .collect();
    let energies = ElementEnergies::new(vec![energy.clone(), energy], tags).unwrap();
    let densities = vec![DENSITY; mesh.n_triangles()];
    let masses = mesh.lumped_masses_from_densities(&densities).unwrap();
    let mut model = Model::with_regions(mesh, energies, masses).unwrap();
    if rigid {
        model.make_rigid(1, DENSITY).unwrap();
    }
    model
}

/// The series bar: middle third rigid, left end pinned, traction on the right end.
fn series_bar() -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams::new(LENGTH, 0.2, 30, 2)).unwrap();
    let third = LENGTH / 3.0;
    let mut model = with_region(
        mesh,
        corotational(SOFT, 0.0),
        |c| c.x > third && c.x < 2.0 * third,
        true,
    );
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.2)))
        .unwrap()
        .add_traction(
            &Region::in_box(Vec2::new(LENGTH, 0.0), Vec2::new(LENGTH, 0.2)),
            Vec2::new(TRACTION, 0.0),
        )
        .unwrap();
    model
}

/// The solvers that move rigid regions.
fn rigid_solvers() -> Vec<SolverKind> {
    (SolverKind::ALL.iter().copied())
        .filter(|k| k.capabilities().rigid_regions)
        .collect()
}

/// The mean x-displacement of the vertices on the line `x = at`.
fn ux_at<E: Energy>(model: &Model<E>, state: &State, at: Real) -> Real {
    let (mut sum, mut n) = (0.0, 0.0);
    for (v, p) in model.mesh().vertices().iter().enumerate() {
        if (p.x - at).abs() < 1e-9 {
            sum += state.x[v].x - p.x;
            n += 1.0;
        }
    }
    sum / n
}

/// The mean position of the vertices on the line `x = at`.
fn mean_at<E: Energy>(model: &Model<E>, state: &State, at: Real) -> Vec2 {
    let (mut sum, mut n) = (Vec2::zeros(), 0.0);
    for (v, p) in model.mesh().vertices().iter().enumerate() {
        if (p.x - at).abs() < 1e-9 {
            sum += state.x[v];
            n += 1.0;
        }
    }
    sum / n
}

/// Run `kind` on the series bar to rest; returns the state.
fn bar_at_rest(kind: SolverKind, model: &Model<AnyEnergy>) -> State {
    let mut p = kind.default_params();
    // Soft wave speed 10 m/s on 0.1 m elements: explicit needs dt < 1e-2.
    let (dt, steps) = match kind {
        SolverKind::Explicit => (1e-3, 8_000),
        SolverKind::Static => (1.0, 1),
        _ => (1e-2, 800),
    };
    p.set_dt(dt);
    let damping = 20.0;
    match &mut p {
        SolverParams::Explicit(x) => x.damping = damping,
        // Converged steps (Newton's tolerance alone, no velocity tolerance): the analytic
        // strain is the converged equilibrium's.
        SolverParams::Implicit(x) => (x.damping, x.velocity_tolerance) = (damping, 0.0),
        SolverParams::LinearImplicit(x) => x.damping = damping,
        SolverParams::Static(_) => {}
        SolverParams::Pbd(x) => (x.iterations, x.damping) = (50, damping),
        SolverParams::Xpbd(x) => (x.substeps, x.iterations, x.damping) = (10, 20, damping),
        SolverParams::Vbd(x) => (x.iterations, x.damping) = (100, damping),
        SolverParams::Pd(x) => (x.iterations, x.damping) = (200, damping),
        SolverParams::QuasiNewton(x) => (x.iterations, x.damping) = (200, damping),
        _ => panic!("{kind}: no settings for this solver in the series bar"),
    }
    let mut stepper = p.build(model).unwrap();
    let mut state = State::at_rest(model);
    let steps = match &p {
        SolverParams::Static(s) => s.load_steps,
        _ => steps,
    };
    for _ in 0..steps {
        stepper
            .step(model, &mut state)
            .unwrap_or_else(|e| panic!("{kind}: step {} failed: {e}", state.step));
    }
    state
}

/// The largest change of a distance between two vertices of body `b`, m.
pub(crate) fn rigidity_error<E: Energy>(model: &Model<E>, state: &State, b: usize) -> Real {
    let body = &model.rigid_bodies()[b];
    let x0 = model.mesh().vertices();
    let mut worst: Real = 0.0;
    for &i in &body.vertices {
        for &j in &body.vertices {
            let (i, j) = (i as usize, j as usize);
            let d = (state.x[i] - state.x[j]).norm() - (x0[i] - x0[j]).norm();
            worst = worst.max(d.abs());
        }
    }
    worst
}

#[test]
fn a_bar_with_a_rigid_middle_third_has_the_soft_thirds_analytic_strain() {
    let model = series_bar();
    assert_eq!(model.rigid_bodies().len(), 1);
    let third = LENGTH / 3.0;
    let want = TRACTION / SOFT;
    let solvers = rigid_solvers();
    assert!(solvers.contains(&SolverKind::Explicit));
    for kind in solvers {
        let state = bar_at_rest(kind, &model);
        let rigid = rigidity_error(&model, &state, 0);
        assert!(
            rigid < 1e-12,
            "{kind}: the rigid third deformed by {rigid:e} m"
        );
        let u1 = ux_at(&model, &state, third);
        let u2 = ux_at(&model, &state, 2.0 * third);
        let u3 = ux_at(&model, &state, LENGTH);
        // The middle third's stretch from the distance between its end lines' mean positions
        // (a small tilt of the bar, as XPBD's iterations leave, is no stretch).
        let gap = (mean_at(&model, &state, 2.0 * third) - mean_at(&model, &state, third)).norm();
        let (left, middle, right) = (u1 / third, gap / third - 1.0, (u3 - u2) / third);
        eprintln!(
            "{kind}: strains {left:.6e} / {middle:.3e} / {right:.6e} (analytic {want:.6e} / 0 / {want:.6e}); rigid third kept its distances to {rigid:.1e} m"
        );
        if kind == SolverKind::Pbd {
            continue;
        }
        let err = ((left - want) / want)
            .abs()
            .max(((right - want) / want).abs());
        assert!(err < 5e-3, "{kind}: relative strain error {err:e}");
        assert!(
            middle.abs() < 1e-9,
            "{kind}: the rigid third stretched by {middle:e}"
        );
    }
}

/// A 1 m square (16 x 16 cells) whose central 0.4 m square is rigid, Neo-Hookean
/// (E = 1e4 Pa, nu = 0.3), thrown at (1, 2) m/s and spinning at 3 rad/s about its centre.
fn spinning_body() -> (Model<AnyEnergy>, State) {
    let mesh = rectangle(&RectangleParams::new(1.0, 1.0, 16, 16)).unwrap();
    let model = with_region(
        mesh,
        neo_hookean(1.0e4, 0.3),
        |c| (c.x - 0.5).abs() < 0.2 && (c.y - 0.5).abs() < 0.2,
        true,
    );
    let (v0, omega, c) = (Vec2::new(1.0, 2.0), 3.0, Vec2::new(0.5, 0.5));
    let spin = |p: Vec2| v0 + Vec2::new(-(p.y - c.y), p.x - c.x) * omega;
    let x = model.mesh().vertices().to_vec();
    let v: Vec<Vec2> = x.iter().map(|&p| spin(p)).collect();
    let mut state = State::new(&model, x, v).unwrap();
    for (body, b) in model.rigid_bodies().iter().zip(state.rigid.iter_mut()) {
        b.velocity = spin(body.centroid);
        b.angular_velocity = omega;
    }
    let rigid = state.rigid.clone();
    for (body, b) in model.rigid_bodies().iter().zip(&rigid) {
        body.place(b, &mut state.x, &mut state.v);
    }
    (model, state)
}

/// Linear and angular momentum (about the origin) of the soft vertices and the bodies.
fn momentum<E: Energy>(model: &Model<E>, state: &State) -> (Vec2, Real) {
    let cross = |a: Vec2, b: Vec2| a.x * b.y - a.y * b.x;
    let (mut p, mut l) = (Vec2::zeros(), 0.0);
    for (v, (x, u)) in state.x.iter().zip(&state.v).enumerate() {
        if model.rigid_body_of(v).is_none() {
            let m = model.masses()[v];
            p += u * m;
            l += m * cross(*x, *u);
        }
    }
    for (body, b) in model.rigid_bodies().iter().zip(&state.rigid) {
        p += b.velocity * body.mass;
        l += body.mass * cross(b.position, b.velocity) + body.inertia * b.angular_velocity;
    }
    (p, l)
}

/// How far each solver's momenta may drift over the spinning body's 0.2 s, relative to their
/// start. Explicit: round-off. Implicit Euler conserves linear momentum to the Newton
/// tolerance, and angular momentum only up to `h sum m v_{n+1} x v_n` per step (its update is
/// not symmetric in time).
fn momentum_tolerance(kind: SolverKind) -> (Real, Real) {
    match kind {
        SolverKind::Explicit => (1e-12, 1e-12),
        // Implicit Euler: linear momentum to the Newton tolerance (measured 4.9e-15), angular
        // up to its own asymmetry (measured 1.7e-3 over the run). VBD's 10 sweeps a step leave
        // the internal forces slightly unbalanced (measured 5.2e-12); its angular drift is
        // implicit Euler's (measured 1.7e-3).
        // Linearly implicit Euler's one linear solve a step balances the internal forces to
        // round-off (measured 9.0e-15; angular 1.7e-3, implicit Euler's).
        SolverKind::Implicit | SolverKind::Vbd | SolverKind::LinearImplicit => (1e-9, 5e-3),
        // Quasi-Newton's steps stop at Newton's tolerance (measured 5.2e-15; angular 1.7e-3,
        // implicit Euler's).
        SolverKind::QuasiNewton => (1e-9, 5e-3),
        // PBD and XPBD: every correction is mass-weighted and a constraint's gradients sum to
        // zero, so linear momentum keeps to round-off (measured 4.5e-13 and 2.1e-13); velocities
        // from positions drift angular momentum by O(h), like implicit Euler (measured 1.7e-3).
        SolverKind::Pbd | SolverKind::Xpbd => (1e-11, 5e-3),
        _ => (1e-6, 2e-2),
    }
}

#[test]
fn a_spinning_body_with_a_rigid_core_conserves_momentum() {
    let (model, start) = spinning_body();
    assert_eq!(model.rigid_bodies().len(), 1);
    let (p0, l0) = momentum(&model, &start);
    for kind in rigid_solvers() {
        let mut p = kind.default_params();
        if kind == SolverKind::Static {
            continue;
        }
        // Soft wave speed 1.2e1 m/s... on 1/16 m elements: explicit's limit is about 2e-3 s.
        let (dt, steps) = match kind {
            SolverKind::Explicit => (2e-4, 1000),
            _ => (2e-3, 100),
        };
        p.set_dt(dt);
        let mut stepper = p.build(&model).unwrap();
        let mut state = start.clone();
        let (mut dp, mut dl): (Real, Real) = (0.0, 0.0);
        for _ in 0..steps {
            stepper.step(&model, &mut state).unwrap();
            let (p1, l1) = momentum(&model, &state);
            dp = dp.max((p1 - p0).norm() / p0.norm());
            dl = dl.max((l1 - l0).abs() / l0.abs());
        }
        let rigid = rigidity_error(&model, &state, 0);
        eprintln!(
            "{kind}: linear momentum drift {dp:.2e}, angular {dl:.2e} (relative), body turned {:.3} rad, rigid to {rigid:.1e} m",
            state.rigid[0].angle
        );
        let (tp, tl) = momentum_tolerance(kind);
        assert!(dp < tp, "{kind}: linear momentum drifted by {dp:e}");
        assert!(dl < tl, "{kind}: angular momentum drifted by {dl:e}");
        assert!(rigid < 1e-12, "{kind}: the core deformed by {rigid:e} m");
        assert!(state.rigid[0].angle > 0.5, "{kind}: the core did not turn");
    }
}

#[test]
fn solvers_without_rigid_regions_refuse_a_free_body_and_run_a_pinned_one() {
    let model = series_bar();
    let mut pinned = series_bar();
    // A pin box through the rigid third holds the whole body.
    pinned
        .pin(&Region::in_box(Vec2::new(1.45, 0.0), Vec2::new(1.55, 0.2)))
        .unwrap();
    assert!(!pinned.rigid_bodies()[0].is_free());
    for kind in SolverKind::ALL {
        if !kind.capabilities().rigid_regions {
            let err = kind.default_params().build(&model).unwrap_err().to_string();
            eprintln!("{kind}: {err}");
            assert!(!err.contains('\n'), "{kind}: one line: {err}");
            assert!(
                err.contains(kind.name()) && err.contains("rigid") && err.contains("explicit"),
                "{kind}: {err}"
            );
        }
        let mut p = kind.default_params();
        p.set_dt(1e-3);
        let mut stepper = p.build(&pinned).unwrap();
        let mut state = State::at_rest(&pinned);
        for _ in 0..5 {
            stepper.step(&pinned, &mut state).unwrap();
        }
        let body = &pinned.rigid_bodies()[0];
        for &v in &body.vertices {
            let v = v as usize;
            assert_eq!(
                state.x[v],
                pinned.mesh().vertices()[v],
                "{kind}: vertex {v}"
            );
        }
        assert_eq!(state.rigid[0], body.initial_state(), "{kind}");
    }
}

#[test]
fn a_rigid_region_falls_freely_with_the_body() {
    // Discrete free fall of symplectic and implicit Euler: y_n = -g dt^2 n (n + 1) / 2.
    let mesh = rectangle(&RectangleParams::new(1.0, 0.2, 10, 2)).unwrap();
    let mut model = with_region(mesh, neo_hookean(1.0e4, 0.3), |c| c.x > 0.5, true);
    model.set_standard_gravity();
    let (dt, n) = (1e-3, 200);
    let want = -9.8 * dt * dt * (n * (n + 1)) as Real / 2.0;
    for kind in rigid_solvers() {
        if kind == SolverKind::Static {
            continue;
        }
        let mut p = kind.default_params();
        p.set_dt(dt);
        let mut stepper = p.build(&model).unwrap();
        let mut state = State::at_rest(&model);
        for _ in 0..n {
            stepper.step(&model, &mut state).unwrap();
        }
        let mut worst: Real = 0.0;
        for (v, x) in state.x.iter().enumerate() {
            let u = x - model.mesh().vertices()[v];
            worst = worst.max(u.x.abs()).max((u.y - want).abs());
        }
        let b = &state.rigid[0];
        let body = &model.rigid_bodies()[0];
        worst = worst
            .max((b.position.y - body.centroid.y - want).abs())
            .max(b.angle.abs());
        eprintln!("{kind}: free fall within {worst:.1e} m of y = {want:.6e} m");
        assert!(worst < 1e-9, "{kind}: {worst:e}");
    }
}

#[test]
fn rigid_regions_give_the_same_bits_on_1_2_and_4_threads() {
    let mesh = rectangle(&RectangleParams::new(4.0, 1.0, 80, 20)).unwrap();
    let mut model = with_region(
        mesh,
        neo_hookean(1.0e4, 0.3),
        |c| (c.x - 1.0).abs() < 0.4 && (c.y - 0.5).abs() < 0.3 || (c.x - 3.0).abs() < 0.3,
        true,
    );
    assert_eq!(model.rigid_bodies().len(), 2);
    model.set_standard_gravity();
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    for kind in rigid_solvers() {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut p = kind.default_params();
                p.set_dt(if kind == SolverKind::Explicit {
                    1e-4
                } else {
                    5e-3
                });
                let mut stepper = p.build(&model).unwrap();
                let mut state = State::at_rest(&model);
                for _ in 0..10 {
                    stepper.step(&model, &mut state).unwrap();
                }
                state
            })
        };
        let one = run(1);
        for threads in [2, 4] {
            let other = run(threads);
            assert_eq!(bits(&one.x), bits(&other.x), "{kind}: {threads} threads");
            assert_eq!(one.rigid, other.rigid, "{kind}: {threads} threads");
            assert_eq!(one.digest(), other.digest(), "{kind}: {threads} threads");
        }
    }
}

#[test]
fn the_explicit_stability_limit_ignores_rigid_triangles() {
    // A stiff region (100 E) sets the step when elastic; made rigid, the soft tissue does.
    let mesh = || rectangle(&RectangleParams::new(2.0, 0.2, 20, 2)).unwrap();
    let stiff_half = |c: Vec2| c.x > 1.0;
    let soft = with_region(mesh(), neo_hookean(SOFT, 0.3), stiff_half, false);
    let tags: Vec<u32> = (0..soft.mesh().n_triangles())
        .map(|t| u32::from(soft.energies().tag(t) == 1))
        .collect();
    let energies = ElementEnergies::new(
        vec![neo_hookean(SOFT, 0.3), neo_hookean(100.0 * SOFT, 0.3)],
        tags,
    )
    .unwrap();
    let masses = soft.masses().to_vec();
    let mut stiff = Model::with_regions(mesh(), energies, masses).unwrap();
    let elastic = stiff.elastic_critical_time_step();
    stiff.make_rigid(1, DENSITY).unwrap();
    let rigid = stiff.elastic_critical_time_step();
    let uniform = soft.elastic_critical_time_step();
    eprintln!(
        "critical step: stiff half elastic {elastic:.3e} s, rigid {rigid:.3e} s, all soft {uniform:.3e} s"
    );
    assert!(rigid > 9.0 * elastic, "{rigid} against {elastic}");
    assert!(rigid >= uniform, "{rigid} against {uniform}");
}

#[test]
fn make_rigid_checks_its_input() {
    let mesh = rectangle(&RectangleParams::new(1.0, 0.2, 10, 2)).unwrap();
    let mut model = with_region(mesh, neo_hookean(1.0e4, 0.3), |c| c.x > 0.5, false);
    let e = model.make_rigid(2, DENSITY).unwrap_err().to_string();
    assert!(
        e.contains("regions[2]") && e.contains("no such region"),
        "{e}"
    );
    let e = model.make_rigid(1, -1.0).unwrap_err().to_string();
    assert!(e.contains("regions[1].density"), "{e}");
    model.make_rigid(1, DENSITY).unwrap();
    let e = model.make_rigid(0, DENSITY).unwrap_err().to_string();
    assert!(e.contains("every triangle rigid"), "{e}");
    assert_eq!(model.rigid_regions(), &[(1, DENSITY)]);
    // Mass is neither lost nor made: the soft vertices and the body weigh the lumped total.
    let free: Real = (0..model.mesh().n_vertices())
        .filter(|&v| model.rigid_body_of(v).is_none())
        .map(|v| model.masses()[v])
        .sum();
    let bodies: Real = model.rigid_bodies().iter().map(|b| b.mass).sum();
    let total: Real = model.masses().iter().sum();
    assert!((free + bodies - total).abs() < 1e-12 * total);
}

/// A cantilever (2 m x 0.4 m, 20 x 4 cells, left end pinned,
/// Neo-Hookean E = 1e4 Pa) with a rigid block in its outer half: free, hanging from the soft
/// root.
pub(crate) fn cantilever_with_a_rigid_block() -> Model<AnyEnergy> {
    let mesh = rectangle(&RectangleParams::new(2.0, 0.4, 20, 4)).unwrap();
    let mut model = with_region(
        mesh,
        neo_hookean(1.0e4, 0.3),
        |c| c.x > 1.2 && c.x < 1.8,
        true,
    );
    model
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.4)))
        .unwrap()
        .set_standard_gravity();
    model
}

/// How far each solver's rollout of [`cantilever_with_a_rigid_block`] may end from implicit
/// Euler's (Newton tolerance 1e-12), over the reference's largest displacement, and why. The
/// same reasons as the stepper battery's (`battery.rs`).
fn rollout_tolerance(kind: SolverKind) -> Real {
    match kind {
        // Both first order in dt, their errors of opposite sign: O(dt) apart (measured 5.4e-4).
        SolverKind::Explicit => 5e-3,
        // No material limit: PBD is nearly rigid at this step; only "does not run away".
        SolverKind::Pbd => 1.05,
        // 10 iterations approximate the implicit Euler step; the dropped primal residual
        // (measured 1.7e-5).
        SolverKind::Xpbd => 1e-4,
        // Quadratic convergence: the reference at a tighter tolerance.
        SolverKind::Implicit => 1e-9,
        // 10 sweeps a step of 0.25 ms converge the step nearly to round-off (measured 3.5e-11).
        SolverKind::Vbd => 1e-6,
        // One Newton iteration a step, off implicit Euler's solution by the square of the
        // step's motion (measured 2.0e-5).
        SolverKind::LinearImplicit => 1e-4,
        // At most 10 L-BFGS iterations a step, stopped at Newton's tolerance 1e-8 (measured
        // 7.1e-11).
        SolverKind::QuasiNewton => 1e-8,
        _ => 0.0,
    }
}

#[test]
fn with_a_rigid_block_every_solver_stays_near_implicit_euler() {
    let model = cantilever_with_a_rigid_block();
    assert_eq!(model.rigid_bodies().len(), 1);
    let (dt, t_end): (Real, Real) = (2.5e-4, 0.4);
    let steps = (t_end / dt).round() as usize;
    let run = |kind: SolverKind, tolerance: Option<Real>| {
        let mut p = kind.default_params();
        p.set_dt(dt);
        if let (SolverParams::Implicit(p), Some(tol)) = (&mut p, tolerance) {
            p.newton.tolerance = tol;
        }
        let mut stepper = p.build(&model).unwrap();
        let mut state = State::at_rest(&model);
        for _ in 0..steps {
            stepper
                .step(&model, &mut state)
                .unwrap_or_else(|e| panic!("{kind}: {e}"));
        }
        state
    };
    let reference = run(SolverKind::Implicit, Some(1e-12));
    let reach = (0..model.mesh().n_vertices())
        .map(|v| reference.displacement(&model, v).norm())
        .fold(0.0, Real::max);
    assert!(reach > 0.05, "the cantilever sags: {reach} m");
    for kind in rigid_solvers() {
        if kind == SolverKind::Static {
            continue;
        }
        let state = run(kind, None);
        let d = (state.x.iter().zip(&reference.x))
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max)
            / reach;
        let rigid = rigidity_error(&model, &state, 0);
        eprintln!(
            "{kind}: {d:.3e} of implicit Euler's largest displacement ({reach:.4e} m) from it; block rigid to {rigid:.1e} m"
        );
        assert!(rigid < 1e-12, "{kind}: the block deformed by {rigid:e} m");
        assert!(
            d <= rollout_tolerance(kind),
            "{kind}: {d:e} from implicit Euler"
        );
    }
}

#[test]
fn with_a_rigid_block_no_solver_writes_a_non_finite_state() {
    // The battery's failure scene: stretched threefold under 1e8 g, steps of 50 ms.
    let mut model = cantilever_with_a_rigid_block();
    model.set_gravity(Vec2::new(0.0, -9.8e8)).unwrap();
    for kind in rigid_solvers() {
        let mut p = kind.default_params();
        p.set_dt(5e-2);
        let mut stepper = p.build(&model).unwrap();
        let x: Vec<Vec2> = (model.mesh().vertices().iter())
            .map(|p| Vec2::new(3.0 * p.x, p.y))
            .collect();
        let v = vec![Vec2::zeros(); x.len()];
        let mut state = State::new(&model, x, v).unwrap();
        // The block moves with the stretch (rigidly: its centroid goes where the stretch
        // takes it).
        let body = &model.rigid_bodies()[0];
        state.rigid[0].position.x *= 3.0;
        let b = state.rigid[0];
        body.place(&b, &mut state.x, &mut state.v);
        let finite = |s: &State| {
            s.x.iter()
                .chain(&s.v)
                .all(|p| p.x.is_finite() && p.y.is_finite())
                && s.rigid.iter().all(|b| {
                    b.position.x.is_finite()
                        && b.position.y.is_finite()
                        && b.angle.is_finite()
                        && b.velocity.x.is_finite()
                        && b.velocity.y.is_finite()
                        && b.angular_velocity.is_finite()
                })
        };
        let mut outcome = "40 steps, every state finite".to_string();
        for _ in 0..40 {
            let before = state.clone();
            match stepper.step(&model, &mut state) {
                Ok(_) => assert!(finite(&state), "{kind}: a step wrote a non-finite value"),
                Err(e) => {
                    assert_eq!(state, before, "{kind}: a failed step changed the state");
                    outcome = format!("failed at step {}: {e}", state.step);
                    break;
                }
            }
        }
        eprintln!("{kind}: {outcome}");
    }
}
