//! Wall-clock time for the pipeline's stage times, from a clock the caller may supply.
//!
//! Natively the stage times read `std::time::Instant`. `wasm32-unknown-unknown` has no clock
//! (`Instant::now` panics there), so in a WebAssembly build they read zero unless the host
//! supplies one with [`set_clock`] (for example the page's `performance.now()` imported into
//! the module). The mesh never depends on a timing.
//!
//! (The same small mechanism as `fem_core::clock`, repeated because this crate depends on no
//! other fem2d crate; a WebAssembly host that uses both sets both.)

use std::sync::OnceLock;
use std::time::Duration;

/// Seconds since any fixed origin (only differences are used).
pub type ClockFn = fn() -> f64;

static CLOCK: OnceLock<ClockFn> = OnceLock::new();

/// Use `clock` for every stage time from now on (on every target). Only the first call takes
/// effect; it returns whether this one did.
pub fn set_clock(clock: ClockFn) -> bool {
    CLOCK.set(clock).is_ok()
}

/// Seconds since a fixed origin: the supplied clock, else `Instant` natively; `None` on a
/// target without a clock when none was supplied.
fn now() -> Option<f64> {
    if let Some(clock) = CLOCK.get() {
        return Some(clock());
    }
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    {
        static ORIGIN: OnceLock<std::time::Instant> = OnceLock::new();
        Some(
            ORIGIN
                .get_or_init(std::time::Instant::now)
                .elapsed()
                .as_secs_f64(),
        )
    }
    #[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
    {
        None
    }
}

/// Started at construction; [`Stopwatch::elapsed`] is the time since.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stopwatch {
    start: Option<f64>,
}

impl Stopwatch {
    /// A stopwatch started now.
    pub(crate) fn start() -> Self {
        Stopwatch { start: now() }
    }

    /// Time since [`Stopwatch::start`] (zero where there is no clock).
    pub(crate) fn elapsed(&self) -> Duration {
        match (self.start, now()) {
            (Some(a), Some(b)) => Duration::from_secs_f64((b - a).max(0.0)),
            _ => Duration::ZERO,
        }
    }
}
