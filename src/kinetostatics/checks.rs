//! The input checks of every solve: actuation, pose, wrench, warm start and Newton
//! settings, each violation named with its value (all listed at once, as
//! [`Error::Input`]).

use super::Solver;
use super::state::RobotState;
use crate::analysis::AnalysisSettings;
use crate::error::{Error, Violations};
use crate::model::Pose;
use crate::newton::NewtonSettings;
use crate::rod::Wrench;

/// An actuation of the wrong length or with non-finite values, as violations.
pub(super) fn actuation_violations(solver: &Solver, q: &[f64]) -> Violations {
    let mut v = Violations::default();
    let n = solver.model.n_actuators();
    if q.len() != n {
        v.push(
            "q",
            crate::error::counted(q.len(), "value"),
            &format!("{n} values: per leg [bend_x, (bend_y), translation]"),
        );
    }
    for (i, x) in q.iter().enumerate() {
        if !x.is_finite() {
            v.push(format!("q[{i}]"), x, "a finite number [m]");
        }
    }
    v
}

/// A pose with a non-finite entry, as a violation.
pub(super) fn pose_violations(pose: &Pose) -> Violations {
    let mut v = Violations::default();
    if !pose
        .position
        .iter()
        .chain(pose.rotation.iter())
        .all(|x| x.is_finite())
    {
        v.push("pose", "a non-finite value", "finite numbers");
    }
    v
}

/// Adds the wrench, warm-start, settings (and, without the `qp` feature, redundancy)
/// checks to `v`; the total wrench if nothing failed.
///
/// # Errors
/// [`Error::Input`] listing every violation.
pub(super) fn checked_wrench(
    solver: &Solver,
    mut v: Violations,
    extra: &Wrench,
    init: Option<&RobotState>,
    settings: &NewtonSettings,
) -> Result<Wrench, Error> {
    check_wrench(&mut v, extra);
    check_init(solver, &mut v, init);
    settings.check("settings", &mut v);
    #[cfg(not(feature = "qp"))]
    if matches!(solver.redundancy, super::Redundancy::WithinLimits(_)) {
        v.push(
            "redundancy",
            "WithinLimits",
            "LeastNorm: steps within the limits need the cargo feature `qp` of tdpcr",
        );
    }
    if v.0.is_empty() {
        Ok(solver.total_wrench(extra))
    } else {
        Err(Error::Input(v))
    }
}

fn check_wrench(v: &mut Violations, w: &Wrench) {
    for (i, x) in w.force.iter().chain(w.moment.iter()).enumerate() {
        if !x.is_finite() {
            v.push(format!("wrench[{i}]"), x, "a finite number");
        }
    }
}

pub(super) fn check_init(solver: &Solver, v: &mut Violations, init: Option<&RobotState>) {
    if let Some(s) = init {
        if s.q.len() != solver.model.n_actuators() {
            v.push(
                "init.q",
                crate::error::counted(s.q.len(), "value"),
                &crate::error::counted(solver.model.n_actuators(), "value"),
            );
        }
        let ny = 3 * solver.model.n_leg_unknowns();
        if s.y_u.len() != ny {
            v.push(
                "init.y_u",
                crate::error::counted(s.y_u.len(), "value"),
                &format!("{ny} values"),
            );
        }
        let all = s.position.iter().chain(&s.rotvec).chain(&s.q).chain(&s.y_u);
        if !all.clone().all(|x| x.is_finite()) {
            v.push("init", "a non-finite value", "finite numbers");
        }
    }
}

/// A state or wrench of the wrong size or with non-finite values, or singularity
/// thresholds that are negative or not finite, as violations (the inputs of
/// [`Solver::analyze`]).
pub(super) fn analysis_violations(
    solver: &Solver,
    state: &RobotState,
    extra: &Wrench,
    settings: &AnalysisSettings,
) -> Violations {
    let mut v = Violations::default();
    let model = solver.model();
    for (field, found, expected) in [
        ("state.q", state.q.len(), model.n_actuators()),
        ("state.y_u", state.y_u.len(), 3 * model.n_leg_unknowns()),
    ] {
        if found != expected {
            v.push(
                field,
                format!("{found} values"),
                &format!("{expected} values"),
            );
        }
    }
    let values = state.position.iter().chain(&state.rotvec).chain(&state.q);
    if !values.chain(&state.y_u).all(|x| x.is_finite()) {
        v.push("state", "a non-finite value", "finite numbers");
    }
    if !extra
        .force
        .iter()
        .chain(&extra.moment)
        .all(|x| x.is_finite())
    {
        v.push("wrench", "a non-finite value", "finite numbers");
    }
    for (field, x) in [
        ("type_i_threshold", settings.type_i_threshold),
        ("type_ii_threshold", settings.type_ii_threshold),
        ("leg_threshold", settings.leg_threshold),
    ] {
        if !(x.is_finite() && x >= 0.0) {
            v.push(field, x, ">= 0 and finite");
        }
    }
    v
}
