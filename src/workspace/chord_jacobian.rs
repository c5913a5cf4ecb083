//! The Jacobian a path step's Newton run starts from ([`Solver::reuse_ik_jacobian`]): the
//! exact IK Jacobians that the per-point analyses evaluated at the last solutions on the
//! path (a ray, or the path along z), extrapolated to the next point at the same step like
//! the states ([`super::predict`]): the polynomial through up to
//! [`PREDICTOR_POINTS`](super::predict) of them (quartic from five), the last one alone
//! from one, within one taut/slack pattern of the tendons (a switch changes the
//! tendon columns of the solver's ζ unknowns, so only the trailing Jacobians with the
//! pattern of the last one are extrapolated).
//!
//! Why: a chord step with the exact Jacobian at the last solution, a step Δ = 3 mm
//! behind, contracts the residual by only 0.02–0.1, so a step took 3–5 residual
//! evaluations; the extrapolated Jacobian is off by O(Δ³) instead of O(Δ). Measured on the
//! reference design, z ∈ [−12, 0] mm, φ = 0.1, one thread: 46 729 Newton iterations and
//! 64 161 residual evaluations with the last Jacobian, 33 303 and 49 697 with the linear
//! extrapolation, 30 831 and 47 233 with the quadratic one (the same 8665 cells). The
//! quartic from five (with the states' quartic) leaves the first chord step's residual
//! ‖F₁‖ at 1e-5–1e-4 × ‖F₀‖, within the tolerance at most points, where the
//! quadratic's mostly just missed it (1.2–9e-10 against 1e-10).
//! Newton's tolerance is the same whatever Jacobian it starts from; a start that does not
//! contract tenfold is dropped for a fresh exact Jacobian.

use nalgebra::{DMatrix, DVector};

use crate::kinetostatics::{RobotState, Solver};
use crate::model::Model;

use super::predict::{PREDICTOR_POINTS, extrapolate};

/// The exact IK Jacobians (in the solver's unknowns) at the last solutions of a path at
/// equal steps, with their tendons' taut/slack patterns.
#[derive(Debug, Clone)]
pub(super) struct JacobianHistory {
    /// Slot `(first + k) % PREDICTOR_POINTS` holds the k-th oldest of `len`.
    jacobians: [DMatrix<f64>; PREDICTOR_POINTS],
    /// Bit i set: tendon unknown i (in [`Model::tendon_unknown_indices`] order) is taut.
    patterns: [u64; PREDICTOR_POINTS],
    first: usize,
    len: usize,
    /// The extrapolation handed to the solver.
    next: DMatrix<f64>,
}

impl JacobianHistory {
    /// An empty history for the IK of `model`.
    pub(super) fn new(model: &Model) -> Self {
        let n = model.n_residuals();
        Self {
            jacobians: std::array::from_fn(|_| DMatrix::zeros(n, n)),
            patterns: [0; PREDICTOR_POINTS],
            first: 0,
            len: 0,
            next: DMatrix::zeros(n, n),
        }
    }

    /// Forgets every Jacobian (a new path, or a change of step).
    pub(super) fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds the Jacobian at the path's newest solution `state` from the solver's last
    /// blocks (its analysis at `state`), dropping the oldest; where the solver has none
    /// (the redundant design, a tendon at γ = 0) the history is cleared.
    pub(super) fn push(&mut self, model: &Model, solver: &Solver, state: &RobotState) {
        self.push_with(model, state, |jac| {
            solver.ik_jacobian_from_blocks(state, jac)
        });
    }

    /// Adds `jacobian`, the IK Jacobian at the path's newest solution `state`, dropping
    /// the oldest.
    pub(super) fn push_jacobian(
        &mut self,
        model: &Model,
        state: &RobotState,
        jacobian: &DMatrix<f64>,
    ) {
        self.push_with(model, state, |jac| {
            jac.copy_from(jacobian);
            true
        });
    }

    /// Adds the Jacobian `fill` writes (false: none, the history is cleared).
    fn push_with(
        &mut self,
        model: &Model,
        state: &RobotState,
        fill: impl FnOnce(&mut DMatrix<f64>) -> bool,
    ) {
        let slot = if self.len < PREDICTOR_POINTS {
            self.len += 1;
            (self.first + self.len - 1) % PREDICTOR_POINTS
        } else {
            let oldest = self.first;
            self.first = (self.first + 1) % PREDICTOR_POINTS;
            oldest
        };
        if !fill(&mut self.jacobians[slot]) {
            self.clear();
            return;
        }
        self.patterns[slot] = model
            .tendon_unknown_indices()
            .enumerate()
            .filter(|&(_, i)| state.y_u[i] > 0.0)
            .fold(0, |bits, (k, _)| bits | 1 << k);
    }

    /// Hands the solver the last extrapolation ([`JacobianHistory::seed`]) with `columns`
    /// (index in \[q, ζ\], column) in place of its own: the other sides' columns of a
    /// start across kinks ([`super::kink_start`]). Nothing if the history is empty.
    pub(super) fn seed_with_columns<'c>(
        &mut self,
        solver: &mut Solver,
        columns: impl Iterator<Item = (usize, &'c DVector<f64>)>,
    ) {
        if self.len == 0 {
            return;
        }
        for (index, column) in columns {
            self.next.column_mut(index).copy_from(column);
        }
        solver.reuse_ik_jacobian(&self.next);
    }

    /// Hands the solver the Jacobians extrapolated one step ahead (nothing if empty).
    pub(super) fn seed(&mut self, solver: &mut Solver) {
        if self.len == 0 {
            return;
        }
        let slot = |k: usize| (self.first + k) % PREDICTOR_POINTS;
        let newest = self.patterns[slot(self.len - 1)];
        let run = (0..self.len)
            .rev()
            .take_while(|&k| self.patterns[slot(k)] == newest)
            .count();
        let mut points: [&[f64]; PREDICTOR_POINTS] = [&[]; PREDICTOR_POINTS];
        for (point, k) in points.iter_mut().zip(self.len - run..self.len) {
            *point = self.jacobians[slot(k)].as_slice();
        }
        extrapolate(&points[..run], self.next.as_mut_slice());
        solver.reuse_ik_jacobian(&self.next);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::AnalysisSettings;
    use crate::design::Tdpcr;
    use crate::rod::Wrench;
    use nalgebra::Vector3;

    /// IK solutions at x = 0, Δ, 2Δ, … (Δ = 3 mm) with the solver's blocks at the last.
    fn walk(points: usize) -> (Solver, Vec<RobotState>) {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/designs/lilge2022.ron");
        let mut solver = Solver::new(&Tdpcr::from_ron_file(path).unwrap()).unwrap();
        let w = Wrench::default();
        let mut state = solver.solve_fk(&[0.0; 6], &w, None).unwrap().state;
        let start = state.pose();
        let mut states = Vec::new();
        for k in 0..points {
            let mut pose = start;
            pose.position += Vector3::new(0.003 * k as f64, 0.0, 0.0);
            state = solver.solve_ik(&pose, &w, Some(&state)).unwrap().state;
            states.push(state.clone());
        }
        (solver, states)
    }

    /// Along a ray the extrapolation of the Jacobians at the last solutions is much nearer
    /// the exact Jacobian at the next one than the last Jacobian is, and more so the more
    /// solutions it extrapolates (measured: the quadratic from three 1.2e-3 times as far
    /// as the last one, the quartic from five 1.1e-2 times as far as the quadratic).
    #[test]
    fn the_extrapolation_is_nearer_the_next_jacobian_than_the_last_one() {
        let (mut solver, states) = walk(PREDICTOR_POINTS + 1);
        let model = solver.model().clone();
        let settings = AnalysisSettings::default();
        let n = model.n_residuals();
        let mut exact = Vec::new();
        for s in &states {
            solver.condition(s, &Wrench::default(), &settings).unwrap();
            let mut j = DMatrix::zeros(n, n);
            assert!(solver.ik_jacobian_from_blocks(s, &mut j));
            exact.push(j);
        }
        let next = &exact[PREDICTOR_POINTS];
        let mut extrapolated_from = |points: usize| {
            let mut history = JacobianHistory::new(&model);
            for s in &states[PREDICTOR_POINTS - points..PREDICTOR_POINTS] {
                solver.condition(s, &Wrench::default(), &settings).unwrap();
                history.push(&model, &solver, s);
            }
            assert_eq!(history.len, points);
            history.seed(&mut solver);
            (&history.next - next).norm()
        };
        let last = (&exact[PREDICTOR_POINTS - 1] - next).norm();
        let quadratic = extrapolated_from(3);
        let quartic = extrapolated_from(PREDICTOR_POINTS);
        assert!(
            quadratic < 0.01 * last && quartic < 0.05 * quadratic,
            "the last off by {last:.3e}, the quadratic by {quadratic:.3e}, the quartic by \
             {quartic:.3e}"
        );
    }

    /// Only the trailing Jacobians with the newest taut/slack pattern are extrapolated; a
    /// full history drops its oldest.
    #[test]
    fn a_pattern_change_restarts_the_extrapolation() {
        let (mut solver, states) = walk(1);
        let model = solver.model().clone();
        let mut history = JacobianHistory::new(&model);
        solver
            .condition(&states[0], &Wrench::default(), &AnalysisSettings::default())
            .unwrap();
        for _ in 0..=PREDICTOR_POINTS {
            history.push(&model, &solver, &states[0]);
        }
        assert_eq!(history.len, PREDICTOR_POINTS);
        // Make the older entries differ from the newest: each by its own amount.
        let newest = (history.first + PREDICTOR_POINTS - 1) % PREDICTOR_POINTS;
        for k in 0..PREDICTOR_POINTS - 1 {
            let slot = (history.first + k) % PREDICTOR_POINTS;
            history.jacobians[slot].add_scalar_mut(1.0 + k as f64);
        }
        history.seed(&mut solver);
        let extrapolated = history.next.clone();
        assert!((&extrapolated - &history.jacobians[newest]).norm() > 1.0);
        history.patterns[newest] ^= 1;
        history.seed(&mut solver);
        assert_eq!(history.next, history.jacobians[newest]);
    }
}
