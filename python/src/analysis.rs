//! The analysis of a solution as a Python dict: matrices as 2-d arrays, the structured
//! parts (rcond, singularity, ellipsoids, stability) as nested dicts with the CLI's JSON
//! names (`tdpcr analyze --format json`).

use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::Serialize;

use tdpcr::{Analysis, AnalysisSettings};

use crate::arrays::matrix;

/// A serializable value as the Python object of its JSON (dicts, lists, floats, bools).
pub fn json_value<'py>(py: Python<'py>, value: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Every field of `a` (and the thresholds used) as a dict.
pub fn analysis_dict<'py>(
    py: Python<'py>,
    a: &Analysis,
    settings: &AnalysisSettings,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("j_fk", matrix(py, &a.j_fk))?;
    out.set_item("j_ik", matrix(py, &a.j_ik))?;
    out.set_item("compliance", matrix(py, &a.compliance))?;
    out.set_item("lambda_fk", matrix(py, &a.lambda_fk))?;
    out.set_item("lambda_ik", matrix(py, &a.lambda_ik))?;
    out.set_item("lambda_c", matrix(py, &a.lambda_c))?;
    let rcond = PyDict::new(py);
    rcond.set_item("raw", json_value(py, &a.rcond)?)?;
    rcond.set_item("scaled", json_value(py, &a.rcond_scaled)?)?;
    out.set_item("rcond", rcond)?;
    out.set_item("singularity", json_value(py, &a.singularity)?)?;
    out.set_item("ellipsoids", json_value(py, &a.ellipsoids)?)?;
    out.set_item("stability", json_value(py, &a.stability)?)?;
    out.set_item("thresholds", json_value(py, settings)?)?;
    out.set_item("min_tension", a.min_tension)?;
    Ok(out)
}
