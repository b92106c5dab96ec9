//! # fem-py: the Python package `pyfem2d`
//!
//! The extension module `pyfem2d._native`, built by maturin (`crates/fem-py/pyproject.toml`)
//! as one abi3 wheel for CPython 3.9 and later. It is a thin layer: scenes come from
//! `fem-scene` (the command line's scene files, built-in cases and `--set` overrides), steps
//! from the solver registry of `fem-solvers`, whole runs, Table 1 and the frame budget from
//! `fem-cases`, meshes from `fem-mesh`. It adds no physics of its own.
//!
//! Python conventions, enforced here for every entry point:
//! - a bad value raises `pyfem2d.InvalidInputError` (a `ValueError`) with the command line's
//!   one-line message; a file that cannot be read `pyfem2d.FileError` (an `OSError`); a run
//!   whose step fails (a blow-up, no convergence) `pyfem2d.StepFailedError`; all three derive
//!   from `pyfem2d.Fem2dError`;
//! - no Rust panic reaches Python: `guard` catches it and raises `pyfem2d.InternalError`
//!   (a `Fem2dError`, so `except Exception` sees it) instead of PyO3's `PanicException`, a
//!   `BaseException`;
//! - steps release the GIL, and long runs check for signals between chunks (Ctrl-C).
//!
//! docs/python.md describes the API; `python/pyfem2d/_native.pyi` types it.

mod convert;
mod simulation;
mod studies;

use std::panic::{AssertUnwindSafe, catch_unwind};

use fem_scene::SceneError;
use pyo3::prelude::*;
use pyo3::types::PyType;

/// The package's exception classes live in Python (`pyfem2d/_errors.py`): an exception with
/// two bases (`Fem2dError` and `ValueError`) cannot be declared from Rust.
fn raise(kind: &str, message: impl Into<String>) -> PyErr {
    let message: String = message.into();
    Python::attach(|py| {
        match py
            .import("pyfem2d._errors")
            .and_then(|m| m.getattr(kind))
            .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from))
        {
            Ok(class) => PyErr::from_type(class, message),
            // The package is imported before its extension runs; fall back all the same.
            Err(_) => pyo3::exceptions::PyRuntimeError::new_err(message),
        }
    })
}

/// A bad value: `pyfem2d.InvalidInputError` (a `ValueError`).
pub(crate) fn invalid(message: impl Into<String>) -> PyErr {
    raise("InvalidInputError", message)
}

/// A scene error as the matching exception, with the command line's one-line message.
pub(crate) fn scene_err(e: SceneError) -> PyErr {
    let message = e.to_string();
    match e {
        SceneError::Io(_) => raise("FileError", message),
        SceneError::BlowUp(_) => raise("StepFailedError", message),
        _ => invalid(message),
    }
}

/// A run that blew up: `pyfem2d.StepFailedError`.
pub(crate) fn blow_up(message: impl Into<String>) -> PyErr {
    raise("StepFailedError", message)
}

/// Run `f`, turning a panic into `pyfem2d.InternalError` (see the module docs).
pub(crate) fn guard<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            Err(raise(
                "InternalError",
                format!("internal error (a bug in fem2d; please report it): {what}"),
            ))
        }
    }
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<simulation::Simulation>()?;
    m.add_class::<simulation::Snapshot>()?;
    m.add_class::<simulation::StepReport>()?;
    m.add_function(wrap_pyfunction!(studies::cases, m)?)?;
    m.add_function(wrap_pyfunction!(studies::energies, m)?)?;
    m.add_function(wrap_pyfunction!(studies::solvers, m)?)?;
    m.add_function(wrap_pyfunction!(studies::case_text, m)?)?;
    m.add_function(wrap_pyfunction!(studies::run, m)?)?;
    m.add_function(wrap_pyfunction!(studies::table1, m)?)?;
    m.add_function(wrap_pyfunction!(studies::budget, m)?)?;
    m.add_function(wrap_pyfunction!(studies::mesh_model, m)?)?;
    m.add_function(wrap_pyfunction!(studies::mesh_json, m)?)?;
    m.add_function(wrap_pyfunction!(simulation::_rust_loop, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}

/// Panics inside [`guard`]: the tests' proof that a panic reaches Python as
/// `pyfem2d.InternalError`, an `Exception`.
#[pyfunction]
fn _panic_for_tests() -> PyResult<()> {
    guard(|| -> PyResult<()> { panic!("a panic raised on purpose by _panic_for_tests") })
}
