//! Why a ray or the path along z ended: one walk's [`End`], counted over the rays
//! ([`RayEnds`]) and told for the path down and up ([`PathEnd`]). Shared by the walking
//! ([`super::walk`]) and the summary ([`super::summary`]).

use serde::Serialize;

/// Why a ray or path ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum End {
    /// Newton stopped without a solution here (iteration limit, no progress, trust region
    /// collapsed): the end of the reachable set in this direction.
    NotConverged,
    /// Some q left its actuation limits.
    Limits,
    /// A collision ([`CollisionPolicy::Stop`](super::CollisionPolicy::Stop)).
    Collision,
    /// The equilibrium became unstable with the actuators held.
    Unstable,
    /// The ray reached the geometric bound of the design.
    MaxRadius,
    /// Any other error; its message is in [`Worker::error`](super::walk::Worker::error).
    Failed,
}

/// Why rays ended (counts over all rays).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub struct RayEnds {
    /// Newton did not converge.
    pub not_converged: usize,
    /// Some q left its actuation limits.
    pub actuation_limits: usize,
    /// A collision ([`CollisionPolicy::Stop`](super::CollisionPolicy::Stop)).
    pub collision: usize,
    /// The equilibrium became unstable with the actuators held.
    pub unstable: usize,
    /// The ray reached the geometric bound of the design (should not happen).
    pub max_radius: usize,
    /// An error other than a solve that did not converge (e.g. a leg integration that
    /// turned non-finite): the first one is in
    /// [`WorkspaceSummary::first_error`](super::WorkspaceSummary::first_error).
    pub failed: usize,
}

impl RayEnds {
    pub(super) fn count(&mut self, end: End) {
        match end {
            End::NotConverged => self.not_converged += 1,
            End::Limits => self.actuation_limits += 1,
            End::Collision => self.collision += 1,
            End::Unstable => self.unstable += 1,
            End::MaxRadius => self.max_radius += 1,
            End::Failed => self.failed += 1,
        }
    }

    pub(super) fn add(&mut self, other: &Self) {
        self.not_converged += other.not_converged;
        self.actuation_limits += other.actuation_limits;
        self.collision += other.collision;
        self.unstable += other.unstable;
        self.max_radius += other.max_radius;
        self.failed += other.failed;
    }
}

/// Why the path along z from the home configuration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PathEnd {
    /// It reached the end of the z-range (or the range does not extend this way).
    EndOfRange,
    /// A step did not converge.
    NotConverged,
    /// A step left the actuation limits.
    ActuationLimits,
    /// A step collided ([`CollisionPolicy::Stop`](super::CollisionPolicy::Stop)).
    Collision,
    /// A step reached an unstable equilibrium.
    Unstable,
    /// A step failed with an error other than non-convergence
    /// ([`WorkspaceSummary::first_error`](super::WorkspaceSummary::first_error)).
    Failed,
    /// The home configuration itself is invalid (out of limits or colliding).
    InvalidHome,
}

impl From<End> for PathEnd {
    fn from(e: End) -> Self {
        match e {
            End::NotConverged | End::MaxRadius => Self::NotConverged,
            End::Limits => Self::ActuationLimits,
            End::Collision => Self::Collision,
            End::Unstable => Self::Unstable,
            End::Failed => Self::Failed,
        }
    }
}
