//! `Robot`: one [`Solver`] of a design behind Python calls: `fk`, `ik`, `analyze` and the
//! parallel batch `fk_many`. Per-call options (tolerance, iteration limit, Jacobian,
//! redundancy) apply to that call only.

use std::sync::Arc;

use nalgebra::Vector3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tdpcr::boundary::FiniteDifference;
use tdpcr::kinetostatics::{JacobianMethod, Objective, Redundancy};
use tdpcr::model::Model;
use tdpcr::trajectory::{StepResult, Targets, run_trajectory_until};
use tdpcr::workspace::{CollisionPolicy, WorkspaceSettings};
use tdpcr::{AnalysisSettings, Error, NewtonSettings, Pose, RobotState, Solver, Wrench};

use crate::analysis::analysis_dict;
use crate::arrays::vector;
use crate::batch::{parallel, pose_of_row, stack_solutions, stack_steps, threads_arg};
use crate::design::Design;
use crate::errors::to_py_err;
use crate::interrupt;
use crate::solution::{Solution, State};

/// FK and IK of one design; holds the solver and all its buffers (not shared between
/// threads: use one `Robot` per thread, or `fk_many`).
#[pyclass(module = "tdpcr")]
pub struct Robot {
    solver: Solver,
    /// The design (the workspace sweep builds its own solvers from it).
    design: tdpcr::Tdpcr,
    /// The model, shared with every `Solution` (for its `shape`).
    model: Arc<Model>,
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
        // Checked once per call, before any solve: a batch with a bad tolerance raised
        // nothing and failed every row.
        let mut v = tdpcr::error::Violations::default();
        settings.check("settings", &mut v);
        if !v.0.is_empty() {
            return Err(PyValueError::new_err(tdpcr::Error::Input(v).to_string()));
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
            model: Arc::clone(&self.model),
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

/// Poses (m, 6) [x, y, z [m], rx, ry, rz [rad]] as poses.
fn poses_arg(poses: &Bound<'_, PyAny>) -> PyResult<Vec<Pose>> {
    let rows = crate::arrays::rows(poses, "poses", 6)?;
    rows.iter()
        .enumerate()
        .map(|(i, r)| pose_of_row(r, || format!("poses: row {i}'s rotation vector")))
        .collect()
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
        let model = Arc::new(solver.model().clone());
        Ok(Self {
            solver,
            design: design.design.clone(),
            model,
        })
    }

    /// Length of q.
    #[getter]
    fn n_actuators(&self) -> usize {
        self.solver.model().n_actuators()
    }

    /// Whether a least-norm `ik` of the 9-DoF design from this robot's last least-norm
    /// solution starts with chord steps on the latest least-norm factorization
    /// (`Solver::reuse_least_norm_factorization`; default false).
    #[getter]
    fn get_reuse_least_norm_factorization(&self) -> bool {
        self.solver.reuse_least_norm_factorization
    }

    #[setter]
    fn set_reuse_least_norm_factorization(&mut self, on: bool) {
        self.solver.reuse_least_norm_factorization = on;
    }

    /// Whether a least-norm `ik` of the 9-DoF design takes every step with the Jacobian at
    /// its iterate (Gauss–Newton, the behaviour before 2026-11-28) instead of all with the
    /// Jacobian at its start (`Solver::least_norm_gauss_newton`; default false).
    #[getter]
    fn get_least_norm_gauss_newton(&self) -> bool {
        self.solver.least_norm_gauss_newton
    }

    #[setter]
    fn set_least_norm_gauss_newton(&mut self, on: bool) {
        self.solver.least_norm_gauss_newton = on;
    }

    /// Whether an `ik` of the 9-DoF design takes one-sided steps across tendon kinks (the
    /// least-norm steps from the start, any run whose line search fails once more so;
    /// `Solver::across_kinks`; default true).
    #[getter]
    fn get_across_kinks(&self) -> bool {
        self.solver.across_kinks
    }

    #[setter]
    fn set_across_kinks(&mut self, on: bool) {
        self.solver.across_kinks = on;
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
        // With the GIL: the robot is borrowed mutably for the call, and without the GIL
        // another thread's use of it failed ("Already borrowed") where it waited.
        let result = self.with_call(o.jacobian, None, |s| {
            s.solve_fk_with(&q, &wrench, init.as_ref(), &o.settings)
        });
        result
            .map(|s| self.solution(s))
            .map_err(|e| to_py_err(py, e))
    }

    /// Inverse kinetostatics: the actuation that holds the platform at `position` [m] and
    /// `rotvec` [rad] under its weight plus `wrench`. `limits` and `reference` choose
    /// among a redundant (9-DoF) design's solutions; a 6-DoF design has one q per pose
    /// and ignores them (as the CLI's `ik`): its q may lie beyond the actuation limits.
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
        let mut row = vector(position, "position", Some(3))?;
        match rotvec {
            Some(r) => row.extend(vector(r, "rotvec", Some(3))?),
            None => row.extend([0.0; 3]),
        }
        let pose = pose_of_row(&row, || "rotvec".to_string())?;
        let wrench = wrench_arg(wrench)?;
        let init = init_arg(init)?;
        let redundancy = self.redundancy(limits, reference)?;
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
        // A solution of another design of the same size analysed here gave that design's
        // state this robot's blocks: numbers of neither (a ψ = 0 twin's J_FK 2.1× off).
        if !Arc::ptr_eq(&solution.model, &self.model) && *solution.model != *self.model {
            return Err(PyValueError::new_err(
                "solution: a solution of another design: expected one of this robot's \
                 (analyse it with the Robot that solved it)",
            ));
        }
        let a = self
            .solver
            .analyze_solution(&solution.solution, &settings)
            .map_err(|e| to_py_err(py, e))?;
        analysis_dict(py, &a, &settings)
    }

    /// FK of every row of `q` (m, n) [m], independently (cold starts) and in parallel
    /// on `threads` workers (all cores if None), without the GIL. A dict of stacked
    /// arrays: position (m, 3) [m], rotation (m, 3, 3), rotvec (m, 3) [rad], q (m, n)
    /// [m], tensions (m, 3, n_t) [N], iterations (m,), residual_norm (m,),
    /// solve_time_us (m,) [µs], converged (m,) bool, errors {row: message} and reasons
    /// {row: snake_case reason}; rows that failed are 0 (read them through `converged`).
    #[pyo3(signature = (q, wrench=None, *, tolerance=None, max_iterations=None, jacobian="exact", threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn fk_many<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let rows = crate::arrays::rows(q, "q", self.n_actuators())?;
        let wrench = wrench_arg(wrench)?;
        let threads = threads_arg(threads)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        self.solve_many(py, &o, None, &rows, threads, |s, q, settings| {
            s.solve_fk_with(q, &wrench, None, settings)
        })
    }

    /// IK of every row of `poses` (m, 6) [x, y, z [m], rx, ry, rz [rad]], independently
    /// (cold starts) and in parallel, without the GIL; options as `ik`. The dict of
    /// `fk_many`.
    #[pyo3(signature = (poses, wrench=None, *, tolerance=None, max_iterations=None, jacobian="exact", limits="free", reference=None, threads=None))]
    #[allow(clippy::too_many_arguments)]
    fn ik_many<'py>(
        &self,
        py: Python<'py>,
        poses: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
        limits: &str,
        reference: Option<&Bound<'py, PyAny>>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let poses = poses_arg(poses)?;
        let wrench = wrench_arg(wrench)?;
        let threads = threads_arg(threads)?;
        let redundancy = self.redundancy(limits, reference)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        self.solve_many(
            py,
            &o,
            Some(redundancy),
            &poses,
            threads,
            |s, p, settings| s.solve_ik_with(p, &wrench, None, settings),
        )
    }

    /// FK along the rows of `q` (m, n) [m] in order, each step warm-started from the
    /// previous step's solution (the first, and any step after a failed one, cold), on
    /// this robot's solver, without the GIL. Equals the loop
    /// `s = robot.fk(q[k], wrench, init=s.state if s converged else None)`. A dict:
    /// position (m, 3) [m], rotation (m, 3, 3), rotvec (m, 3) [rad], q (m, n) [m],
    /// iterations (m,), residual_norm (m,), solve_time_us (m,) [µs], converged (m,)
    /// bool, errors {row: message}, reasons {row: snake_case reason}; failed rows are 0
    /// (read them through `converged`).
    #[pyo3(signature = (q, wrench=None, *, tolerance=None, max_iterations=None, jacobian="exact"))]
    fn trajectory_fk<'py>(
        &mut self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let targets = Targets::Actuations(crate::arrays::rows(q, "q", self.n_actuators())?);
        let wrench = wrench_arg(wrench)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        let steps = self.trajectory(py, &o, None, &targets, &wrench)?;
        stack_steps(py, self.n_actuators(), &steps)
    }

    /// IK along the rows of `poses` (m, 6) [x, y, z [m], rx, ry, rz [rad]] in order,
    /// warm-started as `trajectory_fk` (the loop of `ik` calls with `init` the previous
    /// state); options as `ik`; the dict of `trajectory_fk`.
    #[pyo3(signature = (poses, wrench=None, *, tolerance=None, max_iterations=None, jacobian="exact", limits="free", reference=None))]
    #[allow(clippy::too_many_arguments)]
    fn trajectory_ik<'py>(
        &mut self,
        py: Python<'py>,
        poses: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        jacobian: &str,
        limits: &str,
        reference: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let targets = Targets::Poses(poses_arg(poses)?);
        let wrench = wrench_arg(wrench)?;
        let redundancy = self.redundancy(limits, reference)?;
        let o = self.options(tolerance, max_iterations, jacobian)?;
        let steps = self.trajectory(py, &o, Some(redundancy), &targets, &wrench)?;
        stack_steps(py, self.n_actuators(), &steps)
    }

    /// The workspace at the fixed orientation `rotvec` [rad]: the library's sweep (rays
    /// of IK steps of `step` [m] at angles `angle_step` [rad] in the planes z = k·step
    /// within `z_range` [m]; `collisions` "stop" | "continue"), in parallel without the
    /// GIL. `progress(rays_done, rays_total)` is called on the calling thread, one call at a
    /// time, at most about four times a second and once at the end (an exception it raises
    /// stops the sweep and is raised). A dict of columns, one row per cell: cell (m, 3) int,
    /// position (m, 3) [m], rotvec (m, 3) [rad], q (m, n) [m], tensions (m, 3 n_t) [N],
    /// reachable and collision (m,) bool, rcond and rcond_scaled ({name: (m,)}), singularity
    /// ({type_i, type_ii, leg: (m,) bool}), min_tension (m,) [N], stable (m,) bool,
    /// min_compliance_eigenvalue (m,), leg_switch (m,) bool; summary and settings (dicts, as
    /// the CLI's workspace JSON). `one_sided_kinks=False` sweeps with the Jacobian's taut
    /// slopes only and, for the 9-DoF design, without retrying a failed step across a tendon's
    /// kink one-sided (the CLI's `--two-sided-kinks`); `chord_contraction` in [0, 1) (default
    /// 0.1) as the CLI's `--chord-contraction`; `probe_iterations` ≥ 1 (default 15) as the
    /// CLI's `--probe-iterations`.
    #[pyo3(signature = (*, step=None, angle_step=None, z_range=None, rotvec=None, collisions="stop", tolerance=None, max_iterations=None, progress=None, one_sided_kinks=true, chord_contraction=None, probe_iterations=None))]
    #[allow(clippy::too_many_arguments)]
    fn workspace<'py>(
        &self,
        py: Python<'py>,
        step: Option<f64>,
        angle_step: Option<f64>,
        z_range: Option<&Bound<'py, PyAny>>,
        rotvec: Option<&Bound<'py, PyAny>>,
        collisions: &str,
        tolerance: Option<f64>,
        max_iterations: Option<usize>,
        progress: Option<Py<PyAny>>,
        one_sided_kinks: bool,
        chord_contraction: Option<f64>,
        probe_iterations: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let d = WorkspaceSettings::default();
        let three = |v: Option<&Bound<'py, PyAny>>, name, default: [f64; 3]| match v {
            Some(v) => vector(v, name, Some(3)).map(|v| [v[0], v[1], v[2]]),
            None => Ok(default),
        };
        let z_range = match z_range {
            Some(z) => vector(z, "z_range", Some(2)).map(|z| [z[0], z[1]])?,
            None => d.z_range,
        };
        let collisions = match collisions {
            "stop" => CollisionPolicy::Stop,
            "continue" => CollisionPolicy::Continue,
            other => {
                return Err(PyValueError::new_err(format!(
                    "collisions: {other:?}: expected \"stop\" or \"continue\""
                )));
            }
        };
        let settings = WorkspaceSettings {
            rotvec: three(rotvec, "rotvec", d.rotvec)?,
            step: step.unwrap_or(d.step),
            angle_step: angle_step.unwrap_or(d.angle_step),
            z_range,
            collisions,
            tolerance: tolerance.unwrap_or(d.tolerance),
            max_iterations: max_iterations.unwrap_or(d.max_iterations),
            one_sided_kinks,
            chord_contraction: chord_contraction.unwrap_or(d.chord_contraction),
            probe_iterations: probe_iterations.unwrap_or(d.probe_iterations),
            ..d
        };
        crate::workspace::sweep(py, &self.design, &settings, progress)
    }
}

impl Robot {
    /// `solve` of every item, independently, on `threads` rayon workers (one clone of
    /// this robot's solver with the call's Jacobian and redundancy each), without the
    /// GIL; the results stacked.
    #[allow(clippy::too_many_arguments)]
    fn solve_many<'py, I: Sync>(
        &self,
        py: Python<'py>,
        o: &CallOptions,
        redundancy: Option<Redundancy>,
        items: &[I],
        threads: Option<usize>,
        solve: impl Fn(&mut Solver, &I, &NewtonSettings) -> Result<tdpcr::Solution, Error> + Sync,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut template = self.solver.clone();
        template.jacobian = o.jacobian;
        if let Some(r) = redundancy {
            template.redundancy = r;
        }
        let rows = interrupt::run(py, items.len() >= interrupt::MIN_ROWS, |stop| {
            parallel(&template, items, threads, stop, |s, item| {
                solve(s, item, &o.settings)
            })
        })?
        .map_err(PyValueError::new_err)?;
        // Every row solved: a stopped run raised the signal's exception above.
        let results: Vec<_> = rows.into_iter().flatten().collect();
        stack_solutions(py, self.solver.model(), &results)
    }

    /// The library's warm-started trajectory with the call's options, without the GIL.
    fn trajectory(
        &mut self,
        py: Python<'_>,
        o: &CallOptions,
        redundancy: Option<Redundancy>,
        targets: &Targets,
        wrench: &Wrench,
    ) -> PyResult<Vec<StepResult>> {
        let saved = self.solver.settings;
        self.solver.settings = o.settings;
        let rows = match targets {
            Targets::Poses(p) => p.len(),
            Targets::Actuations(q) => q.len(),
        };
        let steps = self.with_call(o.jacobian, redundancy, |s| {
            interrupt::run(py, rows >= interrupt::MIN_ROWS, |stop| {
                run_trajectory_until(s, targets, wrench, None, stop).0
            })
        });
        self.solver.settings = saved;
        steps
    }

    /// The IK redundancy resolution of `limits` ("free" | "strict") and `reference`.
    fn redundancy(
        &self,
        limits: &str,
        reference: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Redundancy> {
        match (limits, reference) {
            ("free", None) => Ok(Redundancy::LeastNorm),
            ("free", Some(_)) => Err(PyValueError::new_err(
                "reference: given: expected only with limits=\"strict\"",
            )),
            ("strict", None) => Ok(Redundancy::WithinLimits(Objective::LeastChange)),
            ("strict", Some(q)) => Ok(Redundancy::WithinLimits(Objective::ClosestTo(vector(
                q,
                "reference",
                Some(self.n_actuators()),
            )?))),
            (other, _) => Err(PyValueError::new_err(format!(
                "limits: {other:?}: expected \"free\" or \"strict\""
            ))),
        }
    }
}
