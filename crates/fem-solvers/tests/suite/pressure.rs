//! Contact pressure of a resting block: the 1 m x 1 m, 1 kg block of the contact suite dropped
//! on the ground and left to settle, under implicit Euler (barrier contact, dt = 1/90 s) and
//! explicit stepping (penalty contact, dt = 0.2 ms). At rest the pressure integrated along the
//! boundary must carry the block's weight (9.8 N per metre) within 1 %, and the contact length
//! must be the block's bottom width (1 m) within one edge length (0.125 m): the two bottom
//! corners' tributary lengths include half of a side edge each, so the exact expectation is
//! 1.125 m, slightly more as the weight spreads the bottom.

use crate::contact::block;
use fem_core::energy::Energy;
use fem_core::math::Real;
use fem_solvers::{
    ContactPressure, ExplicitParams, ExplicitStepper, ImplicitParams, ImplicitStepper, Model,
    State, Stepper,
};

const WEIGHT: Real = 9.8;
const WIDTH: Real = 1.0;
const EDGE: Real = 0.125;

/// Settle for `t_end` seconds, updating the pressure every step (as the step loop does);
/// returns the pressure after the last step and the state.
fn settle<E: Energy, S: Stepper>(
    model: &Model<E>,
    mut s: S,
    t_end: Real,
) -> (ContactPressure, State) {
    let mut state = State::at_rest(model);
    let mut p = ContactPressure::new();
    while state.t < t_end {
        s.step(model, &mut state).unwrap();
        p.update(model, &state.x, s.contacts());
    }
    (p, state)
}

fn check_rest(p: &ContactPressure, state: &State, solver: &str) {
    let speed = state.v.iter().map(|v| v.norm()).fold(0.0, Real::max);
    assert!(speed < 1e-2, "{solver}: still moving at {speed} m/s");
    let integral = p.integral();
    assert!(
        (integral - WEIGHT).abs() < 0.01 * WEIGHT,
        "{solver}: integrated pressure {integral} N/m, weight {WEIGHT} N/m"
    );
    // The exact-integral property on a real contact set: to round-off.
    assert!(
        (integral - p.total_force()).abs() < 1e-12 * WEIGHT,
        "{solver}: integral {integral} against the contacts' sum {}",
        p.total_force()
    );
    let length = p.contact_length();
    assert!(
        (length - WIDTH).abs() <= EDGE * 1.02,
        "{solver}: contact length {length} m, bottom width {WIDTH} m (edge {EDGE} m)"
    );
    // The peak lies on the bottom.
    let peak = p.peak().unwrap();
    assert!(
        peak.position.y.abs() < 1e-3,
        "{solver}: peak at {:?}",
        peak.position
    );
    eprintln!(
        "{solver}: integral {integral:.6} N/m, length {length:.6} m, mean {:.3} Pa, peak {:.3} Pa at {:?}",
        p.mean_pressure(),
        peak.pressure,
        peak.position
    );
}

#[test]
fn resting_block_pressure_carries_its_weight_implicit() {
    let model = block();
    let params = ImplicitParams {
        dt: 1.0 / 90.0,
        damping: 2.0,
        ..Default::default()
    };
    let (p, state) = settle(&model, ImplicitStepper::new(&model, params).unwrap(), 3.0);
    check_rest(&p, &state, "implicit");
}

#[test]
fn resting_block_pressure_carries_its_weight_explicit() {
    let model = block();
    let params = ExplicitParams {
        dt: 2e-4,
        damping: 3.0,
        ..Default::default()
    };
    let (p, state) = settle(&model, ExplicitStepper::new(&model, params).unwrap(), 3.0);
    check_rest(&p, &state, "explicit");
}
