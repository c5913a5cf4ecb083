//! How far the inputs of a solve lie outside the design's range: the words of a
//! [`SolveError::Diverged`] (which input, how many times its natural scale, what to try).
//!
//! The scales are linear-theory estimates of a cantilever leg (length L, bending
//! stiffness EI, tendon offset r): a tip force 3EI/L² or a tip moment EI/L bends it by
//! about its own length or one radian; a tendon tension EI/(rL) or a tendon displacement
//! r bends it by about one radian. The parallel robot's three legs share the platform
//! load; its actuation has the design's `actuation_limits`. An input beyond its scale
//! (factor > 1) is reported, the largest factor first.

use crate::error::{OutOfRange, SolveError, short_number};
use crate::model::Model;
use crate::rod::LegModel;
use crate::rod::Wrench;
use crate::tdcr::TendonControl;

/// Number of legs of the parallel robot that share the platform load.
const LEGS: f64 = 3.0;

/// `error` in the user's terms when it is a non-finite state ([`SolveError::NonFinite`]):
/// a [`SolveError::Diverged`] naming `inputs` beyond their scale; other errors unchanged.
pub fn diverged_if_non_finite(
    error: SolveError,
    inputs: impl FnOnce() -> Vec<OutOfRange>,
) -> SolveError {
    match error {
        SolveError::NonFinite { stage } => {
            let mut inputs: Vec<OutOfRange> =
                inputs().into_iter().filter(|i| i.factor > 1.0).collect();
            inputs.sort_by(|a, b| b.factor.total_cmp(&a.factor));
            SolveError::Diverged { stage, inputs }
        }
        e => e,
    }
}

/// |v|, at most f64::MAX: a wrench of 1e308 N had an infinite length (`inf N` in the
/// message, `null` in JSON). Scaled by the largest component so that it does not
/// overflow on the way.
fn length(v: &nalgebra::Vector3<f64>) -> f64 {
    let largest = v.amax();
    if largest == 0.0 || !largest.is_finite() {
        return largest.min(f64::MAX);
    }
    (largest * (v / largest).norm()).min(f64::MAX)
}

/// Tip force that bends a cantilever leg by about its own length, 3EI/L² \[N\].
fn bending_force(leg: &LegModel) -> f64 {
    3.0 * leg.bending_stiffness() / (leg.length * leg.length)
}

/// Tip moment that bends a cantilever leg by about one radian, EI/L \[N·m\].
fn bending_moment(leg: &LegModel) -> f64 {
    leg.bending_stiffness() / leg.length
}

/// The actuation `q` against the actuation limits, and the platform load (weight plus
/// `extra`) against the force and moment that bend the three legs by about their length.
pub fn parallel_robot_inputs(model: &Model, q: Option<&[f64]>, extra: &Wrench) -> Vec<OutOfRange> {
    let mut out = Vec::new();
    let per_leg = model.n_actuators() / 3;
    for (i, &x) in q.unwrap_or_default().iter().enumerate() {
        let (scale, limit) = if i % per_leg == per_leg - 1 {
            (model.limits.base_translation, "base_translation")
        } else {
            (model.limits.tendon_displacement, "tendon_displacement")
        };
        let meaning = format!("the actuation limit actuation_limits.{limit}");
        out.push(OutOfRange::new(format!("q[{i}]"), x, "m", scale, &meaning));
    }
    let weight = length(&model.platform_weight);
    let load = format!(
        "the platform load (weight {} N of platform.mass plus wrench force {} N)",
        short_number(weight),
        short_number(length(&extra.force))
    );
    let force = length(&(model.platform_weight + extra.force));
    let meaning = "the force that bends the three legs by about their length (3 x 3EI/L^2)";
    out.push(OutOfRange::new(
        load,
        force,
        "N",
        LEGS * bending_force(&model.leg),
        meaning,
    ));
    let meaning = "the moment that bends the three legs by about one radian (3 x EI/L)";
    let scale = LEGS * bending_moment(&model.leg);
    let moment = length(&extra.moment);
    out.push(OutOfRange::new(
        "the wrench moment".into(),
        moment,
        "N m",
        scale,
        meaning,
    ));
    out
}

/// The tendon tensions or displacements and the tip wrench of a single TDCR against what
/// bends its rod by about one radian (or its length).
pub fn tdcr_inputs(leg: &LegModel, control: &TendonControl, wrench: &Wrench) -> Vec<OutOfRange> {
    let mut out = Vec::new();
    let (name, values, unit) = match control {
        TendonControl::Tension(t) => ("tensions", t, "N"),
        TendonControl::Displacement(d) => ("displacements", d, "m"),
    };
    for (k, &x) in values.iter().enumerate().take(leg.n_tendons) {
        let r = leg.tendon_offsets[k].norm();
        let (scale, meaning) = match control {
            TendonControl::Tension(_) => (
                leg.bending_stiffness() / (r * leg.length),
                "the tension that bends the rod by about one radian (EI/(r L))",
            ),
            TendonControl::Displacement(_) => (
                r,
                "the displacement that bends the rod by about one radian (the tendon offset r)",
            ),
        };
        out.push(OutOfRange::new(
            format!("{name}[{k}]"),
            x,
            unit,
            scale,
            meaning,
        ));
    }
    let meaning = "the force that bends the rod by about its length (3EI/L^2)";
    let force = length(&wrench.force);
    out.push(OutOfRange::new(
        "the tip force".into(),
        force,
        "N",
        bending_force(leg),
        meaning,
    ));
    let meaning = "the moment that bends the rod by about one radian (EI/L)";
    let moment = length(&wrench.moment);
    out.push(OutOfRange::new(
        "the tip moment".into(),
        moment,
        "N m",
        bending_moment(leg),
        meaning,
    ));
    out
}
