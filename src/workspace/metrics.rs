//! The per-point measures of the workspace map (MODEL.md §4, §6): reciprocal condition
//! numbers (raw SI and unit-scaled), singularity flags, stability and the minimum tendon
//! tension at a solved state, from the kinetostatic analysis ([`crate::analysis`]). Every
//! point of a sweep goes through [`point_metrics`] and nothing else; `tensions` gives a
//! state's tendon tensions \[N\].

use serde::Serialize;

use crate::analysis::AnalysisError;
pub use crate::analysis::{AnalysisSettings, Rconds, Singularity};
use crate::error::Error;
use crate::kinetostatics::{RobotState, Solver};
use crate::model::Model;
use crate::rod::Wrench;
use crate::rod::tendon::tension;

/// Everything the workspace map records about one solved point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointMetrics {
    /// rcond of the raw SI matrices (as the paper).
    pub rcond: Rconds,
    /// rcond of the unit-scaled matrices (for design scoring; scaling in
    /// [`crate::analysis::scaling`]).
    pub rcond_scaled: Rconds,
    /// Singularity flags.
    pub singularity: Singularity,
    /// Smallest tendon tension over all legs \[N\].
    pub min_tension: f64,
    /// Stable with the actuators held ([`crate::analysis::stability`]): every eigenvalue
    /// of sym(C) is positive. An unstable point ends its ray (MODEL.md §6).
    pub stable: bool,
    /// Smallest eigenvalue of the unit-scaled sym(C) (dimensionless; negative where
    /// unstable, 0 where \[B_x B_u\] is exactly singular).
    pub min_compliance_eigenvalue: f64,
    /// A tendon pair's taut side differs from the neighbouring solution's on the ray (a
    /// leg-singularity line crossed between them, paper Fig. 9); set by the sweep, which
    /// also sets `singularity.leg`.
    pub leg_switch: bool,
}

/// The measures at a solved `state` (platform weight only, no extra wrench). Where
/// \[B_x B_u\] is exactly singular (J_FK and C do not exist) every rcond is 0, the
/// point is flagged near Type II only and counts as not stable (the stiffness K = C⁻¹ is
/// singular: not positive definite).
///
/// The measures are those of [`Solver::analyze`], bit for bit, from the leaner
/// [`Solver::condition`] (no J_IK, Λ or ellipsoid axes).
///
/// # Errors
/// As [`Solver::analyze`], except [`AnalysisError::Singular`] (handled as above).
pub fn point_metrics(
    solver: &mut Solver,
    state: &RobotState,
    settings: &AnalysisSettings,
) -> Result<PointMetrics, Error> {
    match solver.condition(state, &Wrench::default(), settings) {
        Ok(a) => Ok(PointMetrics {
            rcond: a.rcond,
            rcond_scaled: a.rcond_scaled,
            singularity: a.singularity,
            min_tension: a.min_tension,
            stable: a.stability.stable,
            min_compliance_eigenvalue: a.stability.eigenvalues[0],
            leg_switch: false,
        }),
        Err(Error::Analysis(AnalysisError::Singular { .. })) => {
            let zero = Rconds {
                b_xu: 0.0,
                b_qu: 0.0,
                b_u: 0.0,
                j_p: 0.0,
                j_o: 0.0,
                c_p: 0.0,
                c_o: 0.0,
            };
            let min_tension = tensions(solver.model(), state)
                .into_iter()
                .fold(f64::INFINITY, f64::min);
            Ok(PointMetrics {
                rcond: zero,
                rcond_scaled: zero,
                singularity: Singularity {
                    type_i: false,
                    type_ii: true,
                    leg: false,
                },
                min_tension,
                stable: false,
                min_compliance_eigenvalue: 0.0,
                leg_switch: false,
            })
        }
        Err(e) => Err(e),
    }
}

/// Tendon tensions \[N\] of a state, legs concatenated.
pub(super) fn tensions(model: &Model, state: &RobotState) -> Vec<f64> {
    model
        .tendon_unknown_indices()
        .map(|i| tension(state.y_u[i]))
        .collect()
}
