//! A clock the caller supplies drives every stopwatch (its own process: the clock is global).

use std::sync::atomic::{AtomicU64, Ordering};

use fem_core::clock::{Stopwatch, now, set_clock};

static TICKS: AtomicU64 = AtomicU64::new(0);

/// A clock that advances 0.25 s each time it is read.
fn fake() -> f64 {
    TICKS.fetch_add(1, Ordering::SeqCst) as f64 * 0.25
}

#[test]
fn a_supplied_clock_is_the_one_stopwatches_read() {
    assert!(set_clock(fake));
    // Only the first call takes effect.
    assert!(!set_clock(|| 1e9));
    let w = Stopwatch::start(); // reads 0
    assert_eq!(w.seconds(), 0.25); // reads 0.25
    assert_eq!(now(), Some(0.5));
}
