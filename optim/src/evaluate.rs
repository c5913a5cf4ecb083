//! The design problem: from a validated design to its [`Outcome`]. The search only sees
//! the [`Evaluator`] trait, so the expensive workspace evaluation
//! ([`crate::workspace_eval::WorkspaceEvaluator`]) and cheap test functions are
//! interchangeable.

use std::time::Instant;

use tdpcr::Tdpcr;

use crate::objectives::{Infeasibility, Outcome};
use crate::space::ParameterSpace;

/// Scores designs. Called from several threads at once (one call per candidate);
/// the result must depend only on the design (not on timing or thread count), or the
/// search is not reproducible. Must not panic on any valid design.
pub trait Evaluator: Sync {
    /// The outcome of `design` (already validated by the design rules).
    fn evaluate(&self, design: &Tdpcr) -> Outcome;
}

/// The outcome of the box point `x` of `space` and the evaluation's wall time \[s\]:
/// an invalid parameter combination is [`Infeasibility::InvalidDesign`] without calling
/// the evaluator; non-finite measures are [`Infeasibility::NonFinite`].
pub fn evaluate_point(
    space: &ParameterSpace,
    evaluator: &dyn Evaluator,
    x: &[f64],
) -> (Outcome, f64) {
    let start = Instant::now();
    let outcome = match space.design(x) {
        Err(e) => Outcome::Infeasible {
            reason: Infeasibility::InvalidDesign {
                message: e.to_string(),
            },
        },
        Ok(design) => evaluate_design(evaluator, &design),
    };
    (outcome, start.elapsed().as_secs_f64())
}

/// `evaluator` on `design`, with non-finite measures turned into
/// [`Infeasibility::NonFinite`].
pub fn evaluate_design(evaluator: &dyn Evaluator, design: &Tdpcr) -> Outcome {
    match evaluator.evaluate(design) {
        Outcome::Feasible(m) => Outcome::checked(m),
        infeasible => infeasible,
    }
}
