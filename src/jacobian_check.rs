//! The exact boundary blocks against the finite-difference baseline at solved
//! configurations, with both timed side by side in the same run.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::boundary::{
    BoundaryJacobians, BoundaryScratch, FiniteDifference, boundary_derivatives,
    boundary_derivatives_fd,
};
use crate::error::{Error, SolveError};
use crate::kinetostatics::Solver;
use crate::rod::Wrench;
use crate::sampling::seeded_actuations;

/// Largest relative error per block: max|exact − FD| / max|FD| over the block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BlockErrors {
    /// B_x.
    pub b_x: f64,
    /// B_q.
    pub b_q: f64,
    /// B_w.
    pub b_w: f64,
    /// B_u.
    pub b_u: f64,
}

/// The outcome of [`jacobian_check`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JacobianCheck {
    /// Configurations requested.
    pub samples: usize,
    /// Configurations that solved and were compared.
    pub solved: usize,
    /// Worst relative error per block against central differences.
    pub max_rel_error: BlockErrors,
    /// Mean time of one exact Jacobian (all four blocks) \[µs\].
    pub time_exact_us: f64,
    /// Mean time of one forward-difference Jacobian \[µs\].
    pub time_fd_forward_us: f64,
    /// Mean time of one central-difference Jacobian \[µs\].
    pub time_fd_central_us: f64,
    /// The samples that did not solve (or whose blocks could not be evaluated), in
    /// order, and why.
    pub failures: Vec<SampleFailure>,
    /// The first failure's error, for a caller that has nothing else to report.
    #[serde(skip)]
    pub first_error: Option<SolveError>,
}

/// A sample of [`jacobian_check`] that was not compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SampleFailure {
    /// Index of the sample (0-based).
    pub sample: usize,
    /// Its actuation \[m\].
    pub q: Vec<f64>,
    /// Why it failed.
    pub error: String,
}

fn rel_error(a: &DMatrix<f64>, fd: &DMatrix<f64>) -> f64 {
    let den = fd.amax();
    if den == 0.0 {
        (a - fd).amax()
    } else {
        (a - fd).amax() / den
    }
}

/// Solves FK at `samples` seeded actuation vectors (half the actuation range, from the
/// straight guess), and at each solved one compares the exact blocks with central
/// differences and times one exact, one forward and one central Jacobian.
pub fn jacobian_check(solver: &mut Solver, samples: usize, seed: u64) -> JacobianCheck {
    let model = solver.model().clone();
    let wrench = solver.total_wrench(&Wrench::default());
    let mut sc = BoundaryScratch::new(&model);
    let mut exact = BoundaryJacobians::new(&model);
    let mut fd = BoundaryJacobians::new(&model);
    let mut r = DVector::zeros(model.n_residuals());
    let mut errors = BlockErrors {
        b_x: 0.0,
        b_q: 0.0,
        b_w: 0.0,
        b_u: 0.0,
    };
    let (mut t_exact, mut t_fwd, mut t_cen, mut solved) = (0.0, 0.0, 0.0, 0usize);
    let mut failures = Vec::new();
    let mut first_error = None;
    for (sample, q) in seeded_actuations(&model, samples, seed).iter().enumerate() {
        let q: Vec<f64> = q.iter().map(|x| 0.5 * x).collect();
        let mut compared = || -> Result<[Instant; 4], Error> {
            let sol = solver.solve_fk(&q, &Wrench::default(), None)?;
            let pose = sol.state.pose();
            let p = sol.state.boundary_point(&pose, &wrench);
            let start = Instant::now();
            boundary_derivatives(&model, &mut sc, &p, &mut r, &mut exact)?;
            let t1 = Instant::now();
            boundary_derivatives_fd(
                &model,
                &mut sc,
                &p,
                FiniteDifference::Forward,
                &mut r,
                &mut fd,
            )?;
            let t2 = Instant::now();
            boundary_derivatives_fd(
                &model,
                &mut sc,
                &p,
                FiniteDifference::Central,
                &mut r,
                &mut fd,
            )?;
            Ok([start, t1, t2, Instant::now()])
        };
        let [start, t1, t2, t3] = match compared() {
            Ok(times) => times,
            Err(e) => {
                if let (None, Error::Solve(se)) = (&first_error, &e) {
                    first_error = Some(se.clone());
                }
                failures.push(SampleFailure {
                    sample,
                    q,
                    error: e.to_string(),
                });
                continue;
            }
        };
        t_exact += (t1 - start).as_secs_f64();
        t_fwd += (t2 - t1).as_secs_f64();
        t_cen += (t3 - t2).as_secs_f64();
        solved += 1;
        errors.b_x = errors.b_x.max(rel_error(&exact.b_x, &fd.b_x));
        errors.b_q = errors.b_q.max(rel_error(&exact.b_q, &fd.b_q));
        errors.b_w = errors.b_w.max(rel_error(&exact.b_w, &fd.b_w));
        errors.b_u = errors.b_u.max(rel_error(&exact.b_u, &fd.b_u));
    }
    let mean = |t: f64| {
        if solved == 0 {
            0.0
        } else {
            t / solved as f64 * 1e6
        }
    };
    JacobianCheck {
        samples,
        solved,
        max_rel_error: errors,
        time_exact_us: mean(t_exact),
        time_fd_forward_us: mean(t_fwd),
        time_fd_central_us: mean(t_cen),
        failures,
        first_error,
    }
}
