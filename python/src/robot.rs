//! `Robot`: one [`Solver`] of a design behind Python calls: `fk`, `ik`, `analyze` and the
//! parallel batch `fk_many`. Per-call options (tolerance, iteration limit, Jacobian,
//! redundancy) apply to that call only.

use std::collections::HashMap;

use nalgebra::{Rotation3, Vector3};
use numpy::IntoPyArray;
use numpy::ndarray::{Array1, Array2, Array3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use tdpcr::boundary::FiniteDifference;
use tdpcr::kinetostatics::{JacobianMethod, Objective, Redundancy};
use tdpcr::{AnalysisSettings, Error, NewtonSettings, Pose, RobotState, Solver, Wrench};

use crate::analysis::analysis_dict;
use crate::arrays::vector;
use crate::design::Design;
use crate::errors::to_py_err;
use crate::solution::{Solution, State};

/// FK and IK of one design; holds the solver and all its buffers (not shared between
/// threads: use one `Robot` per thread, or `fk_many`).
#[pyclass(module = "tdpcr")]
pub struct Robot {
    solver: Solver,
}

/// The per-call options of a solve.
struct CallOptions {
    settings: NewtonSettings,
    jacobian: JacobianMethod,
}

impl Robot {
    fn options(
        &self,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
    ) -> PyResult<CallOptions> {
        let mut settings = self.solver.settings;
        if let Some(t) = tolerance {
            settings.tolerance = t;
        }
        if let Some(m) = max_iterations {
            settings.max_iterations = m;
        }
        let jacobian = match jacobian {
            "exact" => JacobianMethod::Exact,
            "fd" => JacobianMethod::FiniteDifference(FiniteDifference::Forward),
            "fd-central" => JacobianMethod::FiniteDifference(FiniteDifference::Central),
            other => {
                return Err(PyValueError::new_err(format!(
                    "jacobian: {other:?}: expected \"exact\", \"fd\" or \"fd-central\""
                )));
            }
        };
        Ok(CallOptions { settings, jacobian })
    }

    /// `solve` with the call's Jacobian (and redundancy), the solver's own restored after.
    fn with_call<T>(
        &mut self,
        jacobian: JacobianMethod,
        redundancy: Option<Redundancy>,
        solve: impl FnOnce(&mut Solver) -> T,
    ) -> T {
        let saved = (self.solver.jacobian, self.solver.redundancy.clone());
        self.solver.jacobian = jacobian;
        if let Some(r) = redundancy {
            self.solver.redundancy = r;
        }
        let result = solve(&mut self.solver);
        (self.solver.jacobian, self.solver.redundancy) = saved;
        result
    }

    fn solution(&self, solution: tdpcr::Solution) -> Solution {
        Solution {
            tensions: solution.tensions(self.solver.model()),
            solution,
        }
    }
}

/// The extra wrench [fx, fy, fz, mx, my, mz] (zero if `None`).
fn wrench_arg(wrench: Option<&Bound<'_, PyAny>>) -> PyResult<Wrench> {
    Ok(match wrench {
        None => Wrench::default(),
        Some(w) => {
            let w = vector(w, "wrench", Some(6))?;
            Wrench {
                force: Vector3::new(w[0], w[1], w[2]),
                moment: Vector3::new(w[3], w[4], w[5]),
            }
        }
    })
}

/// A warm start: a `State` or a `Solution` (its state).
fn init_arg(init: Option<&Bound<'_, PyAny>>) -> PyResult<Option<RobotState>> {
    let Some(init) = init else { return Ok(None) };
    if let Ok(s) = init.cast::<State>() {
        return Ok(Some(s.get().state.clone()));
    }
    if let Ok(s) = init.cast::<Solution>() {
        return Ok(Some(s.get().solution.state.clone()));
    }
    Err(PyValueError::new_err(format!(
        "init: {}: expected a tdpcr.State or tdpcr.Solution",
        init.get_type().name()?
    )))
}

#[pymethods]
impl Robot {
    /// A robot of `design` (validated again: `DesignError`).
    #[new]
    fn new(py: Python<'_>, design: PyRef<'_, Design>) -> PyResult<Self> {
        let solver = Solver::new(&design.design).map_err(|e| to_py_err(py, e))?;
        Ok(Self { solver })
    }

    /// Length of q.
    #[getter]
    fn n_actuators(&self) -> usize {
        self.solver.model().n_actuators()
    }

    /// Forward kinetostatics at actuation `q` [m] under the platform weight plus `wrench`.
    #[pyo3(signature = (q, wrench=None, init=None, *, tolerance=None, max_iterations=None, jacobian="exact"))]
    #[allow(clippy::too_many_arguments)]
    fn fk(
        &mut self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        wrench: Option<&Bound<'_, PyAny>>,
        init: Option<&Bound<'_, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
    ) -> PyResult<Solution> {
        let q = vector(q, "q", Some(self.n_actuators()))?;
        let wrench = wrench_arg(wrench)?;
        let init = init_arg(init)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        let result = self.with_call(o.jacobian, None, |s| {
            s.solve_fk_with(&q, &wrench, init.as_ref(), &o.settings)
        });
        result
            .map(|s| self.solution(s))
            .map_err(|e| to_py_err(py, e))
    }

    /// Inverse kinetostatics: the actuation that holds the platform at `position` [m] and
    /// `rotvec` [rad] under its weight plus `wrench`.
    #[pyo3(signature = (position, rotvec=None, *, wrench=None, init=None, tolerance=None, max_iterations=None, jacobian="exact", limits="free", reference=None))]
    #[allow(clippy::too_many_arguments)]
    fn ik(
        &mut self,
        py: Python<'_>,
        position: &Bound<'_, PyAny>,
        rotvec: Option<&Bound<'_, PyAny>>,
        wrench: Option<&Bound<'_, PyAny>>,
        init: Option<&Bound<'_, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
        limits: &str,
        reference: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Solution> {
        let p = vector(position, "position", Some(3))?;
        let r = match rotvec {
            Some(r) => vector(r, "rotvec", Some(3))?,
            None => vec![0.0; 3],
        };
        let pose = Pose {
            position: Vector3::new(p[0], p[1], p[2]),
            rotation: *Rotation3::new(Vector3::new(r[0], r[1], r[2])).matrix(),
        };
        let wrench = wrench_arg(wrench)?;
        let init = init_arg(init)?;
        let redundancy = match (limits, reference) {
            ("free", None) => Redundancy::LeastNorm,
            ("free", Some(_)) => {
                return Err(PyValueError::new_err(
                    "reference: given: expected only with limits=\"strict\"",
                ));
            }
            ("strict", None) => Redundancy::WithinLimits(Objective::LeastChange),
            ("strict", Some(q)) => Redundancy::WithinLimits(Objective::ClosestTo(vector(
                q,
                "reference",
                Some(self.n_actuators()),
            )?)),
            (other, _) => {
                return Err(PyValueError::new_err(format!(
                    "limits: {other:?}: expected \"free\" or \"strict\""
                )));
            }
        };
        let o = self.options(tolerance, max_iterations, jacobian)?;
        let result = self.with_call(o.jacobian, Some(redundancy), |s| {
            s.solve_ik_with(&pose, &wrench, init.as_ref(), &o.settings)
        });
        result
            .map(|s| self.solution(s))
            .map_err(|e| to_py_err(py, e))
    }

    /// The kinetostatic analysis of `solution` under the wrench it was solved under: a
    /// dict with j_fk, j_ik, compliance, lambda_fk, lambda_ik, lambda_c (arrays), rcond
    /// ({"raw": {...}, "scaled": {...}}), singularity, ellipsoids, stability (dicts) and
    /// min_tension [N].
    #[pyo3(signature = (solution, *, type_i_threshold=None, type_ii_threshold=None, leg_threshold=None))]
    fn analyze<'py>(
        &mut self,
        py: Python<'py>,
        solution: PyRef<'_, Solution>,
        type_i_threshold: Option<f64>,
        type_ii_threshold: Option<f64>,
        leg_threshold: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = AnalysisSettings::default();
        let settings = AnalysisSettings {
            type_i_threshold: type_i_threshold.unwrap_or(d.type_i_threshold),
            type_ii_threshold: type_ii_threshold.unwrap_or(d.type_ii_threshold),
            leg_threshold: leg_threshold.unwrap_or(d.leg_threshold),
        };
        let a = self
            .solver
            .analyze_solution(&solution.solution, &settings)
            .map_err(|e| to_py_err(py, e))?;
        analysis_dict(py, &a, &settings)
    }

    /// FK of every row of `q` (m, n) [m], independently (cold starts) and in parallel,
    /// without the GIL. A dict of stacked arrays: position (m, 3), rotation (m, 3, 3),
    /// rotvec (m, 3), q (m, n), tensions (m, 3, n_t), iterations (m,), residual_norm
    /// (m,) and converged (m,) bool; rows that failed are NaN (iterations 0).
    #[pyo3(signature = (q, wrench=None, *, tolerance=None, max_iterations=None, jacobian="exact"))]
    fn fk_many<'py>(
        &mut self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = self.n_actuators();
        let rows = crate::arrays::rows(q, "q", n)?;
        let wrench = wrench_arg(wrench)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        let mut template = self.solver.clone();
        template.jacobian = o.jacobian;
        let results: Vec<Result<tdpcr::Solution, Error>> = py.detach(|| {
            rows.par_iter()
                .map_init(
                    || template.clone(),
                    |s, q| s.solve_fk_with(q, &wrench, None, &o.settings),
                )
                .collect()
        });
        self.stack(py, &results)
    }
}

impl Robot {
    /// The batch results as stacked arrays (NaN rows where a solve failed).
    fn stack<'py>(
        &self,
        py: Python<'py>,
        results: &[Result<tdpcr::Solution, Error>],
    ) -> PyResult<Bound<'py, PyDict>> {
        let model = self.solver.model();
        let (m, n, nt) = (results.len(), model.n_actuators(), model.n_tendons());
        let mut position = Array2::from_elem((m, 3), f64::NAN);
        let mut rotation = Array3::from_elem((m, 3, 3), f64::NAN);
        let mut rotvec = Array2::from_elem((m, 3), f64::NAN);
        let mut q = Array2::from_elem((m, n), f64::NAN);
        let mut tensions = Array3::from_elem((m, 3, nt), f64::NAN);
        let mut iterations = Array1::<u64>::zeros(m);
        let mut residual_norm = Array1::from_elem(m, f64::NAN);
        let mut converged = Array1::from_elem(m, false);
        let mut errors: HashMap<usize, String> = HashMap::new();
        for (k, r) in results.iter().enumerate() {
            let s = match r {
                Ok(s) => s,
                Err(e) => {
                    errors.insert(k, e.to_string());
                    continue;
                }
            };
            let r = s.state.pose().rotation;
            for i in 0..3 {
                position[(k, i)] = s.state.position[i];
                rotvec[(k, i)] = s.state.rotvec[i];
                for j in 0..3 {
                    rotation[(k, i, j)] = r[(i, j)];
                }
            }
            for (j, &x) in s.state.q.iter().enumerate() {
                q[(k, j)] = x;
            }
            for (i, leg) in s.tensions(model).iter().enumerate() {
                for (j, &t) in leg.iter().enumerate() {
                    tensions[(k, i, j)] = t;
                }
            }
            iterations[k] = s.report.iterations as u64;
            residual_norm[k] = s.report.residual_norm;
            converged[k] = true;
        }
        let out = PyDict::new(py);
        out.set_item("position", position.into_pyarray(py))?;
        out.set_item("rotation", rotation.into_pyarray(py))?;
        out.set_item("rotvec", rotvec.into_pyarray(py))?;
        out.set_item("q", q.into_pyarray(py))?;
        out.set_item("tensions", tensions.into_pyarray(py))?;
        out.set_item("iterations", iterations.into_pyarray(py))?;
        out.set_item("residual_norm", residual_norm.into_pyarray(py))?;
        out.set_item("converged", converged.into_pyarray(py))?;
        out.set_item("errors", errors)?;
        Ok(out)
    }
}
