//! Conversions between Python values and the scene's overrides, numpy arrays and JSON.

use fem_core::math::{Real, Vec2};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use crate::invalid;

/// The command line's flags as overrides, in its order (`--energy`, `--solver`, `--dt`,
/// `--steps`, then every `--set`), from the keyword arguments and `overrides`: a mapping of
/// scene keys to Python values (`{"material.youngs_modulus": 2e3, "energy": "stvk"}`) or a
/// sequence of `KEY=VALUE` strings in TOML syntax, as `--set` takes them.
pub fn overrides(
    energy: Option<&str>,
    solver: Option<&str>,
    dt: Option<f64>,
    steps: Option<u64>,
    overrides: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    if let Some(e) = energy {
        out.push(format!("energy={}", toml::Value::String(e.to_owned())));
    }
    if let Some(s) = solver {
        out.push(format!("solver.kind={}", toml::Value::String(s.to_owned())));
    }
    if let Some(dt) = dt {
        out.push(format!("solver.dt={dt:e}"));
    }
    if let Some(n) = steps {
        out.push(format!("solver.steps={n}"));
    }
    let Some(o) = overrides else {
        return Ok(out);
    };
    if o.is_none() {
        return Ok(out);
    }
    if let Ok(d) = o.cast::<PyDict>() {
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| invalid(format!("overrides: the key {k} is not a string")))?;
            let value =
                toml_value(&v).map_err(|why| invalid(format!("overrides: {key}: {why}")))?;
            out.push(format!("{key}={value}"));
        }
        return Ok(out);
    }
    if o.is_instance_of::<PyString>() {
        return Err(invalid(
            "overrides: expected a dict of scene keys or a list of KEY=VALUE strings, got a string",
        ));
    }
    let items = o.try_iter().map_err(|_| {
        invalid(format!(
            "overrides: expected a dict of scene keys or a list of KEY=VALUE strings, got {}",
            type_name(o)
        ))
    })?;
    for item in items {
        let item = item?;
        let s: String = item.extract().map_err(|_| {
            invalid(format!(
                "overrides: expected KEY=VALUE strings, got {}",
                type_name(&item)
            ))
        })?;
        out.push(s);
    }
    Ok(out)
}

fn type_name(o: &Bound<'_, PyAny>) -> String {
    o.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".to_owned())
}

/// A Python value as a TOML value (bool, int, float, str, and lists or tuples of them).
fn toml_value(v: &Bound<'_, PyAny>) -> Result<toml::Value, String> {
    // bool before int: Python's bool is an int.
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(
            v.extract::<bool>().map_err(|e| e.to_string())?,
        ));
    }
    if v.is_instance_of::<PyInt>() {
        return v
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| format!("the integer {v} does not fit 64 bits"));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(
            v.extract::<f64>().map_err(|e| e.to_string())?,
        ));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(
            v.extract::<String>().map_err(|e| e.to_string())?,
        ));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for item in v.try_iter().map_err(|e| e.to_string())? {
            items.push(toml_value(&item.map_err(|e| e.to_string())?)?);
        }
        return Ok(toml::Value::Array(items));
    }
    // numpy scalars and other numbers: take their float value.
    if let Ok(x) = v.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    Err(format!(
        "{} is not a scene value (bool, int, float, str or a list of them)",
        type_name(v)
    ))
}

/// A thread count as the command line's `--threads` takes it: 1 to
/// [`fem_cases::run::MAX_THREADS`], or `None` for rayon's default pool.
pub fn check_threads(threads: Option<usize>) -> PyResult<()> {
    let max = fem_cases::run::MAX_THREADS;
    match threads {
        Some(n) if n == 0 || n > max => Err(invalid(format!(
            "threads: {n} is not a thread count; give 1 to {max}, or None for rayon's default"
        ))),
        _ => Ok(()),
    }
}

/// JSON text as Python data (`json.loads`).
pub fn json_to_py<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// `(n, 2)` float64 from 2-vectors: a new array, or `out` filled (shape and type checked).
pub fn points<'py>(
    py: Python<'py>,
    v: impl ExactSizeIterator<Item = [Real; 2]>,
    out: Option<Bound<'py, PyArray2<f64>>>,
    what: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = v.len();
    let array = match out {
        Some(a) => {
            check_out(&a, &[n, 2], what)?;
            a
        }
        None => PyArray2::<f64>::zeros(py, [n, 2], false),
    };
    {
        let mut rw = array.readwrite();
        let slice = rw
            .as_slice_mut()
            .map_err(|_| invalid(format!("out: {what} needs a C-contiguous array")))?;
        for (dst, p) in slice.chunks_exact_mut(2).zip(v) {
            dst.copy_from_slice(&p);
        }
    }
    Ok(array)
}

/// `(n,)` float64: a new array, or `out` filled (shape and type checked).
pub fn values<'py>(
    py: Python<'py>,
    v: impl ExactSizeIterator<Item = Real>,
    out: Option<Bound<'py, PyArray1<f64>>>,
    what: &str,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let n = v.len();
    let array = match out {
        Some(a) => {
            check_out(&a, &[n], what)?;
            a
        }
        None => PyArray1::<f64>::zeros(py, [n], false),
    };
    {
        let mut rw = array.readwrite();
        let slice = rw
            .as_slice_mut()
            .map_err(|_| invalid(format!("out: {what} needs a C-contiguous array")))?;
        for (dst, x) in slice.iter_mut().zip(v) {
            *dst = x;
        }
    }
    Ok(array)
}

fn check_out<D>(a: &Bound<'_, numpy::PyArray<f64, D>>, shape: &[usize], what: &str) -> PyResult<()>
where
    D: numpy::ndarray::Dimension,
{
    if a.shape() != shape {
        return Err(invalid(format!(
            "out: {what} has shape {shape:?}, the array given has {:?}",
            a.shape()
        )));
    }
    if !a.is_c_contiguous() {
        return Err(invalid(format!("out: {what} needs a C-contiguous array")));
    }
    Ok(())
}

/// Vec2s as `[x, y]`.
pub fn pairs(v: &[Vec2]) -> impl ExactSizeIterator<Item = [Real; 2]> + '_ {
    v.iter().map(|p| [p.x, p.y])
}
