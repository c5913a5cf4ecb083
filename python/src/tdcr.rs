//! `Tdcr`: one tendon-driven continuum robot alone ([`tdpcr::TdcrSolver`]), tension or
//! displacement control, with the names of `tdpcr tdcr --format json`.

use nalgebra::Vector3;
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tdpcr::error::{Error, Violations};
use tdpcr::tdcr::{TdcrSolver, TdcrState, TendonControl, TipWrench};

use crate::analysis::json_value;
use crate::arrays::{array1, array2, vector};
use crate::errors::{design_error, to_py_err};

/// One TDCR (a `designs/tdcr_*.ron` file), base at the world origin; holds its solver.
#[pyclass(module = "tdpcr")]
pub struct Tdcr {
    solver: TdcrSolver,
}

#[pymethods]
impl Tdcr {
    /// Loads and validates a single-TDCR RON file; `DesignError` lists every bad field.
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let robot = tdpcr::Tdcr::from_ron_file(&path).map_err(design_error)?;
        Ok(Self {
            solver: TdcrSolver::new(&robot),
        })
    }

    /// Parses and validates RON text; `DesignError` lists every bad field.
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_ron(text: &str, source: &str) -> PyResult<Self> {
        let robot = tdpcr::Tdcr::from_ron_str(text, source).map_err(design_error)?;
        Ok(Self {
            solver: TdcrSolver::new(&robot),
        })
    }

    /// Number of tendons n_t.
    #[getter]
    fn n_tendons(&self) -> usize {
        self.solver.model().n_tendons
    }

    /// The equilibrium under given `tensions` (n_t,) [N] or tendon length changes
    /// `displacements` (n_t,) [m] (negative = pulled; exactly one of the two), a tip
    /// force [N] and moment [N·m] (world frame), from `init` (the `state` dict of an
    /// earlier result) or a cold guess. A dict as `tdpcr tdcr --format json`:
    /// tip_position (3,) [m], tip_rotation (3, 3), tensions (n_t,) [N], slacks (n_t,)
    /// [m], iterations, residual_evaluations, residual_norm, shape (n_disks, 3) [m]
    /// (disk centres, base excluded), shape_arcs (n_disks,) [m], state
    /// ({u0, v0, gammas}). Raises ConvergenceError, ValueError.
    #[pyo3(signature = (tensions=None, displacements=None, *, tip_force=None, tip_moment=None, init=None, tolerance=None, max_iterations=None))]
    #[allow(clippy::too_many_arguments)]
    fn solve<'py>(
        &mut self,
        py: Python<'py>,
        tensions: Option<&Bound<'py, PyAny>>,
        displacements: Option<&Bound<'py, PyAny>>,
        tip_force: Option<&Bound<'py, PyAny>>,
        tip_moment: Option<&Bound<'py, PyAny>>,
        init: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let control = match (tensions, displacements) {
            (Some(t), None) => TendonControl::Tension(vector(t, "tensions", None)?),
            (None, Some(d)) => TendonControl::Displacement(vector(d, "displacements", None)?),
            _ => {
                return Err(PyValueError::new_err(
                    "tensions, displacements: expected exactly one of the two",
                ));
            }
        };
        let three = |v: Option<&Bound<'py, PyAny>>, name| -> PyResult<Vector3<f64>> {
            Ok(match v {
                Some(v) => Vector3::from_column_slice(&vector(v, name, Some(3))?),
                None => Vector3::zeros(),
            })
        };
        let wrench = TipWrench {
            force: three(tip_force, "tip_force")?,
            moment: three(tip_moment, "tip_moment")?,
        };
        let init = init.map(state_arg).transpose()?;
        let saved = self.solver.settings;
        if let Some(t) = tolerance {
            self.solver.settings.tolerance = t;
        }
        if let Some(m) = max_iterations {
            self.solver.settings.max_iterations = m;
        }
        let mut v = Violations::default();
        self.solver.settings.check("settings", &mut v);
        let result = if v.0.is_empty() {
            self.solver.solve(&control, &wrench, init.as_ref())
        } else {
            Err(Error::Input(v))
        };
        self.solver.settings = saved;
        let sol = result.map_err(|e| to_py_err(py, e))?;
        let out = PyDict::new(py);
        let tip = &sol.tip;
        out.set_item("tip_position", array1(py, tip.position.as_slice()))?;
        out.set_item(
            "tip_rotation",
            array2(py, (3, 3), |i, j| tip.rotation[(i, j)]),
        )?;
        out.set_item("tensions", array1(py, &sol.tensions))?;
        out.set_item("slacks", array1(py, &sol.slacks))?;
        out.set_item("iterations", sol.report.iterations)?;
        out.set_item("residual_evaluations", sol.report.residual_evaluations)?;
        out.set_item("residual_norm", sol.report.residual_norm)?;
        let disks = &sol.shape.positions[1..];
        let shape = Array2::from_shape_fn((disks.len(), 3), |(k, i)| disks[k][i]);
        out.set_item("shape", shape.into_pyarray(py))?;
        out.set_item("shape_arcs", array1(py, &sol.shape.arcs[1..]))?;
        out.set_item("state", json_value(py, &sol.state)?)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!("Tdcr(n_tendons={})", self.n_tendons())
    }
}

/// A warm start: the `state` dict {u0, v0, gammas} of an earlier result.
fn state_arg(init: &Bound<'_, PyAny>) -> PyResult<TdcrState> {
    let bad = |e: String| {
        PyValueError::new_err(format!(
            "init: expected the state dict {{u0, v0, gammas}} of an earlier result ({e})"
        ))
    };
    let json = init.py().import("json")?;
    let text: String = json
        .call_method1("dumps", (init,))
        .and_then(|t| t.extract())
        .map_err(|e| bad(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| bad(e.to_string()))
}
