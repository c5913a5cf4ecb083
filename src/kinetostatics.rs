//! Forward and inverse kinetostatics of the parallel robot by shooting (MODEL.md §3):
//! Newton on the boundary residual b with the exact Jacobian (or the finite-difference
//! baseline), globalized by the dogleg trust region of [`crate::newton`].
//!
//! - FK: given q and the wrench, unknowns [p_ee (3), θ_ee (3), y_u (3 (6 + n_t))];
//!   Jacobian \[B_x B_u\]. Rotation steps compose: R ← exp(δθ^) R.
//! - IK (6-DoF design): given the pose and the wrench, unknowns \[q (6), y_u\];
//!   Jacobian \[B_q B_u\].
//!
//! A cold start uses the straight home guess of MODEL.md §9 (legs straight, strains
//! consistent with tensions from a constant-curvature estimate, γ never 0); if that fails
//! for FK, the actuation is ramped from zero in steps (continuation).

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use crate::boundary::{
    BoundaryJacobians, BoundaryPoint, BoundaryScratch, FiniteDifference, boundary_derivatives,
    boundary_derivatives_fd, boundary_residual, convert_tendon_unknowns,
};
use crate::design::Tdpcr;
use crate::error::{Error, SolveError, StopReason, Violations};
use crate::linalg::DenseLu;
use crate::model::{Model, Pose};
use crate::newton::{self, NewtonReport, NewtonScratch, NewtonSettings, NonlinearSystem};
use crate::redundancy::{Redundancy, within_limits_ik};
use crate::rod::Wrench;
use crate::rod::tendon::TendonUnknown;

/// The tendon variable Newton iterates on (states report γ): the piecewise-linear ζ
/// converges in a few steps where γ stalls near the taut/slack boundary.
pub(crate) const SOLVER_TENDON_UNKNOWN: TendonUnknown = TendonUnknown::Linear;

/// Weight ε of the scaled leg unknowns in the least-norm IK step (q in metres). Without
/// it the step can move far along null-space directions that change q little (measured:
/// the line search then stalls; 1e-6 to 1e-4 converge in 3–5 steps).
pub(crate) const LEAST_NORM_Y_WEIGHT: f64 = 1e-6;
use crate::tdcr::{TendonControl, cold_guess_at};

/// How the Newton Jacobian is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JacobianMethod {
    /// Exact, from forward sensitivities.
    Exact,
    /// The paper's finite-difference baseline.
    FiniteDifference(FiniteDifference),
}

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
    /// tendon variable (converted back to γ).
    pub(crate) fn at_pose(model: &Model, pose: &Pose, q: Vec<f64>, mut y_u: Vec<f64>) -> Self {
        convert_tendon_unknowns(model, &mut y_u, SOLVER_TENDON_UNKNOWN, TendonUnknown::Gamma);
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

/// A converged solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The configuration.
    pub state: RobotState,
    /// Newton work and final residual norm.
    pub report: NewtonReport,
    /// Wall time of the solve \[µs\].
    pub solve_time_us: f64,
    /// The external wrench it was solved under, beyond the platform's weight (the `extra`
    /// of the solve; the state is the equilibrium under it): [`Solver::analyze_solution`]
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

/// Solves FK and IK problems of one design; holds every buffer.
#[derive(Debug, Clone)]
pub struct Solver {
    model: Model,
    boundary: BoundaryScratch,
    blocks: BoundaryJacobians,
    newton: NewtonScratch,
    /// Newton settings (tolerance on ‖b‖₂ in SI units, iteration limit).
    pub settings: NewtonSettings,
    /// Jacobian used by Newton.
    pub jacobian: JacobianMethod,
    /// How IK of the 9-DoF design chooses among its solutions (least-norm steps by
    /// default; [`Redundancy::WithinLimits`] keeps q within its limits).
    pub redundancy: Redundancy,
    /// The last converged square solve whose factorized Jacobian is still in `newton`
    /// (the tangent predictor of warm starts from it).
    last: Option<LastSolve>,
}

/// What the Newton scratch's factorized Jacobian linearizes.
#[derive(Debug, Clone, PartialEq)]
struct LastSolve {
    /// The solution.
    state: RobotState,
    /// The total wrench it was solved under.
    wrench: Wrench,
    /// FK (true) or square IK (false).
    forward: bool,
}

/// Tendon crossings earlier than this fraction of a Newton step do not limit it.
const STEP_LIMIT_MIN_FRACTION: f64 = 0.05;

/// First continuation step in λ.
const CONTINUATION_FIRST_STEP: f64 = 0.25;
/// Pretension \[N\] of the continuation's start: every tendon taut (γ = 1, far from the
/// γ = 0 trap of MODEL.md §9), relaxed to the design's pretension as λ → 1.
const CONTINUATION_PRETENSION: f64 = 1.0;
/// Newton iterations allowed per continuation step before the step is halved.
const CONTINUATION_MAX_ITERATIONS: usize = 25;

/// How the loads evolve along a continuation.
#[derive(Debug, Clone, Copy)]
enum Loads {
    /// The full loads throughout.
    Full,
    /// From zero to full with λ, with an auxiliary `pretension` \[N\] relaxing to the design's.
    FromUnloaded { pretension: f64 },
}

/// The continuation target at one λ.
enum Target {
    Forward(Vec<f64>),
    Inverse(Pose),
}

/// What is being solved for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Problem<'a> {
    Forward { q: &'a [f64] },
    Inverse { pose: &'a Pose },
}

impl Solver {
    /// A solver for a validated design.
    pub fn new(design: &Tdpcr) -> Self {
        let model = Model::new(design);
        let settings = NewtonSettings::default();
        let n = model.n_residuals();
        Self {
            boundary: BoundaryScratch::new(&model),
            blocks: BoundaryJacobians::new(&model),
            newton: NewtonScratch::new(n, settings.max_iterations),
            model,
            settings,
            jacobian: JacobianMethod::Exact,
            redundancy: Redundancy::LeastNorm,
            last: None,
        }
    }

    /// The robot model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The total wrench on the platform: its weight plus `extra`.
    pub fn total_wrench(&self, extra: &Wrench) -> Wrench {
        Wrench {
            force: self.model.platform_weight + extra.force,
            moment: extra.moment,
        }
    }

    fn check_wrench(v: &mut Violations, w: &Wrench) {
        for (i, x) in w.force.iter().chain(w.moment.iter()).enumerate() {
            if !x.is_finite() {
                v.push(format!("wrench[{i}]"), x, "a finite number");
            }
        }
    }

    /// Adds the wrench and warm-start checks to `v`; the total wrench if nothing failed.
    fn checked_wrench(
        &self,
        mut v: Violations,
        extra: &Wrench,
        init: Option<&RobotState>,
    ) -> Result<Wrench, Error> {
        Self::check_wrench(&mut v, extra);
        self.check_init(&mut v, init);
        self.settings.check("settings", &mut v);
        if v.0.is_empty() {
            Ok(self.total_wrench(extra))
        } else {
            Err(Error::Input(v))
        }
    }

    fn check_init(&self, v: &mut Violations, init: Option<&RobotState>) {
        if let Some(s) = init {
            if s.q.len() != self.model.n_actuators() {
                v.push(
                    "init.q",
                    format!("{} values", s.q.len()),
                    &format!("{} values", self.model.n_actuators()),
                );
            }
            let ny = 3 * self.model.n_leg_unknowns();
            if s.y_u.len() != ny {
                v.push(
                    "init.y_u",
                    format!("{} values", s.y_u.len()),
                    &format!("{ny} values"),
                );
            }
            let all = s.position.iter().chain(&s.rotvec).chain(&s.q).chain(&s.y_u);
            if !all.clone().all(|x| x.is_finite()) {
                v.push("init", "a non-finite value", "finite numbers");
            }
        }
    }

    /// Forward kinetostatics: the pose and leg states for actuation `q` under the platform
    /// weight plus `extra` (world frame, at the platform centre).
    ///
    /// # Errors
    /// [`Error::Input`] for a q of the wrong length or non-finite values;
    /// [`Error::Solve`] with residual norm and iterations if Newton fails.
    pub fn solve_fk(
        &mut self,
        q: &[f64],
        extra: &Wrench,
        init: Option<&RobotState>,
    ) -> Result<Solution, Error> {
        let mut v = Violations::default();
        let n = self.model.n_actuators();
        if q.len() != n {
            v.push(
                "q",
                format!("{} values", q.len()),
                &format!("{n} values: per leg [bend_x, (bend_y), translation]"),
            );
        }
        for (i, x) in q.iter().enumerate() {
            if !x.is_finite() {
                v.push(format!("q[{i}]"), x, "a finite number [m]");
            }
        }
        let wrench = self.checked_wrench(v, extra, init)?;
        let start = Instant::now();
        let result = match init {
            Some(s) => {
                let settings = self.settings;
                let direct = self.solve_target(
                    None,
                    &settings,
                    &Target::Forward(q.to_vec()),
                    &wrench,
                    s.clone(),
                );
                // A warm start too far away: follow the straight line in q from it.
                direct.or_else(|e| self.ramp_actuation(s.clone(), q, &wrench).map_err(|_| e))
            }
            None => self.cold_fk(q, &wrench),
        };
        finish(result, start, extra)
    }

    /// Inverse kinetostatics: actuation and leg states that hold the platform at `pose`
    /// under its weight plus `extra`. The 6-DoF design solves the square system; the 9-DoF
    /// design resolves its redundancy as [`Solver::redundancy`] says: by default the
    /// least-norm change of q at every Gauss–Newton step, or with
    /// [`Redundancy::WithinLimits`] a QP step that keeps q within its limits
    /// ([`crate::redundancy`]).
    ///
    /// # Errors
    /// As [`Solver::solve_fk`].
    pub fn solve_ik(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        init: Option<&RobotState>,
    ) -> Result<Solution, Error> {
        let wrench = self.checked_wrench(pose_violations(pose), extra, init)?;
        let start = Instant::now();
        let guess = match init {
            Some(s) => RobotState {
                position: pose.position.into(),
                rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
                    .scaled_axis()
                    .into(),
                ..s.clone()
            },
            None if self.model.pairs == 1 => {
                return finish(self.cold_ik(pose, &wrench), start, extra);
            }
            None => self.home_guess(pose, &straight_leg_translations(&self.model, pose), &wrench),
        };
        let settings = self.settings;
        let direct = self.solve_target(None, &settings, &Target::Inverse(*pose), &wrench, guess);
        let result = match (direct, init) {
            // A warm start too far away: follow the pose path from it.
            (Err(e), Some(s)) if s.q.len() == self.model.n_actuators() => {
                self.ramp_pose(s.clone(), pose, &wrench).map_err(|_| e)
            }
            (r, _) => r,
        };
        finish(result, start, extra)
    }

    /// IK of the redundant (9-DoF) design: Gauss–Newton steps that change q least,
    /// min ½‖δq‖² + ½ε‖D δy‖² subject to B_q δq + B_u δy = −b (a KKT system; ε =
    /// [`LEAST_NORM_Y_WEIGHT`] on the column-scaled leg unknowns keeps the step bounded in
    /// the null space), with a backtracking line search on the weighted residual.
    fn least_norm_ik(
        &mut self,
        scaled: Option<&Model>,
        settings: &NewtonSettings,
        pose: &Pose,
        wrench: &Wrench,
        guess: RobotState,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        self.last = None;
        let model = scaled.unwrap_or(&self.model);
        let (nq, nu, m) = (
            model.n_actuators(),
            3 * model.n_leg_unknowns(),
            model.n_residuals(),
        );
        let n = nq + nu + m;
        let mut q = guess.q.clone();
        let mut y = guess.y_u.clone();
        convert_tendon_unknowns(model, &mut y, TendonUnknown::Gamma, SOLVER_TENDON_UNKNOWN);
        let mut weights = DVector::zeros(m);
        row_weights(model, &mut weights);
        let mut r = DVector::zeros(m);
        let mut kkt = DMatrix::zeros(n, n);
        let mut rhs = DVector::zeros(n);
        let mut lu = DenseLu::new(n);
        let mut report = NewtonReport::none();
        let mut first_norm = f64::NAN;
        loop {
            let p = BoundaryPoint {
                pose,
                q: &q,
                wrench,
                y_u: &y,
                tendon_unknown: SOLVER_TENDON_UNKNOWN,
            };
            boundary_derivatives(model, &mut self.boundary, &p, &mut r, &mut self.blocks)?;
            report.residual_evaluations += 1;
            report.jacobian_evaluations += 1;
            report.residual_norm = r.norm();
            if report.iterations == 0 {
                first_norm = report.residual_norm;
            }
            if report.residual_norm <= settings.tolerance {
                return Ok((RobotState::at_pose(model, pose, q, y), report));
            }
            if let Some(reason) =
                settings.stop_reason(report.iterations, first_norm, report.residual_norm)
            {
                return Err(SolveError::NotConverged {
                    iterations: report.iterations,
                    residual_norm: report.residual_norm,
                    tolerance: settings.tolerance,
                    reason,
                });
            }
            // [I 0 Aᵀ; 0 0 Cᵀ; A C 0] [δq; δỹ; λ] = [0; 0; −W b] with A = W B_q,
            // C = W B_u D⁻¹ (rows weighted, y columns scaled to unit norm; δy = D⁻¹ δỹ).
            let mut a = self.blocks.b_q.clone();
            let mut c = self.blocks.b_u.clone();
            for i in 0..m {
                a.row_mut(i).scale_mut(weights[i]);
                c.row_mut(i).scale_mut(weights[i]);
            }
            let scale: Vec<f64> = (0..nu)
                .map(|j| {
                    let norm = c.column(j).norm();
                    if norm > 0.0 { 1.0 / norm } else { 1.0 }
                })
                .collect();
            for j in 0..nu {
                c.column_mut(j).scale_mut(scale[j]);
            }
            kkt.fill(0.0);
            rhs.fill(0.0);
            for i in 0..nq {
                kkt[(i, i)] = 1.0;
            }
            // A small weight on the (scaled) leg unknowns keeps the step out of the
            // null-space directions that move y much and q little.
            for j in 0..nu {
                kkt[(nq + j, nq + j)] = LEAST_NORM_Y_WEIGHT;
            }
            kkt.view_mut((nq + nu, 0), (m, nq)).copy_from(&a);
            kkt.view_mut((nq + nu, nq), (m, nu)).copy_from(&c);
            kkt.view_mut((0, nq + nu), (nq, m))
                .copy_from(&a.transpose());
            kkt.view_mut((nq, nq + nu), (nu, m))
                .copy_from(&c.transpose());
            for i in 0..m {
                rhs[nq + nu + i] = -r[i] * weights[i];
            }
            if lu.factor(&kkt).is_err() {
                return Err(SolveError::NotConverged {
                    iterations: report.iterations,
                    residual_norm: report.residual_norm,
                    tolerance: settings.tolerance,
                    reason: StopReason::SingularLeastNormStep,
                });
            }
            lu.solve_in_place(&mut rhs);
            for j in 0..nu {
                rhs[nq + j] *= scale[j];
            }
            let step = (&rhs.as_slice()[..nq], &rhs.as_slice()[nq..nq + nu]);
            let at = (pose, wrench);
            if !backtrack(
                model,
                &mut self.boundary,
                at,
                (&weights, &r),
                (&mut q, &mut y),
                step,
                &mut report,
            ) {
                return Err(SolveError::NotConverged {
                    iterations: report.iterations,
                    residual_norm: report.residual_norm,
                    tolerance: settings.tolerance,
                    reason: StopReason::LineSearchFailed,
                });
            }
            report.iterations += 1;
        }
    }

    /// The straight home guess for platform `pose` and actuation `q`.
    pub fn home_guess(&self, pose: &Pose, q: &[f64], wrench: &Wrench) -> RobotState {
        home_guess(&self.model, pose, q, wrench)
    }

    /// Cold FK: Newton from the straight guess; if that fails, q is ramped from the solved
    /// q = 0 configuration; last, continuation from the unloaded straight home. Where one
    /// q has several equilibria (e.g. legs buckled one way or the other under large base
    /// translations), this returns the one Newton reaches from the straight guess, not
    /// necessarily the one a robot moved there from home is in: warm-start from a known
    /// state (or follow a trajectory) to stay on a branch.
    fn cold_fk(
        &mut self,
        q: &[f64],
        wrench: &Wrench,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let pose = straight_leg_pose(&self.model, q);
        let guess = self.home_guess(&pose, q, wrench);
        let direct = self.run(Problem::Forward { q }, wrench, guess);
        if direct.is_ok() {
            return direct;
        }
        // Ramp q from the solved q = 0 configuration under the same loads.
        let zero = vec![0.0; q.len()];
        let home = if q.iter().all(|&x| x == 0.0) {
            None
        } else {
            let pose = straight_leg_pose(&self.model, &zero);
            let guess = self.home_guess(&pose, &zero, wrench);
            self.run(Problem::Forward { q: &zero }, wrench, guess).ok()
        };
        if let Some((home, r)) = home {
            if let Ok((state, mut report)) = self.ramp_actuation(home, q, wrench) {
                report.add_work(&r);
                return Ok((state, report));
            }
        }
        let q_final = q.to_vec();
        self.continuation(wrench, &|lambda: f64| {
            Target::Forward(q_final.iter().map(|x| x * lambda).collect())
        })
        .or(direct)
    }

    /// Solves for one target (FK, square IK or least-norm IK) from `guess`.
    /// `scaled` replaces the model when given (continuation of the loads).
    fn solve_target(
        &mut self,
        scaled: Option<&Model>,
        settings: &NewtonSettings,
        target: &Target,
        wrench: &Wrench,
        mut guess: RobotState,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        match target {
            Target::Forward(q) => {
                guess.q = q.clone();
                self.run_with(scaled, settings, Problem::Forward { q }, wrench, guess)
            }
            Target::Inverse(pose) if self.model.pairs == 1 => {
                self.run_with(scaled, settings, Problem::Inverse { pose }, wrench, guess)
            }
            Target::Inverse(pose) => match &self.redundancy {
                Redundancy::LeastNorm => self.least_norm_ik(scaled, settings, pose, wrench, guess),
                Redundancy::WithinLimits(objective) => within_limits_ik(
                    scaled.unwrap_or(&self.model),
                    &mut self.boundary,
                    &mut self.blocks,
                    settings,
                    pose,
                    wrench,
                    guess,
                    objective,
                ),
            },
        }
    }

    /// Follows `target(λ)`, λ: 0 → 1, from `start` (the solution at λ = 0), warm-starting
    /// each step; the step is halved when Newton needs more than
    /// [`CONTINUATION_MAX_ITERATIONS`] and doubled after an easy step. With
    /// [`Loads::FromUnloaded`] the gravity loads and `wrench` grow with λ and the auxiliary
    /// pretension relaxes to the design's; intermediate steps then stop at 1e-7.
    fn ramp(
        &mut self,
        start: RobotState,
        wrench: &Wrench,
        target: &dyn Fn(f64) -> Target,
        loads: Loads,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let last_settings = NewtonSettings {
            max_iterations: CONTINUATION_MAX_ITERATIONS.min(self.settings.max_iterations),
            ..self.settings
        };
        let intermediate = match loads {
            Loads::Full => last_settings,
            Loads::FromUnloaded { .. } => NewtonSettings {
                tolerance: last_settings.tolerance.max(1e-7),
                ..last_settings
            },
        };
        let mut state = start;
        let mut total = NewtonReport::none();
        let (mut lambda, mut step) = (0.0f64, CONTINUATION_FIRST_STEP);
        while lambda < 1.0 {
            let next = (lambda + step).min(1.0);
            let settings = if next >= 1.0 {
                last_settings
            } else {
                intermediate
            };
            let (scaled, w) = match loads {
                Loads::Full => (None, *wrench),
                Loads::FromUnloaded { pretension } => (
                    Some(self.model.with_homotopy(
                        next,
                        pretension + (self.model.pretension - pretension) * next,
                    )),
                    Wrench {
                        force: wrench.force * next,
                        moment: wrench.moment * next,
                    },
                ),
            };
            match self.solve_target(scaled.as_ref(), &settings, &target(next), &w, state.clone()) {
                Ok((s, r)) => {
                    total.add_work(&r);
                    total.residual_norm = r.residual_norm;
                    state = s;
                    lambda = next;
                    if r.iterations <= 4 {
                        step *= 2.0;
                    }
                }
                Err(e) => {
                    if let SolveError::NotConverged { iterations, .. } = e {
                        total.iterations += iterations;
                    }
                    step /= 2.0;
                    if step < 1.0 / 256.0 {
                        return Err(match e {
                            SolveError::NotConverged {
                                residual_norm,
                                tolerance,
                                ..
                            } => SolveError::NotConverged {
                                iterations: total.iterations,
                                residual_norm,
                                tolerance,
                                reason: StopReason::ContinuationStalled,
                            },
                            other => other,
                        });
                    }
                }
            }
        }
        Ok((state, total))
    }

    /// FK along q(λ) = q_start + λ (q − q_start) from the solved `start`.
    fn ramp_actuation(
        &mut self,
        start: RobotState,
        q: &[f64],
        wrench: &Wrench,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let q0 = start.q.clone();
        let q1 = q.to_vec();
        let target = move |l: f64| {
            Target::Forward(q0.iter().zip(&q1).map(|(a, b)| a + (b - a) * l).collect())
        };
        self.ramp(start, wrench, &target, Loads::Full)
    }

    /// IK along the pose interpolated from `start`'s pose to `pose` (position linearly,
    /// rotation along the geodesic).
    fn ramp_pose(
        &mut self,
        start: RobotState,
        pose: &Pose,
        wrench: &Wrench,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let p0 = start.pose();
        let (dp, dr) = (
            pose.position - p0.position,
            Rotation3::from_matrix_unchecked(pose.rotation * p0.rotation.transpose()).scaled_axis(),
        );
        let target = move |l: f64| {
            Target::Inverse(Pose {
                position: p0.position + dp * l,
                rotation: Rotation3::new(dr * l).matrix() * p0.rotation,
            })
        };
        self.ramp(start, wrench, &target, Loads::Full)
    }

    /// Cold IK: Newton from the straight guess; if that fails, continuation from the
    /// unloaded straight home configuration.
    fn cold_ik(
        &mut self,
        pose: &Pose,
        wrench: &Wrench,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let guess = self.home_guess(pose, &straight_leg_translations(&self.model, pose), wrench);
        let direct = self.run(Problem::Inverse { pose }, wrench, guess);
        if direct.is_ok() {
            return direct;
        }
        let (p, phi) = (
            pose.position,
            Rotation3::from_matrix_unchecked(pose.rotation).scaled_axis(),
        );
        self.continuation(wrench, &|lambda: f64| {
            Target::Inverse(Pose {
                position: p * lambda,
                rotation: *Rotation3::new(phi * lambda).matrix(),
            })
        })
        .or(direct)
    }

    /// Homotopy from the unloaded straight home configuration (an exact solution with an
    /// auxiliary pretension that keeps every tendon taut) to `target(1)` under the full
    /// loads and the design's pretension; see [`Solver::ramp`].
    fn continuation(
        &mut self,
        wrench: &Wrench,
        target: &dyn Fn(f64) -> Target,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let zero = vec![0.0; self.model.n_actuators()];
        let home = straight_leg_pose(&self.model, &zero);
        let pretension = CONTINUATION_PRETENSION.max(self.model.pretension);
        let start = home_guess(
            &self.model.with_homotopy(0.0, pretension),
            &home,
            &zero,
            &Wrench::default(),
        );
        self.ramp(start, wrench, target, Loads::FromUnloaded { pretension })
    }

    /// Newton from `guess` on `problem` with the solver's model.
    fn run(
        &mut self,
        problem: Problem,
        wrench: &Wrench,
        guess: RobotState,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let settings = self.settings;
        self.run_with(None, &settings, problem, wrench, guess)
    }

    /// Newton from `guess` on `problem`, with `scaled` replacing the model if given.
    fn run_with(
        &mut self,
        scaled: Option<&Model>,
        settings: &NewtonSettings,
        problem: Problem,
        wrench: &Wrench,
        guess: RobotState,
    ) -> Result<(RobotState, NewtonReport), SolveError> {
        let model = scaled.unwrap_or(&self.model);
        let n_u = 3 * model.n_leg_unknowns();
        let from_last = scaled.is_none() && self.is_last_solution(problem, wrench, &guess);
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
            self.predict(problem, &x)
        } else {
            None
        };
        self.last = None;
        let mut system = ShootingSystem {
            model,
            boundary: &mut self.boundary,
            blocks: &mut self.blocks,
            method: self.jacobian,
            problem,
            wrench,
        };
        // From the tangent prediction if there is one; from the guess itself if that fails.
        let report = match predicted {
            Some(mut xp) => match newton::solve(&mut system, &mut xp, settings, &mut self.newton) {
                Ok(r) => {
                    x = xp;
                    Ok(r)
                }
                Err(_) => newton::solve(&mut system, &mut x, settings, &mut self.newton),
            },
            None => newton::solve(&mut system, &mut x, settings, &mut self.newton),
        }?;
        let mut y_u: Vec<f64> = x.rows(n_head, n_u).iter().copied().collect();
        convert_tendon_unknowns(model, &mut y_u, SOLVER_TENDON_UNKNOWN, TendonUnknown::Gamma);
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
        if scaled.is_none() && self.jacobian == JacobianMethod::Exact {
            self.last = Some(LastSolve {
                state: state.clone(),
                wrench: *wrench,
                forward: matches!(problem, Problem::Forward { .. }),
            });
        }
        Ok((state, report))
    }

    /// Whether `guess` is the last solution with only the target of `problem` changed
    /// (FK: q; IK: the pose), under the same wrench.
    fn is_last_solution(&self, problem: Problem, wrench: &Wrench, guess: &RobotState) -> bool {
        let Some(last) = self.last.as_ref() else {
            return false;
        };
        let same_legs = last.wrench == *wrench && last.state.y_u == guess.y_u;
        match problem {
            Problem::Forward { .. } => {
                last.forward
                    && same_legs
                    && last.state.position == guess.position
                    && last.state.rotvec == guess.rotvec
            }
            Problem::Inverse { .. } => !last.forward && same_legs && last.state.q == guess.q,
        }
    }

    /// The first-order (tangent) prediction of the solution of `problem` from the last
    /// solve: FK \[δx; δy\] = −\[B_x B_u\]⁻¹ B_q δq, IK \[δq; δy\] = −\[B_q B_u\]⁻¹ B_x δx
    /// (MODEL.md §4), with the exact Jacobian factorized in the last Newton iteration (near
    /// the solution). `x` is the last solution in the solver's unknowns with the new target;
    /// the prediction is returned in the same form.
    fn predict(&self, problem: Problem, x: &DVector<f64>) -> Option<DVector<f64>> {
        let last = self.last.as_ref()?;
        let mut rhs = DVector::zeros(self.model.n_residuals());
        match problem {
            Problem::Forward { q } => {
                for (j, (a, b)) in q.iter().zip(&last.state.q).enumerate() {
                    rhs.axpy(-(a - b), &self.blocks.b_q.column(j), 1.0);
                }
            }
            Problem::Inverse { pose } => {
                let from = last.state.pose();
                let dp = pose.position - from.position;
                let dtheta =
                    Rotation3::from_matrix_unchecked(pose.rotation * from.rotation.transpose())
                        .scaled_axis();
                for c in 0..3 {
                    rhs.axpy(-dp[c], &self.blocks.b_x.column(c), 1.0);
                    rhs.axpy(-dtheta[c], &self.blocks.b_x.column(3 + c), 1.0);
                }
            }
        }
        self.newton.solve_with_last_jacobian(&mut rhs)?;
        let mut out = DVector::zeros(x.len());
        retract(problem, x, &rhs, &mut out);
        Some(out)
    }

    /// ‖b‖₂ after each iteration of the last Newton run (the last continuation step when
    /// a solve needed continuation).
    pub fn residual_history(&self) -> &[f64] {
        self.newton.residual_history()
    }

    /// The model and the blocks of the last evaluation (after [`Solver::blocks_at`]).
    pub(crate) fn model_and_blocks(&self) -> (&Model, &BoundaryJacobians) {
        (&self.model, &self.blocks)
    }

    /// The residual and exact blocks at a state (for analysis and tests).
    ///
    /// # Errors
    /// [`SolveError::NonFinite`] if a leg integration blows up.
    pub fn blocks_at(
        &mut self,
        state: &RobotState,
        extra: &Wrench,
    ) -> Result<(DVector<f64>, &BoundaryJacobians), SolveError> {
        let wrench = self.total_wrench(extra);
        let pose = state.pose();
        let p = state.boundary_point(&pose, &wrench);
        self.last = None;
        let mut r = DVector::zeros(self.model.n_residuals());
        boundary_derivatives(
            &self.model,
            &mut self.boundary,
            &p,
            &mut r,
            &mut self.blocks,
        )?;
        Ok((r, &self.blocks))
    }
}

/// The straight home guess (MODEL.md §9) for platform `pose` and actuation `q` under the
/// loads of `m`: legs straight, each carrying a third of `wrench`, tensions from the
/// constant-curvature estimate, base strains consistent with them.
pub fn home_guess(m: &Model, pose: &Pose, q: &[f64], wrench: &Wrench) -> RobotState {
    let share = Wrench {
        force: wrench.force / 3.0,
        moment: Vector3::zeros(),
    };
    let mut y_u = Vec::with_capacity(3 * m.n_leg_unknowns());
    for i in 0..3 {
        let d = m.tendon_displacements(i, q);
        let control = TendonControl::Displacement(d[..m.n_tendons()].to_vec());
        let g = cold_guess_at(&m.leg, &m.bases[i].rotation, &control, &share);
        y_u.extend(g.gammas);
        y_u.extend(g.u0);
        y_u.extend(g.v0);
    }
    RobotState {
        position: pose.position.into(),
        rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
            .scaled_axis()
            .into(),
        q: q.to_vec(),
        y_u,
    }
}

fn finish(
    result: Result<(RobotState, NewtonReport), SolveError>,
    start: Instant,
    extra: &Wrench,
) -> Result<Solution, Error> {
    let (state, report) = result?;
    Ok(Solution {
        state,
        report,
        solve_time_us: start.elapsed().as_secs_f64() * 1e6,
        extra: *extra,
    })
}

/// Base translations that put straight legs' joints closest to the coupling points of
/// `pose`: q_t,i = t_i · (joint_i − home joint_i); bending zero.
pub fn straight_leg_translations(model: &Model, pose: &Pose) -> Vec<f64> {
    let mut q = vec![0.0; model.n_actuators()];
    for i in 0..3 {
        let joint = pose.position + pose.rotation * model.coupling_points[i];
        q[i * (model.pairs + 1) + model.pairs] =
            model.tangents[i].dot(&(joint - model.coupling_points[i]));
    }
    q
}

/// The platform pose that best fits straight legs on bases translated by q (Kabsch).
pub fn straight_leg_pose(model: &Model, q: &[f64]) -> Pose {
    let joints: Vec<Vector3<f64>> = (0..3)
        .map(|i| model.coupling_points[i] + model.tangents[i] * model.translation(i, q))
        .collect();
    let centroid = (joints[0] + joints[1] + joints[2]) / 3.0;
    let body_centroid =
        (model.coupling_points[0] + model.coupling_points[1] + model.coupling_points[2]) / 3.0;
    let mut h = Matrix3::zeros();
    for i in 0..3 {
        h += (model.coupling_points[i] - body_centroid) * (joints[i] - centroid).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = vt.transpose() * d * u.transpose();
    Pose {
        position: centroid - rotation * body_centroid,
        rotation,
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

/// Backtracking line search of an IK step (least-norm or QP) from (q, y) (solver
/// tendon unknowns, residual `r` there) along (δq, δy): α = 1, ½, … until the weighted
/// residual ‖W b‖² falls below (1 − 1e-4 α) of ‖W r‖² (Armijo); moves (q, y) and
/// returns true, or false once α < 1e-6.
#[allow(clippy::too_many_arguments)]
pub(crate) fn backtrack(
    model: &Model,
    boundary: &mut BoundaryScratch,
    (pose, wrench): (&Pose, &Wrench),
    (weights, r): (&DVector<f64>, &DVector<f64>),
    (q, y): (&mut Vec<f64>, &mut Vec<f64>),
    (dq, dy): (&[f64], &[f64]),
    report: &mut NewtonReport,
) -> bool {
    let merit = |r: &DVector<f64>| r.component_mul(weights).norm_squared();
    let mut trial = DVector::zeros(model.n_residuals());
    let m0 = merit(r);
    let mut alpha = 1.0;
    while alpha >= 1e-6 {
        let q_t: Vec<f64> = q.iter().zip(dq).map(|(x, d)| x + alpha * d).collect();
        let y_t: Vec<f64> = y.iter().zip(dy).map(|(x, d)| x + alpha * d).collect();
        let p = BoundaryPoint {
            pose,
            q: &q_t,
            wrench,
            y_u: &y_t,
            tendon_unknown: SOLVER_TENDON_UNKNOWN,
        };
        report.residual_evaluations += 1;
        let ok = boundary_residual(model, boundary, &p, &mut trial).is_ok()
            && trial.iter().all(|x| x.is_finite());
        if ok && merit(&trial) < (1.0 - 1e-4 * alpha) * m0 {
            *q = q_t;
            *y = y_t;
            return true;
        }
        alpha *= 0.5;
    }
    false
}

/// The shooting problem as a [`NonlinearSystem`].
struct ShootingSystem<'a> {
    model: &'a Model,
    boundary: &'a mut BoundaryScratch,
    blocks: &'a mut BoundaryJacobians,
    method: JacobianMethod,
    problem: Problem<'a>,
    wrench: &'a Wrench,
}

impl ShootingSystem<'_> {
    fn head(&self) -> usize {
        match self.problem {
            Problem::Forward { .. } => 6,
            Problem::Inverse { .. } => self.model.n_actuators(),
        }
    }

    /// Evaluates the residual (and blocks if `jac` is given) at x.
    fn evaluate(
        &mut self,
        x: &DVector<f64>,
        r: &mut DVector<f64>,
        jac: Option<&mut DMatrix<f64>>,
    ) -> Result<(), SolveError> {
        let head = self.head();
        let (pose, q): (Pose, &[f64]) = match self.problem {
            Problem::Forward { q } => (
                Pose {
                    position: Vector3::new(x[0], x[1], x[2]),
                    rotation: *Rotation3::new(Vector3::new(x[3], x[4], x[5])).matrix(),
                },
                q,
            ),
            Problem::Inverse { pose } => (*pose, &x.as_slice()[..head]),
        };
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
        match self.method {
            JacobianMethod::Exact => {
                boundary_derivatives(self.model, self.boundary, &p, r, self.blocks)?
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
}

/// x ⊕ step in the unknowns of `problem`: FK rotations compose, R ← exp(δθ^) R.
fn retract(problem: Problem, x: &DVector<f64>, step: &DVector<f64>, out: &mut DVector<f64>) {
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

/// A pose with a non-finite entry, as a violation.
fn pose_violations(pose: &Pose) -> Violations {
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

/// Path following without fallbacks (additive; used by the workspace sweep).
impl Solver {
    /// IK by one Newton run from `guess`, without the continuation fallback of
    /// [`Solver::solve_ik`]: for path following, where a step that fails ends the path
    /// (the workspace rays of MODEL.md §6) and a fallback would only cost time. The
    /// guess's pose is replaced by `pose`; its q and y_u are the start.
    ///
    /// # Errors
    /// As [`Solver::solve_ik`].
    pub fn solve_ik_newton(
        &mut self,
        pose: &Pose,
        extra: &Wrench,
        guess: &RobotState,
    ) -> Result<Solution, Error> {
        let wrench = self.checked_wrench(pose_violations(pose), extra, Some(guess))?;
        let start = Instant::now();
        let guess = RobotState {
            position: pose.position.into(),
            rotvec: Rotation3::from_matrix_unchecked(pose.rotation)
                .scaled_axis()
                .into(),
            ..guess.clone()
        };
        let settings = self.settings;
        let result = self.solve_target(None, &settings, &Target::Inverse(*pose), &wrench, guess);
        finish(result, start, extra)
    }
}
