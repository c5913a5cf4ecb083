//! Sequences of solves, each warm-started from the previous solution (paper Tab. VII):
//! per-step results and timing statistics. (Reading the targets from CSV is the CLI's.)
//!
//! Recovery rule: a step starts warm from the previous step's solution when that step
//! converged; after a failed step, the next step starts cold (as the first step does), so
//! a failure never leaves later steps starting from a stale solution. A failed step has
//! no residual (`residual_norm` is `None`) unless Newton ran and stopped, and its
//! `error` says why; [`Stats`] counts the failed steps and names the first.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::Rotation3;
use serde::Serialize;

use crate::error::{Error, StopReason};
use crate::kinetostatics::{RobotState, Solver};
use crate::model::Pose;
use crate::rod::Wrench;

/// What each row of a trajectory asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Targets {
    /// IK targets: platform poses.
    Poses(Vec<Pose>),
    /// FK targets: actuation vectors.
    Actuations(Vec<Vec<f64>>),
}

/// The result of one step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepResult {
    /// Row index in the input (0-based, header excluded).
    pub step: usize,
    /// Whether Newton converged.
    pub converged: bool,
    /// Platform position \[m\]: of the solution; of the target where an IK step did not
    /// converge; `None` where an FK step did not (it has no pose).
    pub position: Option<[f64; 3]>,
    /// Platform rotation vector \[rad\] (as `position`).
    pub rotvec: Option<[f64; 3]>,
    /// Actuation \[m\].
    pub q: Vec<f64>,
    /// Newton iterations.
    pub iterations: usize,
    /// Final residual norm (of the best point when Newton stopped without converging;
    /// `None` when the step has no residual, e.g. it diverged).
    pub residual_norm: Option<f64>,
    /// Why the step failed (`None` when it converged).
    pub error: Option<String>,
    /// Why Newton stopped, where a failed step's Newton run stopped short of the
    /// tolerance (`None` when it converged, diverged or failed otherwise).
    pub stop_reason: Option<StopReason>,
    /// Why a failed step failed, snake_case, for every failure ([`Error::reason`]: the
    /// stop reason, or `"diverged"`, `"invalid_input"`, ...; `None` when it converged).
    /// Not in the CLI's JSON (its `stop_reason` and `error` tell it).
    #[serde(skip)]
    pub failure_reason: Option<&'static str>,
    /// Wall time of the solve \[µs\].
    pub solve_time_us: f64,
}

/// Timing over all steps of a trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stats {
    /// Number of steps.
    pub steps: usize,
    /// Median solve time per step \[µs\].
    pub median_us: f64,
    /// Mean solve time per step \[µs\].
    pub mean_us: f64,
    /// Largest solve time of a step \[µs\].
    pub max_us: f64,
    /// Median Newton iterations per step.
    pub median_iterations: f64,
    /// Steps that did not converge.
    pub failed: usize,
    /// Index of the first step that did not converge.
    pub first_failed_step: Option<usize>,
    /// Why the first failed step failed.
    pub first_failure: Option<String>,
}

/// Solves every target in order, each step warm-started from the previous step's solution
/// (the first from a cold start), which lets the solver predict the step from its exact
/// Jacobian there. A failed step is recorded and the next one starts cold (the recovery
/// rule of the module doc).
pub fn run_trajectory(
    solver: &mut Solver,
    targets: &Targets,
    extra: &Wrench,
) -> (Vec<StepResult>, Stats) {
    run_trajectory_from(solver, targets, extra, None)
}

/// As [`run_trajectory`], the first step warm-started from `init` if given (e.g. the
/// state a previous run or a single solve ended at).
pub fn run_trajectory_from(
    solver: &mut Solver,
    targets: &Targets,
    extra: &Wrench,
    init: Option<RobotState>,
) -> (Vec<StepResult>, Stats) {
    run_trajectory_until(solver, targets, extra, init, &AtomicBool::new(false))
}

/// As [`run_trajectory_from`], stopping before the next step once `stop` is set (by
/// another thread: a user's interrupt): the steps done so far are returned, fewer than
/// the targets.
pub fn run_trajectory_until(
    solver: &mut Solver,
    targets: &Targets,
    extra: &Wrench,
    init: Option<RobotState>,
    stop: &AtomicBool,
) -> (Vec<StepResult>, Stats) {
    let mut state: Option<RobotState> = init;
    let mut steps = Vec::new();
    let count = match targets {
        Targets::Poses(p) => p.len(),
        Targets::Actuations(q) => q.len(),
    };
    for step in 0..count {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let start = std::time::Instant::now();
        // Warm start from the last solution: the solver predicts from its Jacobian there.
        let result = match targets {
            Targets::Poses(p) => solver.solve_ik(&p[step], extra, state.as_ref()),
            Targets::Actuations(q) => solver.solve_fk(&q[step], extra, state.as_ref()),
        };
        let elapsed = start.elapsed().as_secs_f64() * 1e6;
        steps.push(match result {
            Ok(sol) => {
                let r = StepResult {
                    step,
                    converged: true,
                    position: Some(sol.state.position),
                    rotvec: Some(sol.state.rotvec),
                    q: sol.state.q.clone(),
                    iterations: sol.report.iterations,
                    residual_norm: Some(sol.report.residual_norm),
                    error: None,
                    stop_reason: None,
                    failure_reason: None,
                    solve_time_us: sol.solve_time_us,
                };
                state = Some(sol.state);
                r
            }
            Err(e) => {
                // Recovery rule: the next step starts cold, not from a stale solution.
                state = None;
                let (iterations, residual_norm, stop_reason) = match &e {
                    Error::Solve(crate::SolveError::NotConverged {
                        iterations,
                        residual_norm,
                        reason,
                        ..
                    }) => (
                        *iterations,
                        Some(*residual_norm).filter(|r| r.is_finite()),
                        Some(*reason),
                    ),
                    _ => (0, None, None),
                };
                let (position, rotvec, q) = match targets {
                    Targets::Poses(p) => (
                        Some(p[step].position.into()),
                        Some(
                            Rotation3::from_matrix_unchecked(p[step].rotation)
                                .scaled_axis()
                                .into(),
                        ),
                        Vec::new(),
                    ),
                    Targets::Actuations(q) => (None, None, q[step].clone()),
                };
                StepResult {
                    step,
                    converged: false,
                    position,
                    rotvec,
                    q,
                    iterations,
                    residual_norm,
                    error: Some(e.to_string()),
                    stop_reason,
                    failure_reason: Some(e.reason()),
                    solve_time_us: elapsed,
                }
            }
        });
    }
    let stats = stats_of(&steps);
    (steps, stats)
}

fn stats_of(steps: &[StepResult]) -> Stats {
    let first_failed = steps.iter().find(|s| !s.converged);
    let mut times: Vec<f64> = steps.iter().map(|s| s.solve_time_us).collect();
    times.sort_by(f64::total_cmp);
    let mut its: Vec<f64> = steps.iter().map(|s| s.iterations as f64).collect();
    its.sort_by(f64::total_cmp);
    let median = |v: &[f64]| match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    };
    Stats {
        steps: steps.len(),
        median_us: median(&times),
        mean_us: if times.is_empty() {
            0.0
        } else {
            times.iter().sum::<f64>() / times.len() as f64
        },
        max_us: times.last().copied().unwrap_or(0.0),
        median_iterations: median(&its),
        failed: steps.iter().filter(|s| !s.converged).count(),
        first_failed_step: first_failed.map(|s| s.step),
        first_failure: first_failed.and_then(|s| s.error.clone()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Once the stop flag is set, no further step is solved: the steps so far return.
    #[test]
    fn a_trajectory_stops_before_the_next_step_when_asked() {
        let design = crate::Tdpcr::from_ron_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/designs/lilge2022.ron"
        ))
        .unwrap();
        let mut solver = Solver::new(&design).unwrap();
        let targets = Targets::Actuations(vec![vec![0.0; 6]; 3]);
        let w = Wrench::default();
        let stop = AtomicBool::new(false);
        let (all, _) = run_trajectory_until(&mut solver, &targets, &w, None, &stop);
        assert_eq!(all.len(), 3);
        stop.store(true, Ordering::Relaxed);
        let (none, stats) = run_trajectory_until(&mut solver, &targets, &w, None, &stop);
        assert!(none.is_empty() && stats.steps == 0, "{none:?}");
    }

    #[test]
    fn stats_use_all_steps() {
        let step = |t: f64, ok: bool| StepResult {
            step: t as usize,
            converged: ok,
            position: ok.then_some([0.0; 3]),
            rotvec: ok.then_some([0.0; 3]),
            q: vec![],
            iterations: 2,
            residual_norm: None,
            error: (!ok).then(|| "why".to_string()),
            stop_reason: None,
            failure_reason: (!ok).then_some("diverged"),
            solve_time_us: t,
        };
        let s = stats_of(&[
            step(3.0, true),
            step(1.0, true),
            step(10.0, false),
            step(2.0, true),
        ]);
        assert_eq!(
            (s.median_us, s.mean_us, s.max_us, s.failed),
            (2.5, 4.0, 10.0, 1)
        );
        assert_eq!(s.first_failed_step, Some(10));
        assert_eq!(s.first_failure.as_deref(), Some("why"));
    }
}
