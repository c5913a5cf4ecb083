//! The tangent predictor of warm starts (MODEL.md §4): a solve whose guess is the last
//! solution with only its target changed starts from the first-order prediction, with
//! the Jacobian the last Newton run factorized.

use nalgebra::{DVector, Rotation3};

use super::Solver;
use super::shooting::{Problem, retract};
use super::state::RobotState;
use crate::rod::Wrench;

/// What the Newton scratch's factorized Jacobian linearizes.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LastSolve {
    /// The solution.
    pub(super) state: RobotState,
    /// The total wrench it was solved under.
    pub(super) wrench: Wrench,
    /// FK (true) or square IK (false).
    pub(super) forward: bool,
}

/// Whether `guess` is the last solution with only the target of `problem` changed
/// (FK: q; IK: the pose), under the same wrench.
pub(super) fn is_last_solution(
    solver: &Solver,
    problem: Problem,
    wrench: &Wrench,
    guess: &RobotState,
) -> bool {
    let Some(last) = solver.last.as_ref() else {
        return false;
    };
    let same_legs = last.wrench == *wrench && last.state.y_u == guess.y_u;
    match problem {
        Problem::Forward { .. } => {
            last.forward
                && same_legs
                && last.state.position == guess.position
                && last.state.rotvec == guess.rotvec
        }
        Problem::Inverse { .. } => !last.forward && same_legs && last.state.q == guess.q,
    }
}

/// The first-order (tangent) prediction of the solution of `problem` from the last
/// solve: FK \[δx; δy\] = −\[B_x B_u\]⁻¹ B_q δq, IK \[δq; δy\] = −\[B_q B_u\]⁻¹ B_x δx
/// (MODEL.md §4), with the exact Jacobian factorized in the last Newton iteration (near
/// the solution). `x` is the last solution in the solver's unknowns with the new target;
/// the prediction is returned in the same form.
pub(super) fn predict(solver: &Solver, problem: Problem, x: &DVector<f64>) -> Option<DVector<f64>> {
    let last = solver.last.as_ref()?;
    let mut rhs = DVector::zeros(solver.model.n_residuals());
    match problem {
        Problem::Forward { q } => {
            for (j, (a, b)) in q.iter().zip(&last.state.q).enumerate() {
                rhs.axpy(-(a - b), &solver.blocks.b_q.column(j), 1.0);
            }
        }
        Problem::Inverse { pose } => {
            let from = last.state.pose();
            let dp = pose.position - from.position;
            let dtheta =
                Rotation3::from_matrix_unchecked(pose.rotation * from.rotation.transpose())
                    .scaled_axis();
            for c in 0..3 {
                rhs.axpy(-dp[c], &solver.blocks.b_x.column(c), 1.0);
                rhs.axpy(-dtheta[c], &solver.blocks.b_x.column(3 + c), 1.0);
            }
        }
    }
    solver.newton.solve_with_last_jacobian(&mut rhs)?;
    let mut out = DVector::zeros(x.len());
    retract(problem, x, &rhs, &mut out);
    Some(out)
}
