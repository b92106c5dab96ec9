//! A wall-clock stopwatch for the timing splits solvers report, reading zero where there is
//! no clock.
//!
//! `std::time::Instant::now()` panics at run time on `wasm32-unknown-unknown` (the browser
//! target without WASI), so there the stopwatch never reads the clock and every duration is
//! 0 s. Timings are reports only: no result depends on them.

use fem_core::math::Real;

/// Started by [`Stopwatch::start`]; [`Stopwatch::seconds`] is the time since then.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stopwatch {
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    start: std::time::Instant,
}

impl Stopwatch {
    /// Start timing now.
    #[inline]
    pub(crate) fn start() -> Self {
        Stopwatch {
            #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
            start: std::time::Instant::now(),
        }
    }

    /// Seconds since [`Stopwatch::start`]; 0 on targets without a clock.
    #[inline]
    pub(crate) fn seconds(&self) -> Real {
        #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
        {
            self.start.elapsed().as_secs_f64()
        }
        #[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
        {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_elapsed_time_where_there_is_a_clock() {
        let w = Stopwatch::start();
        let s = w.seconds();
        assert!(s >= 0.0 && s.is_finite());
    }
}
