//! # fem-web: the interactive browser app
//!
//! Grab and drag the soft body in a web browser, switch energy, solver and parameters live,
//! and watch the stress, the grab force and the errors in real time. The app is the project's
//! own crates compiled to WebAssembly: scenes are read, built and stepped by `fem-scene` and
//! the solver registry of `fem-solvers`, exactly as `fem2d run` does; this crate only binds
//! them (no scene parser, no stepper of its own).
//!
//! - [`app`]: the app's state and API in plain Rust ([`app::App`]), tested natively: real-time
//!   frames, grab / drag / release, live settings, reset, blow-up recovery, the fields the page
//!   draws.
//! - `wasm` (only for `wasm32`): the functions the page calls, exported with plain numbers and
//!   byte buffers in the module's memory, so no binding generator is needed.
//! - `www/`: the page (`index.html`, `app.js`), which draws on a canvas and drives the loop.
//!
//! `cargo xtask web --serve` builds the module and serves the page (docs/interactive.md).

pub mod app;
#[cfg(target_arch = "wasm32")]
mod wasm;

pub use app::{App, Field, Hud, MemoryFiles};
pub use fem_scene::drag::Held;
