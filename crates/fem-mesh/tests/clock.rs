//! A clock the caller supplies gives the pipeline's stage times (its own process: the clock is
//! global).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use fem_mesh::body::human_body;
use fem_mesh::clock::set_clock;
use fem_mesh::pipeline::{PipelineParams, mesh_surface};

static TICKS: AtomicU64 = AtomicU64::new(0);

/// A clock that advances 1 s each time it is read.
fn fake() -> f64 {
    TICKS.fetch_add(1, Ordering::SeqCst) as f64
}

#[test]
fn a_supplied_clock_times_every_stage() {
    assert!(set_clock(fake));
    let out = mesh_surface(human_body(), &PipelineParams::default()).unwrap();
    // Each stage reads the clock twice, one tick apart.
    for (name, t) in [
        ("project", out.times.project),
        ("alpha", out.times.alpha),
        ("simplify", out.times.simplify),
        ("triangulate", out.times.triangulate),
        ("quality", out.times.quality),
    ] {
        assert_eq!(t, Duration::from_secs(1), "{name}");
    }
}
