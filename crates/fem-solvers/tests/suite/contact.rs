//! Contact: a soft block dropped on the ground comes to rest on it, and a dynamic rigid slab
//! dropped on a soft strip comes to rest on the strip (two-way coupling), with penalty contact
//! (explicit) and projection (XPBD).

use crate::common::lame;
use fem_core::energy::{Energy, NeoHookean};
use fem_core::math::{Real, Vec2};
use fem_solvers::testing::{RectangleParams, rectangle};
use fem_solvers::{
    ContactParams, ExplicitParams, ExplicitStepper, Ground, Model, ObstacleMotion, Region, State,
    Stepper, XpbdParams, XpbdStepper,
};

/// A 1 m x 1 m, 1 kg Neo-Hookean block (E = 10 kPa, 8 x 8 cells) 0.2 m above the ground y = 0.
fn block() -> Model<NeoHookean> {
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
fn strip_and_slab() -> (Model<NeoHookean>, usize) {
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
