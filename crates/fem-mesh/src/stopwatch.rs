//! A stopwatch for the pipeline's stage times. It reads the system's monotonic clock, except on
//! `wasm32-unknown-unknown`, which has no clock (`std::time::Instant::now` panics there): in a
//! browser build every stage time reads zero and the pipeline still runs.

use std::time::Duration;

/// Started at construction; [`Stopwatch::elapsed`] is the time since.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stopwatch {
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    start: std::time::Instant,
}

impl Stopwatch {
    /// A stopwatch started now.
    pub(crate) fn start() -> Self {
        Stopwatch {
            #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
            start: std::time::Instant::now(),
        }
    }

    /// Time since [`Stopwatch::start`] (zero where there is no clock).
    pub(crate) fn elapsed(&self) -> Duration {
        #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
        return self.start.elapsed();
        #[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
        return Duration::ZERO;
    }
}
