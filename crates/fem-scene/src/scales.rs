//! The scales of a scene's terms, checked against what double precision can hold.
//!
//! Every solver sums squares of forces (residual norms) and products of stiffnesses and
//! displacements; a term whose force on the body is beyond [`MAX_FORCE_SCALE`] overflows
//! them, and a solver would then read an infinite residual as anything from "converged" to
//! "blew up". [`check_scales`] refuses such a scene before it runs, naming the field; the
//! solvers' own round-off checks (a load below the floor of the stiffness it acts against, a
//! Newton step below the round-off of the coordinates) report what is left at run time, and
//! [`precision_hint`] names the scene's extreme scales beside them.

use fem_core::math::readable;
use fem_core::mesh::Mesh;
use fem_solvers::{Model, SolverError};

use crate::error::SceneError;
use crate::scene::LoadedScene;

/// The largest force a term may put on the body, N per metre of thickness: squares of forces
/// (residual norms over up to 1e6 unknowns) stay below `f64::MAX` (about 1.8e308) with six
/// orders of magnitude to spare.
pub const MAX_FORCE_SCALE: f64 = 1e150;

/// `x` as a reader takes it in: scientific notation outside `[1e-3, 1e6)` (`1e14`, not
/// fifteen digits), else as [`readable`] prints it.
fn sci(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        readable(x)
    }
}

/// The diagonal of the mesh's rest bounding box, m.
fn size(mesh: &Mesh) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in mesh.vertices() {
        for d in 0..2 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (hi[0] - lo[0]).hypot(hi[1] - lo[1])
}

/// Refuse a scene one of whose terms puts a force beyond [`MAX_FORCE_SCALE`] on the body:
/// the weight (`gravity` times the body's mass), a traction over the body's size, a Young's
/// modulus over the body's size (the force of a unit strain), and the barrier's force at half
/// its activation distance (`contact.barrier_stiffness d_hat^3`); or a kinematic obstacle
/// whose window moves it farther than [`MAX_FORCE_SCALE`] metres during the run.
pub fn check_scales<E: fem_core::energy::Energy>(
    scene: &LoadedScene,
    model: &Model<E>,
) -> Result<(), SceneError> {
    let s = &scene.scene;
    let length = size(model.mesh());
    // Rigid regions' masses are their vertices' (see `Model::masses`).
    let mass: f64 = model.masses().iter().sum();
    let refuse = |field: &str, value: String, what: &str, force: f64| {
        Err(scene.error(
            field,
            value,
            &format!(
                "{what} is {force:.3e} N, beyond {} N: sums of squared forces would overflow double precision",
                sci(MAX_FORCE_SCALE)
            ),
        ))
    };
    let g = s.gravity[0].hypot(s.gravity[1]);
    if g * mass > MAX_FORCE_SCALE {
        let value = format!("[{}, {}]", sci(s.gravity[0]), sci(s.gravity[1]));
        return refuse("gravity", value, "the body's weight", g * mass);
    }
    let e = s.material.youngs_modulus;
    if e * length > MAX_FORCE_SCALE {
        let what = "the force of a unit strain over the body's size";
        return refuse("material.youngs_modulus", sci(e), what, e * length);
    }
    for (k, r) in s.regions.iter().enumerate() {
        if let Some(e) = r.youngs_modulus.filter(|e| e * length > MAX_FORCE_SCALE) {
            let what = "the force of a unit strain over the body's size";
            let field = format!("regions.{k}.youngs_modulus");
            return refuse(&field, sci(e), what, e * length);
        }
    }
    for (k, t) in s.traction.iter().enumerate() {
        let f = t.traction[0].hypot(t.traction[1]) * length;
        if f > MAX_FORCE_SCALE {
            let value = format!("[{}, {}]", sci(t.traction[0]), sci(t.traction[1]));
            let what = "the traction over the body's size";
            return refuse(&format!("traction.{k}.traction"), value, what, f);
        }
    }
    // A kinematic obstacle's travel in each window over the run: its coordinates must stay
    // squarable (the barrier's distances, the tether's force).
    let horizon = s.solver.dt * s.solver.planned_steps() as f64;
    for (o, ob) in s.obstacles.iter().enumerate() {
        let windows = (ob
            .velocity
            .map(|v| (String::new(), v, ob.start.unwrap_or(0.0), ob.end)))
        .into_iter()
        .chain(
            ob.moves
                .iter()
                .enumerate()
                .map(|(m, mv)| (format!(".moves.{m}"), mv.velocity, mv.start, mv.end)),
        );
        for (at, v, start, end) in windows {
            let span = (end.unwrap_or(f64::INFINITY).min(horizon) - start).max(0.0);
            let travel = v[0].hypot(v[1]) * span;
            if travel > MAX_FORCE_SCALE {
                return Err(scene.error(
                    &format!("obstacles.{o}{at}.velocity"),
                    format!("[{}, {}]", sci(v[0]), sci(v[1])),
                    &format!(
                        "moves the obstacle {travel:.3e} m during the run, beyond {} m: its coordinates could not be squared in double precision",
                        sci(MAX_FORCE_SCALE)
                    ),
                ));
            }
        }
    }
    if s.ground.is_some() || !s.obstacles.is_empty() {
        let p = model.contact_params();
        let force = p.barrier_stiffness * p.barrier_distance.powi(3);
        if force > MAX_FORCE_SCALE {
            let what = "the barrier's force at half its distance (barrier_stiffness d_hat^3)";
            let value = sci(p.barrier_stiffness);
            return refuse("contact.barrier_stiffness", value, what, force);
        }
    }
    Ok(())
}

/// The scene's extreme scales, for a message about round-off: the stiffest and the softest
/// material (when they differ), the time step and the gravity.
pub fn precision_hint(scene: &LoadedScene) -> String {
    let s = &scene.scene;
    let mut moduli = vec![(
        "material.youngs_modulus".to_string(),
        s.material.youngs_modulus,
    )];
    for (k, r) in s.regions.iter().enumerate() {
        if let (Some(e), false) = (r.youngs_modulus, r.rigid) {
            moduli.push((format!("regions.{k}.youngs_modulus"), e));
        }
    }
    let stiff = moduli
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("one");
    let soft = moduli
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("one");
    let mut hint = if stiff.1 > soft.1 {
        format!(
            "the scene's scales: {} = {} Pa is {} times {} = {} Pa",
            stiff.0,
            sci(stiff.1),
            sci(stiff.1 / soft.1),
            soft.0,
            sci(soft.1)
        )
    } else {
        format!("the scene's scales: {} = {} Pa", soft.0, sci(soft.1))
    };
    hint.push_str(&format!(
        ", solver.dt = {} s, gravity = [{}, {}] m/s^2",
        sci(s.solver.dt),
        sci(s.gravity[0]),
        sci(s.gravity[1])
    ));
    hint
}

/// The span of the scene's elastic moduli, stiffest over softest (1 for one material).
fn modulus_span(scene: &LoadedScene) -> f64 {
    let s = &scene.scene;
    let moduli = std::iter::once(s.material.youngs_modulus)
        .chain((s.regions.iter()).filter_map(|r| r.youngs_modulus.filter(|_| !r.rigid)));
    let (lo, hi) = moduli.fold((f64::INFINITY, 0.0f64), |(lo, hi), e| {
        (lo.min(e), hi.max(e))
    });
    hi / lo
}

/// The moduli span from which a failed Newton solve names them: a factorisation of a
/// stiffness matrix whose entries span `1e8` loses half of double precision's digits.
pub const WIDE_MODULUS_SPAN: f64 = 1e8;

/// `e` as a run's blow-up message: a round-off failure (an overflowed force, a load below
/// the floors, a step below the round-off), or a Newton solve that did not converge in a
/// scene whose moduli span [`WIDE_MODULUS_SPAN`] or more, is followed by
/// [`precision_hint`], so the message names the fields whose scales are at fault.
pub fn explain(scene: &LoadedScene, e: &SolverError) -> String {
    let precision = matches!(e, SolverError::BeyondPrecision { .. })
        || matches!(e, SolverError::InvalidParameter { field, .. } if field.ends_with(".forces"));
    let newton = matches!(
        e,
        SolverError::NotConverged { .. } | SolverError::LoadIncrement { .. }
    );
    if precision || (newton && modulus_span(scene) >= WIDE_MODULUS_SPAN) {
        format!("{}: {e} ({})", scene.origin, precision_hint(scene))
    } else {
        format!("{}: {e}", scene.origin)
    }
}
