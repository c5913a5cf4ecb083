//! The predictor of a path step: the start of the next IK solve extrapolated from the last
//! solutions on a ray or on the path along z ([`predict`]), within one taut/slack regime of
//! the tendons ([`same_regime`]).

use crate::boundary::convert_tendon_unknowns;
use crate::kinetostatics::RobotState;
use crate::model::Model;
use crate::rod::tendon::TendonUnknown;

/// Solutions used by the predictor of a path step: the last three give a quadratic
/// extrapolation.
pub(super) const PREDICTOR_POINTS: usize = 3;

/// The start of the next path step extrapolated from the last solutions at equal steps
/// (oldest first): quadratic from three, linear from two, none from one. Tendon unknowns
/// are extrapolated in ζ = γ|γ| (tension when positive, slack when negative: linear in
/// the pose away from the taut/slack switch, where γ = ±√ζ is not), and a tendon whose
/// prediction would switch between taut and slack is predicted at the switch (ζ = 0):
/// the two sides have different units (N, m), so extrapolating across is meaningless.
///
/// The solution is smooth in the pose only between switches, so once the last two
/// solutions share their taut/slack pattern only the trailing solutions with that pattern
/// are extrapolated ([`same_regime`]). Measured on the reference design at Δ = 3 mm,
/// φ = 0.035: 14 % fewer Jacobian evaluations on the plane z = 0 and 20 % fewer on
/// z = −0.06 m, the same cells. Right after a switch (one solution with the new pattern)
/// the whole history is still used: both alternatives measured worse there (starting from
/// the last solution lost 7 of 1581 cells on z = 0, a linear extrapolation from the last
/// two lost 24).
pub(super) fn predict(model: &Model, history: &[&RobotState]) -> Option<RobotState> {
    let extrapolate = |xs: &[&[f64]]| -> Vec<f64> {
        let mut out = vec![0.0; xs[xs.len() - 1].len()];
        extrapolate(xs, &mut out);
        out
    };
    let history = same_regime(model, history);
    if history.len() < 2 {
        return None;
    }
    let zeta: Vec<Vec<f64>> = history.iter().map(|s| in_zeta(model, s)).collect();
    let last = history[history.len() - 1];
    let y_u = extrapolate(&zeta.iter().map(Vec::as_slice).collect::<Vec<_>>());
    let q = extrapolate(&history.iter().map(|s| s.q.as_slice()).collect::<Vec<_>>());
    Some(predicted_state(model, last, &zeta[zeta.len() - 1], q, y_u))
}

/// The leg unknowns of `state` with the tendons' in ζ = γ|γ|.
pub(super) fn in_zeta(model: &Model, state: &RobotState) -> Vec<f64> {
    let mut y = state.y_u.clone();
    convert_tendon_unknowns(model, &mut y, TendonUnknown::Gamma, TendonUnknown::Linear);
    y
}

/// The predicted state of actuation `q` and leg unknowns `y_u` (tendons in ζ) at the pose
/// of `last` (whose leg unknowns in ζ are `last_zeta`): a tendon predicted across its
/// kink (ζ of the other sign than in `last`) starts at the kink, ζ = 0.
pub(super) fn predicted_state(
    model: &Model,
    last: &RobotState,
    last_zeta: &[f64],
    q: Vec<f64>,
    mut y_u: Vec<f64>,
) -> RobotState {
    for i in model.tendon_unknown_indices() {
        if y_u[i] * last_zeta[i] < 0.0 {
            y_u[i] = 0.0;
        }
    }
    convert_tendon_unknowns(model, &mut y_u, TendonUnknown::Linear, TendonUnknown::Gamma);
    RobotState {
        position: last.position,
        rotvec: last.rotvec,
        q,
        y_u,
    }
}

/// The values one step past the last of `xs` (equal steps, oldest first) into `out`:
/// quadratic from three, linear from two, the last itself from one.
pub(super) fn extrapolate(xs: &[&[f64]], out: &mut [f64]) {
    let last = xs[xs.len() - 1];
    for (i, o) in out.iter_mut().enumerate() {
        *o = match xs {
            [a, b, c] => 3.0 * c[i] - 3.0 * b[i] + a[i],
            [a, b] => 2.0 * b[i] - a[i],
            _ => last[i],
        };
    }
}

/// The trailing solutions of `history` whose tendons are taut or slack as in the last
/// one, if there are at least two of them; otherwise the whole history (see [`predict`]).
///
/// Always the whole history for a redundant design (more actuators than a square IK):
/// there the least-norm IK picks the solution nearest its start, so the predictor also
/// chooses the path through the solution set, and the shorter history measured worse
/// (Δ = 6 mm, φ = 0.05 rad: 11 044 instead of 12 057 reachable cells).
fn same_regime<'h, 's>(model: &Model, history: &'h [&'s RobotState]) -> &'h [&'s RobotState] {
    if model.pairs > 1 {
        return history;
    }
    let same_pattern = |a: &RobotState, b: &RobotState| {
        model
            .tendon_unknown_indices()
            .all(|i| (a.y_u[i] > 0.0) == (b.y_u[i] > 0.0))
    };
    let Some(last) = history.last() else {
        return history;
    };
    let run = history
        .iter()
        .rev()
        .take_while(|s| same_pattern(s, last))
        .count();
    if run >= 2 {
        &history[history.len() - run..]
    } else {
        history
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Tdpcr;

    /// A state with every q = s², every tendon unknown γ = `gamma` (positive = taut) and
    /// the other leg unknowns s.
    fn state(model: &Model, s: f64, gamma: f64) -> RobotState {
        let nu = model.n_leg_unknowns();
        let y_u = (0..3 * nu)
            .map(|i| if i % nu < model.n_tendons() { gamma } else { s })
            .collect();
        RobotState {
            position: [0.0; 3],
            rotvec: [0.0; 3],
            q: vec![s * s; model.n_actuators()],
            y_u,
        }
    }

    fn model(design: &str) -> Model {
        let path = format!("{}/designs/{design}", env!("CARGO_MANIFEST_DIR"));
        Model::new(&Tdpcr::from_ron_file(path).unwrap())
    }

    #[test]
    fn the_predictor_is_quadratic_within_one_taut_slack_pattern() {
        let m = model("lilge2022.ron");
        let h = [
            state(&m, 1.0, 1.0),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        // q = s² is extrapolated exactly by a quadratic.
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }

    #[test]
    fn the_predictor_extrapolates_only_the_solutions_after_a_switch() {
        let m = model("lilge2022.ron");
        // The tendons switched from slack to taut between the first and second solution.
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        // Linear from the last two: 2 · 9 − 4 = 14 (the quadratic through all three: 16).
        assert!(p.q.iter().all(|q| (q - 14.0).abs() < 1e-12), "{:?}", p.q);
        // Right after the switch the whole history is extrapolated (see `predict`).
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, -0.4),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }

    #[test]
    fn the_predictor_of_a_redundant_design_always_extrapolates_the_whole_history() {
        let m = model("lilge2022_redundant.ron");
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }
}
