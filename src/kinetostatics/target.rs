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
            let prepare = prepare_redundant(solver, scaled.is_some(), &guess);
            let mut system = IkSystem {
                model: scaled.unwrap_or(&solver.model),
                boundary: &mut solver.boundary,
                blocks: &mut solver.blocks,
                pose,
                wrench,
                evaluated: NewtonReport::none(),
                speculate: solver.speculate_trials,
                prepare,
                one_sided_kinks: false,
                across_kinks: solver.across_kinks,
            };
            let result = match &solver.redundancy {
                Redundancy::LeastNorm => {
                    // The last run's factorization starts a path step from its solution
                    // (on the solver's own model only: not within a continuation of the
                    // loads, whose model is scaled).
                    let last = (scaled.is_none() && solver.reuse_least_norm_factorization)
                        .then_some(&mut solver.least_norm);
                    let gauss_newton = solver.least_norm_gauss_newton;
                    least_norm_ik(&mut system, settings, guess, last, gauss_newton)
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
            match &result {
                Ok((state, _)) if scaled.is_none() => {
                    let (q, y_u) = solver.last_redundant.get_or_insert_default();
                    q.clone_from(&state.q);
                    y_u.clone_from(&state.y_u);
                }
                _ => solver.last_redundant = None,
            }
            result
        }
    }
}

/// Whether a run of the redundant IK from `guess` prepares its last residual for a
/// Jacobian at its solution (`Some(knots)`), and with the legs' knots: for the
/// analysis that follows each solution ([`Solver::prepare_for_analysis`]), or where
/// the run starts from the solver's last solution (a path, whose next step will start
/// from this run's solution with a Jacobian there; not with
/// [`Solver::reuse_least_norm_factorization`], whose runs start with chord steps, nor
/// towards a reference, whose runs start from it). Never on a scaled model (a
/// continuation of the loads).
fn prepare_redundant(solver: &Solver, scaled: bool, guess: &RobotState) -> Option<bool> {
    if scaled {
        return None;
    }
    if solver.prepare_for_analysis {
        return Some(true);
    }
    let path_step = solver
        .last_redundant
        .as_ref()
        .is_some_and(|(q, y_u)| *q == guess.q && *y_u == guess.y_u);
    let starts_with_jacobian = match &solver.redundancy {
        Redundancy::LeastNorm => !solver.reuse_least_norm_factorization,
        Redundancy::WithinLimits(objective) => {
            !matches!(objective, super::redundant::Objective::ClosestTo(_))
        }
    };
    (path_step && starts_with_jacobian).then_some(false)
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

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::Tdpcr;
    use crate::analysis::AnalysisSettings;
    use crate::kinetostatics::Solution;
    use crate::rod::ShapeDetail;

    fn solver(design: &str) -> Solver {
        let file = format!("{}/designs/{design}.ron", env!("CARGO_MANIFEST_DIR"));
        Solver::new(&Tdpcr::from_ron_file(&file).expect("bundled design")).expect("valid")
    }

    /// The FK solution at q = 0.
    fn solution_at_zero(s: &mut Solver) -> RobotState {
        let q = vec![0.0; s.model.n_actuators()];
        s.solve_fk(&q, &Wrench::default(), None).unwrap().state
    }

    /// `steps` warm IK solves of 1 mm, back and forth along x from the solution at q = 0,
    /// each from the last solution (or, with `fresh`, after the solver forgot its last
    /// solves): the states, reports and the legs' integrations (with or without
    /// sensitivities) the solves took.
    fn path(s: &mut Solver, steps: usize, fresh: bool) -> (Vec<Solution>, usize) {
        let w = Wrench::default();
        let mut last = solution_at_zero(s);
        let start = last.pose();
        let before = s.boundary.integrations();
        let mut solutions = Vec::new();
        for k in 0..steps {
            if fresh {
                s.forget_jacobian();
            }
            let pose = Pose {
                position: start.position + Vector3::new(1e-3 * ((k + 1) % 2) as f64, 0.0, 0.0),
                ..start
            };
            let solution = s.solve_ik(&pose, &w, Some(&last)).unwrap();
            last = solution.state.clone();
            solutions.push(solution);
        }
        (solutions, s.boundary.integrations() - before)
    }

    /// A warm IK of the redundant design from the solver's last solution starts with the
    /// integration its predecessor's last residual prepared: the same solutions and
    /// reports, fewer integrations. Least-norm steps from the start's Jacobian (the
    /// default) contract 50–250-fold per chord step at 1 mm, their last trial predicted
    /// with [`PATH_STEP_FINAL_PREDICTION`](super::super::redundant::PATH_STEP_FINAL_PREDICTION)
    /// (10 of these 12 steps start from a prepared integration; with the sweep's factor
    /// 0.1, none did); Gauss–Newton steps, whose last step is quadratic, too.
    #[test]
    fn a_redundant_path_step_starts_from_the_prepared_integration() {
        let mut rules = vec![
            (Redundancy::LeastNorm, false),
            (Redundancy::LeastNorm, true),
        ];
        #[cfg(feature = "qp")]
        rules.push((
            Redundancy::WithinLimits(super::super::redundant::Objective::LeastChange),
            false,
        ));
        for (rule, gauss_newton) in rules {
            let run = |fresh: bool| {
                let mut s = solver("lilge2022_redundant");
                s.redundancy = rule.clone();
                s.least_norm_gauss_newton = gauss_newton;
                path(&mut s, 12, fresh)
            };
            let (prepared, integrations) = run(false);
            let (plain, plain_integrations) = run(true);
            for (a, b) in prepared.iter().zip(&plain) {
                assert_eq!(a.state, b.state, "{rule:?}");
                // The same work; the last residual's norm is that of the point the state
                // restates (within round-off of the last iterate).
                let (x, y) = (a.report, b.report);
                assert_eq!(
                    (x.iterations, x.residual_evaluations, x.jacobian_evaluations),
                    (y.iterations, y.residual_evaluations, y.jacobian_evaluations),
                    "{rule:?}"
                );
                assert!(
                    x.residual_norm.max(y.residual_norm) <= 1e-10,
                    "{x:?}, {y:?}"
                );
            }
            assert!(
                integrations < plain_integrations,
                "{rule:?}: {integrations} integrations, {plain_integrations} without"
            );
        }
    }

    /// A solver prepared for analysis (the workspace sweep's) gives the same solutions,
    /// analyses and knots as one without, with fewer integrations (steps of 0.2 mm, so
    /// that the chord steps from the last solution's Jacobian contract well enough for
    /// the last residual to be predicted).
    #[test]
    fn solves_prepared_for_analysis_change_nothing_but_their_integrations() {
        for design in ["lilge2022", "lilge2022_redundant"] {
            let run = |prepare: bool| {
                let mut s = solver(design);
                s.prepare_for_analysis(prepare);
                let w = Wrench::default();
                let mut last = solution_at_zero(&mut s);
                let start = last.pose();
                let before = s.boundary.integrations();
                let mut results = Vec::new();
                for k in 1..=8 {
                    let pose = Pose {
                        position: start.position + Vector3::new(2e-4 * k as f64, 0.0, 0.0),
                        ..start
                    };
                    let solution = s.solve_ik_newton(&pose, &w, &last).unwrap();
                    // As the sweep analyses each solution and starts the next step from
                    // its Jacobian.
                    s.record_shape_detail(Some(ShapeDetail::Knots));
                    let analysis = s
                        .analyze(&solution.state, &w, &AnalysisSettings::default())
                        .unwrap();
                    let shapes = format!("{:?}", s.shapes());
                    s.record_shape_detail(None);
                    s.reuse_blocks_for_ik(&solution.state);
                    last = solution.state.clone();
                    results.push((solution.state, analysis, shapes));
                }
                (results, s.boundary.integrations() - before)
            };
            let (prepared, integrations) = run(true);
            let (plain, plain_integrations) = run(false);
            assert_eq!(prepared, plain, "{design}");
            assert!(
                integrations < plain_integrations,
                "{design}: {integrations} integrations, {plain_integrations} without"
            );
        }
    }
}
