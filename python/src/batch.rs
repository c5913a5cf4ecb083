//! Batches of solves as dicts of stacked arrays: the independent, parallel batches
//! (`fk_many`, `ik_many`, one cold solve per row on a rayon pool) and the warm-started
//! trajectories (`trajectory_fk`, `trajectory_ik`, the library's
//! [`tdpcr::trajectory::run_trajectory`]).
//!
//! Convention for a row whose solve failed: `converged[k]` is False, `errors[k]` says
//! why and `reasons[k]` names why in snake_case (as `ConvergenceError.reason`; also
//! `"invalid_input"` for a row the library refused), `iterations[k]` counts the Newton
//! iterations done, and every other numeric output of the row (position, rotation,
//! rotvec, q, tensions, residual_norm, solve_time_us) is 0, never NaN: read rows
//! through the `converged` mask.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::{Rotation3, Vector3};
use numpy::IntoPyArray;
use numpy::ndarray::{Array1, Array2, Array3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use tdpcr::model::Model;
use tdpcr::trajectory::StepResult;
use tdpcr::{Error, Pose};

/// The pose of a row [x, y, z, rx, ry, rz] (position [m], rotation vector [rad]; the
/// values checked finite).
///
/// # Errors
/// `ValueError` naming the rotation vector (`rotvec()`) if it is longer than
/// [`tdpcr::spatial::MAX_ROTVEC_NORM`] (its length overflowed: the rotation became NaN).
pub fn pose_of_row(row: &[f64], rotvec: impl Fn() -> String) -> PyResult<Pose> {
    let r = Vector3::new(row[3], row[4], row[5]);
    if !tdpcr::spatial::is_rotation_vector(&r) {
        return Err(PyValueError::new_err(format!(
            "{}: [{:?}, {:?}, {:?}]: expected {}",
            rotvec(),
            r.x,
            r.y,
            r.z,
            tdpcr::spatial::ROTVEC_RULE
        )));
    }
    Ok(Pose {
        position: Vector3::new(row[0], row[1], row[2]),
        rotation: *Rotation3::new(r).matrix(),
    })
}

/// `solve` of every item on `threads` workers (rayon's global pool if `None`), one
/// clone of `template` per worker; results in input order. Once `stop` is set the items
/// not yet started are skipped (`None`).
pub fn parallel<S, I, R>(
    template: &S,
    items: &[I],
    threads: Option<usize>,
    stop: &AtomicBool,
    solve: impl Fn(&mut S, &I) -> R + Sync,
) -> Result<Vec<Option<R>>, String>
where
    S: Clone + Send + Sync,
    I: Sync,
    R: Send,
{
    let run = || {
        items
            .par_iter()
            .map_init(
                || template.clone(),
                |s, item| (!stop.load(Ordering::Relaxed)).then(|| solve(s, item)),
            )
            .collect()
    };
    match threads {
        None => Ok(run()),
        // No more workers than items: each is a thread started (30 000 for one row
        // loaded the machine for minutes).
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n.min(items.len()).max(1))
            .build()
            .map(|pool| pool.install(run))
            .map_err(|e| e.to_string()),
    }
}

/// Most worker threads a call takes (as the CLI's `--threads`).
const MAX_THREADS: usize = 1024;

/// `threads` checked: None or 1 to [`MAX_THREADS`].
pub fn threads_arg(threads: Option<usize>) -> PyResult<Option<usize>> {
    match threads {
        Some(n) if !(1..=MAX_THREADS).contains(&n) => Err(PyValueError::new_err(format!(
            "threads: {n}: expected 1 to {MAX_THREADS} (or None for all cores)"
        ))),
        t => Ok(t),
    }
}

/// The stacked outputs of a batch, zero where a row failed.
struct Stacked {
    position: Array2<f64>,
    rotation: Array3<f64>,
    rotvec: Array2<f64>,
    q: Array2<f64>,
    iterations: Array1<u64>,
    residual_norm: Array1<f64>,
    solve_time_us: Array1<f64>,
    converged: Array1<bool>,
    errors: BTreeMap<usize, String>,
    reasons: BTreeMap<usize, &'static str>,
}

impl Stacked {
    fn zeros(m: usize, n: usize) -> Self {
        Self {
            position: Array2::zeros((m, 3)),
            rotation: Array3::zeros((m, 3, 3)),
            rotvec: Array2::zeros((m, 3)),
            q: Array2::zeros((m, n)),
            iterations: Array1::zeros(m),
            residual_norm: Array1::zeros(m),
            solve_time_us: Array1::zeros(m),
            converged: Array1::from_elem(m, false),
            errors: BTreeMap::new(),
            reasons: BTreeMap::new(),
        }
    }

    /// Row `k` from a converged pose, actuation and report.
    #[allow(clippy::too_many_arguments)]
    fn set(
        &mut self,
        k: usize,
        position: &[f64; 3],
        rotvec: &[f64; 3],
        q: &[f64],
        iterations: usize,
        residual_norm: f64,
        solve_time_us: f64,
    ) {
        let r = Rotation3::new(Vector3::from(*rotvec));
        for i in 0..3 {
            self.position[(k, i)] = position[i];
            self.rotvec[(k, i)] = rotvec[i];
            for j in 0..3 {
                self.rotation[(k, i, j)] = r[(i, j)];
            }
        }
        for (j, &x) in q.iter().enumerate() {
            self.q[(k, j)] = x;
        }
        self.iterations[k] = iterations as u64;
        self.residual_norm[k] = residual_norm;
        self.solve_time_us[k] = solve_time_us;
        self.converged[k] = true;
    }

    /// Row `k` failed: `error` says why, `reason` names why.
    fn fail(&mut self, k: usize, iterations: usize, error: String, reason: &'static str) {
        self.iterations[k] = iterations as u64;
        self.errors.insert(k, error);
        self.reasons.insert(k, reason);
    }

    fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        out.set_item("position", self.position.into_pyarray(py))?;
        out.set_item("rotation", self.rotation.into_pyarray(py))?;
        out.set_item("rotvec", self.rotvec.into_pyarray(py))?;
        out.set_item("q", self.q.into_pyarray(py))?;
        out.set_item("iterations", self.iterations.into_pyarray(py))?;
        out.set_item("residual_norm", self.residual_norm.into_pyarray(py))?;
        out.set_item("solve_time_us", self.solve_time_us.into_pyarray(py))?;
        out.set_item("converged", self.converged.into_pyarray(py))?;
        out.set_item("errors", self.errors)?;
        out.set_item("reasons", self.reasons)?;
        Ok(out)
    }
}

/// Iterations done by a failed solve (0 unless Newton ran and stopped).
fn failed_iterations(e: &Error) -> usize {
    match e {
        Error::Solve(tdpcr::SolveError::NotConverged { iterations, .. }) => *iterations,
        _ => 0,
    }
}

/// Independent solves as stacked arrays, with tensions (m, 3, n_t) [N].
pub fn stack_solutions<'py>(
    py: Python<'py>,
    model: &Model,
    results: &[Result<tdpcr::Solution, Error>],
) -> PyResult<Bound<'py, PyDict>> {
    let (m, n, nt) = (results.len(), model.n_actuators(), model.n_tendons());
    let mut stacked = Stacked::zeros(m, n);
    let mut tensions = Array3::zeros((m, 3, nt));
    for (k, r) in results.iter().enumerate() {
        match r {
            Ok(s) => {
                let (st, rep) = (&s.state, &s.report);
                stacked.set(
                    k,
                    &st.position,
                    &st.rotvec,
                    &st.q,
                    rep.iterations,
                    rep.residual_norm,
                    s.solve_time_us,
                );
                for (i, leg) in s.tensions(model).iter().enumerate() {
                    for (j, &t) in leg.iter().enumerate() {
                        tensions[(k, i, j)] = t;
                    }
                }
            }
            Err(e) => stacked.fail(k, failed_iterations(e), e.to_string(), e.reason()),
        }
    }
    let out = stacked.into_dict(py)?;
    out.set_item("tensions", tensions.into_pyarray(py))?;
    Ok(out)
}

/// The steps of a trajectory as stacked arrays.
pub fn stack_steps<'py>(
    py: Python<'py>,
    n_actuators: usize,
    steps: &[StepResult],
) -> PyResult<Bound<'py, PyDict>> {
    let mut stacked = Stacked::zeros(steps.len(), n_actuators);
    for (k, s) in steps.iter().enumerate() {
        if s.converged {
            stacked.set(
                k,
                &s.position.unwrap_or_default(),
                &s.rotvec.unwrap_or_default(),
                &s.q,
                s.iterations,
                s.residual_norm.unwrap_or(0.0),
                s.solve_time_us,
            );
        } else {
            let why = s.error.clone().unwrap_or_default();
            let reason = s.failure_reason.unwrap_or("unknown");
            stacked.fail(k, s.iterations, why, reason);
        }
    }
    stacked.into_dict(py)
}
