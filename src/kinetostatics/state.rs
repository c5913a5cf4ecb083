//! The solver's results: a configuration ([`RobotState`], also a warm start) and a
//! converged solve ([`Solution`]: the state, the Newton work and the wrench it was
//! solved under).

use nalgebra::{Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use super::SOLVER_TENDON_UNKNOWN;
use crate::boundary::{BoundaryPoint, convert_tendon_unknowns};
use crate::model::{Model, Pose};
use crate::newton::NewtonReport;
use crate::rod::Wrench;
use crate::rod::tendon::TendonUnknown;

/// A solved (or guessed) configuration; serializes to JSON and is accepted as a warm start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotState {
    /// Platform position p_ee \[m\].
    pub position: [f64; 3],
    /// Platform orientation as a rotation vector (axis × angle) \[rad\], world frame.
    pub rotvec: [f64; 3],
    /// Actuation q (per leg \[q_b per pair, q_t\]) \[m\].
    pub q: Vec<f64>,
    /// Leg unknowns y_u (per leg [γ (n_t), u(0) (3), v(0) (3)]).
    pub y_u: Vec<f64>,
}

impl RobotState {
    /// The platform pose.
    pub fn pose(&self) -> Pose {
        Pose {
            position: Vector3::from(self.position),
            rotation: *Rotation3::new(Vector3::from(self.rotvec)).matrix(),
        }
    }

    /// The boundary conditions' evaluation point of this state at its pose `pose`
    /// (from [`RobotState::pose`]) under the total platform wrench `wrench`.
    pub fn boundary_point<'a>(&'a self, pose: &'a Pose, wrench: &'a Wrench) -> BoundaryPoint<'a> {
        BoundaryPoint {
            pose,
            q: &self.q,
            wrench,
            y_u: &self.y_u,
            tendon_unknown: TendonUnknown::Gamma,
        }
    }

    /// The IK state at `pose` with actuation `q` and leg unknowns `y_u` in the solver's
    /// tendon variable (converted back to γ, [`as_reported`]).
    pub(crate) fn at_pose(model: &Model, pose: &Pose, q: Vec<f64>, mut y_u: Vec<f64>) -> Self {
        as_reported(model, &mut y_u);
        RobotState {
            position: pose.position.into(),
            rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
                .scaled_axis()
                .into(),
            q,
            y_u,
        }
    }
}

/// The solver's leg unknowns `y_u` (tendons in its ζ) as a state reports them (in γ,
/// [`as_reported`]) and a solve or an analysis of that state reads them back: ζ → γ → ζ,
/// in place (the round trip can move them by round-off, and a tendon exactly at its kink
/// to ζ = 1e-16; the legs' starts from the result are those of the state's, bit for
/// bit).
pub(crate) fn as_restated(model: &Model, y_u: &mut [f64]) {
    as_reported(model, y_u);
    convert_tendon_unknowns(model, y_u, TendonUnknown::Gamma, SOLVER_TENDON_UNKNOWN);
}

/// γ of a tendon that a solve ends exactly at its kink (ζ = 0: no tension, no slack, as
/// the redundant IK's one-sided steps hold a tendon there): just taut, τ = γ² = 1e-16 N.
/// At γ = 0 both slopes dτ/dγ and dΘ/dγ vanish (MODEL.md §9), so the analysis' blocks
/// (γ columns, the paper's) would have a zero column and \[B_x B_u\] would be exactly
/// singular, leaving no J_FK or compliance; at this γ the column is the taut side's times
/// 2e-8 (the paper's rconds then near 0, the point flagged near Type II and leg
/// singular) and J_FK and C are the taut side's. The residual moves by the tension's
/// 1e-16 N, far below any tolerance.
pub(crate) const GAMMA_AT_KINK: f64 = 1e-8;

/// The solver's leg unknowns `y_u` (tendons in its ζ) as a state reports them, in γ, in
/// place: a tendon exactly at its kink as [`GAMMA_AT_KINK`].
pub(crate) fn as_reported(model: &Model, y_u: &mut [f64]) {
    convert_tendon_unknowns(model, y_u, SOLVER_TENDON_UNKNOWN, TendonUnknown::Gamma);
    for i in model.tendon_unknown_indices() {
        if y_u[i] == 0.0 {
            y_u[i] = GAMMA_AT_KINK;
        }
    }
}

/// A converged solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The configuration.
    pub state: RobotState,
    /// Newton work and final residual norm. The work is the whole call's: also that of
    /// the runs that failed before the one that converged (a direct attempt before its
    /// continuation, a predicted start before the guess, continuation steps that were
    /// halved).
    pub report: NewtonReport,
    /// Wall time of the solve \[µs\].
    pub solve_time_us: f64,
    /// The external wrench it was solved under, beyond the platform's weight (the `extra`
    /// of the solve; the state is the equilibrium under it): [`Solver::analyze_solution`](super::Solver::analyze_solution)
    /// needs nothing else.
    pub extra: Wrench,
}

impl Solution {
    /// Tension of every tendon \[N\], per leg.
    pub fn tensions(&self, model: &Model) -> Vec<Vec<f64>> {
        let nu = model.n_leg_unknowns();
        (0..3)
            .map(|i| {
                self.state.y_u[i * nu..i * nu + model.n_tendons()]
                    .iter()
                    .map(|&g| crate::rod::tendon::tension(g))
                    .collect()
            })
            .collect()
    }
}
