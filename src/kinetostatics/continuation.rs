//! Cold starts and continuation: Newton from the straight home guess; if that fails, the
//! actuation (FK) or the pose (IK) is ramped from a solved configuration, and last a
//! homotopy from the unloaded straight home (every tendon taut under an auxiliary
//! pretension) to the full loads (MODEL.md §9).

use nalgebra::{DVector, Rotation3};

use super::Solver;
use super::home::{home_guess, straight_leg_pose, straight_leg_translations};
use super::shooting::Problem;
use super::state::RobotState;
use super::target::{Target, run, solve_target};
use crate::analysis::{AnalysisSettings, condition_blocks};
use crate::boundary::{BoundaryJacobians, BoundaryScratch, boundary_derivatives};
use crate::error::{SolveError, StopReason};
use crate::model::Pose;
use crate::newton::{NewtonReport, NewtonSettings};
use crate::rod::Wrench;

/// First continuation step in λ.
const CONTINUATION_FIRST_STEP: f64 = 0.25;
/// Pretension \[N\] of the continuation's start: every tendon taut (γ = 1, far from the
/// γ = 0 trap of MODEL.md §9), relaxed to the design's pretension as λ → 1.
const CONTINUATION_PRETENSION: f64 = 1.0;
/// Newton iterations allowed per continuation step before the step is halved.
const CONTINUATION_MAX_ITERATIONS: usize = 25;

/// How the loads evolve along a continuation.
#[derive(Debug, Clone, Copy)]
enum Loads {
    /// The full loads throughout.
    Full,
    /// From zero to full with λ, with an auxiliary `pretension` \[N\] relaxing to the design's.
    FromUnloaded { pretension: f64 },
}

/// The window of the cold FK's direct run's nonmonotone acceptance
/// ([`NewtonScratch::nonmonotone_once`](crate::newton::NewtonScratch::nonmonotone_once)):
/// over the 30 seeded reachable draws of each bundled parallel design (`cold_fk_stats`),
/// median iterations 27 → 17 (9-DoF), 51 → 16 (9-DoF, ψ = 0), 10 → 10 and 11 → 11
/// (6-DoF) against the monotone test (BENCHMARKS.md).
const COLD_FK_NONMONOTONE_WINDOW: usize = 5;

/// Cold FK: Newton from the straight guess, accepting steps by a nonmonotone test
/// ([`COLD_FK_NONMONOTONE_WINDOW`]); if that fails or ends at an unstable equilibrium
/// (the analysis' [`Stability`](crate::analysis::Stability), actuators held), q is ramped
/// from the solved q = 0 configuration; last, continuation from the unloaded straight
/// home (the direct run's unstable equilibrium is returned only where both fail). Where
/// one q has several stable equilibria (e.g. legs buckled one way or the other under
/// large base translations), this returns the one Newton reaches from the straight
/// guess, not necessarily the one a robot moved there from home is in: warm-start from a
/// known state (or follow a trajectory) to stay on a branch.
pub(super) fn cold_fk(
    solver: &mut Solver,
    settings: &NewtonSettings,
    q: &[f64],
    wrench: &Wrench,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let pose = straight_leg_pose(&solver.model, q);
    let guess = solver.home_guess(&pose, q, wrench);
    solver.newton.nonmonotone_once(COLD_FK_NONMONOTONE_WINDOW);
    let direct = run(solver, settings, Problem::Forward { q }, wrench, guess);
    if let Ok((state, _)) = &direct {
        if !unstable(solver, state, wrench) {
            return direct;
        }
    }
    // Ramp q from the solved q = 0 configuration under the same loads.
    let zero = vec![0.0; q.len()];
    let home = if q.iter().all(|&x| x == 0.0) {
        None
    } else {
        let pose = straight_leg_pose(&solver.model, &zero);
        let guess = solver.home_guess(&pose, &zero, wrench);
        run(
            solver,
            settings,
            Problem::Forward { q: &zero },
            wrench,
            guess,
        )
        .ok()
    };
    if let Some((home, _)) = home {
        if let Ok(done) = ramp_actuation(solver, settings, home, q, wrench) {
            return Ok(done);
        }
    }
    let q_final = q.to_vec();
    continuation(solver, settings, wrench, &|lambda: f64| {
        Target::Forward(q_final.iter().map(|x| x * lambda).collect())
    })
    .or(direct)
}

/// Whether `state` is an equilibrium under the total `wrench` that the analysis calls
/// unstable (false where its blocks or analysis fail: nothing is known). It is evaluated
/// in buffers of its own, so the solver's (the blocks the next warm start's predictor
/// reads, the legs' last integration a prepared solve left for the next Jacobian) stay
/// as the solve left them; the evaluation counts as one residual and Jacobian of the
/// call's work.
fn unstable(solver: &mut Solver, state: &RobotState, wrench: &Wrench) -> bool {
    let model = &solver.model;
    let (mut boundary, mut blocks) = (BoundaryScratch::new(model), BoundaryJacobians::new(model));
    let mut r = DVector::zeros(model.n_residuals());
    let pose = state.pose();
    let evaluated = boundary_derivatives(
        model,
        &mut boundary,
        &state.boundary_point(&pose, wrench),
        &mut r,
        &mut blocks,
    );
    solver.boundary.count_evaluations_of(&boundary);
    solver.work.add_work(&NewtonReport {
        residual_evaluations: 1,
        jacobian_evaluations: 1,
        ..NewtonReport::none()
    });
    evaluated.is_ok()
        && condition_blocks(model, &blocks, &state.y_u, &AnalysisSettings::default())
            .is_ok_and(|c| !c.stability.stable)
}

/// Follows `target(λ)`, λ: 0 → 1, from `start` (the solution at λ = 0), warm-starting
/// each step; the step is halved when Newton needs more than
/// [`CONTINUATION_MAX_ITERATIONS`] and doubled after an easy step. With
/// [`Loads::FromUnloaded`] the gravity loads and `wrench` grow with λ and the auxiliary
/// pretension relaxes to the design's; intermediate steps then stop at 1e-7.
///
/// Its steps start from the tangent prediction only, never from extrapolated solutions
/// (`Solver::extrapolate_starts` off), and it leaves only its last solution for the
/// predictor of the next warm solve: a continuation's steps are long (a quarter of the
/// way and more) and change length, and a polynomial through them misled Newton (the cold
/// FK of the ψ = 0 9-DoF design from the q = 0 state: one of 30 draws more failed).
fn ramp(
    solver: &mut Solver,
    base: &NewtonSettings,
    start: RobotState,
    wrench: &Wrench,
    target: &dyn Fn(f64) -> Target,
    loads: Loads,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let extrapolate = std::mem::replace(&mut solver.extrapolate_starts, false);
    let result = ramp_steps(solver, base, start, wrench, target, loads);
    solver.extrapolate_starts = extrapolate;
    solver.keep_last_solution_only();
    result
}

/// The steps of [`ramp`].
fn ramp_steps(
    solver: &mut Solver,
    base: &NewtonSettings,
    start: RobotState,
    wrench: &Wrench,
    target: &dyn Fn(f64) -> Target,
    loads: Loads,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let last_settings = NewtonSettings {
        max_iterations: CONTINUATION_MAX_ITERATIONS.min(base.max_iterations),
        ..*base
    };
    let intermediate = match loads {
        Loads::Full => last_settings,
        Loads::FromUnloaded { .. } => NewtonSettings {
            tolerance: last_settings.tolerance.max(1e-7),
            ..last_settings
        },
    };
    let mut state = start;
    // The last converged step's report (the work of every step is in the solver's tally
    // of the call, which the call reports).
    let mut last = NewtonReport::none();
    let (mut lambda, mut step) = (0.0f64, CONTINUATION_FIRST_STEP);
    while lambda < 1.0 {
        let next = (lambda + step).min(1.0);
        let settings = if next >= 1.0 {
            last_settings
        } else {
            intermediate
        };
        let (scaled, w) = match loads {
            Loads::Full => (None, *wrench),
            Loads::FromUnloaded { pretension } => (
                Some(solver.model.with_homotopy(
                    next,
                    pretension + (solver.model.pretension - pretension) * next,
                )),
                Wrench {
                    force: wrench.force * next,
                    moment: wrench.moment * next,
                },
            ),
        };
        match solve_target(
            solver,
            scaled.as_ref(),
            &settings,
            &target(next),
            &w,
            state.clone(),
        ) {
            Ok((s, r)) => {
                last = r;
                state = s;
                lambda = next;
                if r.iterations <= 4 {
                    step *= 2.0;
                }
            }
            Err(e) => {
                step /= 2.0;
                if step < 1.0 / 256.0 {
                    return Err(match e {
                        SolveError::NotConverged {
                            iterations,
                            residual_norm,
                            tolerance,
                            ..
                        } => SolveError::NotConverged {
                            iterations,
                            residual_norm,
                            tolerance,
                            reason: StopReason::ContinuationStalled,
                        },
                        other => other,
                    });
                }
            }
        }
    }
    Ok((state, last))
}

/// FK along q(λ) = q_start + λ (q − q_start) from the solved `start`.
pub(super) fn ramp_actuation(
    solver: &mut Solver,
    settings: &NewtonSettings,
    start: RobotState,
    q: &[f64],
    wrench: &Wrench,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let q0 = start.q.clone();
    let q1 = q.to_vec();
    let target =
        move |l: f64| Target::Forward(q0.iter().zip(&q1).map(|(a, b)| a + (b - a) * l).collect());
    ramp(solver, settings, start, wrench, &target, Loads::Full)
}

/// IK along the pose interpolated from `start`'s pose to `pose` (position linearly,
/// rotation along the geodesic).
pub(super) fn ramp_pose(
    solver: &mut Solver,
    settings: &NewtonSettings,
    start: RobotState,
    pose: &Pose,
    wrench: &Wrench,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let p0 = start.pose();
    let (dp, dr) = (
        pose.position - p0.position,
        Rotation3::from_matrix_unchecked(pose.rotation * p0.rotation.transpose()).scaled_axis(),
    );
    let target = move |l: f64| {
        Target::Inverse(Pose {
            position: p0.position + dp * l,
            rotation: Rotation3::new(dr * l).matrix() * p0.rotation,
        })
    };
    ramp(solver, settings, start, wrench, &target, Loads::Full)
}

/// Cold IK: Newton from the straight guess; if that fails, continuation from the
/// unloaded straight home configuration.
pub(super) fn cold_ik(
    solver: &mut Solver,
    settings: &NewtonSettings,
    pose: &Pose,
    wrench: &Wrench,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let guess = solver.home_guess(
        pose,
        &straight_leg_translations(&solver.model, pose),
        wrench,
    );
    let direct = run(solver, settings, Problem::Inverse { pose }, wrench, guess);
    if direct.is_ok() {
        return direct;
    }
    let (p, phi) = (
        pose.position,
        Rotation3::from_matrix_unchecked(pose.rotation).scaled_axis(),
    );
    continuation(solver, settings, wrench, &|lambda: f64| {
        Target::Inverse(Pose {
            position: p * lambda,
            rotation: *Rotation3::new(phi * lambda).matrix(),
        })
    })
    .or(direct)
}

/// Homotopy from the unloaded straight home configuration (an exact solution with an
/// auxiliary pretension that keeps every tendon taut) to `target(1)` under the full
/// loads and the design's pretension; see [`ramp`].
fn continuation(
    solver: &mut Solver,
    settings: &NewtonSettings,
    wrench: &Wrench,
    target: &dyn Fn(f64) -> Target,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let zero = vec![0.0; solver.model.n_actuators()];
    let home = straight_leg_pose(&solver.model, &zero);
    let pretension = CONTINUATION_PRETENSION.max(solver.model.pretension);
    let start = home_guess(
        &solver.model.with_homotopy(0.0, pretension),
        &home,
        &zero,
        &Wrench::default(),
    );
    ramp(
        solver,
        settings,
        start,
        wrench,
        target,
        Loads::FromUnloaded { pretension },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Tdpcr;
    use crate::kinetostatics::Solution;

    fn solver(design: &str) -> Solver {
        let file = format!("{}/designs/{design}.ron", env!("CARGO_MANIFEST_DIR"));
        Solver::new(&Tdpcr::from_ron_file(&file).expect("bundled design")).expect("valid")
    }

    /// A solve's report against the boundary evaluations it made (counted apart, in the
    /// evaluation functions): every residual and every Jacobian, of failed runs too.
    /// Returns the report.
    fn assert_report_counts_every_evaluation(
        solver: &mut Solver,
        solve: &str,
        run: &dyn Fn(&mut Solver) -> Solution,
    ) -> NewtonReport {
        let [r0, j0] = solver.boundary.evaluations();
        let report = run(solver).report;
        let [r1, j1] = solver.boundary.evaluations();
        assert_eq!(
            (report.residual_evaluations, report.jacobian_evaluations),
            (r1 - r0 + j1 - j0, j1 - j0),
            "{solve}: report {report:?}"
        );
        report
    }

    #[test]
    fn a_cold_fk_that_falls_back_reports_its_failed_direct_attempt_too() {
        let mut s = solver("lilge2022_redundant");
        // A seeded draw of `cold_fk_stats` (certified reachable from q = 0, draw 9) whose
        // direct attempt from the straight guess fails after the iteration limit.
        let q = [
            0.0020940769549205674,
            -0.004421908695830863,
            -0.041016952445253455,
            -0.005906447594347555,
            -0.002321861835161636,
            -0.06908687664650784,
            0.007520911643380626,
            -4.008795593204662e-5,
            -0.03942444739227396,
        ];
        let (settings, wrench) = (s.settings, s.total_wrench(&Wrench::default()));
        let guess = s.home_guess(&straight_leg_pose(&s.model, &q), &q, &wrench);
        s.newton.nonmonotone_once(COLD_FK_NONMONOTONE_WINDOW);
        let direct = run(
            &mut s,
            &settings,
            Problem::Forward { q: &q },
            &wrench,
            guess,
        );
        let Err(SolveError::NotConverged { iterations, .. }) = direct else {
            panic!("the direct attempt was to fail: {direct:?}");
        };
        let mut s = solver("lilge2022_redundant");
        let cold = |s: &mut Solver| {
            s.solve_fk(&q, &Wrench::default(), None)
                .expect("falls back")
        };
        let report = assert_report_counts_every_evaluation(&mut s, "cold FK", &cold);
        assert!(
            report.iterations > iterations,
            "{report:?} after a direct attempt of {iterations}"
        );
    }

    #[test]
    fn warm_and_cold_solves_report_every_evaluation() {
        let mut s = solver("lilge2022");
        let q = [0.004, 0.02, -0.003, -0.01, 0.002, 0.03];
        let cold = |s: &mut Solver| s.solve_fk(&q, &Wrench::default(), None).unwrap();
        assert_report_counts_every_evaluation(&mut s, "cold FK", &cold);
        let state = cold(&mut s).state;
        let pose = state.pose();
        let warm = |s: &mut Solver| {
            let moved = Pose {
                position: pose.position + nalgebra::Vector3::new(1e-3, 0.0, 0.0),
                ..pose
            };
            s.solve_ik(&moved, &Wrench::default(), Some(&state))
                .unwrap()
        };
        assert_report_counts_every_evaluation(&mut s, "warm IK", &warm);
        let cold_ik = |s: &mut Solver| s.solve_ik(&pose, &Wrench::default(), None).unwrap();
        assert_report_counts_every_evaluation(&mut s, "cold IK", &cold_ik);
    }

    #[test]
    fn redundant_ik_reports_every_evaluation_with_either_rule() {
        let mut s = solver("lilge2022_redundant");
        let q = [
            0.002, -0.001, 0.005, -0.001, 0.001, -0.004, 0.0, 0.001, 0.008,
        ];
        let state = s.solve_fk(&q, &Wrench::default(), None).unwrap().state;
        let pose = state.pose();
        let moved = Pose {
            position: pose.position + nalgebra::Vector3::new(1e-3, 0.0, -1e-3),
            ..pose
        };
        let warm = |s: &mut Solver| {
            s.solve_ik(&moved, &Wrench::default(), Some(&state))
                .unwrap()
        };
        let cold = |s: &mut Solver| s.solve_ik(&pose, &Wrench::default(), None).unwrap();
        assert_report_counts_every_evaluation(&mut s, "least-norm warm IK", &warm);
        assert_report_counts_every_evaluation(&mut s, "least-norm cold IK", &cold);
        #[cfg(feature = "qp")]
        {
            use crate::kinetostatics::{Objective, Redundancy};
            s.redundancy = Redundancy::WithinLimits(Objective::ClosestTo(vec![0.0; 9]));
            assert_report_counts_every_evaluation(&mut s, "within-limits warm IK", &warm);
            assert_report_counts_every_evaluation(&mut s, "within-limits cold IK", &cold);
        }
    }
}
