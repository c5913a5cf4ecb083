//! The per-point measures of the workspace map (MODEL.md §4, §6): reciprocal condition
//! numbers (raw SI and unit-scaled), singularity flags, stability and the minimum tendon
//! tension at a solved state, from the kinetostatic analysis ([`crate::analysis`]). Every
//! point of a sweep goes through [`point_metrics`] and nothing else; `tensions` gives a
//! state's tendon tensions \[N\].

use serde::Serialize;

use crate::analysis::{AnalysisError, Conditioning, scaled_block_rconds};
pub use crate::analysis::{AnalysisSettings, Rconds, Singularity};
use crate::boundary::BoundaryJacobians;
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
        Ok(c) => Ok(metrics_of(&c)),
        Err(Error::Analysis(AnalysisError::Singular { .. })) => Ok(singular(solver, state)),
        Err(e) => Err(e),
    }
}

/// [`point_metrics`] without the unit-scaled rconds of \[B_x B_u\], \[B_q B_u\] and B_u
/// (a second factorization of the blocks): where the analysis succeeds, those three
/// entries of `rcond_scaled` are NaN and the blocks are returned for
/// [`complete_scaled`], which the sweep calls only for the points that represent cells
/// (the per-sample statistics use the raw rconds). The completed measures equal
/// [`point_metrics`]'s, bit for bit (the analysis behind them computes only what they
/// hold: no ellipsoid axes, only the sign part of the stability).
///
/// # Errors
/// As [`point_metrics`].
pub(super) fn point_metrics_deferred(
    solver: &mut Solver,
    state: &RobotState,
    settings: &AnalysisSettings,
) -> Result<(PointMetrics, Option<Box<BoundaryJacobians>>), Error> {
    match solver.condition_with(state, &Wrench::default(), settings, false) {
        Ok(c) => Ok((metrics_of(&c), Some(Box::new(solver.last_blocks().clone())))),
        Err(Error::Analysis(AnalysisError::Singular { .. })) => Ok((singular(solver, state), None)),
        Err(e) => Err(e),
    }
}

/// Fills in the unit-scaled rconds that [`point_metrics_deferred`] left out, from the
/// `blocks` it returned with `metrics`.
pub(super) fn complete_scaled(
    model: &Model,
    metrics: &mut PointMetrics,
    blocks: &BoundaryJacobians,
) {
    let [b_xu, b_qu, b_u] = scaled_block_rconds(model, blocks);
    metrics.rcond_scaled.b_xu = b_xu;
    metrics.rcond_scaled.b_qu = b_qu;
    metrics.rcond_scaled.b_u = b_u;
}

/// The measures of an analysis.
fn metrics_of(c: &Conditioning) -> PointMetrics {
    PointMetrics {
        rcond: c.rcond,
        rcond_scaled: c.rcond_scaled,
        singularity: c.singularity,
        min_tension: c.min_tension,
        stable: c.stability.stable,
        min_compliance_eigenvalue: c.stability.eigenvalues[0],
        leg_switch: false,
    }
}

/// The measures where \[B_x B_u\] is exactly singular (see [`point_metrics`]).
fn singular(solver: &Solver, state: &RobotState) -> PointMetrics {
    let zero = Rconds::ZERO;
    let min_tension = tensions(solver.model(), state)
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    PointMetrics {
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
    }
}

/// Tendon tensions \[N\] of a state, legs concatenated.
pub(super) fn tensions(model: &Model, state: &RobotState) -> Vec<f64> {
    model
        .tendon_unknown_indices()
        .map(|i| tension(state.y_u[i]))
        .collect()
}
