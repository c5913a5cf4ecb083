//! `Robot.workspace`: the library's workspace sweep
//! ([`tdpcr::workspace::sweep_workspace_until`]) without the GIL, stopped by Ctrl-C
//! (`interrupt.rs`), its cells as columns of arrays, and an optional progress callback
//! called on the calling thread at most about four times a second.

use std::sync::Mutex;
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

/// A Python callable `progress(rays_done, rays_total)`, called on the calling thread (the
/// sweep's threads only record how far they are), at most every [`PROGRESS_PERIOD`] and
/// once at the end; an exception it raises stops the sweep and is raised.
struct ProgressCallback {
    callable: Py<PyAny>,
    /// When the callable was last called, and with what.
    called: Option<(Instant, Progress)>,
}

impl ProgressCallback {
    /// Calls the callable with the sweep's `latest` report if it is new and the period is
    /// over (or `end` is set).
    fn call_if_due(
        &mut self,
        py: Python<'_>,
        latest: &Mutex<Option<Progress>>,
        end: bool,
    ) -> PyResult<()> {
        let Some(p) = *latest.lock().unwrap_or_else(|e| e.into_inner()) else {
            return Ok(());
        };
        let due = match self.called {
            None => true,
            Some((t, last)) => last != p && (end || t.elapsed() >= PROGRESS_PERIOD),
        };
        if due {
            self.called = Some((Instant::now(), p));
            self.callable.call1(py, (p.rays_done, p.rays_total))?;
        }
        Ok(())
    }
}

/// Sweeps the workspace of `design`, returning the cells as a dict of columns.
pub fn sweep<'py>(
    py: Python<'py>,
    design: &Tdpcr,
    settings: &WorkspaceSettings,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut callback = progress.map(|callable| ProgressCallback {
        callable,
        called: None,
    });
    // The sweep's latest report, written by its threads.
    let latest: Mutex<Option<Progress>> = Mutex::new(None);
    // The furthest report: threads report in any order (one that counted N − 1 rays done
    // may write after the one that counted N, and the end call reported N − 1 of N).
    let record = |p: Progress| {
        let mut latest = latest.lock().unwrap_or_else(|e| e.into_inner());
        if latest.is_none_or(|l| p.rays_done >= l.rays_done) {
            *latest = Some(p);
        }
    };
    let map = interrupt::run_polling(
        py,
        |stop| sweep_workspace_until(design, settings, &record, stop),
        |py| match &mut callback {
            Some(c) => c.call_if_due(py, &latest, false),
            None => Ok(()),
        },
    )?;
    if let Some(c) = &mut callback {
        c.call_if_due(py, &latest, true)?;
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
