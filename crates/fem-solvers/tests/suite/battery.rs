//! The stepper battery, applied to every solver of the registry by one macro.
//!
//! Each solver is built through the registry ([`SolverKind::default_params`], `set_dt`,
//! [`SolverParams::build`]) and held as an [`AnyStepper`], so the battery sees exactly what a
//! scene runs. For each solver:
//! - **free fall** (time-stepping solvers): a free body under gravity with no elastic strain
//!   follows the scheme's discrete free fall `y_n = -g dt^2 n (n + 1) / 2` (symplectic and
//!   implicit Euler alike, and PBD/XPBD whose constraints all rest) to round-off: within
//!   `1e-9` m over 200 steps of 1 ms (measured 1e-12 m at worst); **equilibrium** (load-factor
//!   solvers): an anchored cantilever under gravity ends at exactly `t = 1`, at rest, with an
//!   independently assembled force imbalance below the Newton tolerance times the load;
//! - **never non-finite**: driven to failure (an anchored Neo-Hookean beam stretched threefold
//!   under 1e8 g, steps of 50 ms: every solver fails, by a non-finite value, Newton or a load
//!   increment), every state after every step is finite, and the step that fails leaves the
//!   state exactly as it was;
//! - **thread independence**: bit-identical states (positions, velocities, bodies, clock) on
//!   1, 2 and 4 rayon threads, on a 10240-triangle mesh whose parallel paths split into many
//!   chunks, with a ground and a dynamic obstacle for the solvers that handle contact;
//! - **no energy growth**: from a 20 % stretch with no load and no damping, kinetic plus
//!   elastic energy never exceeds its start by more than the tolerance written in the
//!   solver's line (round-off for the solvers that dissipate by construction);
//! - **rollout**: a cantilever sagging under gravity (0.4 s in steps of 0.25 ms) stays within
//!   the distance written in the solver's line of the implicit Euler rollout; the static
//!   solver's equilibrium is compared with a long, damped implicit rollout. The distance is
//!   the largest vertex distance over the reference's largest displacement.
//!
//! A test checks that the macro's list is [`SolverKind::ALL`], so a new solver fails the suite
//! until its line is added here.
//!
//! **BDF2** ([`Integrator::Bdf2`]): every solver with an `integrator` parameter also runs the
//! free fall (BDF2's discrete one, its first step backward Euler:
//! `y_n = -g dt^2 (n^2 / 2 + 3/4 (1 - 3^-n))`, `v_n = -g dt n`) and the thread independence
//! (three of its four steps BDF2, with the dynamic obstacle under contact) under BDF2; a test
//! checks that the second list is the solvers with the parameter.

use crate::common::{bits, lame};
use fem_core::assembly::{Scratch, populate_forces};
use fem_core::energy::{AnyEnergy, Energy, EnergyKind};
use fem_core::math::{Real, Vec2};
use fem_solvers::diagnostics::{EnergyScratch, energies};
use fem_solvers::testing::beam_mesh;
use fem_solvers::{
    AnyStepper, Clock, Ground, Integrator, Model, ObstacleMotion, Region, SolverKind, SolverParams,
    State, Stepper,
};

/// The stepper of `kind` for `model`, with time step `dt` (ignored by load-factor solvers) and
/// the defaults otherwise, after `tweak`.
fn build<E: Energy>(
    kind: SolverKind,
    model: &Model<E>,
    dt: Real,
    tweak: impl FnOnce(&mut SolverParams),
) -> AnyStepper {
    let mut p = kind.default_params();
    p.set_dt(dt);
    tweak(&mut p);
    p.build(model)
        .unwrap_or_else(|e| panic!("{kind}: cannot build: {e}"))
}

/// The energy the battery runs `kind` with: Neo-Hookean, or co-rotational for Projective
/// Dynamics (which runs that energy only; its rollout reference is implicit Euler of the same
/// energy).
fn energy_for(kind: SolverKind) -> EnergyKind {
    if kind == SolverKind::Pd {
        EnergyKind::Corotational
    } else {
        EnergyKind::NeoHookean
    }
}

/// A beam of `nx` x `ny` cells (5 m x 1 m) with Young's modulus `e`, 1 kg, in `kind`'s energy.
fn beam(kind: SolverKind, nx: usize, ny: usize, e: Real) -> Model<AnyEnergy> {
    let energy = energy_for(kind).build(lame(e)).unwrap();
    Model::with_total_mass(beam_mesh(nx, ny).unwrap(), energy, 1.0).unwrap()
}

/// The same beam with its left edge pinned.
fn anchored(kind: SolverKind, nx: usize, ny: usize, e: Real) -> Model<AnyEnergy> {
    let mut m = beam(kind, nx, ny, e);
    m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))
        .unwrap();
    m
}

/// The model's rest shape mapped by `f`, at rest.
fn deformed<E: Energy>(model: &Model<E>, f: impl Fn(Vec2) -> Vec2) -> State {
    let x = model.mesh().vertices().iter().map(|&p| f(p)).collect();
    State::new(model, x, vec![Vec2::zeros(); model.mesh().n_vertices()]).unwrap()
}

fn all_finite(s: &State) -> bool {
    s.x.iter()
        .chain(&s.v)
        .all(|p| p.x.is_finite() && p.y.is_finite())
        && s.bodies.iter().all(|b| {
            b.position.x.is_finite()
                && b.position.y.is_finite()
                && b.velocity.x.is_finite()
                && b.velocity.y.is_finite()
                && b.angle.is_finite()
                && b.angular_velocity.is_finite()
        })
        && s.t.is_finite()
}

/// `state` stepped by `stepper` until the clock reaches `t_end` (to within half a step).
fn run_until<E: Energy>(
    kind: SolverKind,
    stepper: &mut AnyStepper,
    model: &Model<E>,
    state: &mut State,
    t_end: Real,
) {
    let half = 0.5 * stepper.dt();
    while state.t < t_end - half {
        stepper
            .step(model, state)
            .unwrap_or_else(|e| panic!("{kind}: step {} failed: {e}", state.step));
    }
}

/// `p` with integrator `integrator` (backward Euler: unchanged, whether the solver has the
/// choice or not).
fn with_integrator(p: &mut SolverParams, integrator: Integrator) {
    if integrator != Integrator::BackwardEuler {
        assert!(
            p.set_integrator(integrator),
            "{:?}: no integrator",
            p.kind()
        );
    }
}

/// (a) for time-stepping solvers: exact discrete free fall (BDF2's, after a backward Euler
/// first step, under `Integrator::Bdf2`: also the velocities, exact).
fn free_fall(kind: SolverKind, integrator: Integrator) {
    let g = 9.8;
    let mut model = beam(kind, 10, 2, 1000.0);
    model.set_standard_gravity();
    let dt = 1e-3;
    let mut stepper = build(kind, &model, dt, |p| with_integrator(p, integrator));
    let mut state = State::at_rest(&model);
    let mut worst: Real = 0.0;
    for n in 1..=200i32 {
        stepper.step(&model, &mut state).unwrap();
        let nf = Real::from(n);
        let exact = match integrator {
            Integrator::Bdf2 => {
                for w in &state.v {
                    worst = worst.max(w.x.abs()).max((w.y + g * dt * nf).abs());
                }
                -g * dt * dt * (nf * nf / 2.0 + 0.75 * (1.0 - Real::powi(3.0, -n)))
            }
            _ => -g * dt * dt * nf * (nf + 1.0) / 2.0,
        };
        for v in 0..model.mesh().n_vertices() {
            let u = state.displacement(&model, v);
            worst = worst.max(u.x.abs()).max((u.y - exact).abs());
        }
    }
    eprintln!("{kind} {integrator}: free fall off by {worst:.3e} m after 0.2 s");
    assert!(
        worst < 1e-9,
        "{kind} {integrator}: free fall off by {worst:e} m"
    );
}

/// (a) for load-factor solvers: an anchored cantilever reaches equilibrium at `t = 1`.
fn equilibrium(kind: SolverKind) {
    let mut model = anchored(kind, 20, 4, 1000.0);
    model.set_standard_gravity();
    let mut stepper = build(kind, &model, 0.0, |_| {});
    let mut state = State::at_rest(&model);
    let mut steps = 0;
    while state.t < 1.0 {
        stepper.step(&model, &mut state).unwrap();
        steps += 1;
        assert!(steps <= 1000, "{kind}: no end");
    }
    assert_eq!(state.t, 1.0);
    // The force imbalance on the free vertices, assembled independently of the solver.
    let mut f = vec![Vec2::zeros(); model.mesh().n_vertices()];
    populate_forces(
        model.mesh(),
        model.energies(),
        &state.x,
        &mut f,
        &mut Scratch::new(),
    );
    let pinned: Vec<usize> = model.kinematics().vertices().collect();
    let (mut residual, mut load) = (0.0, 0.0);
    for (v, (fv, m)) in f.iter().zip(model.masses()).enumerate() {
        if pinned.binary_search(&v).is_err() {
            residual += (fv + *m * model.gravity()).norm_squared();
        }
        // Newton's force scale: the norm of the whole external load.
        load += (*m * model.gravity()).norm_squared();
    }
    let (residual, load) = (Real::sqrt(residual), Real::sqrt(load));
    let tolerance = match kind.default_params() {
        SolverParams::Static(p) => p.newton.tolerance,
        _ => unreachable!("only the static solver runs on the load factor"),
    };
    eprintln!("{kind}: residual {residual:.3e} N under a load of {load:.3e} N");
    assert!(
        residual <= tolerance * load,
        "{kind}: residual {residual:e} N"
    );
    assert!(state.v.iter().all(|v| *v == Vec2::zeros()));
}

/// (b) A step never writes a non-finite value; a failed step leaves the state as it was. A
/// solver that runs the scene without failing says why (`survives`): then every state it
/// wrote is checked finite and its largest stretch is printed.
fn never_non_finite(kind: SolverKind, survives: Option<&str>) {
    let mut model = anchored(kind, 20, 4, 1000.0);
    model.set_gravity(Vec2::new(0.0, -9.8e8)).unwrap();
    let mut stepper = build(kind, &model, 5e-2, |_| {});
    let mut state = deformed(&model, |p| Vec2::new(3.0 * p.x, p.y));
    let mut failure = None;
    for _ in 0..40 {
        let before = state.clone();
        match stepper.step(&model, &mut state) {
            Ok(_) => assert!(
                all_finite(&state),
                "{kind}: a step wrote a non-finite value"
            ),
            Err(e) => {
                assert_eq!(state, before, "{kind}: a failed step changed the state");
                assert!(all_finite(&state));
                failure = Some(format!("failed at step {}: {e}", state.step));
                break;
            }
        }
    }
    // The scene is extreme enough that every solver but those that say why fails, so the
    // error path is exercised.
    match (failure, survives) {
        (Some(failure), None) => eprintln!("{kind}: {failure}"),
        (None, Some(why)) => {
            let reach = state.x.iter().map(|p| p.norm()).fold(0.0, Real::max);
            eprintln!(
                "{kind}: 40 steps, every state finite, farthest vertex at {reach:.3e} m ({why})"
            );
        }
        (Some(failure), Some(_)) => panic!("{kind}: said to survive, but {failure}"),
        (None, None) => panic!("{kind}: not driven to failure in 40 steps"),
    }
}

/// (c) Bit-identical states on 1, 2 and 4 threads.
fn thread_independent(kind: SolverKind, integrator: Integrator) {
    let mut model = anchored(kind, 160, 32, 1000.0);
    model.set_standard_gravity();
    if kind.capabilities().contact {
        // Half a millimetre below the sheared start's lowest vertex (-0.015 m): within the
        // barrier's reach, clear of the start.
        model.set_ground(Some(Ground::horizontal(-0.0155))).unwrap();
        model
            .add_obstacle(
                &[
                    Vec2::new(3.0, 1.02),
                    Vec2::new(4.0, 1.02),
                    Vec2::new(4.0, 1.2),
                    Vec2::new(3.0, 1.2),
                ],
                ObstacleMotion::Dynamic {
                    mass: 0.3,
                    rotates: true,
                },
            )
            .unwrap();
    }
    assert!(model.mesh().n_triangles() >= 5000);
    // Sheared so every vertex moves and every element is strained.
    let start = deformed(&model, |p| {
        Vec2::new(p.x + 0.02 * p.y * p.x / 5.0, p.y - 0.015 * p.x * p.x / 25.0)
    });
    let steps = match kind.capabilities().clock {
        Clock::Time => 4,
        Clock::LoadFactor => 1,
    };
    let run_on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut stepper = build(kind, &model, 1e-4, |p| with_integrator(p, integrator));
            let mut s = start.clone();
            for _ in 0..steps {
                stepper.step(&model, &mut s).unwrap();
            }
            s
        })
    };
    let one = run_on(1);
    assert_ne!(bits(&one.x), bits(&start.x), "{kind}: nothing moved");
    for threads in [2, 4] {
        let other = run_on(threads);
        assert!(
            bits(&one.x) == bits(&other.x),
            "{kind}: positions differ on {threads} threads"
        );
        assert!(
            bits(&one.v) == bits(&other.v),
            "{kind}: velocities differ on {threads} threads"
        );
        assert_eq!(one.bodies, other.bodies, "{kind}: bodies differ");
        assert_eq!(one.t.to_bits(), other.t.to_bits(), "{kind}: clocks differ");
    }
}

/// (d) Kinetic plus elastic energy does not grow without load or damping.
fn no_energy_growth(kind: SolverKind, tolerance: Real, why: &str) {
    let model = anchored(kind, 20, 4, 1000.0);
    let mut stepper = build(kind, &model, 5e-4, |_| {});
    let mut state = deformed(&model, |p| Vec2::new(1.2 * p.x, p.y));
    let mut scratch = EnergyScratch::default();
    let total = |s: &State, scratch: &mut EnergyScratch| {
        let e = energies(&model, s, scratch);
        e.kinetic + e.elastic
    };
    let e0 = total(&state, &mut scratch);
    let mut worst: Real = 0.0;
    let mut steps = 0;
    while state.t
        < match kind.capabilities().clock {
            Clock::Time => 0.5,
            Clock::LoadFactor => 1.0,
        }
    {
        stepper.step(&model, &mut state).unwrap();
        worst = worst.max(total(&state, &mut scratch) / e0 - 1.0);
        steps += 1;
    }
    let end = total(&state, &mut scratch) / e0;
    eprintln!(
        "{kind}: energy grew at most {worst:.3e} (relative) over {steps} steps; ends at {end:.3e} of its start"
    );
    assert!(
        worst <= tolerance,
        "{kind}: energy grew by {worst:e}, more than {tolerance:e} ({why})"
    );
}

/// The largest vertex distance between two states over the largest displacement of `reference`.
fn relative_distance<E: Energy>(model: &Model<E>, state: &State, reference: &State) -> Real {
    let scale = (0..model.mesh().n_vertices())
        .map(|v| reference.displacement(model, v).norm())
        .fold(0.0, Real::max);
    let d = state
        .x
        .iter()
        .zip(&reference.x)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    d / scale
}

/// (e) The same scene under this solver and under implicit Euler.
fn rollout(kind: SolverKind, tolerance: Real, why: &str) {
    // A cantilever sagging under gravity, stiff enough (E = 1e4 Pa) to swing back within the
    // run: at 0.4 s its tip has gone down and come back up, so a solver with the wrong
    // stiffness or the wrong inertia is out of phase with the reference.
    let mut model = anchored(kind, 20, 4, 1e4);
    model.set_standard_gravity();
    let distance = match kind.capabilities().clock {
        Clock::Time => {
            let (dt, t_end) = (2.5e-4, 0.4);
            let mut reference = State::at_rest(&model);
            let mut implicit = build(SolverKind::Implicit, &model, dt, |p| {
                if let SolverParams::Implicit(p) = p {
                    p.newton.tolerance = 1e-12;
                }
            });
            run_until(kind, &mut implicit, &model, &mut reference, t_end);
            let mut state = State::at_rest(&model);
            let mut stepper = build(kind, &model, dt, |_| {});
            run_until(kind, &mut stepper, &model, &mut state, t_end);
            let own = (0..model.mesh().n_vertices())
                .map(|v| state.displacement(&model, v).norm())
                .fold(0.0, Real::max);
            let reach = (0..model.mesh().n_vertices())
                .map(|v| reference.displacement(&model, v).norm())
                .fold(0.0, Real::max);
            eprintln!("{kind}: largest displacement {own:.4e} m, implicit Euler's {reach:.4e} m");
            relative_distance(&model, &state, &reference)
        }
        Clock::LoadFactor => {
            // Damping c = 15/s, about 0.65 of critical for the first bending mode (omega near
            // 11.5 rad/s), settles the implicit rollout as exp(-c t / 2), to 2e-10 of its
            // swing by t = 3 s: what is left is its equilibrium.
            let mut reference = State::at_rest(&model);
            let mut implicit = build(SolverKind::Implicit, &model, 1e-2, |p| {
                if let SolverParams::Implicit(p) = p {
                    p.damping = 15.0;
                    p.newton.tolerance = 1e-12;
                }
            });
            run_until(kind, &mut implicit, &model, &mut reference, 3.0);
            let mut state = State::at_rest(&model);
            let mut stepper = build(kind, &model, 0.0, |_| {});
            run_until(kind, &mut stepper, &model, &mut state, 1.0);
            relative_distance(&model, &state, &reference)
        }
    };
    eprintln!("{kind}: {distance:.3e} of the reference's largest displacement from it");
    assert!(
        distance <= tolerance,
        "{kind}: {distance:e} from implicit Euler, more than {tolerance:e} ({why})"
    );
}

macro_rules! battery {
    ($(
        $module:ident => $kind:ident,
        energy_growth: $energy:expr => $energy_why:literal,
        rollout: $rollout:expr => $rollout_why:literal
        $(, survives_failure_scene: $survives:literal)? $(,)?
    );+ $(;)?) => {
        /// The solvers the battery covers, in its order.
        const BATTERY: &[SolverKind] = &[$(SolverKind::$kind),+];

        $(
            mod $module {
                use super::*;
                const KIND: SolverKind = SolverKind::$kind;

                #[test]
                fn free_fall_or_equilibrium() {
                    match KIND.capabilities().clock {
                        Clock::Time => free_fall(KIND, Integrator::BackwardEuler),
                        Clock::LoadFactor => equilibrium(KIND),
                    }
                }

                #[test]
                fn never_writes_a_non_finite_state() {
                    #[allow(unused_mut, unused_assignments)]
                    let mut survives: Option<&str> = None;
                    $(survives = Some($survives);)?
                    never_non_finite(KIND, survives);
                }

                #[test]
                fn bit_identical_on_1_2_and_4_threads() {
                    thread_independent(KIND, Integrator::BackwardEuler);
                }

                #[test]
                fn energy_does_not_grow_without_load() {
                    no_energy_growth(KIND, $energy, $energy_why);
                }

                #[test]
                fn rollout_stays_near_implicit_euler() {
                    rollout(KIND, $rollout, $rollout_why);
                }
            }
        )+
    };
}

// One line per solver: the relative energy growth allowed (d) and the rollout distance allowed
// (e), each with why. Measured values are those of this mesh and these steps.
battery! {
    explicit => Explicit,
        energy_growth: 0.03 => "symplectic Euler conserves a modified energy: the true one oscillates about it by O(omega dt) (measured +1.4 %)",
        rollout: 5e-3 => "both first order in dt, their errors of opposite sign (explicit gains, implicit loses energy): O(dt) apart (measured 0.21 %)";
    pbd => Pbd,
        energy_growth: 200.0 => "no conservation law: C = a psi has no material stiffness and removes the stretch within a few steps at any dt, so kinetic energy peaks near (stretch / dt)^2 (measured 146x at 0.5 ms; ends at 2.7 % of the start); this only catches a runaway",
        rollout: 1.05 => "no material limit: at 0.25 ms with 10 iterations PBD is nearly rigid (sags 3.4 mm where implicit Euler sags 221 mm, measured 0.985); this only says it does not move away from the reference";
    xpbd => Xpbd,
        energy_growth: 1e-12 => "implicit-Euler-like, so dissipative: never above its start but for round-off (measured 0)",
        rollout: 1e-3 => "10 iterations of XPBD approximate the implicit Euler step; the dropped primal residual leaves a small gap (measured 0.046 %)";
    implicit => Implicit,
        energy_growth: 1e-12 => "implicit Euler dissipates: never above its start but for round-off (measured 0; ends at 58 %)",
        rollout: 1e-9 => "the reference itself at Newton tolerance 1e-12 instead of 1e-8: quadratic convergence puts both at round-off (measured 0)";
    statics => Static,
        energy_growth: 1e-12 => "with no load the equilibrium is the rest shape: energy ends at round-off (measured 7e-23 of the start)",
        rollout: 1e-8 => "the damped rollout has settled to 2e-10 of its swing; both solves stop at their Newton tolerance (static: 1e-8 of the load) (measured 1.6e-11)";
    vbd => Vbd,
        energy_growth: 1e-12 => "the sweeps descend implicit Euler's incremental potential, so it dissipates like implicit Euler: never above its start but for round-off (measured 0; ends at 58 %)",
        rollout: 1e-8 => "10 sweeps per step of 0.25 ms converge the implicit Euler step nearly to round-off (measured 1.1e-10)",
        survives_failure_scene: "each vertex takes a Newton step with a positive definite 2x2 block, halved while it would invert a Neo-Hookean triangle, so no step produces a non-finite value to fail on";
    pd => Pd,
        energy_growth: 1e-12 => "every local-global iteration lowers implicit Euler's potential of the co-rotational energy, so it dissipates like implicit Euler (measured 0; ends at 61 %)",
        rollout: 1e-8 => "run on the co-rotational energy, against implicit Euler of that energy; 10 iterations at 0.25 ms converge to round-off of the step (measured 1.1e-10)",
        survives_failure_scene: "the co-rotational energy is finite under inversion and every global step is a linear solve with a fixed positive definite matrix: nothing to fail on";
    quasi_newton => QuasiNewton,
        energy_growth: 1e-12 => "Armijo steps on implicit Euler's potential: dissipates like implicit Euler (measured 0; ends at 58 %)",
        rollout: 1e-8 => "at most 10 L-BFGS iterations per step, stopped at Newton's tolerance 1e-8 (the reference's is 1e-12) (measured 1.9e-10)",
        survives_failure_scene: "the line search accepts only states of finite, lower potential, and a step that stops short of the tolerance is not an error (a fixed real-time budget)";
    linear_implicit => LinearImplicit,
        energy_growth: 1e-12 => "one Newton iteration of implicit Euler per step, with an SPD matrix: dissipates like implicit Euler here (measured 0; ends at 58 %)",
        rollout: 2e-4 => "each step is implicit Euler's first Newton iteration from the step's start, off its solution by the square of the step's motion (measured 8.4e-5)",
        survives_failure_scene: "a step whose end leaves the energy's domain (Neo-Hookean's log J) is halved until it does not, so every state it writes has finite forces";
}

#[test]
fn battery_covers_every_solver() {
    assert_eq!(
        BATTERY,
        SolverKind::ALL,
        "add a line for every solver of the registry to the battery"
    );
}

/// The BDF2 lines: the solvers with an `integrator` parameter, each run through the free fall
/// and thread independence under BDF2.
macro_rules! bdf2_battery {
    ($($module:ident => $kind:ident),+ $(,)?) => {
        /// The solvers the BDF2 battery covers.
        const BDF2_BATTERY: &[SolverKind] = &[$(SolverKind::$kind),+];

        mod bdf2 {
            use super::*;
            $(
                mod $module {
                    use super::*;
                    const KIND: SolverKind = SolverKind::$kind;

                    #[test]
                    fn free_fall() {
                        super::super::free_fall(KIND, Integrator::Bdf2);
                    }

                    #[test]
                    fn bit_identical_on_1_2_and_4_threads() {
                        thread_independent(KIND, Integrator::Bdf2);
                    }
                }
            )+
        }
    };
}

bdf2_battery! {
    implicit => Implicit,
    vbd => Vbd,
    pd => Pd,
    quasi_newton => QuasiNewton,
}

#[test]
fn bdf2_battery_covers_every_solver_with_an_integrator() {
    let with: Vec<SolverKind> = (SolverKind::ALL.into_iter())
        .filter(|k| k.default_params().integrator().is_some())
        .collect();
    assert_eq!(
        BDF2_BATTERY, with,
        "add a line for every solver with an `integrator` parameter to the BDF2 battery"
    );
}
