//! `Robot.workspace`: the library's workspace sweep
//! ([`tdpcr::workspace::sweep_workspace_until`]) without the GIL, stopped by Ctrl-C
//! (`interrupt.rs`), its cells as columns of arrays, and an optional progress callback
//! called with the GIL at most about four times a second.

use std::sync::Mutex;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use numpy::IntoPyArray;
use numpy::ndarray::{Array1, Array2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::Value;

use tdpcr::Tdpcr;
use tdpcr::workspace::{
    PointMetrics, Progress, Rconds, Singularity, WorkspaceMap, WorkspacePoint, WorkspaceSettings,
    sweep_workspace_until,
};

use crate::analysis::json_value;
use crate::errors::to_py_err;
use crate::interrupt;

/// Shortest time between two progress calls.
const PROGRESS_PERIOD: Duration = Duration::from_millis(250);

/// Calls a Python callable `progress(rays_done, rays_total)` from the sweep's threads,
/// throttled; the first exception it raises stops the sweep and is raised after it.
struct ProgressCallback {
    callable: Py<PyAny>,
    last: Mutex<Option<Instant>>,
    error: Mutex<Option<PyErr>>,
}

impl ProgressCallback {
    fn report(&self, p: Progress) {
        let last_call = p.rays_total > 0 && p.rays_done == p.rays_total;
        {
            let Ok(mut last) = self.last.lock() else {
                return;
            };
            let due = last.is_none_or(|t| t.elapsed() >= PROGRESS_PERIOD);
            if !(due || last_call) {
                return;
            }
            *last = Some(Instant::now());
        }
        Python::attach(|py| {
            if let Err(e) = self.callable.call1(py, (p.rays_done, p.rays_total))
                && let Ok(mut error) = self.error.lock()
            {
                error.get_or_insert(e);
            }
        });
    }
}

/// Sweeps the workspace of `design`, returning the cells as a dict of columns.
pub fn sweep<'py>(
    py: Python<'py>,
    design: &Tdpcr,
    settings: &WorkspaceSettings,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let callback = progress.map(|callable| ProgressCallback {
        callable,
        last: Mutex::new(None),
        error: Mutex::new(None),
    });
    let map = interrupt::run(py, true, |stop| {
        // A callback that raised stops the sweep (its exception is raised below).
        let report = |p: Progress| {
            if let Some(c) = &callback {
                c.report(p);
                if c.error.lock().is_ok_and(|e| e.is_some()) {
                    stop.store(true, Ordering::Relaxed);
                }
            }
        };
        sweep_workspace_until(design, settings, &report, stop)
    })?;
    if let Some(e) = callback.and_then(|c| c.error.into_inner().ok().flatten()) {
        return Err(e);
    }
    let map = map.map_err(|e| to_py_err(py, e))?;
    columns(py, &map)
}

/// The cells of `map` as columns (row k = cell k, sorted by z, then y, then x).
fn columns<'py>(py: Python<'py>, map: &WorkspaceMap) -> PyResult<Bound<'py, PyDict>> {
    let points = &map.points;
    let m = points.len();
    let row3 = |at: &dyn Fn(&WorkspacePoint) -> [f64; 3]| {
        Array2::from_shape_fn((m, 3), |(k, i)| at(&points[k])[i])
    };
    let out = PyDict::new(py);
    out.set_item(
        "cell",
        Array2::from_shape_fn((m, 3), |(k, i)| points[k].cell[i]).into_pyarray(py),
    )?;
    out.set_item("position", row3(&|p| p.position).into_pyarray(py))?;
    out.set_item("rotvec", row3(&|p| p.state.rotvec).into_pyarray(py))?;
    let n = map.n_actuators;
    out.set_item(
        "q",
        Array2::from_shape_fn((m, n), |(k, j)| points[k].state.q[j]).into_pyarray(py),
    )?;
    let nt = 3 * map.tendons_per_leg;
    out.set_item(
        "tensions",
        Array2::from_shape_fn((m, nt), |(k, j)| points[k].tensions[j]).into_pyarray(py),
    )?;
    let flag = |at: &dyn Fn(&WorkspacePoint) -> bool| {
        Array1::from_iter(points.iter().map(at)).into_pyarray(py)
    };
    out.set_item("reachable", flag(&|p| p.reachable()))?;
    out.set_item("collision", flag(&|p| p.collision))?;
    let metrics: Vec<Value> = points
        .iter()
        .map(|p| serde_json::to_value(p.metrics))
        .collect::<Result<_, _>>()
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    // The keys and kinds from a point's metrics (a zero one where no point was reached,
    // so that an empty map has every documented column, empty).
    let shape = serde_json::to_value(points.first().map_or_else(zero_metrics, |p| p.metrics))
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    merge_columns(py, &out, &shape, &metrics)?;
    out.set_item("summary", json_value(py, &map.summary)?)?;
    out.set_item("settings", json_value(py, &map.settings)?)?;
    Ok(out)
}

/// Metrics of no point: the shape of the columns of an empty map.
fn zero_metrics() -> PointMetrics {
    PointMetrics {
        rcond: Rconds::ZERO,
        rcond_scaled: Rconds::ZERO,
        singularity: Singularity {
            type_i: false,
            type_ii: false,
            leg: false,
        },
        min_tension: 0.0,
        stable: false,
        min_compliance_eigenvalue: 0.0,
        leg_switch: false,
    }
}

/// Sets in `out`, for every key of the JSON object `shape` (the shape of every row of
/// `rows`), a column over `rows`: a float64 array for numbers, a bool array for
/// booleans, a dict of columns for objects (empty columns where `rows` is empty).
fn merge_columns(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    shape: &Value,
    rows: &[Value],
) -> PyResult<()> {
    let Value::Object(first) = shape else {
        return Ok(());
    };
    for (key, sample) in first {
        let column: Vec<&Value> = rows.iter().map(|r| &r[key]).collect();
        match sample {
            Value::Bool(_) => out.set_item(
                key,
                Array1::from_iter(column.iter().map(|v| v.as_bool() == Some(true)))
                    .into_pyarray(py),
            )?,
            Value::Object(_) => {
                let inner = PyDict::new(py);
                let rows: Vec<Value> = column.into_iter().cloned().collect();
                merge_columns(py, &inner, sample, &rows)?;
                out.set_item(key, inner)?;
            }
            _ => out.set_item(
                key,
                Array1::from_iter(column.iter().map(|v| v.as_f64().unwrap_or(0.0)))
                    .into_pyarray(py),
            )?,
        }
    }
    Ok(())
}
