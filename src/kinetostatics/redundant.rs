//! Redundancy resolution of the 9-DoF design (paper Sec. III, Table I: its IK has 39
//! unknowns for 36 equations): the IK as a [`LineSearchSystem`] in the unknowns
//! \[q (n_q), y_u (3 (6 + n_t))\] and its step rules, all run by the one Gauss–Newton
//! driver [`newton::solve_with_line_search`].
//!
//! [`Redundancy::LeastNorm`] (the default) takes the least change of q and ignores the
//! limits: each step is min ½‖δq‖² + ½ε‖D δy‖² subject to B_q δq + B_u δy = −b, a KKT
//! system solved through its Schur complement (`least_change.rs`; [`LEAST_NORM_Y_WEIGHT`]
//! = ε on the column-scaled leg unknowns keeps the step bounded in the null space). By
//! default every step is taken with the Jacobian at the start (chord steps,
//! [`StepRule::chord_from_start`]): the solution is then the one point of the solution
//! set in the start's least-change directions (x − x₀ in the range of the start's
//! least-norm step), whatever the iterates, at one Jacobian a run. Where a chord step
//! contracts the residual less than tenfold (far starts) the run goes on with
//! Gauss–Newton steps, each with the Jacobian at its iterate, as every step did before
//! 2026-11-28 ([`super::Solver::least_norm_gauss_newton`]; those runs reuse the
//! factorization for chord steps only near the solution, [`newton::CHORD_TAIL`]). Steps
//! across tendon kinks are one-sided ([`across_kinks`], [`super::Solver::across_kinks`];
//! MODEL.md "Least-norm steps across tendon kinks"): the default least-norm steps from
//! the start, and any run whose line search fails on a step across a kink once more so
//! ([`solve_across_kinks`]).
//! On circles of 10–50 mm radius in 1 mm steps, 2–24 steps a circle failed before and
//! none after; the least-norm steps there take 5–9× fewer evaluations.
//! [`Redundancy::WithinLimits`] solves every Newton step as a quadratic program that
//! keeps q within its limits (cargo feature `qp`, on by default; the QP step rule and its
//! mathematics are in `within_limits.rs`).
//!
//! The secondary objective of the QP steps ([`Objective`]): the least change of q from
//! the guess, or a reference q: the steps then start at the reference (clamped to the
//! limits) and pull towards it; a solution at (or near) the reference is reached in a
//! few Newton steps. Steps towards a reference far from every solution converge only
//! linearly (they ignore the curvature of b = 0; on the reference design, moving along
//! the solution set moves the leg unknowns 10²–10⁴ times more than q as tendons switch
//! between taut and slack), so after half the iteration budget the pull stops and
//! least-change steps finish; if that fails too, least-change steps start again from the
//! guess.

use nalgebra::{DMatrix, DVector};

use super::SOLVER_TENDON_UNKNOWN;
use super::least_change::{LeastChange, scaled_step_matrix};
use super::shooting::{
    STEP_LIMIT_MIN_FRACTION, crosses_a_kink, crosses_kink, restated_residual, row_scales,
    row_weights,
};
use super::state::RobotState;
use crate::boundary::{
    BoundaryJacobians, BoundaryPoint, BoundaryScratch, boundary_derivatives, boundary_residual,
    convert_tendon_unknowns, slack_side_column, taut_tension_column,
};
use crate::error::{SolveError, StopReason};
use crate::model::{Model, Pose};
use crate::newton::{self, LineSearchSystem, NewtonReport, NewtonSettings, StepRule};
use crate::rod::Wrench;
use crate::rod::tendon::TendonUnknown;

/// Weight ε of the scaled leg unknowns in the least-norm IK step (q in metres). Without
/// it the step can move far along null-space directions that change q little (measured:
/// the line search then stalls; 1e-6 to 1e-4 converge in 3–5 steps).
pub(crate) const LEAST_NORM_Y_WEIGHT: f64 = 1e-6;

/// The factor of the last-residual prediction ([`newton::ends_the_run`]) for a path
/// step's runs, whose last residual is prepared for the next step's start (the default
/// 0.1 was chosen for the sweep's analyses, where a mispredicted trial costs its
/// sensitivities for nothing). The least-norm steps' chord contraction grows from step
/// to step (0.004, 0.016, 0.023 on a 1 mm step), so the last one repeated
/// underestimates, and on a 1 mm back-and-forth path the last trial's prediction lands
/// at 0.09–0.11 × the tolerance: 37 of 100 steps were prepared, each of the other 63
/// integrated its start's Jacobian afresh. Chord trials of warm 1 mm least-norm steps
/// around circles of 5–50 mm radius (flat and tilted 10°, 7 690 trials, 2 848 of them
/// converged; a prepared trial costs 4.6 residuals): 0.1 prepared 1 905 converged
/// trials and no other; 0.25 prepares 2 527 and mispredicts 73, a net 286 residuals
/// fewer (0.2–0.35 alike, 0.5 worse); within-limits steps 865 → 870 of 872, no
/// misprediction (2026-11-28, twenty-fourth session).
pub(super) const PATH_STEP_FINAL_PREDICTION: f64 = 0.25;

/// How the IK of the redundant (9-DoF) design chooses among its solutions.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Redundancy {
    /// Least change of q, every step with the start's Jacobian (or Gauss–Newton steps:
    /// [`Solver::least_norm_gauss_newton`](super::Solver::least_norm_gauss_newton));
    /// limits not enforced (the default).
    #[default]
    LeastNorm,
    /// Every q within its limits: each step a QP with the limits as bounds (cargo
    /// feature `qp`; without it every solve that asks for it is an
    /// [`Error::Input`](crate::error::Error::Input) naming the feature).
    WithinLimits(Objective),
}

/// The secondary objective of [`Redundancy::WithinLimits`].
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Objective {
    /// The least change of q from the guess (the warm start, or the straight-leg guess
    /// of a cold solve), in units of each actuator's limit.
    #[default]
    LeastChange,
    /// Close to a reference actuation \[m\] (n_q values), distances in units of each
    /// actuator's limit: the steps start at the reference (clamped to the limits) and
    /// pull towards it (see the module documentation for how far).
    ClosestTo(Vec<f64>),
}

/// The IK of one pose in the unknowns x = \[q (n_q), y_u (solver tendon unknowns)\]:
/// the boundary residual b (MODEL.md §3) and its blocks, kept for the step rules.
pub(super) struct IkSystem<'a> {
    pub(super) model: &'a Model,
    pub(super) boundary: &'a mut BoundaryScratch,
    /// The blocks of the last Jacobian evaluation (B_q and B_u are the step rules' input).
    pub(super) blocks: &'a mut BoundaryJacobians,
    pub(super) pose: &'a Pose,
    pub(super) wrench: &'a Wrench,
    /// The evaluations asked of this system so far (residual and Jacobian counts).
    pub(super) evaluated: NewtonReport,
    /// Whether the driver may evaluate a full step's trial point with its Jacobian and
    /// end a run at a chord trial within the tolerance
    /// ([`LineSearchSystem::speculate_jacobians`]): not on the workspace sweep's path
    /// steps ([`super::Solver::solve_ik_newton`]).
    pub(super) speculate: bool,
    /// Whether a run's expected last residual is prepared for the Jacobian at its
    /// solution ([`LineSearchSystem::final_residual`]): `Some(true)` for its analysis
    /// (with the legs' knots, where q is within the actuation limits), `Some(false)`
    /// for the next run's start.
    pub(super) prepare: Option<bool>,
    /// Whether the Jacobian integrates the tension directions of slack tendons too (the
    /// taut side's columns of the one-sided steps, [`across_kinks`]; a retry's).
    pub(super) one_sided_kinks: bool,
    /// Whether runs take one-sided steps across tendon kinks
    /// ([`super::Solver::across_kinks`], [`solve_across_kinks`]).
    pub(super) across_kinks: bool,
}

impl<'a> IkSystem<'a> {
    /// The evaluation point of x = \[q, y_u\].
    fn point<'p>(&self, x: &'p [f64]) -> BoundaryPoint<'p>
    where
        'a: 'p,
    {
        let nq = self.model.n_actuators();
        BoundaryPoint {
            pose: self.pose,
            q: &x[..nq],
            wrench: self.wrench,
            y_u: &x[nq..],
            tendon_unknown: SOLVER_TENDON_UNKNOWN,
        }
    }

    /// Newton by `rule` from q and y_u (γ leg unknowns): the IK state and the work done.
    pub(super) fn solve<R: for<'s> StepRule<IkSystem<'s>>>(
        &mut self,
        rule: &mut R,
        settings: &NewtonSettings,
        q: &[f64],
        y_u: &[f64],
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let nq = q.len();
        let mut y = y_u.to_vec();
        convert_tendon_unknowns(
            self.model,
            &mut y,
            TendonUnknown::Gamma,
            SOLVER_TENDON_UNKNOWN,
        );
        let mut x: Vec<f64> = q.iter().chain(&y).copied().collect();
        let report = newton::solve_with_line_search(self, rule, &mut x, settings)?;
        let y = x.split_off(nq);
        Ok((RobotState::at_pose(self.model, self.pose, x, y), report))
    }
}

impl LineSearchSystem for IkSystem<'_> {
    fn dim(&self) -> usize {
        self.model.n_residuals()
    }

    fn residual_and_jacobian(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
        self.evaluated.count_evaluation(true);
        self.boundary
            .keep_slack_tension_directions(self.one_sided_kinks);
        let p = self.point(x);
        boundary_derivatives(self.model, self.boundary, &p, r, self.blocks)
    }

    fn residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
        self.evaluated.count_evaluation(false);
        let p = self.point(x);
        boundary_residual(self.model, self.boundary, &p, r)
    }

    fn row_weights(&self, w: &mut DVector<f64>) {
        row_weights(self.model, w);
    }

    fn row_scales(&self, c: &mut DVector<f64>) {
        row_scales(self.model, c);
    }

    fn speculate_jacobians(&self) -> bool {
        self.speculate
    }

    fn prepares_final_residual(&self) -> bool {
        self.prepare.is_some()
    }

    fn final_prediction(&self) -> f64 {
        match self.prepare {
            Some(false) => PATH_STEP_FINAL_PREDICTION,
            _ => newton::FINAL_PREDICTION,
        }
    }

    /// The residual at x with the tendon unknowns as the solution's state restates them
    /// ([`restated_residual`]): the legs' integration with sensitivities is then the one
    /// the Jacobian at that state (its analysis, or the next solve's start) asks for.
    fn final_residual(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<(), SolveError> {
        let nq = self.model.n_actuators();
        // An analysis sees only solutions within the actuation limits.
        let Some(knots) = self
            .prepare
            .filter(|&analysis| !analysis || self.model.within_limits(&x[..nq]))
        else {
            return self.residual(x, r);
        };
        self.evaluated.count_evaluation(false);
        let at = (self.pose, &x[..nq], self.wrench);
        restated_residual(self.model, self.boundary, at, &x[nq..], knots, r)
    }

    fn jacobian_row_sums(&self, x: &[f64], sums: &mut DVector<f64>) {
        let nq = self.model.n_actuators();
        let (b_q, b_u) = (&self.blocks.b_q, &self.blocks.b_u);
        for i in 0..sums.len() {
            let q: f64 = (0..nq).map(|j| b_q[(i, j)].abs() * x[j].abs()).sum();
            let y: f64 = (0..b_u.ncols())
                .map(|j| b_u[(i, j)].abs() * x[nq + j].abs())
                .sum();
            sums[i] = q + y;
        }
    }
}

/// The least-norm Gauss–Newton step: min ½‖δq‖² + ½ε‖δỹ‖² subject to
/// W (B_q δq + B_u δy) = −W b with δy = S δỹ ([`scaled_step_matrix`]: rows weighted, leg
/// unknowns scaled to unit columns; ε = [`LEAST_NORM_Y_WEIGHT`] keeps the step out of the
/// null-space directions that move y much and q little), by [`LeastChange`]; the
/// factorization of the last Jacobian serves the chord steps (from the start, unless
/// `gauss_newton`), and with `warm` set, the first steps of the next run (a path step
/// from this run's solution).
#[derive(Debug, Clone)]
pub(super) struct LeastNormStep {
    /// The diagonal of the objective: 1 for q, ε for ỹ.
    p: Vec<f64>,
    /// The scaled constraint matrix, its column scales S and its factorization, of the
    /// last Jacobian.
    factored: Option<(DMatrix<f64>, Vec<f64>, LeastChange)>,
    /// Whether the next run starts with chord steps on `factored`.
    pub(super) warm: bool,
    /// Whether chord steps are taken only near the solution
    /// ([`super::Solver::least_norm_gauss_newton`]).
    gauss_newton: bool,
    /// Whether steps across tendon kinks are one-sided and stop at the first crossing
    /// ([`across_kinks`]).
    one_sided: bool,
    /// Whether the last two-sided step took a tendon across its kink
    /// ([`KinkSteps::last_step_crossed_a_kink`]).
    crossed: bool,
    /// Buffers of [`LeastNormStep::solve`]: λ (m) and Aᵀ λ (n).
    lambda: DVector<f64>,
    at: DVector<f64>,
}

impl LeastNormStep {
    /// The step rule for the IK of `model` (Gauss–Newton steps if `gauss_newton`).
    pub(super) fn new(model: &Model, gauss_newton: bool) -> Self {
        let (nq, nu) = (model.n_actuators(), 3 * model.n_leg_unknowns());
        let mut p = vec![LEAST_NORM_Y_WEIGHT; nq + nu];
        p[..nq].fill(1.0);
        Self {
            p,
            factored: None,
            warm: false,
            gauss_newton,
            one_sided: false,
            crossed: false,
            lambda: DVector::zeros(model.n_residuals()),
            at: DVector::zeros(nq + nu),
        }
    }

    /// The step \[δq, δy\] for residual `r` from the factorized system.
    fn solve(&mut self, r: &DVector<f64>, weights: &DVector<f64>) -> Option<Vec<f64>> {
        let (a, y_scale, factor) = self.factored.as_ref()?;
        self.lambda.copy_from(r);
        self.lambda.component_mul_assign(weights);
        let mut z = vec![0.0; self.p.len()];
        if !factor.least_norm_step(a, &self.p, &mut self.lambda, &mut self.at, &mut z) {
            return None;
        }
        let nq = self.p.len() - y_scale.len();
        for (z, s) in z[nq..].iter_mut().zip(y_scale) {
            *z *= s;
        }
        Some(z)
    }

    /// Factors the least-norm step of the Jacobian `blocks` (rows weighted by `weights`).
    fn factor(&mut self, blocks: &BoundaryJacobians, weights: &DVector<f64>) {
        let nq = self.p.len() - blocks.b_u.ncols();
        let (a, y_scale) = scaled_step_matrix(blocks, weights, &vec![1.0; nq]);
        self.factored = LeastChange::factor(&a, &self.p, &vec![false; self.p.len()])
            .map(|factor| (a, y_scale, factor));
    }
}

/// A step rule that can take one-sided steps across tendon kinks ([`across_kinks`],
/// [`solve_across_kinks`]).
pub(super) trait KinkSteps {
    /// Whether the rule's first run takes one-sided steps too (not only the retry of a
    /// failed run). Only where that keeps the results a run would have: a rule whose
    /// solutions are pinned to earlier ones (the within-limits IK's, to 1e-9 m,
    /// `tests/redundant_path.rs`) moves them by the one-sided steps (8.4e-7 m there).
    fn one_sided_first(&self) -> bool;
    /// Whether the rule's steps are one-sided across kinks.
    fn set_one_sided(&mut self, on: bool);
    /// Sets the rule up for another run from actuation `q` \[m\] (the retry of a failed
    /// run: as a fresh rule would start it).
    fn restart(&mut self, q: &[f64]);
    /// Whether the last step, as the two-sided model gave it, takes some tendon across
    /// its kink ([`crosses_a_kink`]): a run whose line search failed on a step that
    /// does not is not retried with one-sided steps ([`solve_across_kinks`]).
    fn last_step_crossed_a_kink(&self) -> bool;
}

impl KinkSteps for LeastNormStep {
    /// The default steps (from the start's Jacobian): their solutions were never pinned,
    /// and on circles of 10–50 mm radius one-sided steps take 5–9× fewer evaluations;
    /// Gauss–Newton steps keep their earlier results.
    fn one_sided_first(&self) -> bool {
        !self.gauss_newton
    }

    fn set_one_sided(&mut self, on: bool) {
        self.one_sided = on;
    }

    /// The run starts with a Jacobian (not on an earlier run's factorization).
    fn restart(&mut self, _q: &[f64]) {
        self.warm = false;
    }

    fn last_step_crossed_a_kink(&self) -> bool {
        self.crossed
    }
}

/// Whether `step` from `x` takes tendon unknown `j` across its kink within its first
/// [`STEP_LIMIT_MIN_FRACTION`] (the tendon is at the kink) to a side whose column
/// [`across_kinks`] can give it: a slack tendon's taut column needs its tension
/// direction, integrated only where the system keeps the slack tendons' directions.
fn turns_at_kink(system: &IkSystem<'_>, x: &[f64], step: &[f64], j: usize) -> bool {
    crosses_kink(x[j], step[j])
        && -x[j] / step[j] < STEP_LIMIT_MIN_FRACTION
        && (x[j] >= 0.0 || system.boundary.keeps_slack_tension_directions())
}

/// Whether [`across_kinks`] would solve a one-sided model for `step` from `x` (some
/// tendon [turns at its kink](turns_at_kink)): a step rule keeps its two-sided
/// factorization for the case that the model has no step only then.
pub(super) fn crosses_at_a_kink(system: &IkSystem<'_>, x: &[f64], step: &[f64]) -> bool {
    let model = system.model;
    let (nq, nu, nt) = (
        model.n_actuators(),
        model.n_leg_unknowns(),
        model.n_tendons(),
    );
    (0..3).any(|leg| (0..nt).any(|k| turns_at_kink(system, x, step, nq + leg * nu + k)))
}

/// Makes `step` (from `x`, residual `r`, the Jacobian the system holds) one that crosses
/// tendon kinks (MODEL.md "Least-norm steps across tendon kinks", after the square
/// solves' "One-sided columns at the kink"): where it takes tendons at their kinks
/// (crossing ζ = 0 within the first [`STEP_LIMIT_MIN_FRACTION`] of it) to the other side,
/// the step of the linear model with those tendons' columns of that side, anchored at
/// the kink (b + (c_new − c_old) ζ); a tendon that the new side's column keeps on the
/// old side has a step on neither side's model and is held at the kink (δζ = −ζ: no
/// tension, no slack; its column zero and b − c_old ζ); the model's step is checked
/// again, until no further tendon at its kink crosses. `solve` computes a step of the
/// rule from modified blocks and residual (and keeps what the chord steps reuse). Then
/// the step, either one, ends at its first crossing beyond that fraction. Returns whether
/// the step is a one-sided model's: not without a crossing at a kink, nor where `solve`
/// finds no step (`step` is then the two-sided step, shortened as above, and the caller
/// restores what `solve` changed). A slack tendon whose tension direction was not
/// integrated ([`IkSystem::one_sided_kinks`]) keeps its two-sided column.
pub(super) fn across_kinks(
    system: &IkSystem<'_>,
    x: &[f64],
    r: &DVector<f64>,
    step: &mut Vec<f64>,
    mut solve: impl FnMut(&BoundaryJacobians, &DVector<f64>) -> Option<Vec<f64>>,
) -> bool {
    let model = system.model;
    let (nq, nu, nt) = (
        model.n_actuators(),
        model.n_leg_unknowns(),
        model.n_tendons(),
    );
    let tendons = (0..3).flat_map(|leg| (0..nt).map(move |k| (leg, k, nq + leg * nu + k)));
    let at_kink = |j: usize, d: &[f64]| turns_at_kink(system, x, d, j);
    // The tendons with the other side's column, and of those the ones held at the kink.
    let mut turned: Vec<(usize, usize, usize)> = Vec::new();
    let mut held: Vec<usize> = Vec::new();
    let two_sided = crosses_at_a_kink(system, x, step).then(|| step.clone());
    let point = system.point(x);
    let mut one_sided = false;
    // At most one round per tendon (each turns or is held once), none without a crossing.
    let rounds = if two_sided.is_some() { 3 * nt + 1 } else { 0 };
    for _ in 0..rounds {
        let turning: Vec<_> = tendons
            .clone()
            .filter(|&(_, _, j)| at_kink(j, step) && !turned.iter().any(|t| t.2 == j))
            .collect();
        let holding: Vec<_> = turned
            .iter()
            .map(|t| t.2)
            .filter(|&j| !crosses_kink(x[j], step[j]) && !held.contains(&j))
            .collect();
        if turning.is_empty() && holding.is_empty() {
            break;
        }
        turned.extend(turning);
        held.extend(holding);
        let mut blocks = system.blocks.clone();
        let mut anchored = r.clone();
        let mut column = DVector::zeros(r.len());
        for &(leg, k, j) in &turned {
            let mut old = blocks.b_u.column_mut(j - nq);
            if held.contains(&j) {
                // The old side's slope up to the kink, and nothing beyond.
                anchored.axpy(-x[j], &old, 1.0);
                old.fill(0.0);
                continue;
            }
            if x[j] >= 0.0 {
                slack_side_column(model, leg, k, &mut column);
            } else {
                taut_tension_column(model, system.boundary, &point, leg, k, column.column_mut(0));
            }
            // The kink is at ζ = 0: the old side's slope up to it, the new side's beyond.
            anchored.axpy(x[j], &column, 1.0);
            anchored.axpy(-x[j], &old, 1.0);
            old.copy_from(&column);
        }
        match solve(&blocks, &anchored) {
            Some(mut d) => {
                held.iter().for_each(|&j| d[j] = -x[j]);
                *step = d;
                one_sided = true;
            }
            None => {
                step.clone_from(two_sided.as_ref().expect("a crossing at a kink"));
                one_sided = false;
                break;
            }
        }
    }
    let limit = tendons
        .filter_map(|(_, _, j)| {
            let (z, dz) = (x[j], step[j]);
            ((z + dz) * z < 0.0).then_some(-z / dz)
        })
        .filter(|&at| at >= STEP_LIMIT_MIN_FRACTION)
        .fold(1.0, f64::min);
    if limit < 1.0 {
        step.iter_mut().for_each(|d| *d *= limit);
    }
    one_sided
}

impl StepRule<IkSystem<'_>> for LeastNormStep {
    fn step(
        &mut self,
        system: &IkSystem<'_>,
        x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        _iteration: usize,
    ) -> Result<Vec<f64>, StopReason> {
        self.factor(system.blocks, weights);
        let step = self
            .solve(r, weights)
            .ok_or(StopReason::SingularLeastNormStep)?;
        self.crossed = crosses_a_kink(system.model, system.model.n_actuators(), x, &step);
        if !self.one_sided {
            return Ok(step);
        }
        let mut step = step;
        let two_sided = crosses_at_a_kink(system, x, &step).then(|| self.factored.clone());
        let one_sided = across_kinks(system, x, r, &mut step, |blocks, r| {
            self.factor(blocks, weights);
            self.solve(r, weights)
        });
        if let (false, Some(two_sided)) = (one_sided, two_sided) {
            self.factored = two_sided;
        }
        Ok(step)
    }

    /// The last Jacobian's factorized system for the new residual.
    fn chord_step(
        &mut self,
        _system: &IkSystem<'_>,
        _x: &[f64],
        r: &DVector<f64>,
        weights: &DVector<f64>,
        _iteration: usize,
    ) -> Option<Vec<f64>> {
        self.solve(r, weights)
    }

    fn starts_with_chord(&self) -> bool {
        self.warm && self.factored.is_some()
    }

    fn chord_from_start(&self) -> bool {
        !self.gauss_newton
    }
}

/// The last converged least-norm IK and its step rule (holding the factorization of the
/// run's last Jacobian): the next IK from this solution starts with chord steps on it
/// ([`super::Solver::reuse_least_norm_factorization`]).
#[derive(Debug, Clone)]
pub(super) struct LastLeastNorm {
    rule: LeastNormStep,
    q: Vec<f64>,
    y_u: Vec<f64>,
    wrench: Wrench,
}

/// IK of the redundant design by least-norm steps from `guess` (q and γ leg unknowns),
/// chord steps from the start unless `gauss_newton`. With `last` given and `guess` its
/// solution under the same wrench, the run starts with chord steps on `last`'s
/// factorization (taken while each contracts the residual
/// [`NewtonSettings::chord_contraction`]-fold; otherwise the run goes on with a fresh
/// Jacobian). A converged run is left in `last` for the next.
///
/// # Errors
/// [`SolveError::NotConverged`] when the KKT system is singular, the line search fails
/// or the settings stop the run; [`SolveError::NonFinite`] if a leg integration blows up.
pub(super) fn least_norm_ik(
    system: &mut IkSystem<'_>,
    settings: &NewtonSettings,
    guess: RobotState,
    last: Option<&mut Option<LastLeastNorm>>,
    gauss_newton: bool,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let Some(last) = last else {
        let mut rule = LeastNormStep::new(system.model, gauss_newton);
        return solve_across_kinks(system, &mut rule, settings, &guess.q, &guess.y_u);
    };
    let from_last = last
        .as_ref()
        .is_some_and(|l| l.wrench == *system.wrench && l.q == guess.q && l.y_u == guess.y_u);
    let mut rule = match last.take() {
        Some(l) if from_last => l.rule,
        _ => LeastNormStep::new(system.model, gauss_newton),
    };
    rule.warm = from_last;
    rule.gauss_newton = gauss_newton;
    let result = solve_across_kinks(system, &mut rule, settings, &guess.q, &guess.y_u);
    if let Ok((state, _)) = &result {
        *last = Some(LastLeastNorm {
            rule,
            q: state.q.clone(),
            y_u: state.y_u.clone(),
            wrench: *system.wrench,
        });
    }
    result
}

/// Newton by `rule` from q and y_u (γ leg unknowns), with one-sided steps across tendon
/// kinks ([`across_kinks`]) if the system asks for them
/// ([`super::Solver::across_kinks`]): the first run where the rule takes them from the
/// start ([`KinkSteps::one_sided_first`]), without the slack tendons' tension directions
/// (a slack tendon that a step makes taut then keeps its two-sided column); where that
/// run's line search fails on a step that takes a tendon across its kink
/// ([`KinkSteps::last_step_crossed_a_kink`]), once more with one-sided steps and those
/// directions (every crossing one-sided), the report counting the work of both runs (if
/// the retry fails too, the first run's error). A run that fails on a step without a
/// crossing (at the actuation limits, past a fold) is not retried: in the 9-DoF
/// design's within-limits sweep such retries took about 5 % of its time and changed no
/// cell (the map the same, byte for byte). Two-sided steps crawl at a kink: the step
/// with the slope of the side a tendon leaves overshoots beyond it, and the line search
/// shortens it until the tendon just reaches the kink, by ever smaller steps.
pub(super) fn solve_across_kinks<R>(
    system: &mut IkSystem<'_>,
    rule: &mut R,
    settings: &NewtonSettings,
    q: &[f64],
    y_u: &[f64],
) -> Result<(RobotState, NewtonReport), SolveError>
where
    R: for<'s> StepRule<IkSystem<'s>> + KinkSteps,
{
    if !system.across_kinks {
        return system.solve(rule, settings, q, y_u);
    }
    // The system's tally before this run (a within-limits run may follow another).
    let before = system.evaluated;
    rule.set_one_sided(rule.one_sided_first());
    let first = system.solve(rule, settings, q, y_u);
    let retry = match &first {
        Err(
            e @ SolveError::NotConverged {
                reason: StopReason::LineSearchFailed,
                ..
            },
        ) if rule.last_step_crossed_a_kink() => {
            let mut failed = NewtonReport::of_failed_run(e, &system.evaluated);
            failed.residual_evaluations -= before.residual_evaluations;
            failed.jacobian_evaluations -= before.jacobian_evaluations;
            rule.restart(q);
            rule.set_one_sided(true);
            system.one_sided_kinks = true;
            let retry = system.solve(rule, settings, q, y_u);
            system.one_sided_kinks = false;
            // As every other redundant Jacobian leaves it (an analysis that follows
            // reads it).
            system.boundary.keep_slack_tension_directions(false);
            Some(retry.map(|(state, mut report)| {
                report.add_work(&failed);
                (state, report)
            }))
        }
        _ => None,
    };
    rule.set_one_sided(false);
    match retry {
        Some(Ok(done)) => Ok(done),
        _ => first,
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DVector, Vector3};

    use super::*;
    use crate::Tdpcr;
    use crate::boundary::{BoundaryJacobians, BoundaryScratch};
    use crate::kinetostatics::Solver;

    /// x = \[q, y_u\] of `state` in the solver's tendon unknowns.
    fn unknowns(model: &Model, state: &RobotState) -> Vec<f64> {
        let mut y = state.y_u.clone();
        convert_tendon_unknowns(model, &mut y, TendonUnknown::Gamma, SOLVER_TENDON_UNKNOWN);
        state.q.iter().chain(&y).copied().collect()
    }

    /// How far the step from `start` to `end` (IK at `pose`) is from the range of the
    /// start's least-norm step: with A the scaled constraint matrix of the Jacobian at
    /// the start and z the step in scaled unknowns, ‖P z − Π P z‖ / ‖P z‖ for Π the
    /// orthogonal projector onto range(Aᵀ) (by a QR of Aᵀ, not the step rule's algebra).
    fn off_start_directions(
        model: &Model,
        pose: &Pose,
        start: &RobotState,
        end: &RobotState,
    ) -> f64 {
        let nq = model.n_actuators();
        let (x0, x1) = (unknowns(model, start), unknowns(model, end));
        let mut scratch = BoundaryScratch::new(model);
        let mut blocks = BoundaryJacobians::new(model);
        let mut r = DVector::zeros(model.n_residuals());
        let wrench = Wrench {
            force: model.platform_weight,
            moment: Vector3::zeros(),
        };
        let point = BoundaryPoint {
            pose,
            q: &x0[..nq],
            wrench: &wrench,
            y_u: &x0[nq..],
            tendon_unknown: SOLVER_TENDON_UNKNOWN,
        };
        boundary_derivatives(model, &mut scratch, &point, &mut r, &mut blocks).unwrap();
        let mut weights = DVector::zeros(model.n_residuals());
        row_weights(model, &mut weights);
        let (a, y_scale) = scaled_step_matrix(&blocks, &weights, &vec![1.0; nq]);
        let pz = DVector::from_fn(x0.len(), |j, _| {
            let dx = x1[j] - x0[j];
            if j < nq {
                dx
            } else {
                LEAST_NORM_Y_WEIGHT * dx / y_scale[j - nq]
            }
        });
        let q = a.transpose().qr().q();
        let projected: DVector<f64> = &q * (q.transpose() * &pz);
        (&pz - projected).norm() / pz.norm()
    }

    /// The default least-norm IK lands in the start's least-change directions, to
    /// round-off, whatever its iterates; Gauss–Newton steps (each from the Jacobian at
    /// its iterate) land measurably elsewhere, so the check can tell them apart
    /// (measured on these four 1.1 mm steps: 8e-15 to 2e-14 against 8e-10 to 1.1e-9).
    #[test]
    fn least_norm_steps_keep_to_the_start_directions() {
        let file = format!(
            "{}/designs/lilge2022_redundant.ron",
            env!("CARGO_MANIFEST_DIR")
        );
        let design = Tdpcr::from_ron_file(&file).unwrap();
        for gauss_newton in [false, true] {
            let mut s = Solver::new(&design).unwrap();
            s.least_norm_gauss_newton = gauss_newton;
            let w = Wrench::default();
            let home = s.solve_ik(&Pose::identity(), &w, None).unwrap().state;
            let mut start = home.clone();
            let mut worst: f64 = 0.0;
            let mut least: f64 = f64::INFINITY;
            for k in 1..=4 {
                let pose = Pose {
                    position: Vector3::new(1e-3 * k as f64, -0.5e-3 * k as f64, 0.0),
                    rotation: home.pose().rotation,
                };
                let end = s.solve_ik(&pose, &w, Some(&start)).unwrap().state;
                let off = off_start_directions(s.model(), &pose, &start, &end);
                worst = worst.max(off);
                least = least.min(off);
                start = end;
            }
            eprintln!(
                "gauss_newton {gauss_newton}: off the start's directions {least:e} to {worst:e}"
            );
            if gauss_newton {
                assert!(
                    least > 1e-11,
                    "Gauss–Newton steps within {least:e} of the start's directions"
                );
            } else {
                assert!(worst < 1e-12, "steps {worst:e} off the start's directions");
            }
        }
    }

    /// `crosses_a_kink` (the retry's condition) looks at the tendon unknowns alone: a
    /// step that changes the sign of q or of a strain unknown crosses nothing, one that
    /// takes any tendon ζ through 0, either way and however far, does.
    #[test]
    fn a_kink_crossing_is_a_tendon_unknown_changing_sign() {
        let file = format!(
            "{}/designs/lilge2022_redundant.ron",
            env!("CARGO_MANIFEST_DIR")
        );
        let design = Tdpcr::from_ron_file(&file).unwrap();
        let model = Model::new(&design);
        let (nq, nu, nt) = (
            model.n_actuators(),
            model.n_leg_unknowns(),
            model.n_tendons(),
        );
        let n = nq + 3 * nu;
        let x: Vec<f64> = (0..n)
            .map(|j| if j % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let flip = |j: usize, by: f64| {
            let mut d = vec![0.0; n];
            d[j] = -x[j] * by;
            d
        };
        for j in 0..n {
            let tendon = j >= nq && (j - nq) % nu < nt;
            assert_eq!(
                crosses_a_kink(&model, nq, &x, &flip(j, 3.0)),
                tendon,
                "unknown {j}"
            );
            assert!(
                !crosses_a_kink(&model, nq, &x, &flip(j, 0.5)),
                "unknown {j}"
            );
        }
    }
}
