//! # fem-scene: scenes and runs, without a file system, a clock, a terminal or a rasteriser
//!
//! Pick this crate to run whole simulations described by scene files anywhere, a browser
//! (WebAssembly) included:
//! - [`scene`]: the TOML scene format (mesh, material, energy, solver, boundary conditions,
//!   gravity, obstacles, probes, output cadence), `--set key=value` overrides, and the
//!   scene-level validation (the solver's own parameters are checked by their own `validate`,
//!   in `fem-solvers`);
//! - [`cases`]: the built-in cases A-D and `lower-leg` (the files of `fixtures/scenes/`, compiled in);
//! - [`build`]: from a scene to a mesh (rectangle, mesh JSON, 3D model or the built-in body
//!   through `fem-mesh`), a [`fem_solvers::Model`], the probes and the stepper (any solver of
//!   the registry, [`fem_solvers::SolverKind`]);
//! - [`run`]: the step loop with the per-frame numbers (stress, peaks, probes, runaway check)
//!   and the [`run::Summary`];
//! - [`drag`]: a recorded drag (grab, move, release at simulated times), replayed into a run
//!   as the interactive app records it.
//!
//! What the caller supplies, behind small traits in [`run`]: a [`run::Clock`] (or none), a
//! [`run::Progress`] report, [`run::FrameSink`]s that receive every recorded frame (files,
//! VTK, pictures, a browser canvas), and a [`build::MeshSource`] that returns a mesh or model
//! file's bytes by name.
//!
//! Architecture invariant: this crate has no file system access, reads no clock, prints
//! nothing and draws nothing; it compiles for `wasm32-unknown-unknown` (CI builds it).
//! `fem-cases` adds the file outputs and the studies, the `fem2d` crate the command line.
//!
//! ```
//! use fem_scene::{cases::load_case, run::{run, RunEnv}};
//! let scene = load_case("case-a", &["solver.steps=100".into()]).unwrap();
//! let result = run(&scene, &mut RunEnv::default()).unwrap();
//! // After 0.1 s the tip has fallen about 1/2 g t^2 = 49 mm (Table 1, frame 10).
//! let tip = result.probe("tip").unwrap().last().unwrap();
//! assert!((tip[1] + 0.049).abs() < 0.003);
//! ```

pub mod build;
pub mod cases;
pub mod drag;
pub mod error;
pub mod region_stats;
pub mod run;
pub mod scales;
pub mod scene;
pub mod solid;
mod solver_spec;

pub use error::SceneError;
pub use solver_spec::SolverSpec;

/// Supply the wall clock (seconds since any fixed origin) that every timing report below this
/// crate reads: the solvers' ([`fem_core::clock`]) and the mesh pipeline's
/// ([`fem_mesh::clock`]). Needed only on `wasm32-unknown-unknown`, which has no clock of its
/// own (timings read zero there otherwise); natively it replaces `Instant`. Only the first call
/// takes effect; it returns whether this one did.
pub fn set_clock(clock: fn() -> f64) -> bool {
    let core = fem_core::clock::set_clock(clock);
    let mesh = fem_mesh::clock::set_clock(clock);
    core && mesh
}

/// The types most programs need, in one import: `use fem_scene::prelude::*;`.
///
/// Loading a scene (a built-in case or a file's text), running it without a file system, its
/// result and summary, and the crate's error.
pub mod prelude {
    pub use crate::SceneError;
    pub use crate::build::{MeshSource, NoFiles};
    pub use crate::cases::load_case;
    pub use crate::run::{RunEnv, RunResult, Summary, run};
    pub use crate::scene::{LoadedScene, Scene, parse_scene};
}

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

// The programs of docs/using-the-crates.md (fem-core, fem-solvers, fem-mesh: all below this
// crate) run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../docs/using-the-crates.md")]
struct UsingTheCrates;
