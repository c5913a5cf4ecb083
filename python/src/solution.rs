//! `State` (a configuration of the robot, usable as a warm start) and `Solution` (a
//! converged solve), with the names of the CLI's JSON.

use std::sync::Arc;

use nalgebra::Vector3;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use tdpcr::RobotState;
use tdpcr::model::Model;
use tdpcr::workspace::collision::CollisionChecker;

use crate::arrays::{array1, array2};

/// A configuration: platform pose, actuation and the legs' unknowns; pass it as `init`
/// to warm-start the next solve.
#[pyclass(module = "tdpcr", frozen, from_py_object)]
#[derive(Clone)]
pub struct State {
    pub(crate) state: RobotState,
}

#[pymethods]
impl State {
    /// Platform position [m], world frame, shape (3,).
    #[getter]
    fn position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.state.position)
    }

    /// Platform rotation vector (axis × angle) [rad], shape (3,).
    #[getter]
    fn rotvec<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.state.rotvec)
    }

    /// Actuation q [m], shape (n,).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.state.q)
    }

    /// The legs' unknowns at their bases (MODEL.md §3), shape (3 (6 + n_t),).
    #[getter]
    fn y_u<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.state.y_u)
    }

    /// The state as the JSON the CLI reads with `--init` and prints as `state`.
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.state)
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))
    }

    /// A state from JSON (the CLI's `state` object).
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        serde_json::from_str(text)
            .map(|state| Self { state })
            .map_err(|e| {
                pyo3::exceptions::PyValueError::new_err(format!(
                    "text: expected a state with position, rotvec, q, y_u ({e})"
                ))
            })
    }

    fn __repr__(&self) -> String {
        format!(
            "State(position={:?}, rotvec={:?}, q={:?})",
            self.state.position, self.state.rotvec, self.state.q
        )
    }
}

/// A converged solve.
#[pyclass(module = "tdpcr", frozen)]
pub struct Solution {
    pub(crate) solution: tdpcr::Solution,
    /// Tendon tensions per leg [N].
    pub(crate) tensions: Vec<Vec<f64>>,
    /// The robot's model (for `shape`).
    pub(crate) model: Arc<Model>,
}

#[pymethods]
impl Solution {
    /// Platform position [m], world frame, shape (3,).
    #[getter]
    fn position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.solution.state.position)
    }

    /// Platform rotation (body to world), shape (3, 3).
    #[getter]
    fn rotation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let r = self.solution.state.pose().rotation;
        array2(py, (3, 3), |i, j| r[(i, j)])
    }

    /// Platform rotation vector (axis × angle) [rad], shape (3,).
    #[getter]
    fn rotvec<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.solution.state.rotvec)
    }

    /// Actuation q [m], shape (n,): per leg [bend_x, (bend_y), translation].
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.solution.state.q)
    }

    /// Tendon tensions [N], shape (3, n_t): one row per leg.
    #[getter]
    fn tensions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let t = &self.tensions;
        let cols = t.first().map_or(0, Vec::len);
        array2(py, (t.len(), cols), |i, j| t[i][j])
    }

    /// Newton iterations.
    #[getter]
    fn iterations(&self) -> usize {
        self.solution.report.iterations
    }

    /// Residual evaluations.
    #[getter]
    fn residual_evaluations(&self) -> usize {
        self.solution.report.residual_evaluations
    }

    /// Exact Jacobians evaluated.
    #[getter]
    fn jacobian_evaluations(&self) -> usize {
        self.solution.report.jacobian_evaluations
    }

    /// Euclidean norm of the final SI residual.
    #[getter]
    fn residual_norm(&self) -> f64 {
        self.solution.report.residual_norm
    }

    /// Wall time of the solve [µs].
    #[getter]
    fn solve_time_us(&self) -> f64 {
        self.solution.solve_time_us
    }

    /// The legs' backbones for plotting [m], world frame, shape (3, n_disks + 1, 3): per
    /// leg the base point then every disk centre (the library's collision check
    /// integrates the legs of the solved state; computed on each access).
    #[getter]
    fn shape<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let model = &*self.model;
        let state = &self.solution.state;
        let mut legs = CollisionChecker::new(model);
        legs.check(model, state)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        let points: Vec<Vec<Vector3<f64>>> = (0..3)
            .map(|i| {
                let base = model.base_frame(i, model.translation(i, &state.q)).position;
                std::iter::once(base)
                    .chain(legs.disk_centres(i).iter().copied())
                    .collect()
            })
            .collect();
        let k = points[0].len();
        Ok(Array3::from_shape_fn((3, k, 3), |(i, j, c)| points[i][j][c]).into_pyarray(py))
    }

    /// The configuration, usable as `init` of the next solve.
    #[getter]
    fn state(&self) -> State {
        State {
            state: self.solution.state.clone(),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "Solution(position={:?}, rotvec={:?}, iterations={}, residual_norm={:.2e})",
            self.solution.state.position,
            self.solution.state.rotvec,
            self.solution.report.iterations,
            self.solution.report.residual_norm
        )
    }
}
