//! What the program computes, as text: the same lines natively and in WebAssembly.
//!
//! - a Neo-Hookean cantilever under gravity, 0.5 s of explicit (symplectic Euler) steps;
//! - the same cantilever, 0.5 s of implicit Euler steps;
//! - the built-in human body meshed by the pipeline, then dropped for 20 explicit steps.
//!
//! Each part checks its own physics and fails with a message when it is wrong.

use std::error::Error;

use fem_mesh::prelude::*;
use fem_solvers::prelude::*;

/// The case A beam: 5 m x 1 m, 20 x 4 cells, 1 kg, E = 1 kPa, nu = 0.3, left edge pinned,
/// standard gravity.
fn cantilever() -> Result<(Model<NeoHookean>, usize), SolverError> {
    let lame = Material::new(1000.0, 0.3, 1.0)?.lame(PlaneModel::PlaneStrain);
    let params = RectangleParams::new(5.0, 1.0, 20, 4);
    let mut model = Model::with_total_mass(rectangle(&params)?, NeoHookean::new(lame)?, 1.0)?;
    model
        .set_standard_gravity()
        .pin(&Region::in_box(Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)))?;
    // The lower right corner.
    Ok((model, params.node(20, 0)))
}

/// Tip height after 0.5 s of `stepper`.
fn tip_after_half_a_second<S: Stepper>(
    model: &Model<NeoHookean>,
    stepper: &mut S,
    tip: usize,
) -> Result<Real, SolverError> {
    let mut state = State::at_rest(model);
    while state.t < 0.5 - 1e-9 {
        stepper.step(model, &mut state)?;
    }
    Ok(state.x[tip].y)
}

/// Explicit and implicit Euler on the cantilever: both fall, and agree to within the O(dt)
/// difference of the two schemes (2 %; measured 0.13 %).
fn cantilever_lines(out: &mut String) -> Result<(), Box<dyn Error>> {
    let (model, tip) = cantilever()?;
    let mut explicit = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt: 1e-3,
            ..Default::default()
        },
    )?;
    let y_explicit = tip_after_half_a_second(&model, &mut explicit, tip)?;
    let mut implicit = ImplicitStepper::new(
        &model,
        ImplicitParams {
            dt: 1e-2,
            ..Default::default()
        },
    )?;
    let y_implicit = tip_after_half_a_second(&model, &mut implicit, tip)?;
    let newton = implicit.last_newton().iterations;
    out.push_str(&format!(
        "explicit: tip y after 0.5 s = {y_explicit:.12e} m\n"
    ));
    out.push_str(&format!(
        "implicit: tip y after 0.5 s = {y_implicit:.12e} m ({newton} Newton iterations in the last step)\n"
    ));
    // The tip starts at y = 0 and sags (the soft beam whips past free fall's -1.225 m, but it
    // stays attached: within the beam's 5 m length of the pin).
    for (name, y) in [("explicit", y_explicit), ("implicit", y_implicit)] {
        if !(-5.0..-0.05).contains(&y) {
            return Err(
                format!("{name}: the tip at y = {y} m has not sagged as a cantilever").into(),
            );
        }
    }
    if (y_explicit - y_implicit).abs() > 0.02 * y_explicit.abs() {
        return Err(format!("explicit ({y_explicit}) and implicit ({y_implicit}) disagree").into());
    }
    Ok(())
}

/// The built-in body through the pipeline, then into a model: it falls freely.
fn meshing_lines(out: &mut String) -> Result<(), Box<dyn Error>> {
    let mut params = PipelineParams::default();
    params.triangulate.max_area = Some(2e-3);
    let meshed = mesh_surface(human_body(), &params)?;
    let m = &meshed.mesh;
    out.push_str(&format!(
        "meshing: {} vertices, {} triangles, area {:.12e} m^2, {} component(s)\n",
        m.vertices.len(),
        m.triangles.len(),
        m.area(),
        m.edge_components()
    ));
    // The pipeline's stage times come from a clock: natively std's, in WebAssembly the one
    // the host supplied (see `wasm` below).
    let timed = meshed.times.total() > std::time::Duration::ZERO;
    out.push_str(&format!("meshing: timed = {timed}\n"));
    if m.edge_components() != 1 || !timed {
        return Err("meshing: the body is not one piece, or its stages were not timed".into());
    }
    // A mesh of fem-mesh is the input of a model of fem-solvers.
    let mesh = Mesh::from_arrays(&m.vertices, &m.triangles)?;
    let lame = Material::new(1.0e5, 0.4, 1000.0)?.lame(PlaneModel::PlaneStrain);
    let mut model = Model::with_density(mesh, StableNeoHookean::new(lame)?, 1000.0)?;
    model.set_standard_gravity();
    let mut stepper = ExplicitStepper::new(
        &model,
        ExplicitParams {
            dt: 1e-4,
            ..Default::default()
        },
    )?;
    let mut state = State::at_rest(&model);
    for _ in 0..20 {
        stepper.step(&model, &mut state)?;
    }
    // A free body at rest falls without straining: after n symplectic Euler steps every
    // vertex is g dt^2 n (n + 1) / 2 lower, to round-off.
    let n = state.x.len() as Real;
    let drop = state
        .x
        .iter()
        .zip(model.mesh().vertices())
        .map(|(x, x0)| x0.y - x.y)
        .sum::<Real>()
        / n;
    let t = state.t;
    out.push_str(&format!(
        "meshing: mean drop after {t:.4} s = {drop:.12e} m\n"
    ));
    let discrete = 9.8 * 1e-4 * 1e-4 * (20.0 * 21.0) / 2.0;
    if (drop - discrete).abs() > 1e-9 * discrete {
        return Err(format!(
            "the body fell {drop} m in {t} s, symplectic Euler gives {discrete} m"
        )
        .into());
    }
    Ok(())
}

/// The whole report, or the first failure's message.
pub fn report() -> Result<String, String> {
    let mut out = String::new();
    cantilever_lines(&mut out).map_err(|e| e.to_string())?;
    meshing_lines(&mut out).map_err(|e| e.to_string())?;
    Ok(out)
}

/// The module's exports: `run()` computes the report (0 on success, 1 on failure) and
/// `text()` / `text_len()` locate it (or the error) in the module's memory.
#[cfg(target_arch = "wasm32")]
mod wasm {
    use std::cell::RefCell;

    thread_local! {
        static TEXT: RefCell<String> = const { RefCell::new(String::new()) };
    }

    // The host's clock in milliseconds (`performance.now()` under node and in browsers).
    #[link(wasm_import_module = "env")]
    unsafe extern "C" {
        safe fn now_ms() -> f64;
    }

    fn seconds() -> f64 {
        now_ms() / 1000.0
    }

    #[unsafe(no_mangle)]
    pub extern "C" fn run() -> u32 {
        // wasm32-unknown-unknown has no clock: supply one for the timing reports.
        fem_solvers::fem_core::clock::set_clock(seconds);
        fem_mesh::clock::set_clock(seconds);
        let (code, text) = match super::report() {
            Ok(t) => (0, t),
            Err(e) => (1, e),
        };
        TEXT.with(|t| *t.borrow_mut() = text);
        code
    }

    #[unsafe(no_mangle)]
    pub extern "C" fn text() -> *const u8 {
        TEXT.with(|t| t.borrow().as_ptr())
    }

    #[unsafe(no_mangle)]
    pub extern "C" fn text_len() -> usize {
        TEXT.with(|t| t.borrow().len())
    }
}
