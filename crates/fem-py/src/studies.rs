//! Whole runs, Table 1, the frame budget and the mesh pipeline, as the command line runs them,
//! returned as Python data (the JSON the command line writes, as dicts and lists, with numpy
//! arrays for the series).

use fem_cases::budget::{BudgetSpec, Framework, RankBy};
use fem_cases::files::load_case_or_file;
use fem_cases::run::{RunOptions, run_scene};
use fem_core::energy::EnergyKind;
use fem_mesh::Mesh2;
use fem_mesh::alpha::AlphaParams;
use fem_mesh::load::{LoadOptions, load_model};
use fem_mesh::pipeline::{PipelineParams, mesh_surface};
use fem_mesh::triangulate::TriangulateParams;
use fem_mesh::types::Surface3;
use fem_scene::build::preset_camera;
use fem_scene::scene::ViewName;
use fem_solvers::SolverKind;
use numpy::{AllowTypeChange, PyArray1, PyArrayLike2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{check_threads, json_to_py, points, values};
use crate::{guard, invalid, scene_err};

/// The built-in cases' names.
#[pyfunction]
pub fn cases() -> Vec<&'static str> {
    fem_scene::cases::names()
}

/// The energies' names, as the command line and scene files spell them.
#[pyfunction]
pub fn energies() -> Vec<&'static str> {
    EnergyKind::ALL.iter().map(|e| e.name()).collect()
}

/// The solvers' names, as the command line and scene files spell them.
#[pyfunction]
pub fn solvers() -> Vec<&'static str> {
    SolverKind::ALL.iter().map(|s| s.name()).collect()
}

/// A built-in case's scene file (TOML text).
#[pyfunction]
pub fn case_text(name: &str) -> PyResult<&'static str> {
    fem_scene::cases::case_text(name).ok_or_else(|| {
        invalid(format!(
            "`{name}` is not a built-in case ({})",
            fem_scene::cases::names().join(", ")
        ))
    })
}

/// Run a scene to its end as `fem2d run` does; the summary (`summary.json` as a dict), the
/// probes' displacement series and the last frame.
#[pyfunction]
#[pyo3(signature = (scene="case-a", overrides=None, *, energy=None, solver=None, dt=None, steps=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn run<'py>(
    py: Python<'py>,
    scene: &str,
    overrides: Option<&Bound<'py, PyAny>>,
    energy: Option<&str>,
    solver: Option<&str>,
    dt: Option<f64>,
    steps: Option<u64>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let o = crate::convert::overrides(energy, solver, dt, steps, overrides)?;
        check_threads(threads)?;
        let name = scene.to_owned();
        let result = py
            .detach(move || {
                let loaded = load_case_or_file(&name, &o)?;
                run_scene(
                    &loaded,
                    &RunOptions {
                        threads,
                        ..RunOptions::default()
                    },
                )
            })
            .map_err(scene_err)?;
        let d = PyDict::new(py);
        let summary = serde_json::to_string(&result.summary).map_err(|e| invalid(e.to_string()))?;
        d.set_item("summary", json_to_py(py, &summary)?)?;
        let probes = PyDict::new(py);
        for (p, series) in result.probes.iter().zip(&result.probe_series) {
            probes.set_item(&p.name, points(py, series.iter().copied(), None, "probe")?)?;
        }
        d.set_item("probes", probes)?;
        d.set_item(
            "frame_steps",
            PyArray1::from_vec(py, result.frame_times.iter().map(|f| f.0 as i64).collect()),
        )?;
        d.set_item(
            "frame_times",
            values(py, result.frame_times.iter().map(|f| f.1), None, "times")?,
        )?;
        d.set_item(
            "final_positions",
            points(
                py,
                result.final_positions.iter().copied(),
                None,
                "positions",
            )?,
        )?;
        d.set_item(
            "final_von_mises",
            values(
                py,
                result.final_von_mises.iter().copied(),
                None,
                "von Mises",
            )?,
        )?;
        Ok(d)
    })
}

/// The paper's Table 1 regenerated from case A (`fem2d table1 --json`, as a dict).
#[pyfunction]
#[pyo3(signature = (overrides=None, *, repeats=1, threads=1))]
pub fn table1<'py>(
    py: Python<'py>,
    overrides: Option<&Bound<'py, PyAny>>,
    repeats: usize,
    threads: usize,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let o = crate::convert::overrides(None, None, None, None, overrides)?;
        check_threads(Some(threads))?;
        if repeats == 0 {
            return Err(invalid("repeats: 0; give 1 or more"));
        }
        let table = py
            .detach(move || fem_cases::table1::table1(&o, repeats, Some(threads)))
            .map_err(scene_err)?;
        let text = serde_json::to_string(&table).map_err(|e| invalid(e.to_string()))?;
        json_to_py(py, &text)
    })
}

/// The frame budget (`fem2d budget`): which energy x framework fits a real-time frame, at
/// which setting, how wrong it is. The answer (`budget.json` as a dict) plus its table as
/// markdown under `"markdown"`. `progress(message)` is told what runs.
#[pyfunction]
#[pyo3(signature = (scene="case-a", overrides=None, *, fps=None, budget_ms=None, haptics=false, duration=None, energies=None, frameworks=None, rank_by=None, settle=None, criterion=None, reference_steps=None, max_minutes=None, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn budget<'py>(
    py: Python<'py>,
    scene: &str,
    overrides: Option<&Bound<'py, PyAny>>,
    fps: Option<f64>,
    budget_ms: Option<f64>,
    haptics: bool,
    duration: Option<f64>,
    energies: Option<Vec<String>>,
    frameworks: Option<Vec<String>>,
    rank_by: Option<&str>,
    settle: Option<f64>,
    criterion: Option<f64>,
    reference_steps: Option<u64>,
    max_minutes: Option<f64>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    guard(|| {
        let o = crate::convert::overrides(None, None, None, None, overrides)?;
        let mut spec = if haptics {
            BudgetSpec::haptics()
        } else {
            BudgetSpec::default()
        };
        if let Some(f) = fps {
            spec.fps = f;
        }
        if let Some(b) = budget_ms {
            spec.budget_ms = b;
        }
        spec.duration = duration;
        if let Some(r) = rank_by {
            spec.rank_by = Some(RankBy::parse(r).map_err(|e| invalid(format!("rank_by: {e}")))?);
        }
        if let Some(x) = settle {
            spec.settle = x;
        }
        spec.reference_steps = reference_steps;
        if let Some(x) = criterion {
            spec.criterion = x;
        }
        if let Some(x) = max_minutes {
            spec.max_minutes = x;
        }
        if let Some(names) = &energies {
            spec.energies = names
                .iter()
                .map(|e| {
                    e.parse::<EnergyKind>()
                        .map_err(|err| invalid(format!("energies: {err}")))
                })
                .collect::<PyResult<_>>()?;
            twice("energies", names)?;
        }
        if let Some(names) = &frameworks {
            spec.frameworks = names
                .iter()
                .map(|f| Framework::parse(f).map_err(|err| invalid(format!("frameworks: {err}"))))
                .collect::<PyResult<_>>()?;
            twice("frameworks", names)?;
        }
        let base = load_case_or_file(scene, &o).map_err(scene_err)?;
        // The comparison runs with the GIL released; progress messages wait in a channel and
        // are handed to the callback when it is back.
        let (tx, rx) = std::sync::mpsc::channel::<String>();
        let result = py.detach(move || {
            fem_cases::budget::budget(&base, &spec, |what| {
                let _ = tx.send(what.to_owned());
            })
        });
        if let Some(cb) = &progress {
            for message in rx.try_iter() {
                cb.call1((message,))?;
            }
        }
        let result = result.map_err(scene_err)?;
        let text = serde_json::to_string(&result.budget).map_err(|e| invalid(e.to_string()))?;
        let out = json_to_py(py, &text)?;
        out.set_item("markdown", result.budget.to_markdown())?;
        Ok(out)
    })
}

/// A name listed twice is an error naming the argument (the rows would repeat).
fn twice(arg: &str, names: &[String]) -> PyResult<()> {
    for (k, name) in names.iter().enumerate() {
        if names[..k].contains(name) {
            return Err(invalid(format!(
                "{arg} {}: {name} is listed twice",
                names.join(",")
            )));
        }
    }
    Ok(())
}

/// The mesh pipeline (`fem2d mesh`): a 3D model, from a file (OBJ, STL, PLY) or from
/// `points` `(k, 3)` and `triangles` `(l, 3)`, projected from `view`, outlined, simplified and
/// meshed. A dict: `points` `(n, 2)`, `triangles` `(m, 3)` int64, `regions` `(m,)` int64,
/// `region_names`, `quality` (the quality report), `epsilon`, `alpha_radius`.
#[pyfunction]
#[pyo3(signature = (path=None, *, points=None, triangles=None, scale=1.0, view="side", alpha=None, epsilon=None, max_area=None, min_angle=25.0, max_steiner=None, groups=None))]
#[allow(clippy::too_many_arguments)]
pub fn mesh_model<'py>(
    py: Python<'py>,
    path: Option<std::path::PathBuf>,
    points: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
    triangles: Option<PyArrayLike2<'py, i64, AllowTypeChange>>,
    scale: f64,
    view: &str,
    alpha: Option<f64>,
    epsilon: Option<f64>,
    max_area: Option<f64>,
    min_angle: f64,
    max_steiner: Option<usize>,
    groups: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyDict>> {
    guard(|| {
        let view = ViewName::ALL
            .iter()
            .copied()
            .find(|v| v.name() == view)
            .ok_or_else(|| {
                invalid(format!(
                    "view: `{view}` is not a view ({})",
                    ViewName::ALL.map(|v| v.name()).join(", ")
                ))
            })?;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(invalid(format!(
                "scale: {scale} is not a positive finite factor"
            )));
        }
        let mut surface = match (&path, points, triangles) {
            (Some(p), None, None) => {
                let options = LoadOptions {
                    groups: groups.clone().unwrap_or_default(),
                };
                let p = p.clone();
                py.detach(move || load_model(&p, &options))
                    .map_err(|e| mesh_error(&e.to_string()))?
            }
            (None, Some(pts), Some(tris)) => surface(&pts, &tris)?,
            _ => {
                return Err(invalid(
                    "mesh_model: give either a model file's path, or both points (k, 3) and triangles (l, 3)",
                ));
            }
        };
        surface.scale(scale);
        let (lo, hi) = surface
            .bounds()
            .ok_or_else(|| invalid("points: the model has no vertex"))?;
        let mut params = PipelineParams {
            camera: preset_camera(view, lo, hi),
            alpha: AlphaParams {
                radius: alpha,
                ..Default::default()
            },
            epsilon,
            triangulate: TriangulateParams {
                max_area,
                min_angle_deg: min_angle,
                ..Default::default()
            },
            ..PipelineParams::default()
        };
        if let Some(cap) = max_steiner {
            params.triangulate.max_steiner_points = cap;
        }
        let out = py
            .detach(move || mesh_surface(surface, &params))
            .map_err(|e| mesh_error(&e.to_string()))?;
        let d = mesh_dict(py, &out.mesh)?;
        let quality = serde_json::to_string(&out.quality).map_err(|e| invalid(e.to_string()))?;
        d.set_item("quality", json_to_py(py, &quality)?)?;
        d.set_item("epsilon", out.epsilon)?;
        d.set_item("alpha_radius", out.alpha.radius)?;
        Ok(d)
    })
}

/// A pipeline error: bad input, named by the pipeline's own message.
fn mesh_error(message: &str) -> PyErr {
    invalid(format!("mesh: {message}"))
}

/// The rows of `array` when it has `cols` columns, else an error naming `what` and `shape`.
fn rows<'a, T: Copy + numpy::Element>(
    array: &'a PyArrayLike2<'_, T, AllowTypeChange>,
    cols: usize,
    what: &str,
    shape: &str,
) -> PyResult<numpy::ndarray::ArrayView2<'a, T>> {
    let a = array.as_array();
    if a.ncols() != cols {
        return Err(invalid(format!(
            "{what}: expected shape {shape}, got ({}, {})",
            a.nrows(),
            a.ncols()
        )));
    }
    Ok(a)
}

/// Triangles as vertex indices, each checked to be in `0..n` (any non-negative index when `n`
/// is `None`: the mesh check names the rest).
fn triangle_rows(
    triangles: &PyArrayLike2<'_, i64, AllowTypeChange>,
    n: Option<usize>,
    shape: &str,
) -> PyResult<Vec<[usize; 3]>> {
    let t = rows(triangles, 3, "triangles", shape)?;
    let mut out = Vec::with_capacity(t.nrows());
    for (k, row) in t.rows().into_iter().enumerate() {
        let mut tri = [0usize; 3];
        for (c, &i) in row.iter().enumerate() {
            let valid = usize::try_from(i).ok().filter(|&i| n.is_none_or(|n| i < n));
            tri[c] = valid.ok_or_else(|| {
                let count = n.map_or(String::new(), |n| format!(", but there are {n} points"));
                invalid(format!("triangles: row {k} names vertex {i}{count}"))
            })?;
        }
        out.push(tri);
    }
    Ok(out)
}

/// A surface from `(k, 3)` points and `(l, 3)` triangles, checked.
fn surface(
    points: &PyArrayLike2<'_, f64, AllowTypeChange>,
    triangles: &PyArrayLike2<'_, i64, AllowTypeChange>,
) -> PyResult<Surface3> {
    let p = rows(points, 3, "points", "(k, 3)")?;
    let vertices: Vec<[f64; 3]> = p.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
    if let Some((i, v)) = vertices
        .iter()
        .enumerate()
        .find(|(_, v)| !v.iter().all(|c| c.is_finite()))
    {
        return Err(invalid(format!("points: row {i} is {v:?}, not finite")));
    }
    let triangles = triangle_rows(triangles, Some(vertices.len()), "(l, 3)")?;
    Ok(Surface3 {
        vertices,
        triangles,
    })
}

/// A 2D mesh as the dict `mesh_model` returns (without the report).
fn mesh_dict<'py>(py: Python<'py>, mesh: &Mesh2) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "points",
        points(py, mesh.vertices.iter().copied(), None, "points")?,
    )?;
    let flat: Vec<i64> = mesh
        .triangles
        .iter()
        .flat_map(|t| t.map(|i| i as i64))
        .collect();
    let tris = PyArray1::from_vec(py, flat).reshape([mesh.triangles.len(), 3])?;
    d.set_item("triangles", tris)?;
    let regions: Vec<i64> = (0..mesh.triangles.len())
        .map(|t| i64::from(mesh.region_of(t)))
        .collect();
    d.set_item("regions", PyArray1::from_vec(py, regions))?;
    d.set_item("region_names", mesh.region_names.clone())?;
    Ok(d)
}

/// The mesh JSON text (the mesh file contract) of `points` `(n, 2)` and `triangles` `(m, 3)`,
/// with optional per-triangle `regions` and their names; checked as a mesh file is.
#[pyfunction]
#[pyo3(signature = (points, triangles, regions=None, region_names=None))]
pub fn mesh_json<'py>(
    points: PyArrayLike2<'py, f64, AllowTypeChange>,
    triangles: PyArrayLike2<'py, i64, AllowTypeChange>,
    regions: Option<Vec<u32>>,
    region_names: Option<Vec<String>>,
) -> PyResult<String> {
    guard(|| {
        let p = rows(&points, 2, "points", "(n, 2)")?;
        let tris = triangle_rows(&triangles, None, "(m, 3)")?;
        let mesh = Mesh2 {
            vertices: p.rows().into_iter().map(|r| [r[0], r[1]]).collect(),
            triangles: tris,
            regions: regions.unwrap_or_default(),
            region_names: region_names.unwrap_or_default(),
        };
        fem_mesh::io::validate_mesh(&mesh)
            .and_then(|()| fem_mesh::io::validate_regions(&mesh))
            .map_err(|(field, why)| invalid(format!("{field}: {why}")))?;
        Ok(fem_mesh::io::mesh_to_json(&mesh))
    })
}
