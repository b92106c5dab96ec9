//! # fem-cases: scenes, the paper's cases, comparisons and the `fem2d` command
//!
//! Pick this crate to run whole simulations described by scene files, the way the `fem2d`
//! command does:
//! - [`scene`]: the TOML scene format (mesh, material, energy, solver, boundary conditions,
//!   gravity, obstacles, probes, output cadence), `--set key=value` overrides and validation
//!   with one-line errors;
//! - [`build`]: from a scene to a mesh, a [`fem_solvers::Model`] and a stepper (explicit, PBD,
//!   XPBD or implicit Euler);
//! - [`run`]: the step loop (or, for `static`, the load-increment loop of the quasi-static
//!   solver) with probes, frames, stress statistics, blow-up detection, timing and the run
//!   outputs (`summary.json`, `probes.csv`, `frames.jsonl`);
//! - [`cases`]: the built-in cases A-D (`fixtures/scenes/`);
//! - [`compare`]: the energy x solver matrix on one scene;
//! - [`sweep`]: parameter sweeps split into shards, and their merge;
//! - [`table1`]: the paper's Table 1 regenerated, and the calibration scan behind its setting;
//! - [`pictures`]: a run's frames as PNG stress maps and animated GIFs, probe curves as charts
//!   (drawn by `fem-render`);
//! - [`figures`]: the paper's Figures 1-5 and the plots, regenerated from the built-in cases;
//! - [`report`]: `fem2d report`, one self-contained HTML page with all of it.
//!
//! ```
//! use fem_cases::{cases::load_case, run::{run_scene, RunOptions}};
//! let scene = load_case("case-a", &["solver.steps=100".into()]).unwrap();
//! let result = run_scene(&scene, &RunOptions::default()).unwrap();
//! // After 0.1 s the tip has fallen about 1/2 g t^2 = 49 mm (Table 1, frame 10).
//! let tip = result.probe("tip").unwrap().last().unwrap();
//! assert!((tip[1] + 0.049).abs() < 0.003);
//! ```

pub mod build;
pub mod cases;
pub mod compare;
pub mod error;
pub mod figures;
pub mod pictures;
pub mod report;
pub mod run;
pub mod scene;
pub mod sweep;
pub mod table1;

pub use error::CaseError;
