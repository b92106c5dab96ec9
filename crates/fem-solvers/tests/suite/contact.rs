//! Contact: a soft block dropped on the ground comes to rest on it, a dynamic rigid slab
//! dropped on a soft strip comes to rest on the strip (two-way coupling), and a sharp wedge's
//! corner pressed into a coarse soft edge pushes the edge instead of passing through it, with
//! penalty contact (explicit) and projection (PBD, XPBD).

use crate::common::lame;
use fem_core::energy::{Energy, NeoHookean};
use fem_core::math::{Real, Vec2};
use fem_solvers::testing::{RectangleParams, rectangle};
use fem_solvers::{
    ContactKind, ContactParams, ExplicitParams, ExplicitStepper, Ground, Model, ObstacleMotion,
    PbdParams, PbdStepper, Region, State, Stepper, XpbdParams, XpbdStepper,
};

/// A 1 m x 1 m, 1 kg Neo-Hookean block (E = 10 kPa, 8 x 8 cells) 0.2 m above the ground y = 0.
pub(crate) fn block() -> Model<NeoHookean> {
    let mesh = rectangle(&RectangleParams {
        origin: [0.0, 0.2],
        ..RectangleParams::new(1.0, 1.0, 8, 8)
    })
    .unwrap();
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e4)).unwrap(), 1.0).unwrap();
    m.set_standard_gravity();
    m.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    m
}

fn settle<E: Energy, S: Stepper>(model: &Model<E>, mut s: S, t_end: Real) -> State {
    let mut state = State::at_rest(model);
    while state.t < t_end {
        s.step(model, &mut state).unwrap();
    }
    state
}

fn max_speed(state: &State) -> Real {
    state.v.iter().map(|v| v.norm()).fold(0.0, Real::max)
}

#[test]
fn block_dropped_on_ground_rests_with_small_penetration_explicit() {
    // Penalty k = 1e6 1/s^2: the bottom vertices carry about 9x their own mass, so they sink
    // by about 9 g / k = 0.09 mm. Tolerance 0.2 mm; at rest means every speed < 1 cm/s after
    // 3 s (damping 3/s).
    let model = block();
    let params = ExplicitParams {
        dt: 2e-4,
        damping: 3.0,
        ..Default::default()
    };
    assert!(model.check_time_step(params.dt).warning().is_none());
    let state = settle(&model, ExplicitStepper::new(&model, params).unwrap(), 3.0);
    let lowest = state.x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
    assert!(
        lowest > -2e-4 && lowest < 0.0,
        "lowest vertex at {lowest} m"
    );
    assert!(
        max_speed(&state) < 1e-2,
        "still moving: {}",
        max_speed(&state)
    );
    let mean_y = state.x.iter().map(|p| p.y).sum::<Real>() / state.x.len() as Real;
    assert!((mean_y - 0.5).abs() < 0.02, "block centre at {mean_y}");
}

#[test]
fn block_dropped_on_ground_rests_with_small_penetration_xpbd() {
    // Projection leaves no penetration after the last sweep: tolerance 1e-9 m (round-off).
    let model = block();
    let params = XpbdParams {
        dt: 1e-3,
        iterations: 10,
        damping: 2.0,
        ..Default::default()
    };
    let state = settle(&model, XpbdStepper::new(&model, params).unwrap(), 3.0);
    let lowest = state.x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
    assert!(
        lowest > -1e-9 && lowest < 1e-3,
        "lowest vertex at {lowest} m"
    );
    assert!(
        max_speed(&state) < 1e-2,
        "still moving: {}",
        max_speed(&state)
    );
}

/// A 4 m x 0.5 m soft strip (E = 10 kPa, 1 kg) pinned along its bottom edge, and a 2 m x 0.2 m
/// rigid slab of 0.5 kg 0.1 m above its middle.
pub(crate) fn strip_and_slab() -> (Model<NeoHookean>, usize) {
    let mesh = rectangle(&RectangleParams::new(4.0, 0.5, 16, 4)).unwrap();
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e4)).unwrap(), 1.0).unwrap();
    m.set_standard_gravity();
    m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0)))
        .unwrap();
    m.set_contact_params(ContactParams {
        stiffness: 1e6,
        damping_ratio: 1.0,
        ..Default::default()
    })
    .unwrap();
    let slab = m
        .add_obstacle(
            &[
                Vec2::new(1.0, 0.6),
                Vec2::new(3.0, 0.6),
                Vec2::new(3.0, 0.8),
                Vec2::new(1.0, 0.8),
            ],
            ObstacleMotion::Dynamic {
                mass: 0.5,
                rotates: true,
            },
        )
        .unwrap();
    (m, slab)
}

fn check_slab_rests(state: &State, slab: usize, what: &str) {
    // Resting on the strip: its bottom (centroid - 0.1 m) lies below the strip's rest top
    // (0.5 m: the strip is compressed by the slab's weight, a few mm) but not by more than
    // 5 cm, it has stopped (speed < 1 cm/s), stayed level (|angle| < 1e-3 rad) and slid less
    // than 1 cm sideways during the impact (friction 0.5).
    let b = state.bodies[slab];
    let bottom = b.position.y - 0.1;
    assert!(
        bottom < 0.5 && bottom > 0.45,
        "{what}: slab bottom at {bottom}"
    );
    assert!(
        b.velocity.norm() < 1e-2,
        "{what}: slab velocity {:?}",
        b.velocity
    );
    assert!(b.angle.abs() < 1e-3, "{what}: slab angle {}", b.angle);
    assert!(
        (b.position.x - 2.0).abs() < 1e-2,
        "{what}: slab drifted to {}",
        b.position.x
    );
}

#[test]
fn rigid_slab_comes_to_rest_on_soft_strip_explicit() {
    let (model, slab) = strip_and_slab();
    let params = ExplicitParams {
        dt: 2e-4,
        damping: 2.0,
        ..Default::default()
    };
    assert!(model.check_time_step(params.dt).warning().is_none());
    let state = settle(&model, ExplicitStepper::new(&model, params).unwrap(), 3.0);
    check_slab_rests(&state, slab, "explicit");
}

#[test]
fn rigid_slab_comes_to_rest_on_soft_strip_xpbd() {
    let (model, slab) = strip_and_slab();
    let params = XpbdParams {
        dt: 1e-3,
        iterations: 10,
        damping: 2.0,
        ..Default::default()
    };
    let state = settle(&model, XpbdStepper::new(&model, params).unwrap(), 3.0);
    check_slab_rests(&state, slab, "xpbd");
}

#[test]
fn kinematic_obstacle_pushes_the_body_and_static_obstacle_holds_it() {
    // A kinematic plate moving down at 0.2 m/s during [0, 0.5] s presses a pinned-bottom strip
    // by 0.1 m - 0.05 m gap = 5 cm; under projection, no strip vertex stays inside the plate.
    let mesh = rectangle(&RectangleParams::new(4.0, 0.5, 16, 4)).unwrap();
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e4)).unwrap(), 1.0).unwrap();
    m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0)))
        .unwrap();
    let plate = m
        .add_obstacle(
            &[
                Vec2::new(1.0, 0.55),
                Vec2::new(3.0, 0.55),
                Vec2::new(3.0, 0.75),
                Vec2::new(1.0, 0.75),
            ],
            ObstacleMotion::Kinematic {
                velocity: Vec2::new(0.0, -0.2),
                angular_velocity: 0.0,
                start: 0.0,
                end: 0.5,
            },
        )
        .unwrap();
    let state = settle(
        &m,
        XpbdStepper::new(
            &m,
            XpbdParams {
                iterations: 10,
                ..Default::default()
            },
        )
        .unwrap(),
        0.8,
    );
    let b = state.bodies[plate];
    assert!(
        (b.position.y - (0.65 - 0.1)).abs() < 1e-9,
        "plate at {}",
        b.position.y
    );
    let top_mid = state.x[fem_solvers::testing::node_index(8, 4, 16)].y;
    assert!(
        (top_mid - 0.45).abs() < 1e-6,
        "strip top under the plate at {top_mid}"
    );
}

/// A kinematic plate with a second move: lowered 10 cm during [0, 0.5] s (5 cm into the strip
/// of the test above), held, then lifted 10 cm during [0.6, 1.1] s. Mid-way it presses the strip
/// as the one-window plate does; at the end it is back at its initial pose (the two moves cancel
/// to round-off) and no longer touches the strip. Pressed means the strip's top below 0.48 m, 2
/// of the 5 cm: explicit's default penalty lets the plate sink 2.6 cm into the strip, XPBD's
/// projection holds it to round-off. (Implicit Euler's barrier places a kinematic obstacle by
/// the same schedule; the lower-leg scene's tests run it.)
#[test]
fn a_kinematic_obstacle_with_a_second_move_presses_then_lets_go() {
    use fem_solvers::ObstacleMove;
    let model = || {
        let mesh = rectangle(&RectangleParams::new(4.0, 0.5, 16, 4)).unwrap();
        let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e4)).unwrap(), 1.0).unwrap();
        m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0)))
            .unwrap();
        let plate = [
            Vec2::new(1.0, 0.55),
            Vec2::new(3.0, 0.55),
            Vec2::new(3.0, 0.75),
            Vec2::new(1.0, 0.75),
        ];
        let down = ObstacleMotion::Kinematic {
            velocity: Vec2::new(0.0, -0.2),
            angular_velocity: 0.0,
            start: 0.0,
            end: 0.5,
        };
        let k = m.add_obstacle(&plate, down).unwrap();
        let up = ObstacleMove {
            velocity: Vec2::new(0.0, 0.2),
            angular_velocity: 0.0,
            start: 0.6,
            end: 1.1,
        };
        m.set_obstacle_moves(k, &[up]).unwrap();
        assert_eq!(m.obstacles()[k].schedule(), Some((0.0, 1.1)));
        (m, k)
    };
    let (m, k) = model();
    let top_mid = fem_solvers::testing::node_index(8, 4, 16);
    let check = |name: &str, stepper: &mut dyn FnMut(&mut State)| {
        let mut state = State::at_rest(&m);
        while state.t < 0.55 - 1e-9 {
            stepper(&mut state);
        }
        let pressed = state.x[top_mid].y;
        assert!(
            (state.bodies[k].position.y - 0.55).abs() < 1e-9 && pressed < 0.48,
            "{name}: plate at {}, strip top at {pressed} while pressed",
            state.bodies[k].position.y
        );
        while state.t < 1.5 - 1e-9 {
            stepper(&mut state);
        }
        let b = state.bodies[k];
        assert!(
            (b.position.y - 0.65).abs() < 1e-9 && b.velocity.norm() == 0.0,
            "{name}: plate at {} moving {:?} after its moves",
            b.position.y,
            b.velocity
        );
        let highest = state.x.iter().map(|p| p.y).fold(Real::MIN, Real::max);
        assert!(
            highest < 0.55,
            "{name}: strip reaches {highest} under the lifted plate"
        );
    };
    let mut explicit = ExplicitStepper::new(
        &m,
        ExplicitParams {
            dt: 1e-4,
            damping: 5.0,
            ..Default::default()
        },
    )
    .unwrap();
    check("explicit", &mut |s| {
        explicit.step(&m, s).unwrap();
    });
    let mut xpbd = XpbdStepper::new(
        &m,
        XpbdParams {
            iterations: 10,
            ..Default::default()
        },
    )
    .unwrap();
    check("xpbd", &mut |s| {
        xpbd.step(&m, s).unwrap();
    });

    // Moves are for kinematic obstacles only, in time order.
    let (mut m, k) = model();
    let late = |start: Real, end: Real| ObstacleMove {
        velocity: Vec2::new(0.0, 1.0),
        angular_velocity: 0.0,
        start,
        end,
    };
    let e = m
        .set_obstacle_moves(k, &[late(0.4, 0.8)])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("obstacles[0].moves[0].start") && e.contains("at or after the end"),
        "{e}"
    );
    let e = m
        .set_obstacle_moves(k, &[late(0.6, 0.5)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("obstacles[0].moves[0].end"), "{e}");
    let e = m.set_obstacle_moves(3, &[]).unwrap_err().to_string();
    assert!(e.contains("no such obstacle"), "{e}");
    let square = [
        Vec2::new(0.0, 2.0),
        Vec2::new(1.0, 2.0),
        Vec2::new(1.0, 3.0),
        Vec2::new(0.0, 3.0),
    ];
    let s = m.add_obstacle(&square, ObstacleMotion::Static).unwrap();
    let e = m
        .set_obstacle_moves(s, &[late(1.0, 2.0)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("only a kinematic obstacle has moves"), "{e}");
}

/// Geometry at t = 0: a body below the ground, an obstacle over the body (a vertex inside it,
/// or its corner inside a triangle) and a self-crossing polygon are errors naming what and
/// where; a body resting exactly on the ground and an obstacle touching it are fine.
#[test]
fn overlaps_at_the_start_and_self_crossing_obstacles_are_refused() {
    let mesh = rectangle(&RectangleParams::new(1.0, 1.0, 4, 4)).unwrap();
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e4)).unwrap(), 1.0).unwrap();
    // Resting on y = 0: fine. Above the lowest row: an error naming a vertex.
    m.set_ground(Some(Ground::horizontal(0.0))).unwrap();
    let e = m
        .set_ground(Some(Ground::horizontal(0.3)))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("ground: vertex ") && e.contains("3.000e-1 m below"),
        "{e}"
    );
    let square = |x0: Real, y0: Real, s: Real| {
        vec![
            Vec2::new(x0, y0),
            Vec2::new(x0 + s, y0),
            Vec2::new(x0 + s, y0 + s),
            Vec2::new(x0, y0 + s),
        ]
    };
    // Touching the top edge from above: fine.
    m.add_obstacle(&square(0.2, 1.0, 0.5), ObstacleMotion::Static)
        .unwrap();
    // Covering the vertex (0.5, 0.5).
    let e = m
        .add_obstacle(&square(0.4, 0.4, 0.2), ObstacleMotion::Static)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("obstacles[1]: overlaps the body at t = 0: vertex"),
        "{e}"
    );
    // Small enough to hold no vertex: its corners lie inside triangles.
    let e = m
        .add_obstacle(&square(0.55, 0.55, 0.1), ObstacleMotion::Static)
        .unwrap_err()
        .to_string();
    // (Corner 0 lies on a cell diagonal: touching, not inside; corner 1 is inside.)
    assert!(
        e.contains("its corner 1 at [0.65, 0.55] lies inside triangle"),
        "{e}"
    );
    // A bow tie with positive area (one lobe larger).
    let bow = [
        Vec2::new(2.0, 0.0),
        Vec2::new(3.0, 1.0),
        Vec2::new(3.0, 0.0),
        Vec2::new(2.0, 2.0),
    ];
    let e = m
        .add_obstacle(&bow, ObstacleMotion::Static)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("polygon edges 0") && e.contains("must be simple"),
        "{e}"
    );
    assert_eq!(m.obstacles().len(), 1);
}

/// The wedge regression's scene: a 4 m x 0.5 m strip (E = 1 kPa, 1 kg, no gravity) pinned
/// along its bottom, with only 4 x 2 cells, so its top edges are 1 m long; a kinematic wedge
/// (tip down, 0.2 m wide at the top, so no strip vertex ever lies inside it) 2 cm above the
/// middle of the top edge from x = 1 m to x = 2 m, moving down at 0.2 m/s during [0, 0.5] s:
/// 10 cm of travel, so the tip would end 8 cm into the strip. Returns the model, the wedge's
/// index and the edge's vertices (left, right).
fn strip_and_wedge() -> (Model<NeoHookean>, usize, [usize; 2]) {
    let mesh = rectangle(&RectangleParams::new(4.0, 0.5, 4, 2)).unwrap();
    let mut m = Model::with_total_mass(mesh, NeoHookean::new(lame(1e3)).unwrap(), 1.0).unwrap();
    m.pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0)))
        .unwrap();
    m.set_contact_params(ContactParams {
        stiffness: WEDGE_STIFFNESS,
        damping_ratio: 1.0,
        ..Default::default()
    })
    .unwrap();
    let wedge = m
        .add_obstacle(
            &[
                Vec2::new(1.5, 0.52),
                Vec2::new(1.6, 0.82),
                Vec2::new(1.4, 0.82),
            ],
            ObstacleMotion::Kinematic {
                velocity: Vec2::new(0.0, -WEDGE_SPEED),
                angular_velocity: 0.0,
                start: 0.0,
                end: WEDGE_TIME,
            },
        )
        .unwrap();
    let node = |i| fem_solvers::testing::node_index(i, 2, 4);
    (m, wedge, [node(1), node(2)])
}

/// The wedge regression's penalty stiffness, 1/s^2.
const WEDGE_STIFFNESS: Real = 1e7;
/// The wedge's speed (m/s) and how long it moves (s).
const WEDGE_SPEED: Real = 0.2;
const WEDGE_TIME: Real = 0.5;
/// The gap between the tip and the edge at t = 0, m.
const WEDGE_GAP: Real = 0.02;

/// What the wedge run measured: the deepest the tip went below the edge's line (m, positive
/// below), the height of the edge's middle at the end (m), the tip's height at the end (m),
/// and the largest corner-edge normal force the stepper reported (N).
struct WedgeRun {
    deepest: Real,
    middle_y: Real,
    tip_y: Real,
    max_force: Real,
}

/// Run the wedge scene to `t = 0.6 s` (0.1 s after the wedge stops) with `stepper`, checking
/// after every step how far the tip lies below the line through the edge's two vertices.
fn press_wedge<S: Stepper>(
    model: &Model<NeoHookean>,
    mut stepper: S,
    wedge: usize,
    edge: [usize; 2],
) -> WedgeRun {
    let mut state = State::at_rest(model);
    let mut run = WedgeRun {
        deepest: Real::NEG_INFINITY,
        middle_y: 0.0,
        tip_y: 0.0,
        max_force: 0.0,
    };
    while state.t < WEDGE_TIME + 0.1 {
        stepper.step(model, &mut state).unwrap();
        let tip = model.obstacles()[wedge].world_polygon(&state.bodies[wedge])[0];
        let (a, b) = (state.x[edge[0]], state.x[edge[1]]);
        let line_y = a.y + (tip.x - a.x) / (b.x - a.x) * (b.y - a.y);
        run.deepest = run.deepest.max(line_y - tip.y);
        run.middle_y = 0.5 * (a.y + b.y);
        run.tip_y = tip.y;
        for c in stepper.contacts() {
            match c.kind {
                ContactKind::CornerEdge { .. } => run.max_force = run.max_force.max(c.force),
                // The corner alone holds the edge: no strip vertex reaches the wedge.
                other => panic!(
                    "at t = {}: a contact other than the corner's: {other:?}",
                    state.t
                ),
            }
        }
    }
    run
}

/// The edge's middle should have gone down by the wedge's travel less the initial gap (8 cm):
/// it ends where the tip is, up to the penetration, and the tip's final height is exact.
fn check_edge_pushed_down(run: &WedgeRun, tolerance: Real, what: &str) {
    let expected_tip = 0.52 - WEDGE_SPEED * WEDGE_TIME;
    assert!(
        (run.tip_y - expected_tip).abs() < 1e-9,
        "{what}: the wedge's tip ended at {}",
        run.tip_y
    );
    let expected_middle = 0.5 - (WEDGE_SPEED * WEDGE_TIME - WEDGE_GAP);
    assert!(
        (run.middle_y - expected_middle).abs() < tolerance,
        "{what}: the edge's middle ended at {} m, expected {expected_middle} m (within {tolerance} m)",
        run.middle_y
    );
}

#[test]
fn wedge_corner_no_longer_passes_through_a_coarse_soft_edge_explicit() {
    let (model, wedge, edge) = strip_and_wedge();
    let params = ExplicitParams {
        dt: 1e-4,
        damping: 5.0,
        ..Default::default()
    };
    assert!(model.check_time_step(params.dt).warning().is_none());
    let run = press_wedge(
        &model,
        ExplicitStepper::new(&model, params).unwrap(),
        wedge,
        edge,
    );
    // Penalty contact holds the tip where `m_eff k d` balances the strip's reaction F (plus the
    // damping term while the wedge moves): d = F / (m_eff k). The corner sits at the edge's
    // middle, whose two vertices weigh 1/16 kg each (three of the 16 triangles of 1/8 m^2 at
    // 0.5 kg/m^2, a third of each), so m_eff = 1/16 kg. The reaction at 8 cm of indentation is
    // about 500 N (the reported force; XPBD reports the same), so d is about
    // 500 / (1/16 * 1e7) = 0.8 mm. Tolerances: 1.25 times the depth the law gives at the largest
    // reported force, and 2 mm.
    let m_eff = 1.0 / 16.0;
    let penalty_depth = run.max_force / (m_eff * WEDGE_STIFFNESS);
    assert!(
        run.max_force > 0.0 && run.deepest < 1.25 * penalty_depth,
        "explicit: the tip went {} m below the edge (the penalty law allows about {penalty_depth} m at the largest reported force {} N)",
        run.deepest,
        run.max_force
    );
    assert!(
        run.deepest < 2e-3,
        "explicit: the tip went {} m below the edge",
        run.deepest
    );
    check_edge_pushed_down(&run, 2e-3, "explicit");
}

#[test]
fn wedge_corner_no_longer_passes_through_a_coarse_soft_edge_pbd() {
    // Projection leaves the corner on the edge after every pass: round-off (1e-9 m).
    let (model, wedge, edge) = strip_and_wedge();
    let params = PbdParams {
        dt: 1e-3,
        iterations: 10,
        damping: 5.0,
        ..Default::default()
    };
    let run = press_wedge(
        &model,
        PbdStepper::new(&model, params).unwrap(),
        wedge,
        edge,
    );
    assert!(
        run.deepest < 1e-9,
        "pbd: the tip went {} m below the edge",
        run.deepest
    );
    assert!(run.max_force > 0.0, "pbd: no corner-edge force reported");
    check_edge_pushed_down(&run, 1e-3, "pbd");
}

#[test]
fn wedge_corner_no_longer_passes_through_a_coarse_soft_edge_xpbd() {
    let (model, wedge, edge) = strip_and_wedge();
    let params = XpbdParams {
        dt: 1e-3,
        iterations: 10,
        damping: 5.0,
        ..Default::default()
    };
    let run = press_wedge(
        &model,
        XpbdStepper::new(&model, params).unwrap(),
        wedge,
        edge,
    );
    assert!(
        run.deepest < 1e-9,
        "xpbd: the tip went {} m below the edge",
        run.deepest
    );
    assert!(run.max_force > 0.0, "xpbd: no corner-edge force reported");
    check_edge_pushed_down(&run, 1e-3, "xpbd");
}
