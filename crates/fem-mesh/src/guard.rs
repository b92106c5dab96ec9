//! Calls into the triangulator that turn its panics into errors.
//!
//! spade documents no panics for valid input, but some (nearly) collinear or nearly coincident
//! point sets make it panic (`Failed to locate position. This is a bug in spade.`). Every call
//! into spade runs inside [`guarded`], which catches the panic and returns a one-line
//! [`MeshError`] naming the stage, and keeps the panic's own message off standard error (a
//! panic hook, installed once, stays quiet while a guarded call runs on this thread and defers
//! to the previous hook otherwise).

use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Once;

use crate::MeshError;

thread_local! {
    static GUARDED: Cell<bool> = const { Cell::new(false) };
}

fn install_quiet_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !GUARDED.with(Cell::get) {
                previous(info);
            }
        }));
    });
}

/// Run `f`; a panic inside it becomes [`MeshError::Invalid`] for `stage`, saying that the
/// geometry is too degenerate for the triangulator.
pub(crate) fn guarded<R>(stage: &'static str, f: impl FnOnce() -> R) -> Result<R, MeshError> {
    install_quiet_hook();
    let outer = GUARDED.with(|g| g.replace(true));
    let result = catch_unwind(AssertUnwindSafe(f));
    GUARDED.with(|g| g.set(outer));
    result.map_err(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown failure".to_owned());
        MeshError::invalid(
            stage,
            format!(
                "the triangulator failed on this geometry ({}): the points are probably (nearly) collinear or coincident; check the model and the view",
                what.lines().next().unwrap_or_default()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error_naming_the_stage_and_values_pass_through() {
        assert_eq!(guarded("alpha shape", || 42).unwrap(), 42);
        let err = guarded("triangulate", || -> u32 {
            panic!("Failed to locate position")
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with("triangulate: the triangulator failed"),
            "{err}"
        );
        assert!(err.contains("Failed to locate position"), "{err}");
        assert_eq!(err.lines().count(), 1);
        // Nested guards restore the outer state.
        let inner = guarded("outer", || {
            guarded("inner", || -> u8 { panic!("x") }).is_err()
        });
        assert!(inner.unwrap());
        assert!(!GUARDED.with(Cell::get));
    }
}
