//! The functions the page calls (WebAssembly exports), with plain numbers and byte buffers in
//! the module's memory: no binding generator, no JavaScript glue beyond `www/app.js`.
//!
//! Text goes in through [`input`]: the page asks for a buffer of `len` bytes, writes UTF-8
//! into the memory at the returned address, then calls the function that reads it. Results
//! that are arrays (positions, triangles, a field, the heads-up numbers) are written into a
//! buffer owned here, whose address the call returns and whose length [`out_len`] gives;
//! the page copies them out before its next call. Text results (an error message, names, the
//! state hash) go through the byte buffer [`text`] / [`text_len`].
//!
//! Functions that can fail return 0 on success and 1 on failure, with the one-line message in
//! the text buffer. There is one app per page (the side-by-side panes are separate modules).
// `#[unsafe(no_mangle)]` is how a function is exported from a WebAssembly module, and an
// `unsafe extern` block how one is imported (the host's clock); they are the only unsafe
// constructs here (there is no unsafe block), hence this exception to the workspace's
// `unsafe_code = "deny"`.
#![allow(unsafe_code)]

use std::cell::RefCell;

use crate::app::{App, Field, MemoryFiles};

thread_local! {
    static APP: RefCell<Option<App>> = const { RefCell::new(None) };
    static FILES: RefCell<MemoryFiles> = RefCell::new(MemoryFiles::default());
    static INPUT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
    static TEXT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
    static F64: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
    static F32: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
    static U32: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
    static OUT_LEN: RefCell<usize> = const { RefCell::new(0) };
}

// The host's clock in milliseconds (the page's and node's `performance.now()`), so that the
// solvers' and the mesh pipeline's timings are real in the browser.
#[link(wasm_import_module = "env")]
unsafe extern "C" {
    safe fn now_ms() -> f64;
}

fn host_seconds() -> f64 {
    now_ms() / 1000.0
}

fn set_text(s: &str) {
    TEXT.with(|t| {
        let mut t = t.borrow_mut();
        t.clear();
        t.extend_from_slice(s.as_bytes());
    });
}

fn input_string() -> String {
    INPUT.with(|i| String::from_utf8_lossy(&i.borrow()).into_owned())
}

/// 0 on `Ok`, else 1 with the message in the text buffer.
fn status(r: Result<(), String>) -> u32 {
    match r {
        Ok(()) => 0,
        Err(e) => {
            set_text(&e);
            1
        }
    }
}

fn with_app<T>(f: impl FnOnce(&mut App) -> T, default: T) -> T {
    APP.with(|a| match a.borrow_mut().as_mut() {
        Some(app) => f(app),
        None => default,
    })
}

fn out_f64(values: Vec<f64>) -> *const f64 {
    OUT_LEN.with(|l| *l.borrow_mut() = values.len());
    F64.with(|b| {
        let mut b = b.borrow_mut();
        *b = values;
        b.as_ptr()
    })
}

fn out_f32(values: impl Iterator<Item = f64>) -> *const f32 {
    F32.with(|b| {
        let mut b = b.borrow_mut();
        b.clear();
        b.extend(values.map(|v| v as f32));
        OUT_LEN.with(|l| *l.borrow_mut() = b.len());
        b.as_ptr()
    })
}

fn out_u32(values: impl Iterator<Item = u32>) -> *const u32 {
    U32.with(|b| {
        let mut b = b.borrow_mut();
        b.clear();
        b.extend(values);
        OUT_LEN.with(|l| *l.borrow_mut() = b.len());
        b.as_ptr()
    })
}

/// A buffer of `len` bytes for the next text input; its address.
#[unsafe(no_mangle)]
pub extern "C" fn input(len: usize) -> *mut u8 {
    INPUT.with(|i| {
        let mut i = i.borrow_mut();
        i.clear();
        i.resize(len, 0);
        i.as_mut_ptr()
    })
}

/// The address of the text result.
#[unsafe(no_mangle)]
pub extern "C" fn text() -> *const u8 {
    TEXT.with(|t| t.borrow().as_ptr())
}

/// The length of the text result, bytes.
#[unsafe(no_mangle)]
pub extern "C" fn text_len() -> usize {
    TEXT.with(|t| t.borrow().len())
}

/// The length (in elements) of the last array result.
#[unsafe(no_mangle)]
pub extern "C" fn out_len() -> usize {
    OUT_LEN.with(|l| *l.borrow())
}

/// Load the built-in case named by the input.
#[unsafe(no_mangle)]
pub extern "C" fn load_case() -> u32 {
    fem_scene::set_clock(host_seconds);
    let name = input_string();
    status(App::case(&name).map(|app| APP.with(|a| *a.borrow_mut() = Some(app))))
}

/// Keep the input as a file named by its first `name_len` bytes (the rest is its content),
/// for the scenes loaded after it.
#[unsafe(no_mangle)]
pub extern "C" fn add_file(name_len: usize) {
    INPUT.with(|i| {
        let i = i.borrow();
        let n = name_len.min(i.len());
        let name = String::from_utf8_lossy(&i[..n]).into_owned();
        FILES.with(|f| f.borrow_mut().insert(&name, i[n..].to_vec()));
    });
}

/// Load a scene: the input is its name (first `name_len` bytes) and its TOML text.
#[unsafe(no_mangle)]
pub extern "C" fn load_scene(name_len: usize) -> u32 {
    let all = input_string();
    let n = name_len.min(all.len());
    let (origin, text) = all.split_at(n);
    fem_scene::set_clock(host_seconds);
    let files = FILES.with(|f| f.borrow().clone());
    status(App::scene(text, origin, files).map(|app| APP.with(|a| *a.borrow_mut() = Some(app))))
}

/// Set a scene key: the input is the key (first `key_len` bytes) and the value (TOML).
/// Returns 0 (kept the state), 2 (restarted) or 1 (refused; message in the text buffer).
#[unsafe(no_mangle)]
pub extern "C" fn set(key_len: usize) -> u32 {
    let all = input_string();
    let n = key_len.min(all.len());
    let (key, value) = all.split_at(n);
    with_app(
        |app| match app.set(key, value) {
            Ok(false) => 0,
            Ok(true) => 2,
            Err(e) => {
                set_text(&e);
                1
            }
        },
        1,
    )
}

/// Back to `t = 0`.
#[unsafe(no_mangle)]
pub extern "C" fn reset() {
    with_app(App::reset, ());
}

/// Start a frame `wall_seconds` after the last; the steps it wants.
#[unsafe(no_mangle)]
pub extern "C" fn begin_frame(wall_seconds: f64) -> f64 {
    with_app(|app| app.begin_frame(wall_seconds) as f64, 0.0)
}

/// Take up to `n` steps; the number taken, or -1 after a failure (message in the text
/// buffer and in the heads-up numbers).
#[unsafe(no_mangle)]
pub extern "C" fn step(n: f64) -> f64 {
    with_app(
        |app| match app.step(n.max(0.0) as u64) {
            Ok(k) => k as f64,
            Err(e) => {
                set_text(&e);
                -1.0
            }
        },
        -1.0,
    )
}

/// End the frame: `steps` taken in `physics_ms` over `wall_seconds`.
#[unsafe(no_mangle)]
pub extern "C" fn end_frame(steps: f64, physics_ms: f64, wall_seconds: f64) {
    with_app(
        |app| app.end_frame(steps.max(0.0) as u64, physics_ms, wall_seconds),
        (),
    );
}

/// Grab at `(x, y)` (m); `stiffness` > 0 for a spring (N/m), else a pin. 1 if grabbed.
#[unsafe(no_mangle)]
pub extern "C" fn grab_at(x: f64, y: f64, stiffness: f64) -> u32 {
    with_app(
        |app| match app.grab_at(x, y, stiffness) {
            Ok(true) => 1,
            Ok(false) => 0,
            Err(e) => {
                set_text(&e);
                0
            }
        },
        0,
    )
}

/// Move the hand to `(x, y)` (m).
#[unsafe(no_mangle)]
pub extern "C" fn drag_to(x: f64, y: f64) {
    with_app(
        |app| {
            let _ = app.drag_to(x, y);
        },
        (),
    );
}

/// Let go.
#[unsafe(no_mangle)]
pub extern "C" fn release() {
    with_app(App::release, ());
}

/// Vertex positions as `x0, y0, x1, ...` (f32).
#[unsafe(no_mangle)]
pub extern "C" fn positions() -> *const f32 {
    with_app(
        |app| out_f32(app.positions().iter().flat_map(|p| [p.x, p.y])),
        std::ptr::null(),
    )
}

/// Triangles as vertex indices (u32, three per triangle).
#[unsafe(no_mangle)]
pub extern "C" fn triangles() -> *const u32 {
    with_app(
        |app| out_u32(app.triangles().iter().flatten().copied()),
        std::ptr::null(),
    )
}

/// The body's boundary edges as vertex indices (u32, two per edge; the body on the left of
/// each `a -> b`).
#[unsafe(no_mangle)]
pub extern "C" fn boundary_edges() -> *const u32 {
    with_app(
        |app| out_u32(app.boundary_edges().iter().flatten().copied()),
        std::ptr::null(),
    )
}

/// The material region of each triangle (u32; 0 the base material, `k` the `k`-th
/// `[[regions]]` entry).
#[unsafe(no_mangle)]
pub extern "C" fn material_regions() -> *const u32 {
    with_app(
        |app| out_u32(app.material_regions().into_iter()),
        std::ptr::null(),
    )
}

/// The material regions' names, by tag, one per line, into the text buffer.
#[unsafe(no_mangle)]
pub extern "C" fn material_region_names() {
    with_app(|app| set_text(&app.material_region_names().join("\n")), ());
}

/// The normal contact pressure per vertex after the last step, Pa (f32; 0 off contact).
#[unsafe(no_mangle)]
pub extern "C" fn contact_pressure() -> *const f32 {
    with_app(
        |app| out_f32(app.contact_pressure().iter().copied()),
        std::ptr::null(),
    )
}

/// A field (0 von Mises per triangle, 1 displacement per vertex, 2 det F per triangle), f32.
#[unsafe(no_mangle)]
pub extern "C" fn field(kind: u32) -> *const f32 {
    let field = Field::from_index(kind).unwrap_or(Field::VonMises);
    with_app(
        |app| out_f32(app.field(field).into_iter()),
        std::ptr::null(),
    )
}

/// The heads-up numbers (f64): t, step, steps last frame, steps wanted, physics ms, real-time
/// factor, slowed (0/1), peak von Mises, inverted, min det F, area error, area change, has
/// grab force (0/1), force x, force y, stopped on an error (0/1; the message is in the text
/// buffer), contacts, their smallest gap (m; a huge value without contacts), their total
/// force x, y (N), the peak contact pressure (Pa), the contact length (m), the base
/// material's peak von Mises (Pa; the soft tissue's in a body with bones).
#[unsafe(no_mangle)]
pub extern "C" fn hud() -> *const f64 {
    with_app(
        |app| {
            let h = app.hud().clone();
            if let Some(e) = &h.error {
                set_text(e);
            }
            let f = h.grab_force.unwrap_or([0.0, 0.0]);
            out_f64(vec![
                h.t,
                h.step as f64,
                h.steps_last_frame as f64,
                h.steps_wanted as f64,
                h.physics_ms,
                h.real_time_factor,
                f64::from(u8::from(h.slowed)),
                h.peak_von_mises,
                h.inverted as f64,
                h.min_det_f,
                h.area_error,
                h.area_change,
                f64::from(u8::from(h.grab_force.is_some())),
                f[0],
                f[1],
                f64::from(u8::from(h.error.is_some())),
                h.contacts as f64,
                h.min_gap.min(f64::MAX),
                h.contact_force[0],
                h.contact_force[1],
                h.contact_pressure_peak,
                h.contact_length,
                h.peak_von_mises_base,
            ])
        },
        std::ptr::null(),
    )
}

/// Rest-mesh bounds (f64): min x, min y, max x, max y.
#[unsafe(no_mangle)]
pub extern "C" fn bounds() -> *const f64 {
    with_app(
        |app| {
            let (lo, hi) = app.bounds();
            out_f64(vec![lo[0], lo[1], hi[0], hi[1]])
        },
        std::ptr::null(),
    )
}

/// Obstacles and ground (f64): the ground as `has, px, py, nx, ny`, the obstacle count, then
/// each obstacle's corner count and corners `x, y`.
#[unsafe(no_mangle)]
pub extern "C" fn scenery() -> *const f64 {
    with_app(
        |app| {
            let mut v = Vec::new();
            match app.ground() {
                Some((p, n)) => v.extend([1.0, p.x, p.y, n.x, n.y]),
                None => v.extend([0.0; 5]),
            }
            let obstacles = app.obstacles();
            v.push(obstacles.len() as f64);
            for poly in obstacles {
                v.push(poly.len() as f64);
                v.extend(poly.iter().flat_map(|p| [p.x, p.y]));
            }
            out_f64(v)
        },
        std::ptr::null(),
    )
}

/// The energy and solver names, `energy solver`, into the text buffer.
#[unsafe(no_mangle)]
pub extern "C" fn names() {
    with_app(
        |app| {
            let (e, s) = app.names();
            set_text(&format!("{e} {s}"));
        },
        (),
    );
}

/// Start recording the hand.
#[unsafe(no_mangle)]
pub extern "C" fn record_start() {
    with_app(App::start_recording, ());
}

/// Stop recording; the recorded drag's JSON into the text buffer.
#[unsafe(no_mangle)]
pub extern "C" fn record_stop() {
    with_app(|app| set_text(&app.stop_recording().to_json()), ());
}

/// Restart the scene and replay the drag whose JSON is the input (named by its first
/// `name_len` bytes in messages). 0, or 1 with the message in the text buffer.
#[unsafe(no_mangle)]
pub extern "C" fn replay(name_len: usize) -> u32 {
    let all = input_string();
    let n = name_len.min(all.len());
    let (name, json) = all.split_at(n);
    status(
        fem_scene::drag::DragTrajectory::parse(json, name)
            .map_err(|e| e.to_string())
            .and_then(|drag| {
                with_app(
                    |app| {
                        app.replay(&drag);
                        Ok(())
                    },
                    Err("no scene is loaded".to_owned()),
                )
            }),
    )
}

/// The names the page offers, into the text buffer: the built-in cases, the energies and the
/// solvers of the registry, as three lines of space-separated names (so a solver added to
/// the registry appears in the page without page code).
#[unsafe(no_mangle)]
pub extern "C" fn catalogue() {
    let cases = fem_scene::cases::names().join(" ");
    let energies: Vec<&str> = fem_core::energy::EnergyKind::ALL
        .iter()
        .map(|k| k.name())
        .collect();
    let solvers: Vec<&str> = fem_solvers::SolverKind::ALL
        .iter()
        .map(|k| k.name())
        .collect();
    set_text(&format!(
        "{cases}\n{}\n{}",
        energies.join(" "),
        solvers.join(" ")
    ));
}

/// The current value of a scene key named by the input (TOML syntax; empty when unset), into
/// the text buffer, so the page's controls show the scene's settings.
#[unsafe(no_mangle)]
pub extern "C" fn get() {
    let key = input_string();
    let value = with_app(|app| app.get(&key).unwrap_or_default(), String::new());
    set_text(&value);
}

/// The state's fingerprint (hex of [`fem_solvers::State::digest`]) into the text buffer.
#[unsafe(no_mangle)]
pub extern "C" fn state_hash() {
    with_app(
        |app| set_text(&format!("{:016x}", app.state().digest())),
        (),
    );
}
