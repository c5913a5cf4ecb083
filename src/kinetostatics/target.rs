//! What one Newton solve aims at (an actuation for FK, a pose for IK) and which solver
//! takes it: the square shooting Newton ([`super::shooting`]) or, for the IK of the
//! redundant design, the Gauss–Newton step rule of [`super::Solver::redundancy`]
//! ([`super::redundant`]).

use super::Solver;
use super::redundant::{IkSystem, Redundancy, least_norm_ik};
use super::shooting::{Problem, run_with};
use super::state::RobotState;
use crate::error::SolveError;
use crate::model::{Model, Pose};
use crate::newton::{NewtonReport, NewtonSettings};
use crate::rod::Wrench;

/// The target of one solve (at one λ of a continuation).
pub(super) enum Target {
    Forward(Vec<f64>),
    Inverse(Pose),
}

/// Solves for one target (FK, square IK or least-norm IK) from `guess`.
/// `scaled` replaces the model when given (continuation of the loads).
pub(super) fn solve_target(
    solver: &mut Solver,
    scaled: Option<&Model>,
    settings: &NewtonSettings,
    target: &Target,
    wrench: &Wrench,
    mut guess: RobotState,
) -> Result<(RobotState, NewtonReport), SolveError> {
    match target {
        Target::Forward(q) => {
            guess.q = q.clone();
            run_with(
                solver,
                scaled,
                settings,
                Problem::Forward { q },
                wrench,
                guess,
            )
        }
        Target::Inverse(pose) if solver.model.pairs == 1 => run_with(
            solver,
            scaled,
            settings,
            Problem::Inverse { pose },
            wrench,
            guess,
        ),
        Target::Inverse(pose) => {
            // Both step rules overwrite the blocks the tangent predictor reads.
            solver.last = None;
            let mut system = IkSystem {
                model: scaled.unwrap_or(&solver.model),
                boundary: &mut solver.boundary,
                blocks: &mut solver.blocks,
                pose,
                wrench,
                evaluated: NewtonReport::none(),
                speculate: solver.speculate_trials,
            };
            let result = match &solver.redundancy {
                Redundancy::LeastNorm => {
                    // The last run's factorization starts a path step from its solution
                    // (on the solver's own model only: not within a continuation of the
                    // loads, whose model is scaled).
                    let last = (scaled.is_none() && solver.reuse_least_norm_factorization)
                        .then_some(&mut solver.least_norm);
                    least_norm_ik(&mut system, settings, guess, last)
                }
                #[cfg(feature = "qp")]
                Redundancy::WithinLimits(objective) => {
                    super::within_limits::within_limits_ik(&mut system, settings, guess, objective)
                }
                #[cfg(not(feature = "qp"))]
                Redundancy::WithinLimits(_) => {
                    unreachable!("every entry point rejects WithinLimits without the `qp` feature")
                }
            };
            // The run's work, converged or not, to the solver's tally of the call.
            let work = match &result {
                Ok((_, report)) => *report,
                Err(e) => NewtonReport::of_failed_run(e, &system.evaluated),
            };
            solver.work.add_work(&work);
            result
        }
    }
}

/// Newton from `guess` on `problem` with the solver's model and `settings`.
pub(super) fn run(
    solver: &mut Solver,
    settings: &NewtonSettings,
    problem: Problem,
    wrench: &Wrench,
    guess: RobotState,
) -> Result<(RobotState, NewtonReport), SolveError> {
    run_with(solver, None, settings, problem, wrench, guess)
}
