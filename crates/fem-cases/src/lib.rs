//! # fem-cases: studies of scenes, and their files
//!
//! Pick this crate to run scenes with files and to reproduce and extend the paper's studies;
//! the scenes themselves, the step loop and the per-frame numbers live in `fem-scene`, the
//! command line in the `fem2d` crate.
//! - [`run`]: a scene run on a thread pool of the requested size with the system clock, its
//!   outputs (`summary.json`, `probes.csv`, `frames.jsonl`, VTK, ...) written atomically;
//! - [`outdir`]: output directories written as a unit (a lock, a staging directory renamed
//!   into place, leftovers of killed writers cleaned, only fem2d's own directories replaced);
//! - [`files`]: scene files, "case or file" arguments, mesh files next to the scene;
//! - [`compare`]: the energy x solver matrix on one scene;
//! - [`sweep`]: parameter sweeps split into shards, and their merge;
//! - [`table1`]: the paper's Table 1 regenerated, and the calibration scan behind its setting;
//! - [`pictures`]: a run's frames as PNG stress maps and animated GIFs, probe curves as charts
//!   (drawn by `fem-render`);
//! - [`figures`]: the paper's Figures 1-5 and the plots, regenerated from the built-in cases;
//! - [`report`]: one self-contained HTML page with all of it.
//!
//! Studies change typed scenes ([`fem_scene::scene::Scene`]); none prints, each reports
//! through a callback when it has something to say.
//!
//! ```
//! use fem_cases::run::{run_scene, RunOptions};
//! let scene = fem_scene::cases::load_case("case-a", &["solver.steps=100".into()]).unwrap();
//! let result = run_scene(&scene, &RunOptions::default()).unwrap();
//! // After 0.1 s the tip has fallen about 1/2 g t^2 = 49 mm (Table 1, frame 10).
//! let tip = result.probe("tip").unwrap().last().unwrap();
//! assert!((tip[1] + 0.049).abs() < 0.003);
//! ```

pub mod budget;
pub mod compare;
pub mod figures;
pub mod files;
pub mod outdir;
pub mod pictures;
pub mod report;
pub mod run;
pub mod scaling;
pub mod solid;
pub mod sweep;
pub mod table1;

/// The types most programs need, in one import: `use fem_cases::prelude::*;`.
///
/// Running a scene with files, pictures and outputs ([`run_scene`](run::run_scene)), the
/// report, and the scene layer's prelude (loading scenes, [`SceneError`](fem_scene::SceneError)).
pub mod prelude {
    pub use crate::report::{ReportOptions, write_report};
    pub use crate::run::{RunOptions, RunResult, Summary, run_scene};
    pub use fem_scene::prelude::{LoadedScene, Scene, SceneError, load_case, parse_scene};
}

// The README's example runs as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
