//! A lower-leg close-up: a longitudinal (sagittal) section of an adult shank with its tibia, for
//! studies where a load on the shin squeezes its thin soft tissue against the bone.
//!
//! The section runs from just below the knee (x = 0) to just above the ankle
//! (x = [`SHANK_LENGTH`] = 0.36 m), laid horizontally, in metres: anterior (the shin) up (+y),
//! posterior (the calf) down. The shin is a nearly straight line (y = 0.048 m at the knee end
//! down to 0.036 m at the ankle end); the calf bulges posteriorly, the section being 0.119 m deep
//! at x = 0.11 m, 0.096 m at the knee end and 0.076 m at the ankle end. The section's ends are
//! straight cuts.
//!
//! The tibia is one inner region (`"tibia"`): a shaft 25 mm thick whose anterior surface runs
//! [`SHANK_SOFT_TISSUE`] (13 mm) under the shin's skin, widening to 47 mm at the proximal
//! plateau, ending 12 mm short of both cuts. (The fibula is left out: in a sagittal section
//! through the shin it is lateral to the cut plane.)
//!
//! [`shank_params`] are the suggested refinement bounds (max area 2e-5 m², min angle 30
//! degrees): about 2 800 triangles, two across the soft tissue over the tibia.

use crate::triangulate::TriangulateParams;
use crate::types::{InnerRegion, PolygonWithHoles};

/// Length of the section, knee end to ankle end (metres).
pub const SHANK_LENGTH: f64 = 0.36;

/// Soft tissue between the tibia's anterior surface and the shin's skin, measured vertically
/// (metres).
pub const SHANK_SOFT_TISSUE: f64 = 0.013;

/// Distance from the tibia's ends to the section's cuts (metres).
pub const TIBIA_END_MARGIN: f64 = 0.012;

/// Vertex spacing along the outlines (metres).
const SPACING: f64 = 0.005;

/// The shin's skin at `x` (metres): a straight, slightly tapering line.
fn shin(x: f64) -> f64 {
    0.048 - 0.012 * x / SHANK_LENGTH
}

/// The calf's skin at `x` (metres): the posterior outline with the calf muscle's bulge.
fn calf(x: f64) -> f64 {
    -(0.040 + 0.035 * libm::exp(-((x - 0.11) / 0.09).powi(2)))
}

/// Thickness of the tibia at `x` (metres): the 25 mm shaft, widening towards the plateau.
fn tibia_thickness(x: f64) -> f64 {
    0.025 + 0.022 * libm::exp(-((x - TIBIA_END_MARGIN) / 0.04).powi(2))
}

/// `n + 1` evenly spaced values from `a` to `b`, both included.
fn steps(a: f64, b: f64, n: usize) -> impl Iterator<Item = f64> {
    (0..=n).map(move |i| a + (b - a) * i as f64 / n as f64)
}

/// The section's outline (counter-clockwise) and its tibia (see the module docs).
pub fn shank_section() -> (PolygonWithHoles, Vec<InnerRegion>) {
    let n = (SHANK_LENGTH / SPACING).round() as usize;
    // Counter-clockwise: the calf from knee to ankle, the ankle cut, the shin back to the knee,
    // the knee cut.
    let mut outer: Vec<[f64; 2]> = steps(0.0, SHANK_LENGTH, n).map(|x| [x, calf(x)]).collect();
    outer.extend(steps(SHANK_LENGTH, 0.0, n).map(|x| [x, shin(x)]));
    let (x0, x1) = (TIBIA_END_MARGIN, SHANK_LENGTH - TIBIA_END_MARGIN);
    let m = ((x1 - x0) / SPACING).round() as usize;
    let anterior = |x: f64| shin(x) - SHANK_SOFT_TISSUE;
    let mut tibia: Vec<[f64; 2]> = steps(x0, x1, m)
        .map(|x| [x, anterior(x) - tibia_thickness(x)])
        .collect();
    tibia.extend(steps(x1, x0, m).map(|x| [x, anterior(x)]));
    let region = InnerRegion {
        name: "tibia".to_owned(),
        polygons: vec![PolygonWithHoles {
            outer: tibia,
            holes: vec![],
        }],
    };
    (
        PolygonWithHoles {
            outer,
            holes: vec![],
        },
        vec![region],
    )
}

/// The suggested refinement of [`shank_section`]: max area 2e-5 m² (edges of about 7 mm), min
/// angle 30 degrees, the default Steiner cap.
pub fn shank_params() -> TriangulateParams {
    TriangulateParams {
        max_area: Some(2e-5),
        min_angle_deg: 30.0,
        ..TriangulateParams::default()
    }
}
