//! Wall-clock time for the timing reports (Newton's splits, stage times), from a clock the
//! caller may supply.
//!
//! Natively the reports read `std::time::Instant`. `wasm32-unknown-unknown` has no clock
//! (`Instant::now` panics there), so in a WebAssembly build timings read zero unless the host
//! supplies one with [`set_clock`], for example the page's `performance.now()` imported into
//! the module. No result depends on a timing.

use std::sync::OnceLock;

use crate::math::Real;

/// Seconds since any fixed origin (only differences are used).
pub type ClockFn = fn() -> Real;

static CLOCK: OnceLock<ClockFn> = OnceLock::new();

/// Use `clock` for every timing from now on (on every target). Only the first call takes
/// effect; it returns whether this one did.
pub fn set_clock(clock: ClockFn) -> bool {
    CLOCK.set(clock).is_ok()
}

/// Seconds since a fixed origin: the supplied clock, else `Instant` natively; `None` on a
/// target without a clock when none was supplied.
pub fn now() -> Option<Real> {
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

/// Started by [`Stopwatch::start`]; [`Stopwatch::seconds`] is the time since then, 0 where
/// there is no clock.
#[derive(Clone, Copy, Debug)]
pub struct Stopwatch {
    start: Option<Real>,
}

impl Stopwatch {
    /// Start timing now.
    #[inline]
    pub fn start() -> Self {
        Stopwatch { start: now() }
    }

    /// Seconds since [`Stopwatch::start`] (never negative); 0 without a clock.
    #[inline]
    pub fn seconds(&self) -> Real {
        match (self.start, now()) {
            (Some(a), Some(b)) => (b - a).max(0.0),
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_elapsed_time_where_there_is_a_clock() {
        let w = Stopwatch::start();
        let mut x = 0.0;
        for i in 0..100_000 {
            x += (i as Real).sqrt();
        }
        assert!(x > 0.0);
        let s = w.seconds();
        assert!(s > 0.0 && s.is_finite(), "{s}");
        assert!(now().is_some());
    }
}
