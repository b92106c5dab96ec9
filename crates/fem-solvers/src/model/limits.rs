//! Upper bounds on every count a solver takes, so that no setting can make a step run for
//! hours or allocate without bound. A value above its bound is a one-line error naming the
//! field (`xpbd.iterations = 4294967296: must be at most 100000 (fem_solvers::limits)`).
//! Each bound is far above any useful setting.

/// Time steps (or nominal load increments' clock steps) of one run: 1e9 steps of the smallest
/// mesh take hours.
pub const MAX_STEPS: u64 = 1_000_000_000;
/// Frames a run records in memory (a time and each probe's displacement per frame): 1e7
/// frames of a few probes hold about 1 GB.
pub const MAX_RECORDED_FRAMES: u64 = 10_000_000;
/// Constraint iterations per (sub)step of PBD and XPBD.
pub const MAX_ITERATIONS: usize = 100_000;
/// Substeps per step of PBD and XPBD.
pub const MAX_SUBSTEPS: usize = 10_000;
/// Newton iterations per solve (implicit Euler, quasi-static).
pub const MAX_NEWTON_ITERATIONS: usize = 10_000;
/// Step halvings of Newton's line search: 2^-200 is far below f64 resolution of any step.
pub const MAX_HALVINGS: usize = 200;
/// Load increments of the quasi-static solver.
pub const MAX_LOAD_STEPS: usize = 1_000_000;
/// Bisections of a failed load increment: 2^-60 of an increment is below f64 resolution.
pub const MAX_BISECTIONS: usize = 60;
