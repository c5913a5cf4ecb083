//! The shooting problem of FK and square IK (MODEL.md §3) as a [`NonlinearSystem`] for
//! the dogleg Newton of [`crate::newton::solve`]: unknowns, residual row weights, the
//! step limit at tendon kinks, the retraction of rotation unknowns, and the Newton run
//! from a guess (with the predictor of [`super::predictor`]).
//!
//! - FK: given q and the wrench, unknowns [p_ee (3), θ_ee (3), y_u (3 (6 + n_t))];
//!   Jacobian \[B_x B_u\]. Rotation steps compose: R ← exp(δθ^) R.
//! - IK (6-DoF design): given the pose and the wrench, unknowns \[q (6), y_u\];
//!   Jacobian \[B_q B_u\].

use std::cell::Cell;

use nalgebra::{DMatrix, DVector, Rotation3, Vector3};

use super::predictor::{
    LastSolve, PREDICTOR_POINTS, PathPoint, is_last_solution, predict, target_vector,
};
use super::state::{RobotState, as_reported, as_restated};
use super::{JacobianMethod, SOLVER_TENDON_UNKNOWN, Solver};
use crate::boundary::{
    BoundaryJacobians, BoundaryPoint, BoundaryScratch, boundary_derivatives,
    boundary_derivatives_fd, boundary_residual, boundary_residual_with_derivatives,
    convert_tendon_unknowns, slack_side_column, taut_tension_column,
};
use crate::design::MAX_TENDONS;
use crate::error::{SolveError, StopReason};
use crate::model::{Model, Pose};
use crate::newton::{self, NewtonReport, NewtonSettings, NonlinearSystem, RowScales};
use crate::rod::Wrench;
use crate::rod::tendon::TendonUnknown;

/// What is being solved for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Problem<'a> {
    Forward { q: &'a [f64] },
    Inverse { pose: &'a Pose },
}

/// Tendon crossings earlier than this fraction of a Newton step do not limit it.
pub(super) const STEP_LIMIT_MIN_FRACTION: f64 = 0.05;

/// How many times the largest |δq_j| of the Newton step an IK's q plus that step must lie
/// beyond an actuation limit for [`Solver::stop_beyond_limits`] to stop the run: after an
/// iteration that reduced ‖F‖ tenfold the rest of the way is about the step itself (the
/// steps after it shrink at least as fast), so the solution lies beyond the limit too.
pub const BEYOND_LIMITS_MARGIN: f64 = 10.0;

/// Newton from `guess` on `problem`, with `scaled` replacing the model if given.
pub(super) fn run_with(
    solver: &mut Solver,
    scaled: Option<&Model>,
    settings: &NewtonSettings,
    problem: Problem,
    wrench: &Wrench,
    guess: RobotState,
) -> Result<(RobotState, NewtonReport), SolveError> {
    let model = scaled.unwrap_or(&solver.model);
    let n_u = 3 * model.n_leg_unknowns();
    let from_last = scaled.is_none() && is_last_solution(solver, problem, wrench, &guess);
    let mut guess = guess;
    convert_tendon_unknowns(
        model,
        &mut guess.y_u,
        TendonUnknown::Gamma,
        SOLVER_TENDON_UNKNOWN,
    );
    let (mut x, n_head) = match problem {
        Problem::Forward { .. } => {
            let mut x = DVector::zeros(6 + n_u);
            x.rows_mut(0, 3).copy_from_slice(&guess.position);
            x.rows_mut(3, 3).copy_from_slice(&guess.rotvec);
            x.rows_mut(6, n_u).copy_from_slice(&guess.y_u);
            (x, 6)
        }
        Problem::Inverse { .. } => {
            let nq = model.n_actuators();
            let mut x = DVector::zeros(nq + n_u);
            x.rows_mut(0, nq).copy_from_slice(&guess.q);
            x.rows_mut(nq, n_u).copy_from_slice(&guess.y_u);
            (x, nq)
        }
    };
    let predicted = if from_last {
        predict(solver, problem, &x)
    } else {
        None
    };
    // The path of warm solves this one continues (the predictor's points).
    let mut path = match solver.last.take() {
        Some(last) if from_last => last.path,
        _ => Vec::new(),
    };
    let forward = matches!(problem, Problem::Forward { .. });
    if scaled.is_none()
        && solver.reuse_jacobian
        && solver.jacobian == JacobianMethod::Exact
        && solver.newton_system == Some(forward)
        && (from_last || solver.seeded)
    {
        solver.newton.reuse_jacobian_once();
    }
    solver.newton_system = None;
    solver.seeded = false;
    let mut system = ShootingSystem {
        model,
        boundary: &mut solver.boundary,
        blocks: &mut solver.blocks,
        method: solver.jacobian,
        problem,
        wrench,
        one_sided_kinks: solver.one_sided_kinks,
        one_sided_columns_used: Cell::new(0),
        taut: &mut solver.taut_columns,
        evaluated: NewtonReport::none(),
        prepare: solver.prepare_for_analysis && scaled.is_none(),
        stop_beyond_limits: solver.stop_beyond_limits,
    };
    // From the prediction if there is one; from the guess itself if that fails. Every
    // run's work, converged or not, goes to the solver's tally of the call.
    let mut work = NewtonReport::none();
    let report = match predicted {
        Some(mut xp) => match newton::solve(&mut system, &mut xp, settings, &mut solver.newton) {
            Ok(r) => {
                x = xp;
                Ok(r)
            }
            // Stopped on its way to a solution beyond the limits: the run from the guess
            // would not have been tried after that solution either.
            Err(
                e @ SolveError::NotConverged {
                    reason: StopReason::BeyondActuationLimits,
                    ..
                },
            ) => Err(e),
            Err(e) => {
                work = NewtonReport::of_failed_run(&e, &system.evaluated);
                system.evaluated = NewtonReport::none();
                newton::solve(&mut system, &mut x, settings, &mut solver.newton)
            }
        },
        None => newton::solve(&mut system, &mut x, settings, &mut solver.newton),
    };
    match &report {
        Ok(r) => work.add_work(r),
        Err(e) => work.add_work(&NewtonReport::of_failed_run(e, &system.evaluated)),
    }
    solver.one_sided_columns_used = system.one_sided_columns_used.get();
    solver.work.add_work(&work);
    let report = report?;
    if scaled.is_none() {
        solver.newton_system = Some(forward);
    }
    let mut y_u: Vec<f64> = x.rows(n_head, n_u).iter().copied().collect();
    as_reported(model, &mut y_u);
    let state = match problem {
        Problem::Forward { q } => RobotState {
            position: [x[0], x[1], x[2]],
            rotvec: [x[3], x[4], x[5]],
            q: q.to_vec(),
            y_u,
        },
        Problem::Inverse { pose } => RobotState {
            position: pose.position.into(),
            rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
                .scaled_axis()
                .into(),
            q: x.rows(0, n_head).iter().copied().collect(),
            y_u,
        },
    };
    if scaled.is_none() && solver.jacobian == JacobianMethod::Exact {
        if path.len() == PREDICTOR_POINTS {
            path.remove(0);
        }
        path.push(PathPoint {
            target: target_vector(problem),
            x,
        });
        solver.last = Some(LastSolve {
            state: state.clone(),
            wrench: *wrench,
            forward,
            path,
        });
    }
    Ok((state, report))
}

/// Characteristic sizes of the residual rows for the convergence test
/// ([`NonlinearSystem::row_scales`]), from the leg's [`RowScales`]: force rows F*,
/// moment rows M*, coupling-position and tendon-length rows the leg length L.
pub(crate) fn row_scales(model: &Model, c: &mut DVector<f64>) {
    let leg = &model.leg;
    let s = RowScales::of_rod(leg.length, leg.bending_stiffness(), leg.axial_stiffness())
        .relative_to_si_test();
    let nu = model.n_leg_unknowns();
    for i in 0..c.len() {
        c[i] = if i < 3 {
            s.force
        } else if i < 6 {
            s.moment
        } else {
            match (i - 6) % nu {
                3..6 => s.moment,
                _ => s.length,
            }
        };
    }
}

/// Merit-function weights of the residual rows: force rows by L²/(EI), moment rows by
/// L/(EI), coupling rows by 1/L, tendon-length rows by 1/D (each row ~ an angle).
pub(crate) fn row_weights(model: &Model, w: &mut DVector<f64>) {
    let leg = &model.leg;
    let ei = leg.bending_stiffness();
    let len = leg.length;
    let force = len * len / ei;
    let moment = len / ei;
    let length = 1.0 / leg.max_offset().max(1e-6);
    let nu = model.n_leg_unknowns();
    for i in 0..w.len() {
        w[i] = if i < 3 {
            force
        } else if i < 6 {
            moment
        } else {
            match (i - 6) % nu {
                0..3 => 1.0 / len,
                3..6 => moment,
                _ => length,
            }
        };
    }
}

/// The shooting problem as a [`NonlinearSystem`].
struct ShootingSystem<'a> {
    model: &'a Model,
    boundary: &'a mut BoundaryScratch,
    blocks: &'a mut BoundaryJacobians,
    method: JacobianMethod,
    problem: Problem<'a>,
    wrench: &'a Wrench,
    /// [`Solver::one_sided_kinks`].
    one_sided_kinks: bool,
    /// The one-sided columns handed to Newton so far.
    one_sided_columns_used: Cell<usize>,
    /// The slack tendons' taut-side columns at the last exact Jacobian.
    taut: &'a mut TautColumns,
    /// The evaluations asked of this system so far (residual and Jacobian counts).
    evaluated: NewtonReport,
    /// Whether a run's expected last residual is prepared for the analysis of its
    /// solution ([`Solver::prepare_for_analysis`]).
    prepare: bool,
    /// [`Solver::stop_beyond_limits`].
    stop_beyond_limits: bool,
}

/// The taut side's columns ∂b/∂τ_k of the tendons that were slack (ζ < 0) at the last
/// exact Jacobian evaluation, and where it was: the one-sided column of a slack tendon
/// that a Newton step makes taut ([`Solver::one_sided_kinks`]). The exact evaluation
/// integrates every tension direction, slack or not, so they cost no integration.
#[derive(Debug, Clone)]
pub(super) struct TautColumns {
    /// The unknowns of that evaluation (NaN when the last exact evaluation kept none):
    /// the columns of the tendons with ζ < 0 there are valid.
    at: DVector<f64>,
    /// Column leg · n_t + k: tendon k of that leg (n × 3 n_t).
    columns: DMatrix<f64>,
}

impl TautColumns {
    /// Buffers for `model`'s FK and square IK.
    pub(super) fn new(model: &Model) -> Self {
        let n = model.n_residuals();
        let nt = model.n_tendons();
        Self {
            at: DVector::from_element(n, f64::NAN),
            columns: DMatrix::zeros(n, 3 * nt),
        }
    }
}

impl<'a> ShootingSystem<'a> {
    fn head(&self) -> usize {
        match self.problem {
            Problem::Forward { .. } => 6,
            Problem::Inverse { .. } => self.model.n_actuators(),
        }
    }

    /// The pose and actuation of x.
    fn pose_and_actuation<'x>(&self, x: &'x DVector<f64>) -> (Pose, &'x [f64])
    where
        'a: 'x,
    {
        match self.problem {
            Problem::Forward { q } => (
                Pose {
                    position: Vector3::new(x[0], x[1], x[2]),
                    rotation: *Rotation3::new(Vector3::new(x[3], x[4], x[5])).matrix(),
                },
                q,
            ),
            Problem::Inverse { pose } => (*pose, &x.as_slice()[..self.head()]),
        }
    }

    /// Evaluates the residual (and blocks if `jac` is given) at x.
    fn evaluate(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        jac: Option<&mut DMatrix<f64>>,
    ) -> Result<(), SolveError> {
        self.evaluated.count_evaluation(jac.is_some());
        let head = self.head();
        let (pose, q) = self.pose_and_actuation(x);
        let p = BoundaryPoint {
            pose: &pose,
            q,
            wrench: self.wrench,
            y_u: &x.as_slice()[head..],
            tendon_unknown: SOLVER_TENDON_UNKNOWN,
        };
        let Some(jac) = jac else {
            return boundary_residual(self.model, self.boundary, &p, r);
        };
        self.taut.at.fill(f64::NAN);
        match self.method {
            JacobianMethod::Exact => {
                // The one-sided columns of slack tendons need their tension directions.
                self.boundary
                    .keep_slack_tension_directions(self.one_sided_kinks);
                boundary_derivatives(self.model, self.boundary, &p, r, self.blocks)?;
                // The taut column is ∂b/∂τ: the column of ζ only while dτ/dζ = 1.
                debug_assert_eq!(SOLVER_TENDON_UNKNOWN.tension_derivative(0.0), 1.0);
                if self.one_sided_kinks && self.taut.at.len() == x.len() {
                    let (nu, nt) = (self.model.n_leg_unknowns(), self.model.n_tendons());
                    self.taut.at.copy_from(x);
                    for leg in 0..3 {
                        for k in 0..nt {
                            if x[head + leg * nu + k] < 0.0 {
                                let column = self.taut.columns.column_mut(leg * nt + k);
                                taut_tension_column(self.model, self.boundary, &p, leg, k, column);
                            }
                        }
                    }
                }
            }
            JacobianMethod::FiniteDifference(m) => {
                boundary_derivatives_fd(self.model, self.boundary, &p, m, r, self.blocks)?
            }
        }
        let lead = match self.problem {
            Problem::Forward { .. } => &self.blocks.b_x,
            Problem::Inverse { .. } => &self.blocks.b_q,
        };
        jac.columns_mut(0, head).copy_from(lead);
        jac.columns_mut(head, self.blocks.b_u.ncols())
            .copy_from(&self.blocks.b_u);
        Ok(())
    }
}

impl NonlinearSystem for ShootingSystem<'_> {
    fn dim(&self) -> usize {
        self.model.n_residuals()
    }

    fn residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
        self.evaluate(x, r, None)
    }

    fn residual_and_jacobian(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        jac: &mut DMatrix<f64>,
    ) -> Result<(), SolveError> {
        self.evaluate(x, r, Some(jac))
    }

    fn row_weights(&self, w: &mut DVector<f64>) {
        row_weights(self.model, w);
    }

    fn row_scales(&self, c: &mut DVector<f64>) {
        row_scales(self.model, c);
    }

    fn prepares_final_residual(&self) -> bool {
        self.prepare && self.method == JacobianMethod::Exact
    }

    /// The residual at x with the tendon unknowns as the solution's state restates them
    /// ([`as_restated`]), integrated with the sensitivities (and knots) the analysis of
    /// that state asks for, where q is within the actuation limits (an analysis sees no
    /// other solution).
    fn final_residual(&mut self, x: &DVector<f64>, r: &mut DVector<f64>) -> Result<(), SolveError> {
        let head = self.head();
        let (pose, q) = self.pose_and_actuation(x);
        if !self.prepares_final_residual() || !self.model.within_limits(q) {
            return self.residual(x, r);
        }
        self.evaluated.count_evaluation(false);
        self.boundary
            .keep_slack_tension_directions(self.one_sided_kinks);
        let at = (&pose, q, self.wrench);
        restated_residual(
            self.model,
            self.boundary,
            at,
            &x.as_slice()[head..],
            true,
            r,
        )
    }

    fn beyond_reach(&self, x: &DVector<f64>, step: &DVector<f64>) -> bool {
        // A run that took one-sided columns, or whose step takes a tendon across its kink
        // (where it may take one), finishes: its caller may compare its solution with a
        // two-sided run's (the sweep's `solve_on_branch`).
        if !self.stop_beyond_limits
            || matches!(self.problem, Problem::Forward { .. })
            || self.one_sided_columns_used.get() > 0
        {
            return false;
        }
        let head = self.head();
        if crosses_a_kink(self.model, head, x.as_slice(), step.as_slice()) {
            return false;
        }
        beyond_limits(self.model, &x.as_slice()[..head], &step.as_slice()[..head])
    }

    fn step_limit(&self, x: &DVector<f64>, step: &DVector<f64>) -> f64 {
        // Stop at the first tendon that would cross between taut and slack (ζ = 0, the
        // kink of the piecewise-linear variable): semismooth Newton otherwise cycles there.
        // A crossing within the first 5 % of the step is let through (the tendon is at the
        // kink already; stopping would stall the trust region).
        let head = self.head();
        let (nu, nt) = (self.model.n_leg_unknowns(), self.model.n_tendons());
        let mut limit: f64 = 1.0;
        for leg in 0..3 {
            for k in 0..nt {
                let i = head + leg * nu + k;
                let (z, dz) = (x[i], step[i]);
                if (z + dz) * z < 0.0 {
                    let at = -z / dz;
                    if at >= STEP_LIMIT_MIN_FRACTION {
                        limit = limit.min(at);
                    }
                }
            }
        }
        limit
    }

    fn retract(&self, x: &DVector<f64>, step: &DVector<f64>, out: &mut DVector<f64>) {
        retract(self.problem, x, step, out);
    }

    fn one_sided_column(
        &self,
        x: &DVector<f64>,
        step: &DVector<f64>,
        j: usize,
        column: &mut DVector<f64>,
    ) -> Option<f64> {
        // A tendon at its kink (crossing within the first STEP_LIMIT_MIN_FRACTION of the
        // step, which `step_limit` lets through) that the step takes to the side whose
        // slope the Jacobian at x does not hold:
        // - taut (ζ ≥ 0) into slack: the slack side's column, dΘ/dζ = −1 in its length
        //   row (the tension, and with it every other row, no longer depends on ζ);
        // - slack (ζ < 0) into taut: the taut side's column ∂b/∂τ, kept from the exact
        //   Jacobian at x ([`TautColumns`]).
        let (head, nu, nt) = (
            self.head(),
            self.model.n_leg_unknowns(),
            self.model.n_tendons(),
        );
        if !self.one_sided_kinks || j < head || (j - head) % nu >= nt {
            return None;
        }
        let (z, dz) = (x[j], step[j]);
        if !crosses_kink(z, dz) || -z / dz >= STEP_LIMIT_MIN_FRACTION {
            return None;
        }
        let (leg, k) = ((j - head) / nu, (j - head) % nu);
        if z >= 0.0 {
            slack_side_column(self.model, leg, k, column);
        } else {
            // Kept at x (NaN never compares equal), where this tendon was slack.
            if self.taut.at != *x {
                return None;
            }
            column.copy_from(&self.taut.columns.column(leg * nt + k));
        }
        self.one_sided_columns_used
            .set(self.one_sided_columns_used.get() + 1);
        // The kink is at ζ = 0.
        Some(z)
    }
}

/// Whether a tendon unknown ζ = `z` moved by `dz` changes sides of its kink (ζ = 0:
/// taut at ζ ≥ 0, slack below).
pub(super) fn crosses_kink(z: f64, dz: f64) -> bool {
    if z >= 0.0 { z + dz < 0.0 } else { z + dz > 0.0 }
}

/// Whether `step` from `x` takes some tendon unknown across its kink ([`crosses_kink`]),
/// with the legs' unknowns (tendons in ζ) after the first `head` entries of both.
pub(super) fn crosses_a_kink(model: &Model, head: usize, x: &[f64], step: &[f64]) -> bool {
    model
        .tendon_unknown_indices()
        .any(|i| crosses_kink(x[head + i], step[head + i]))
}

/// Whether the actuation `q` \[m\] moved by its Newton step `dq` ends beyond an
/// actuation limit by more than [`BEYOND_LIMITS_MARGIN`] × max_j |dq_j|
/// ([`Solver::stop_beyond_limits`]).
fn beyond_limits(model: &Model, q: &[f64], dq: &[f64]) -> bool {
    let reach = BEYOND_LIMITS_MARGIN * dq.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
    q.iter()
        .zip(dq)
        .enumerate()
        .any(|(i, (q, d))| (q + d).abs() > model.actuation_limit(i) + reach)
}

/// [`boundary_residual_with_derivatives`] at the pose, actuation and wrench `at` and the
/// solver's leg unknowns `y_u` as the solution's state restates them ([`as_restated`]):
/// the legs' starts are then those of that state's Jacobian (its analysis, or the next
/// solve from it), bit for bit. The prepared last residual of both Newton systems.
pub(super) fn restated_residual(
    model: &Model,
    boundary: &mut BoundaryScratch,
    (pose, q, wrench): (&Pose, &[f64], &Wrench),
    y_u: &[f64],
    knots: bool,
    r: &mut DVector<f64>,
) -> Result<(), SolveError> {
    let mut restated = [0.0; 3 * (6 + MAX_TENDONS)];
    let restated = &mut restated[..y_u.len()];
    restated.copy_from_slice(y_u);
    as_restated(model, restated);
    let p = BoundaryPoint {
        pose,
        q,
        wrench,
        y_u: restated,
        tendon_unknown: SOLVER_TENDON_UNKNOWN,
    };
    boundary_residual_with_derivatives(model, boundary, &p, knots, r)
}

/// x ⊕ step in the unknowns of `problem`: FK rotations compose, R ← exp(δθ^) R.
pub(super) fn retract(
    problem: Problem,
    x: &DVector<f64>,
    step: &DVector<f64>,
    out: &mut DVector<f64>,
) {
    out.copy_from(x);
    *out += step;
    if let Problem::Forward { .. } = problem {
        let r = Rotation3::new(Vector3::new(step[3], step[4], step[5]))
            * Rotation3::new(Vector3::new(x[3], x[4], x[5]));
        let phi = r.scaled_axis();
        for c in 0..3 {
            out[3 + c] = phi[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::Tdpcr;

    /// The solved FK of the reference design at q = 0 in the solver's unknowns, with every
    /// leg's first tendon moved to its kink.
    fn system_at_kink() -> (Model, DVector<f64>) {
        let path = format!("{}/designs/lilge2022.ron", env!("CARGO_MANIFEST_DIR"));
        let design = Tdpcr::from_ron_file(path).unwrap();
        let model = Model::new(&design);
        let q = vec![0.0; model.n_actuators()];
        let mut solver = Solver::new(&design).unwrap();
        let s = solver.solve_fk(&q, &Wrench::default(), None).unwrap().state;
        let mut y = s.y_u.clone();
        convert_tendon_unknowns(&model, &mut y, TendonUnknown::Gamma, SOLVER_TENDON_UNKNOWN);
        let x: Vec<f64> = s
            .position
            .iter()
            .chain(&s.rotvec)
            .chain(&y)
            .copied()
            .collect();
        let mut x = DVector::from_vec(x);
        for leg in 0..3 {
            x[6 + leg * model.n_leg_unknowns()] = 0.0;
        }
        (model, x)
    }

    /// What a [`ShootingSystem`] borrows.
    struct Buffers {
        q: Vec<f64>,
        wrench: Wrench,
        boundary: BoundaryScratch,
        blocks: BoundaryJacobians,
        taut: TautColumns,
    }

    impl Buffers {
        fn new(model: &Model) -> Self {
            Self {
                q: vec![0.0; model.n_actuators()],
                wrench: Wrench::default(),
                boundary: BoundaryScratch::new(model),
                blocks: BoundaryJacobians::new(model),
                taut: TautColumns::new(model),
            }
        }

        /// The FK system at q = 0 with one-sided kink columns, exact Jacobians.
        fn fk_at_zero<'a>(&'a mut self, model: &'a Model) -> ShootingSystem<'a> {
            ShootingSystem {
                model,
                boundary: &mut self.boundary,
                blocks: &mut self.blocks,
                method: JacobianMethod::Exact,
                problem: Problem::Forward { q: &self.q },
                wrench: &self.wrench,
                one_sided_kinks: true,
                one_sided_columns_used: Cell::new(0),
                evaluated: NewtonReport::none(),
                taut: &mut self.taut,
                prepare: false,
                stop_beyond_limits: false,
            }
        }
    }

    #[test]
    fn the_one_sided_column_is_the_slack_sides_derivative() {
        let (model, x) = system_at_kink();
        let mut buffers = Buffers::new(&model);
        let mut system = buffers.fk_at_zero(&model);
        let n = x.len();
        let nu = model.n_leg_unknowns();
        let mut step = DVector::from_element(n, 1e-3);
        let (mut column, mut r0, mut r1) =
            (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
        system.residual(&x, &mut r0).unwrap();
        for leg in 0..3 {
            let j = 6 + leg * nu;
            // Into slack: the slack side's slope, checked by a one-sided difference.
            step[j] = -1e-3;
            // Anchored at the kink ζ = 0: the distance is ζ.
            assert_eq!(
                system.one_sided_column(&x, &step, j, &mut column),
                Some(x[j])
            );
            let h = 1e-6;
            let mut xh = x.clone();
            xh[j] = -h;
            system.residual(&xh, &mut r1).unwrap();
            let fd = (&r1 - &r0) / -h;
            assert!(
                (&fd - &column).amax() < 1e-8,
                "leg {leg}: {:e}",
                (&fd - &column).amax()
            );
            // Staying taut, or a taut tendon well before its kink: the Jacobian's own.
            step[j] = 1e-3;
            assert!(system.one_sided_column(&x, &step, j, &mut column).is_none());
            let mut far = x.clone();
            far[j] = 1e-3;
            step[j] = -2e-3;
            assert!(
                system
                    .one_sided_column(&far, &step, j, &mut column)
                    .is_none()
            );
            // Not a tendon unknown.
            assert!(
                system
                    .one_sided_column(&x, &step, j + model.n_tendons(), &mut column)
                    .is_none()
            );
        }
        system.one_sided_kinks = false;
        step[6] = -1e-3;
        assert!(system.one_sided_column(&x, &step, 6, &mut column).is_none());
        assert_eq!(system.one_sided_columns_used.get(), 3);
    }

    #[test]
    fn the_one_sided_column_of_a_slack_tendon_is_the_taut_sides_derivative() {
        let (model, mut x) = system_at_kink();
        let (nu, nt) = (model.n_leg_unknowns(), model.n_tendons());
        let tendons = || (0..3).flat_map(move |leg| (0..nt).map(move |k| 6 + leg * nu + k));
        for j in tendons() {
            x[j] = -1e-9;
        }
        let mut buffers = Buffers::new(&model);
        let mut system = buffers.fk_at_zero(&model);
        let n = x.len();
        let (mut r, mut r0, mut r1) = (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
        let (mut jac, mut jac_at_kink) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        let mut column = DVector::zeros(n);
        let mut at_kink = x.clone();
        for j in tendons() {
            at_kink[j] = 0.0;
        }
        system
            .residual_and_jacobian(&at_kink, &mut r0, &mut jac_at_kink)
            .unwrap();
        system.residual_and_jacobian(&x, &mut r, &mut jac).unwrap();
        let mut step = DVector::from_element(n, 1e-3);
        for j in tendons() {
            // The Jacobian at x holds the slack slope: −1 in the length row only.
            assert_eq!(jac.column(j).iter().filter(|v| **v != 0.0).count(), 1);
            // Into taut: the taut side's slope, which the Jacobian at the kink holds, and a
            // one-sided difference from the kink.
            // Anchored at the kink ζ = 0: the distance is ζ.
            assert_eq!(
                system.one_sided_column(&x, &step, j, &mut column),
                Some(x[j])
            );
            assert!((&column - jac_at_kink.column(j)).amax() < 1e-12 * column.amax());
            // A second-order one-sided difference, (−3 b(0) + 4 b(h) − b(2h)) / 2h: the
            // residual's round-off is ~1e-11 N (the shear force is K_se (v − v*) with
            // K_se ~ 1e4 N), so h = 1e-4 N.
            let h = 1e-4;
            let mut xh = at_kink.clone();
            xh[j] = h;
            system.residual(&xh, &mut r1).unwrap();
            xh[j] = 2.0 * h;
            system.residual(&xh, &mut r).unwrap();
            let fd = (&r1 * 4.0 - &r0 * 3.0 - &r) / (2.0 * h);
            let error = (&fd - &column).amax() / column.amax();
            assert!(error < 1e-6, "unknown {j}: {error:e}");
            // Staying slack: the Jacobian's own.
            step[j] = -1e-3;
            assert!(system.one_sided_column(&x, &step, j, &mut column).is_none());
            step[j] = 1e-3;
        }
        // Only at the point of the last exact Jacobian.
        let mut other = x.clone();
        other[0] += 1e-6;
        assert!(
            system
                .one_sided_column(&other, &step, 6, &mut column)
                .is_none()
        );
        assert_eq!(system.one_sided_columns_used.get(), 3 * nt);
    }
}
