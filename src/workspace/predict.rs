//! The predictor of a path step: the start of the next IK solve extrapolated from the last
//! solutions on a ray or on the path along z ([`predict`]), within one taut/slack regime of
//! the tendons ([`same_regime`]).
//!
//! Tried and dropped (2026-11-27, fifteenth session): the cubic Hermite extrapolation from
//! the last two solutions and their exact tangents ∂[q, ζ]/∂(position), J T = −B_x (one
//! LU of the IK Jacobian each point already has). On the design search's grid (the
//! reference, Δ = 12 mm, φ = 0.25, ε_b = 1e-10, one thread) its start was 10× nearer the
//! solution than this extrapolation's (median ‖Δq‖_∞ 5.9e-6 against 9.1e-5 m from three
//! solutions, 3.8e-5 against 3.9e-4 m from five; nearer at 97–100 % of the steps), but
//! the runs took about as many residuals (24 617 → 24 042 in all, Jacobians 4 782 →
//! 4 899, the same 2 201 cells; 1.78 s against 1.65 s, one run each): a run's chord
//! steps with the extrapolated Jacobian contract by 0.01–0.03 each there, so a start ten
//! times nearer saves about half an iteration, less than the tangents cost.

use crate::boundary::convert_tendon_unknowns;
use crate::kinetostatics::RobotState;
use crate::model::Model;
use crate::rod::tendon::TendonUnknown;

/// Solutions used by the predictor of a path step: the last five give a quartic
/// extrapolation where their tendons share one taut/slack pattern ([`same_regime`]) and
/// it agrees with the quadratic through the last three ([`HIGHER_ORDER_AGREEMENT`]).
/// Measured on the reference design (z ∈ [−6, 0] mm, φ = 0.2, one thread; callgrind),
/// with the extrapolated Jacobians ([`super::chord_jacobian`]) of as many solutions and
/// the first chord step's expected last residual ([`crate::newton::FIRST_STEP_PREDICTION`]):
/// quadratic from three, 8 726 residual integrations and 3 684 with sensitivities, 4.762 G
/// instructions; quartic from five, 6 236 and 3 725, 4.580 G (−3.8 %), the same cells.
/// From four or five with the whole history across a tendon's switch (not only the last
/// three, as [`same_regime`] has it now), more Newton Jacobians (566 and 624 instead of
/// 474) where the prediction crosses the switch.
pub(super) const PREDICTOR_POINTS: usize = 5;

/// The extrapolation of more than three solutions is used where it differs from the
/// quadratic through the last three by at most this fraction of the last step's change
/// (‖·‖_∞ over q); otherwise the quadratic is (the steps are then too long for the
/// solution's curvature to be resolved by the higher order). Measured, that fraction: at
/// Δ = 3 mm (the reference design, z = −30 mm) median 9.0e-4, 99.9 % below 2.0e-2; at
/// the design search's Δ = 12 mm median 1.6e-2, 29 % above 3e-2. Without the test the
/// design search's first candidates lost 2 of 663 and 3 of 678 reachable cells and the
/// ψ = 0 twin's Δ = 3 mm map moved 74 cells (41 lost, 33 gained of 90 490) near its
/// folds, 17 more onto another branch; with it the candidates' cells are those of the
/// quadratic and the twin's map moves 3 cells (2 lost, 1 gained) and 4 onto another
/// branch.
const HIGHER_ORDER_AGREEMENT: f64 = 0.02;

/// The start of the next path step extrapolated from the last solutions at equal steps
/// (oldest first): Lagrange, of degree one less than the number of solutions (at most
/// [`PREDICTOR_POINTS`]; the quadratic where a higher order disagrees with it,
/// [`HIGHER_ORDER_AGREEMENT`]), none from one. Tendon unknowns are extrapolated in
/// ζ = γ|γ| (tension when positive, slack when negative: linear in the pose away from
/// the taut/slack switch, where γ = ±√ζ is not), and a tendon whose prediction would
/// switch between taut and slack is predicted at the switch (ζ = 0): the two sides have
/// different units (N, m), so extrapolating across is meaningless.
///
/// The solution is smooth in the pose only between switches, so once the last two
/// solutions share their taut/slack pattern only the trailing solutions with that pattern
/// are extrapolated ([`same_regime`]). Measured on the reference design at Δ = 3 mm,
/// φ = 0.035: 14 % fewer Jacobian evaluations on the plane z = 0 and 20 % fewer on
/// z = −0.06 m, the same cells. Right after a switch (one solution with the new pattern)
/// the last three solutions are used ([`QUADRATIC`] across the switch): both
/// alternatives measured worse there (starting from the last solution lost 7 of 1581
/// cells on z = 0, a linear extrapolation from the last two lost 24), and a quartic
/// across it more so (see [`PREDICTOR_POINTS`]).
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
    let n = history.len();
    let mut q = extrapolate(&history.iter().map(|s| s.q.as_slice()).collect::<Vec<_>>());
    let mut from = 0;
    if n > QUADRATIC {
        // The higher order only where it agrees with the quadratic (see `PREDICTOR_POINTS`).
        let tail = &history[n - QUADRATIC..];
        let quadratic = extrapolate(&tail.iter().map(|s| s.q.as_slice()).collect::<Vec<_>>());
        let step = max_difference(&history[n - 1].q, &history[n - 2].q);
        let agrees = max_difference(&q, &quadratic) <= HIGHER_ORDER_AGREEMENT * step;
        if !agrees {
            q = quadratic;
            from = n - QUADRATIC;
        }
    }
    let y_u = extrapolate(&zeta[from..].iter().map(Vec::as_slice).collect::<Vec<_>>());
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

/// ‖a − b‖_∞.
pub(super) fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The values one step past the last of `xs` (equal steps, oldest first) into `out`: the
/// polynomial through up to five points (Σ_k (−1)^(m−1−k) C(m, k) x_k for m points), the
/// last itself from one (or from more than five); `out` unchanged from none.
///
/// One loop per point count, over zipped slices: the count matched once per call, no
/// index checks, so the loop vectorizes (the same operations in the same order per entry
/// as matching per entry, which cost 29 instructions an entry: 1.8 % of the reference
/// sweep's instructions, mostly the 900 entries of each extrapolated Jacobian).
pub(super) fn extrapolate(xs: &[&[f64]], out: &mut [f64]) {
    match *xs {
        [a, b, c, d, e] => {
            let points = a.iter().zip(b).zip(c.iter().zip(d)).zip(e);
            for (o, (((a, b), (c, d)), e)) in out.iter_mut().zip(points) {
                *o = 5.0 * e - 10.0 * d + 10.0 * c - 5.0 * b + a;
            }
        }
        [a, b, c, d] => {
            let points = a.iter().zip(b).zip(c.iter().zip(d));
            for (o, ((a, b), (c, d))) in out.iter_mut().zip(points) {
                *o = 4.0 * d - 6.0 * c + 4.0 * b - a;
            }
        }
        [a, b, c] => {
            for (o, ((a, b), c)) in out.iter_mut().zip(a.iter().zip(b).zip(c)) {
                *o = 3.0 * c - 3.0 * b + a;
            }
        }
        [a, b] => {
            for (o, (a, b)) in out.iter_mut().zip(a.iter().zip(b)) {
                *o = 2.0 * b - a;
            }
        }
        [.., last] => out.copy_from_slice(&last[..out.len()]),
        [] => {}
    }
}

/// The solutions of `history` to extrapolate (see [`predict`]): all of them where their
/// tendons are taut or slack as in the last one; otherwise the trailing ones with the
/// last one's pattern if there are at least two, else the last [`QUADRATIC`].
///
/// Always the last [`QUADRATIC`] for a redundant design (more actuators than a square
/// IK): there the least-norm IK picks the solution nearest its start, so the predictor
/// also chooses the path through the solution set; a shorter history measured worse
/// (Δ = 6 mm, φ = 0.05 rad: 11 044 instead of 12 057 reachable cells), and so did the
/// quartic from five (z ∈ [−30, 0] mm, Δ = 3 mm, φ = 0.035: 18 378 instead of 18 995
/// reachable cells, the sweep 15 % slower).
fn same_regime<'h, 's>(model: &Model, history: &'h [&'s RobotState]) -> &'h [&'s RobotState] {
    let n = history.len();
    let quadratic = &history[n.saturating_sub(QUADRATIC)..];
    if model.pairs > 1 {
        return quadratic;
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
        &history[n - run..]
    } else {
        quadratic
    }
}

/// Solutions extrapolated by a redundant design's predictor, and where a tendon switched
/// between taut and slack among the last ones and fewer than two share the last one's
/// pattern: three, a quadratic (as before the quartic of [`PREDICTOR_POINTS`]).
const QUADRATIC: usize = 3;

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
        // Right after the switch the last three are extrapolated (see `predict`).
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, -0.4),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
    }

    /// Five solutions of one pattern at s = s₀ + k h with q = s⁴ (the other unknowns s).
    fn quartic_history(m: &Model, s0: f64, h: f64) -> Vec<RobotState> {
        (0..5)
            .map(|k| {
                let s = s0 + k as f64 * h;
                let mut state = state(m, s, 1.0);
                state.q.iter_mut().for_each(|q| *q *= *q);
                state
            })
            .collect()
    }

    #[test]
    fn the_predictor_is_quartic_from_five_solutions_of_one_pattern() {
        let m = model("lilge2022.ron");
        // Short steps, s = 1, 1.01, …, 1.04: the quartic is exact (1.05⁴) and agrees with
        // the quadratic (off by 2.5e-5, 5.5e-4 of the last step's change).
        let h = quartic_history(&m, 1.0, 0.01);
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(
            p.q.iter().all(|q| (q - 1.05f64.powi(4)).abs() < 1e-12),
            "{:?}",
            p.q
        );
        // Long steps, s = 1 … 5: the quartic (1296) differs from the quadratic through
        // s = 3, 4, 5 (3 · 625 − 3 · 256 + 81 = 1188) by 29 % of the last step: the
        // quadratic.
        let mut h = quartic_history(&m, 1.0, 1.0);
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 1188.0).abs() < 1e-9), "{:?}", p.q);
        // A switch at the newest solution: the quadratic through the last three, whatever
        // the agreement.
        let mut short = quartic_history(&m, 1.0, 0.01);
        for s in [&mut h, &mut short] {
            s[4].y_u = state(&m, 5.0, -1.0).y_u;
        }
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 1188.0).abs() < 1e-9), "{:?}", p.q);
        let quadratic = 3.0 * 1.04f64.powi(4) - 3.0 * 1.03f64.powi(4) + 1.02f64.powi(4);
        let p = predict(&m, &short.iter().collect::<Vec<_>>()).unwrap();
        assert!(
            p.q.iter().all(|q| (q - quadratic).abs() < 1e-12),
            "{:?}",
            p.q
        );
        assert!((quadratic - 1.05f64.powi(4)).abs() > 1e-5);
    }

    #[test]
    fn the_predictor_of_a_redundant_design_extrapolates_the_last_three_solutions() {
        let m = model("lilge2022_redundant.ron");
        let h = [
            state(&m, 1.0, -0.5),
            state(&m, 2.0, 1.1),
            state(&m, 3.0, 1.2),
        ];
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        assert!(p.q.iter().all(|q| (q - 16.0).abs() < 1e-12), "{:?}", p.q);
        // Five of one pattern, close together (where a 6-DoF design takes the quartic):
        // the quadratic through the last three.
        let h = quartic_history(&m, 1.0, 0.01);
        let p = predict(&m, &h.iter().collect::<Vec<_>>()).unwrap();
        let quadratic = 3.0 * 1.04f64.powi(4) - 3.0 * 1.03f64.powi(4) + 1.02f64.powi(4);
        assert!(
            p.q.iter().all(|q| (q - quadratic).abs() < 1e-12),
            "{:?}",
            p.q
        );
    }
}
